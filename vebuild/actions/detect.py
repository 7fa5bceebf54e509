"""Detected vanishing segments: proposals per photo, and their acceptance as ordinary marks.

:func:`detect_photo` decodes a photo (vebuild.project.images.decode_photo: EXIF orientation,
RAW), finds its straight edges and groups them into three orthogonal vanishing directions
(vebuild.calibration.lines), and proposes per world axis the segments that agree, directed by
DESIGN.md's convention. :func:`accept_proposals` writes proposals into the project document as
ordinary ``vanishing_segments``, each with its own measured 1σ in the parallel
``vanishing_segment_sigmas`` (scenes/FORMAT.md), which the calibration weights it by.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from vebuild.calibration.clutter import curved, short, textured
from vebuild.calibration.exif import exif_distortion_prior, exif_focal_prior
from vebuild.calibration.lines import (
    DARK_MEAN_GREY,
    X_AXIS_CHOICES,
    detect_lines,
    direct_segment,
    group_manhattan,
    orient_axes,
    plumb_line_k1,
    single_vanishing_point,
    to_grey,
)
from vebuild.calibration.vanishing import fit_vanishing_point
from vebuild.camera import AXES, Lens, distort_pixels, intrinsic_matrix, undistort_pixels
from vebuild.errors import ProjectError, VebuildError
from vebuild.project import Project
from vebuild.project.images import decode_photo

from .detect_checks import drop_same_point, one_image_line, weak_axes
from .detect_types import Grouped, PhotoProposals, SegmentProposal
from .x_axis import auto_x_axes, choice_from_segments
from .x_axis import choice_turns as choice_turns  # the x-axis choice, named here too
from .x_axis import marker_rays as marker_rays

#: At most this many proposals per axis are kept (the best-scored): more add little to a
#: calibration and slow it.
MAX_PER_AXIS = 40
#: An axis is proposed with this many segments at least: two lines always meet, so a pair has no
#: redundancy to show that one of them (a poster's edge, clutter) belongs to no axis.
MIN_PER_AXIS = 3
#: A focal estimate whose relative 1σ exceeds this is not reported (a frontal or level view).
FOCAL_REPORT_MAX_REL_SIGMA = 0.1


#: The photo field saying that its segments' x axis was not chosen (scenes/FORMAT.md), and why.
UNRESOLVED = "x_axis_unresolved"
#: ``--x-axis auto``: each photo's choice made from the markers the photos share (the default).
AUTO = "auto"


def check_x_axis(x_axis: str | None, where: str = "--x-axis", *, auto: bool = False) -> str:
    """The x-axis choice, default ``right`` (``auto`` where ``auto`` is allowed, and the default
    then); ProjectError naming ``where`` for an unknown one."""
    if x_axis is None:
        return AUTO if auto else "right"
    allowed = X_AXIS_CHOICES + ((AUTO,) if auto else ())
    if x_axis not in allowed:
        raise ProjectError("the command line", where, f"expected one of {', '.join(allowed)}, got {x_axis!r}")
    return x_axis


def x_axis_choices(project: Project, ids: Sequence[str], x_axis: str | Sequence[str] | None) -> dict[str, str]:
    """Photo id → its x-axis choice from ``--x-axis`` items (CHOICE or PHOTO=CHOICE; ``auto``,
    the default, to be chosen from the markers)."""
    items = [x_axis] if isinstance(x_axis, str) else list(x_axis or [])
    default = AUTO
    for item in items:
        if "=" not in item:
            default = check_x_axis(item, auto=True)
    out = {pid: default for pid in ids}
    for item in items:
        if "=" in item:
            pid, choice = item.split("=", 1)
            project.photo(pid)
            out[pid] = check_x_axis(choice, f"--x-axis {item}", auto=True)
    return out


def photo_pixels(project: Project, photo_id: str) -> np.ndarray:
    """The photo's pixels as displayed (ProjectError naming the file and field if unreadable)."""
    photo = project.photo(photo_id)
    index = project.data["photos"].index(photo)
    where = f"$.photos[{index}].file"
    path = project.photo_path(photo)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ProjectError(project.path, where, f"photo file not found: {path}") from None
    except OSError as e:
        raise ProjectError(project.path, where, f"cannot read the photo {path}: {e.strerror or e}") from None
    return decode_photo(data, path.name, project.path, where, label=str(path))


def detect_photo(project: Project, photo_id: str, *, x_axis: str | None = None) -> PhotoProposals:
    """Proposals of directed vanishing segments for one photo (nothing is written)."""
    choice = check_x_axis(x_axis)
    photo = project.photo(photo_id)
    pixels = photo_pixels(project, photo_id)
    return propose(pixels, photo, x_axis=choice)


def propose(pixels: np.ndarray, photo: dict[str, Any], *, x_axis: str = "right", seed: int = 0) -> PhotoProposals:
    """:func:`detect_photo` on pixels already decoded, for a photo object (its id, size, EXIF)."""
    return orient_proposals(group(pixels, photo, seed=seed), x_axis)


def group(pixels: np.ndarray, photo: dict[str, Any], *, seed: int = 0) -> Grouped:
    """Detect a photo's edges and group them into three orthogonal vanishing directions."""
    pid = str(photo.get("id", "photo"))
    h, w = pixels.shape[:2]
    t0 = time.perf_counter()
    grey = to_grey(pixels)
    found = detect_lines(grey)
    prior = exif_focal_prior(photo) if photo.get("exif") else None
    focal_prior = (prior.value, prior.sigma) if prior is not None else None
    dist = exif_distortion_prior(photo) if prior is not None else None
    k1 = dist.k1 if dist is not None else 0.0
    c = np.array([w / 2.0, h / 2.0])
    f0 = prior.value if prior else float(max(w, h))
    if len(found.segments) < 4:
        if found.mean_grey < DARK_MEAN_GREY:
            why = f"the photo is too dark (mean grey level {found.mean_grey:.0f} of 255): no edges to detect"
        else:
            segs = found.segments
            if k1 != 0.0 and len(segs):
                segs = undistort_pixels(intrinsic_matrix(f0, *c), segs.reshape(-1, 2), Lens(k1)).reshape(-1, 4)
            one = _one_direction(pid, segs, w, h, k1, f0 if prior is not None else None, seed, t0)
            if one.message.startswith("one direction only"):  # 3 edges meeting at one point
                return Grouped(pid, w, h, found, segs, k1, f0, None, time.perf_counter() - t0, one)
            why = (f"no straight lines found ({len(found.segments)} straight edges, at least 4 are needed"
                   + (", or 3 meeting at one vanishing point)" if len(found.segments) >= MIN_PER_AXIS else ")"))
        return Grouped(pid, w, h, found, found.segments, k1, 0.0, None, 0.0, PhotoProposals(pid, (), None, why))
    segs = found.segments
    if dist is None:
        # No lens profile: the edges' own bend (plumb lines) undistorts them for the grouping, so
        # that a wide lens's long edges are grouped too (the calibration estimates k1 itself).
        k1 = plumb_line_k1(found.polylines, found.polyline_sigma_px, f0, c, w, h)
    if k1 != 0.0:
        segs = undistort_pixels(intrinsic_matrix(f0, *c), found.segments.reshape(-1, 2), Lens(k1)).reshape(-1, 4)
    # Short edges, texture (cobbles, leaves) and curves (wires, branches) are not grouped
    # (calibration.clutter): they agree with any vanishing point within a wide angle.
    small = short(segs, w, h)
    tex = textured(segs, w, h) & ~small
    bent = curved(found.polylines, found.polyline_sigma_px, intrinsic_matrix(f0, *c), k1) & ~tex & ~small
    keep = np.flatnonzero(~small & ~tex & ~bent)
    frame = group_manhattan(segs[keep], w, h, focal_prior=focal_prior, seed=seed, sigma_px=found.sigma_px[keep])
    if frame is not None:
        labels, resid = np.full(len(segs), -1, np.int64), np.full(len(segs), np.inf)
        labels[keep], resid[keep] = frame.labels, frame.residual_px
        frame = dataclasses.replace(frame, labels=labels, residual_px=resid)
    if frame is None:
        failure = _one_direction(pid, segs, w, h, k1, f0 if prior is not None else None, seed, t0)
        return Grouped(pid, w, h, found, segs, k1, f0, None, time.perf_counter() - t0, failure)
    elapsed = time.perf_counter() - t0
    return Grouped(pid, w, h, found, segs, k1, f0, frame, elapsed, None, prior.value if prior is not None else None,
                   (int(small.sum()), int(tex.sum()), int(bent.sum())))


#: Why a photo whose edges show one vanishing direction gets nothing written.
ONE_DIRECTION_WHY = ("one vanishing direction fixes neither the camera's rotation (it may turn about that "
                     "direction) nor its focal length, so the photo cannot be calibrated from its lines: "
                     "nothing written, mark the segments of a second direction by hand")


def _one_direction(pid: str, segs: np.ndarray, w: int, h: int, k1: float, f_exif: float | None, seed: int,
                   t0: float) -> PhotoProposals:
    """The message (and the one vanishing direction, where EXIF gives a focal length) of a photo
    whose edges the grouping could not split into two directions: the one vanishing point that
    :data:`MIN_PER_AXIS` edges or more agree with (not all pieces of one image line), if any."""
    found = single_vanishing_point(segs, w, h, seed=seed)
    n = int(found[1].sum()) if found is not None else 0
    if found is None or n < MIN_PER_AXIS or one_image_line(segs[found[1]], max(w, h)):
        return PhotoProposals(pid, (), None, f"{len(segs)} straight edges, but they do not share two vanishing "
                              f"directions, nor one that {MIN_PER_AXIS} edges or more agree on (no vanishing "
                              "points): mark the segments by hand")
    v = found[0]
    elapsed = time.perf_counter() - t0
    c = np.array([w / 2.0, h / 2.0])
    directions, how = _exif_direction(v, f_exif, c)
    where = _point_text(v, intrinsic_matrix(f_exif or float(max(w, h)), *c), k1)
    return PhotoProposals(pid, (), None, f"one direction only: {n} of {len(segs)} straight edges meet at one "
                          f"vanishing point, {where} ({how}); {ONE_DIRECTION_WHY}; {1000 * elapsed:.0f} ms",
                          directions)


def _exif_direction(v: np.ndarray, f_exif: float | None, c: np.ndarray
                    ) -> tuple[tuple[tuple[float, float, float], ...], str]:
    """The camera-frame direction (unit, up to sign) of a lone vanishing point v (3,) through EXIF's
    focal length and the principal point c at the centre, and the words for it; none without EXIF."""
    if f_exif is None:
        return (), "its direction in the camera needs a focal length, and the photo's EXIF gives none"
    d = np.linalg.solve(intrinsic_matrix(f_exif, *c), v)
    d = d / np.linalg.norm(d) * (1.0 if d[2] >= 0 else -1.0)
    return (((float(d[0]), float(d[1]), float(d[2])),),
            f"direction ({d[0]:.3f}, {d[1]:.3f}, {d[2]:.3f}) in the camera, up to sign, with EXIF's focal "
            f"length {f_exif:.0f} px and the principal point at the image centre")


def _point_text(v: np.ndarray, K: np.ndarray, k1: float) -> str:
    """Where a homogeneous vanishing point (3,) lies: pixels as the lens puts it (``K``, ``k1``: the
    undistortion the grouping used), or at infinity with its direction in the image."""
    if abs(v[2]) > 1e-9 * np.linalg.norm(v[:2]):
        p = v[:2] / v[2]
        if k1 != 0.0:
            p = distort_pixels(K, p, Lens(k1))
        return f"at ({p[0]:.0f}, {p[1]:.0f})"
    return f"at infinity ({np.degrees(np.arctan2(v[1], v[0])):.1f}° in the image)"


def orient_proposals(g: Grouped, x_axis: str = "right") -> PhotoProposals:
    """The proposals of a grouped photo, directed for a choice of x."""
    if g.failure is not None:
        return g.failure
    pid, w, h, found, segs, k1, frame, elapsed = g.pid, g.width, g.height, g.found, g.segs, g.k1, g.frame, g.elapsed
    c = np.array([w / 2.0, h / 2.0])
    D, cols = orient_axes(frame.directions, x_axis)
    f = frame.focal_px
    props: list[SegmentProposal] = []
    counts = {}
    chosen: dict[str, np.ndarray] = {}
    for k, a in enumerate(AXES):
        idx = np.flatnonzero(frame.labels == cols[k])
        score = 1.0 / (1.0 + frame.residual_px[idx] / np.maximum(found.sigma_px[idx], 1e-6))
        length = np.hypot(*(segs[idx, 2:] - segs[idx, :2]).T)
        idx = idx[np.argsort(-(score * length))][:MAX_PER_AXIS]
        ends = np.c_[found.polylines[idx, :2], found.polylines[idx, -2:]]  # what is written
        if len(idx) < MIN_PER_AXIS or one_image_line(ends, max(w, h)):
            idx = idx[:0]  # pieces of one edge fix no vanishing point: the axis is not proposed
        chosen[a] = idx
    weak = weak_axes(segs, found.sigma_px, chosen, D, f, c, max(w, h))
    for k, a in enumerate(AXES):
        idx = chosen[a] = chosen[a][:0] if a in weak else chosen[a]
        counts[a] = len(idx)
        for i in idx:
            s_u = direct_segment(segs[i], D[:, k], f, c)
            flipped = not np.allclose(s_u, segs[i])
            s = found.segments[i]
            s = np.r_[s[2:], s[:2]] if flipped else s
            poly = found.polylines[i].reshape(-1, 2)
            poly = poly[::-1] if flipped else poly
            sc = float(1.0 / (1.0 + frame.residual_px[i] / max(found.sigma_px[i], 1e-6)))
            props.append(SegmentProposal(a, (float(s[0]), float(s[1]), float(s[2]), float(s[3])),
                                         float(found.polyline_sigma_px[i]), sc,
                                         tuple(float(v) for v in poly.ravel())))
    drop_same_point(props, counts, D, f, c, w, h)
    rel = frame.focal_sigma_px / f if np.isfinite(frame.focal_sigma_px) else np.inf
    focal = f if rel <= FOCAL_REPORT_MAX_REL_SIGMA and not weak else None  # a weak axis' f is not told
    K = intrinsic_matrix(f, *c)
    axes_seen = [a for a in AXES if counts[a]]
    counted = ", ".join(f"{counts[a]} {a}" for a in AXES) + " segments"
    if len(axes_seen) < 2:
        return _one_axis(g, tuple(props), axes_seen, chosen, counted, K @ D)
    angles = [f"{a} {_point_text(K @ D[:, k], intrinsic_matrix(g.f0, *c), k1)}" for k, a in enumerate(AXES)
              if counts[a]]
    directions = tuple((float(D[0, k]), float(D[1, k]), float(D[2, k])) for k, a in enumerate(AXES) if counts[a])
    parts = [counted, "vanishing points " + "; ".join(angles),
             (f"focal length {f:.0f} px (1σ {100 * rel:.1f} %)" if focal is not None
              else "focal length not determined by the lines (a frontal or level view)"),
             f"{1000 * elapsed:.0f} ms"]
    return PhotoProposals(pid, tuple(props), focal, "; ".join(parts[:-1] + _left_out(g, weak) + parts[-1:]),
                          directions)


def _left_out(g: Grouped, weak: dict[str, str]) -> list[str]:
    """The message's words on what was not proposed: weak axes, and edges in texture or curved."""
    out = [f"axis {a} not proposed: {why}" for a, why in weak.items()]
    small, tex, bent = g.left_out
    if small or tex or bent:
        out.append(f"not grouped: {small} short edges, {tex} in texture (edges turned every way: cobbles, "
                   f"leaves), {bent} curved (wires, branches)")
    return out


def _one_axis(g: Grouped, props: tuple[SegmentProposal, ...], axes_seen: list[str], chosen: dict[str, np.ndarray],
              counted: str, V: np.ndarray) -> PhotoProposals:
    """The proposals of a photo whose grouping kept one axis: no focal length (one direction fixes
    none), and that axis' vanishing point fitted to its own segments alone (the frame's rests on a
    focal length the other directions' few edges made), its direction through EXIF's focal length
    where it gives one. Where it kept none, :func:`_one_direction`'s answer."""
    c = np.array([g.width / 2.0, g.height / 2.0])
    ms = f"{1000 * g.elapsed:.0f} ms"
    if not axes_seen:  # no axis of MIN_PER_AXIS segments: the one point most edges meet at, if any
        return _one_direction(g.pid, g.segs, g.width, g.height, g.k1, g.f_exif, 0, time.perf_counter() - g.elapsed)
    a = axes_seen[0]
    v = V[:, AXES.index(a)]
    try:
        v = fit_vanishing_point(g.segs[chosen[a]], g.width, g.height, axis=a, photo=g.pid).point
    except VebuildError:
        pass  # the frame's point, then
    where = _point_text(v, intrinsic_matrix(g.f0, *c), g.k1)
    directions, how = _exif_direction(v, g.f_exif, c)
    return PhotoProposals(g.pid, props, None, f"one direction only: {counted}; vanishing point {a} {where} "
                          f"({how}); {ONE_DIRECTION_WHY}; {ms}", directions)


def accept_proposals(project: Project, proposals: PhotoProposals, indices: Sequence[int] | None = None) -> int:
    """Write proposals (all, or those at ``indices``) into the photo's ``vanishing_segments``, each
    with its 1σ in ``vanishing_segment_sigmas`` (not saved); returns how many were written."""
    photo = project.photo(proposals.photo)
    chosen = list(proposals.segments) if indices is None else []
    if indices is not None:
        for i in indices:
            if not 0 <= int(i) < len(proposals.segments):
                raise ProjectError(project.path, f"$.photos[{project.data['photos'].index(photo)}]",
                                   f"proposal index {i} is out of range (photo '{proposals.photo}' has "
                                   f"{len(proposals.segments)} proposals)")
            chosen.append(proposals.segments[int(i)])
    if not chosen:
        return 0
    segs = photo.setdefault("vanishing_segments", {})
    sigmas = photo.setdefault("vanishing_segment_sigmas", {})
    for a in AXES:
        added = [p for p in chosen if p.axis == a]
        rows = list(segs.get(a) or [])
        if not added and a not in sigmas:
            continue
        # Segments without a recorded 1σ (clicked by hand) keep the click's: null.
        sig = list(sigmas.get(a) or [])[: len(rows)]
        sig += [None] * (len(rows) - len(sig))
        segs[a] = rows + [[round(v, 3) for v in (p.points or p.segment)] for p in added]
        sigmas[a] = sig + [round(max(p.sigma_px, 1e-3), 4) for p in added]
    return len(chosen)


def clear_segments(project: Project, photo_id: str) -> None:
    """Remove a photo's vanishing segments, their 1σ and whether their x axis was chosen
    (``vebuild detect --replace``)."""
    photo = project.photo(photo_id)
    photo.pop("vanishing_segments", None)
    photo.pop("vanishing_segment_sigmas", None)
    photo.pop(UNRESOLVED, None)


def calibrates(props: PhotoProposals) -> bool:
    """Whether the proposals span two axes at least (what a photo's calibration needs)."""
    return len({p.axis for p in props.segments}) >= 2


def detect_project(project: Project, photos: Sequence[str] | None = None, *, replace: bool = False,
                   x_axis: str | Sequence[str] | None = None) -> list[tuple[PhotoProposals, int]]:
    """``vebuild detect``: detect on each photo named (default all), accept every proposal into
    the document (not saved), and return each photo's proposals with how many were written.

    A photo's user-marked segments are kept (the detected ones are added) unless ``replace``. A
    photo whose proposals span one axis only gets none written (its message says why).
    ``x_axis``: one choice for every photo, or a list of ``CHOICE`` (every photo) and
    ``PHOTO=CHOICE`` items (that photo; later items win); ``auto`` (the default) chooses from
    the markers the photos share (:func:`auto_x_axes`)."""
    ids = list(photos) if photos else [p["id"] for p in project.data["photos"]]
    for pid in ids:
        project.photo(pid)  # an unknown id is refused before any photo is read
    choices = x_axis_choices(project, ids, x_axis)
    unresolved: dict[str, str] = {}
    grouped, notes = choose_x_axes(project, ids, choices, replace=replace, unresolved=unresolved)
    out = []
    for pid in ids:
        g = grouped.get(pid)
        if g is None:
            g = group(photo_pixels(project, pid), project.photo(pid))
        props = orient_proposals(g, choices[pid])
        if pid in notes:
            props = replace_message(props, f"{props.message}; x axis: {notes[pid]}")
        if not calibrates(props):  # one direction only: written, it would only stop `calibrate`
            out.append((props, 0))
            continue
        photo = project.photo(pid)
        fresh = replace or not has_segments(photo)
        if replace:
            clear_segments(project, pid)
        out.append((props, accept_proposals(project, props)))
        record_x_axis(photo, unresolved.get(pid), fresh=fresh)
    return out


def has_segments(photo: dict[str, Any]) -> bool:
    """Whether the photo has a vanishing segment on any axis."""
    return any((photo.get("vanishing_segments") or {}).values())


def record_x_axis(photo: dict[str, Any], unresolved: str | None, *, fresh: bool) -> None:
    """Record on ``photo`` whether the x axis that directed the segments just written to it was
    chosen (FORMAT.md `x_axis_unresolved`; ``vebuild detect`` and the modelling screen's line
    proposals alike): ``unresolved``, why it was not, is written, and ``calibrate`` then orients
    the photo from its markers or leaves it out. A chosen x removes the record only where the
    photo's segments are all new (``fresh``: it had none before, or they were replaced): segments
    kept from before are still directed by the x that was not chosen."""
    if unresolved:
        photo[UNRESOLVED] = unresolved
    elif fresh:
        photo.pop(UNRESOLVED, None)


def choose_x_axes(project: Project, ids: Sequence[str], choices: dict[str, str], *, replace: bool = False,
                  grouped: dict[str, Grouped] | None = None, unresolved: dict[str, str] | None = None,
                  by: str = "`vebuild detect`") -> tuple[dict[str, Grouped], dict[str, str]]:
    """Settle every ``auto`` entry of ``choices`` (photo id → x-axis choice, changed in place) from
    the markers the photos share (:func:`auto_x_axes`); returns the photos grouped on the way
    (``grouped``: those already grouped, reused and added to) and a note per photo on its choice.
    Photos not among ``ids``, and photos keeping their marked segments, are held to the choice
    their segments show (``replace``: the segments of ``ids`` are about to go), unless their x axis
    was never chosen (``x_axis_unresolved``). ``unresolved`` gets each ``auto`` photo not chosen,
    with why (the record :func:`record_x_axis` writes; ``by``: what chose, in words)."""
    grouped = {} if grouped is None else grouped
    notes: dict[str, str] = {}
    if not any(c == AUTO for c in choices.values()):
        return grouped, notes
    for pid in ids:
        if pid not in grouped:
            grouped[pid] = group(photo_pixels(project, pid), project.photo(pid))
    auto = [pid for pid in ids if choices[pid] == AUTO]
    given = {pid: c for pid, c in choices.items() if c != AUTO}
    for p in project.data["photos"]:
        pid = p["id"]
        if pid in given or not p.get("vanishing_segments") or (replace and pid in ids) or p.get(UNRESOLVED):
            continue
        if pid not in grouped:
            try:
                grouped[pid] = group(photo_pixels(project, pid), p)
            except ProjectError:
                continue
        shown = choice_from_segments(grouped[pid], p["vanishing_segments"])
        if shown is not None:
            given[pid] = shown
    found, notes = auto_x_axes(project, grouped, given)
    for pid in auto:
        choices[pid] = found.get(pid, "right")
        if pid not in found and unresolved is not None:
            why = notes.get(pid, "").removeprefix("not chosen, kept 'right': ").split("; give --x-axis")[0]
            unresolved[pid] = f"{by} could not choose its x axis and kept 'right': {why}"
    return grouped, notes


def replace_message(props: PhotoProposals, message: str) -> PhotoProposals:
    return dataclasses.replace(props, message=message)


def _cmd_detect(args: argparse.Namespace) -> int:
    from vebuild.analysis.project_check import load_checked
    from vebuild.project import save_project

    project = load_checked(args.project, "detect")
    results = detect_project(project, args.photos, replace=args.replace, x_axis=args.x_axis)
    for props, written in results:
        print(f"{props.photo}: {props.message}" + (f"; {written} segments written" if written else ""))
    if any(written for _, written in results):
        save_project(project)
        print(f"\nsegments written to {project.path}; `vebuild calibrate {args.project}` calibrates from them")
    return 0


def add_detect_parser(sub: Any) -> None:
    """Add ``vebuild detect`` to the top-level subparsers ``sub``."""
    p = sub.add_parser("detect", help="detect straight edges, group them by vanishing point and add them to the "
                       "photos as vanishing segments (then calibrate)")
    p.add_argument("project")
    p.add_argument("photos", nargs="*", metavar="PHOTO", help="photo ids (default: every photo)")
    p.add_argument("--replace", action="store_true", help="remove the photos' existing vanishing segments first")
    p.add_argument("--x-axis", action="append", metavar="[PHOTO=]CHOICE",
                   help="which horizontal direction is world x (auto, right, left, away or toward): auto (default) "
                   "chooses it from the markers the photos share, so the world axes agree across photos; or the "
                   "more horizontal one in the image, pointing right or left, or the one nearer the optical axis, "
                   "pointing away from or toward the camera; PHOTO=CHOICE for one photo (repeatable)")
    p.set_defaults(func=_cmd_detect)
