"""Which horizontal direction is world x in each photo: ``vebuild detect --x-axis auto``.

From the photos' groupings (:class:`vebuild.actions.detect.Grouped`) and the markers they share,
through :mod:`vebuild.calibration.axes_choice`; docs/detect.md "How `--x-axis auto` chooses".
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from vebuild.calibration.axes_choice import MIN_SHARED_MARKERS_TO_PROPOSE, choose_turns, direction_turn, turn_between
from vebuild.calibration.lines import X_AXIS_CHOICES
from vebuild.camera import Lens, intrinsic_matrix, undistort_pixels
from vebuild.project import Project

if TYPE_CHECKING:
    from .detect_types import Grouped

def marker_rays(project: Project, g: Grouped) -> dict[str, np.ndarray]:
    """The photo's markers as camera-frame rays (3,), through the grouping's f and lens."""
    obs = project.photo(g.pid).get("marker_observations") or {}
    if not obs or g.frame is None:
        return {}
    c = np.array([g.width / 2.0, g.height / 2.0])
    names = sorted(obs)
    uv = np.array([obs[m][:2] for m in names], float)
    if g.k1 != 0.0:
        uv = undistort_pixels(intrinsic_matrix(g.f0, *c), uv, Lens(g.k1))
    f = float(g.frame.focal_px)
    return {m: np.array([(u - c[0]) / f, (v - c[1]) / f, 1.0]) for m, (u, v) in zip(names, uv, strict=True)}


def choice_turns(g: Grouped) -> dict[str, int]:
    """Each x-axis choice as a turn k about z of the photo's ``right`` axes."""
    R0 = g.rotation("right")
    return {c: turn_between(R0, g.rotation(c)) for c in X_AXIS_CHOICES}


def choice_from_segments(g: Grouped, segments: dict[str, Any]) -> str | None:
    """The x-axis choice a photo's marked segments show (their horizontal ones directed along the
    choice's axes), or None where they show none clearly (within 25° on average)."""
    if g.frame is None:
        return None
    c = np.array([g.width / 2.0, g.height / 2.0])
    f = float(g.frame.focal_px)
    best: tuple[float, str] | None = None
    for choice in X_AXIS_CHOICES:
        D = g.rotation(choice)
        cos = []
        for k, a in enumerate("xy"):
            for row in segments.get(a) or []:
                p = np.asarray(row, float).reshape(-1, 2)
                step = p[-1] - p[0]
                motion = D[:2, k] - ((p.mean(axis=0) - c) / f) * D[2, k]
                n = np.linalg.norm(step) * np.linalg.norm(motion)
                if n > 0:
                    cos.append(float(step @ motion / n))
        if cos and (best is None or np.mean(cos) > best[0]):
            best = (float(np.mean(cos)), choice)
    return best[1] if best is not None and best[0] >= np.cos(np.radians(25.0)) else None


def auto_x_axes(project: Project, grouped: dict[str, Grouped], given: dict[str, str]
                ) -> tuple[dict[str, str], dict[str, str]]:
    """Each grouped photo's x-axis choice such that the world axes mean the same directions in
    every photo, from the markers they share, and a note per photo saying how it was chosen.

    The photos with a ``given`` choice keep it. Where none is given, the reference is the photo
    that sees the origin marker and the most markers, and every choice is then turned together
    so that the first reference distance from the origin marker runs along +x (where it runs
    along a horizontal axis within 20°); otherwise the reference keeps ``right``."""
    ok = {pid: g for pid, g in grouped.items() if g.frame is not None}
    turns = {pid: choice_turns(g) for pid, g in ok.items()}
    rotations = {pid: g.rotation("right") for pid, g in ok.items()}
    rays = {pid: marker_rays(project, g) for pid, g in ok.items()}
    fixed = {pid: turns[pid][c] for pid, c in given.items() if pid in ok}
    notes: dict[str, str] = {pid: "its edges show no two vanishing directions to orient" for pid in grouped
                             if pid not in ok and pid not in given}
    origin = project.data.get("origin_marker")
    ref = None
    if not fixed and ok:
        ref = max(ok, key=lambda p: (origin in rays[p], len(rays[p])))
        fixed = {ref: 0}
    if not ok:
        return {}, notes
    decided = choose_turns(rotations, rays, fixed, min_shared=MIN_SHARED_MARKERS_TO_PROPOSE)
    k = {pid: d.turn for pid, d in decided.items() if d.turn is not None}
    g_all = 0  # the turn applied to every photo after the choice
    if ref is not None:
        if rays[ref]:
            sees = ", the origin marker among them)" if origin in rays[ref] else ")"
            notes[ref] = "the reference photo (it sees the most markers" + sees
        else:
            notes[ref] = "the reference photo (the first: no photo has markers to choose another by)"
        far = next((r["b"] if r["a"] == origin else r["a"] for r in project.data.get("reference_distances") or []
                    if origin in (r.get("a"), r.get("b"))), None)
        g = direction_turn(rotations, rays, k, origin, far) if origin and far else None
        if g is not None:
            g_all = g
            k = {pid: (t + g) % 4 for pid, t in k.items()}
            notes[ref] += f"; turned so that the reference distance {origin}→{far} runs along +x"
    out: dict[str, str] = {}
    for pid, d in decided.items():
        if d.turn is None:
            notes[pid] = f"not chosen, kept 'right': {d.message}; give --x-axis {pid}=CHOICE for it"
            continue
        choice = next(c for c, t in turns[pid].items() if t == k[pid])
        out[pid] = choice
        if pid in given:
            notes[pid] = f"{choice} (given, or shown by its marked segments)"
        elif pid == ref:
            notes[pid] = f"{choice}, {notes[pid]}"
        else:
            per = ", ".join(f"{c} {d.residual_deg[(t - g_all) % 4]:.1f}°" for c, t in turns[pid].items())
            notes[pid] = f"{choice}: {d.message} (RMS miss per choice: {per})"
    return out, notes
