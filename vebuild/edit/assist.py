"""Assisted marking in the modelling screen (issue "assisted marking"), without a window: snapping
a click or a drawn segment to the photo (:mod:`.snap`), and proposals the user accepts or rejects:
detected vanishing segments (:mod:`vebuild.actions.detect`), markers suggested from feature points
matched across calibrated photos and along a marker's epipolar line (:mod:`.suggest`), and a pin's
image corner near where a model vertex projects.

A proposal is no part of the project until it is accepted; then it is an ordinary mark, made by
one undoable edit (accepting all of a photo's proposals is one edit too).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .history import EditError
from .rename import MarkerRename
from .snap import SNAP_RADIUS_PX, SegmentFit, Snap, grey, noise_sigma, refine_segment, snap_point

if TYPE_CHECKING:
    from vebuild.camera import ImageCamera

#: The most markers suggested from matched feature points per photo at once.
MAX_SUGGESTED_MARKERS = 12
#: What chose a photo's x axis, in its ``x_axis_unresolved`` record (scenes/FORMAT.md).
SCREEN_DETECTION = "the modelling screen's line detection (D)"


def _not_chosen(why: str) -> str:
    """The screen's words for a photo whose x axis the line detection could not choose."""
    reason = why.split(": ", 1)[-1]
    return (f"x not chosen: the markers do not tell which way x runs ({reason}), so it runs right as a guess; if "
            "the red arrows do not run along your world x, press D on this photo until they do; accepted as they "
            "are, the photo is recorded as not oriented, and calibration leaves it out unless its markers orient it")


@dataclass(frozen=True)
class Proposal:
    """Something the screen proposes on a photo. ``kind``: ``segment`` (``axis``, ``segment``,
    ``sigma_px`` its end points' 1σ), ``marker`` (``name`` at ``uv``; ``also``: the same marker's
    position in other photos, placed with it) or ``pin`` (``node``:``handle`` fixed at ``uv``);
    ``score`` how well it agrees (higher is better), ``why`` a short line for the screen;
    ``x_unresolved``: for a detected segment whose photo's x axis could not be chosen, why (the
    photo's ``x_axis_unresolved`` once it is accepted)."""

    kind: str
    photo: str
    uv: tuple[float, float] = (0.0, 0.0)
    axis: str = ""
    segment: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    sigma_px: float | None = None
    name: str = ""
    node: str = ""
    handle: str = ""
    also: tuple[tuple[str, tuple[float, float]], ...] = ()
    points: tuple[float, ...] = ()  # a detected segment's polyline along its edge (written), or () for the segment
    score: float = 0.0
    why: str = ""
    x_unresolved: str = ""  # a detected segment's: why its photo's x axis was not chosen ("" where it was)


class Assist(MarkerRename):
    """Snapping and proposals (mixed into the session)."""

    if TYPE_CHECKING:
        project: Any
        revision: int

        @property
        def cameras(self) -> dict[str, ImageCamera]: ...

        @property
        def data(self) -> dict[str, Any]: ...

        @property
        def photo_ids(self) -> list[str]: ...

        def photo(self, photo_id: str) -> dict[str, Any]: ...

        def photo_pixels(self, photo_id: str) -> NDArray[np.uint8]: ...

        def say(self, text: str) -> None: ...

        def _edit(self, label: str) -> Any: ...

        def _set_segment_sigma(self, photo: str, axis: str, index: int, sigma_px: float | None) -> None: ...

        def _segments(self, photo: str, axis: str) -> list[list[float]]: ...

        def _check_segment(self, seg: Sequence[float], axis: str) -> None: ...

        def handles(self, photo: str,
                    nodes: Sequence[str] | None = None) -> list[tuple[str, str, tuple[float, float], bool]]: ...

        def _pins(self) -> list[dict[str, Any]]: ...

        def _model_doc(self) -> dict[str, Any]: ...

        def next_marker_name(self) -> str: ...

    # -- the photo as grey levels, once per photo -------------------------------------------------

    def _grey(self, photo: str) -> tuple[NDArray[np.float32], float]:
        store: dict[str, tuple[NDArray[np.float32], float]] = self.__dict__.setdefault("_grey_store", {})
        if photo not in store:
            g = grey(self.photo_pixels(photo))
            store.clear()  # one photo kept: a 12 MP photo's grey levels are 48 MB
            store[photo] = (g, noise_sigma(g))
        return store[photo]

    # -- snapping -----------------------------------------------------------------------------------

    def snap(self, photo: str, uv: Sequence[float], exact: bool = False) -> tuple[tuple[float, float], Snap | None]:
        """Where a click at uv lands: at the image corner or on the edge near it (at most
        :data:`~vebuild.edit.snap.SNAP_RADIUS_PX` away), or exactly at uv (``exact``: the modifier
        held, or nothing to snap to)."""
        q = (float(uv[0]), float(uv[1]))
        if exact:
            return q, None
        try:
            g, noise = self._grey(photo)
        except EditError:
            return q, None
        s = snap_point(g, q, SNAP_RADIUS_PX, noise)
        return (s.uv, s) if s is not None else (q, None)

    def snap_vertex(self, photo: str, uv: Sequence[float], exact: bool = False,
                    ) -> tuple[tuple[float, float], Snap | None]:
        """Where a dragged vertex released at uv lands: at the image corner near it (at most
        :data:`~vebuild.edit.snap.SNAP_RADIUS_PX` away; a vertex is a corner, never a point along an
        edge), or exactly at uv (``exact``: Alt held, or no corner there)."""
        from .snap import snap_corner

        q = (float(uv[0]), float(uv[1]))
        if exact:
            return q, None
        try:
            g, noise = self._grey(photo)
        except EditError:
            return q, None
        s = snap_corner(g, q, SNAP_RADIUS_PX, noise)
        return (s.uv, s) if s is not None else (q, None)

    def snap_segment(self, photo: str, p1: Sequence[float], p2: Sequence[float], exact: bool = False,
                     ) -> tuple[tuple[float, float], tuple[float, float], SegmentFit | None]:
        """A drawn segment refined to the image line it covers (both ends on the fitted line), or
        as drawn (``exact``, or no line there)."""
        a, b = (float(p1[0]), float(p1[1])), (float(p2[0]), float(p2[1]))
        if exact:
            return a, b, None
        try:
            g, _ = self._grey(photo)
        except EditError:
            return a, b, None
        fit = refine_segment(g, (*a, *b), SNAP_RADIUS_PX)
        if fit is None:
            return a, b, None
        s = fit.segment
        return (s[0], s[1]), (s[2], s[3]), fit

    # -- proposals ------------------------------------------------------------------------------------

    @property
    def proposals(self) -> dict[str, list[Proposal]]:
        """The proposals shown, per photo (not part of the project until accepted)."""
        out: dict[str, list[Proposal]] = self.__dict__.setdefault("_proposals", {})
        return out

    def _set_proposals(self, photo: str, kind: str, items: list[Proposal]) -> None:
        self.proposals[photo] = [p for p in self.proposals.get(photo, []) if p.kind != kind] + items
        self.revision += 1

    def _grouped(self) -> dict[str, Any]:
        """The photos' edges grouped into vanishing directions (:func:`vebuild.actions.detect.group`),
        kept per photo file: D and Shift+D group each photo once."""
        store: dict[str, Any] = self.__dict__.setdefault("_grouped_store", {})
        files = {p["id"]: p.get("file") for p in self.data.get("photos", [])}
        for pid in [k for k, (f, _) in store.items() if files.get(k) != f]:
            del store[pid]
        return {pid: g for pid, (_, g) in store.items()}

    def _keep_grouped(self, grouped: dict[str, Any]) -> None:
        store: dict[str, Any] = self.__dict__.setdefault("_grouped_store", {})
        for pid, g in grouped.items():
            store[pid] = (self.photo(pid).get("file"), g)

    def _detect(self, photos: Sequence[str], x_axis: dict[str, str | None]
                ) -> tuple[dict[str, Any], dict[str, str]]:
        """The proposals of each photo (PhotoProposals), x chosen as given or (None) from the
        markers the photos share (:func:`vebuild.actions.detect.choose_x_axes`, as ``vebuild
        detect`` chooses it), and for each photo whose x could not be chosen, why."""
        from vebuild.actions.detect import AUTO, choose_x_axes, group, orient_proposals, photo_pixels, replace_message
        from vebuild.errors import VebuildError

        choices = {pid: c or AUTO for pid, c in x_axis.items()}
        unresolved: dict[str, str] = {}
        try:
            grouped, notes = choose_x_axes(self.project, list(photos), choices, grouped=self._grouped(),
                                           unresolved=unresolved, by=SCREEN_DETECTION)
            out = {}
            for pid in photos:
                if pid not in grouped:
                    grouped[pid] = group(photo_pixels(self.project, pid), self.photo(pid))
                props = orient_proposals(grouped[pid], choices[pid])
                if pid in notes and x_axis.get(pid) is None and pid not in unresolved:
                    props = replace_message(props, f"{props.message}; x {choices[pid]}: {notes[pid]}")
                out[pid] = props
        except VebuildError as e:
            raise EditError(f"line detection failed: {e}") from None
        self._keep_grouped(grouped)
        last: dict[str, str] = self.__dict__.setdefault("_x_axis", {})
        last.update(choices)
        return out, unresolved

    def _show_detected(self, photo: str, found: Any, unresolved: str = "") -> list[Proposal]:
        items = [Proposal("segment", photo, axis=s.axis, segment=tuple(float(v) for v in s.segment),  # type: ignore[arg-type]
                          sigma_px=float(s.sigma_px), score=float(s.score),
                          points=tuple(float(v) for v in getattr(s, "points", ()) or ()), x_unresolved=unresolved)
                 for s in found.segments]
        self._set_proposals(photo, "segment", items)
        return items

    def detect_lines(self, photo: str, x_axis: str | None = None) -> int:
        """Detect the photo's vanishing segments (:func:`vebuild.actions.detect.detect_photo`) and
        show them as proposals; returns how many. ``x_axis``: which horizontal direction of the
        photo world x runs (``right``, ``left``, ``away``, ``toward``); None: the first time, the
        choice that agrees with the other photos through the markers they share (``vebuild
        detect``'s ``auto``; ``right`` where they do not tell), the next choice each time after
        (D again turns the proposed axes)."""
        from vebuild.calibration.lines import X_AXIS_CHOICES

        self.photo(photo)
        last: dict[str, str] = self.__dict__.setdefault("_x_axis", {})
        if x_axis is None and photo in last:
            x_axis = X_AXIS_CHOICES[(X_AXIS_CHOICES.index(last[photo]) + 1) % len(X_AXIS_CHOICES)]
        got, unresolved = self._detect([photo], {photo: x_axis})
        found, why = got[photo], unresolved.get(photo, "")
        items = self._show_detected(photo, found, why)
        per_axis = {a: sum(p.axis == a for p in items) for a in ("x", "y", "z")}
        self.say(f"detected in {photo} with x {last[photo]}: " + ", ".join(f"{n} {a}" for a, n in per_axis.items())
                 + f" segment proposals ({found.message})" + (f"; {_not_chosen(why)}" if why and items else "")
                 + "; Enter accepts all, a click on one accepts it, the Delete tool rejects it; D again turns x to "
                 "the next horizontal direction")
        return len(items)

    def detect_everywhere(self) -> int:
        """Shift+D: detect on every photo and show the proposals, each photo's x chosen from the
        markers the photos share (place three or more markers shared between photos first); returns
        how many proposals in all. The photos where nothing was found, or x was not chosen, are named."""
        ids = self.photo_ids
        if not ids:
            raise EditError("no photos to detect lines on: add photos first")
        found, unresolved = self._detect(ids, {pid: None for pid in ids})
        total = 0
        lines = []
        for pid in ids:
            n = len(self._show_detected(pid, found[pid], unresolved.get(pid, "")))
            total += n
            note = found[pid].message.split("; x ")[-1] if "; x " in found[pid].message else found[pid].message
            if pid in unresolved:
                note = _not_chosen(unresolved[pid])
            lines.append(f"{pid}: {n} ({note})" if n else f"{pid}: none ({found[pid].message})")
        self.say(f"detected {total} segment proposals over {len(ids)} photos; Q accepts every photo's, D on a "
                 "photo turns its x: " + "; ".join(lines))
        return total

    def suggest_markers(self, photo: str, features: bool = False) -> int:
        """Markers proposed in a calibrated photo: each marker placed in another calibrated photo
        but not here (triangulated from two, or along its epipolar line from one); with
        ``features``, new markers at feature points matched between this photo and the others and
        checked against the cameras' epipolar geometry instead. Returns how many were proposed."""
        from .suggest import match_photos

        cams = self.cameras
        if photo not in cams:
            raise EditError(f"photo '{photo}' has no calibrated camera yet: markers are suggested between "
                            "calibrated photos (calibrate first)")
        others = [p for p in self.photo_ids if p != photo and p in cams]
        if not others:
            raise EditError("markers are suggested once two or more photos are calibrated")
        here = self.photo(photo).get("marker_observations") or {}
        pix = self.photo_pixels(photo)
        items: list[Proposal] = []
        rejected = 0
        for name in [] if features else self.project.marker_names():
            if name in here:
                continue
            seen = [(o, uv) for o in others
                    if (uv := (self.photo(o).get("marker_observations") or {}).get(name)) is not None]
            got = self._marker_here(photo, pix, seen)
            if got is not None:
                items.append(Proposal("marker", photo, uv=got[0], name=name, score=got[1], why=got[2]))
        taken = set(self.project.marker_names())
        new: list[Proposal] = []
        for o in others if features else []:
            matches, rej = match_photos(pix, cams[photo], self.photo_pixels(o), cams[o])
            rejected += rej
            for m in matches:
                if len(new) >= MAX_SUGGESTED_MARKERS:
                    break
                if any(np.hypot(m.uv_a[0] - q.uv[0], m.uv_a[1] - q.uv[1]) < 20.0 for q in items + new):
                    continue
                k = len(taken) + 1
                while f"M{k}" in taken:
                    k += 1
                taken.add(f"M{k}")
                new.append(Proposal("marker", photo, uv=m.uv_a, name=f"M{k}", also=((o, m.uv_b),),
                                    score=1.0 - m.ratio, why=f"matched in {o}, {m.sampson_px:.2f} px from its "
                                                             f"epipolar line (≤ {m.threshold_px:.2f})"))
        items += new
        self._set_proposals(photo, "marker", items)
        if features:
            self.say(f"suggested {len(new)} new markers in {photo} at feature points matched with the other calibrated "
                     f"photos ({rejected} matches off their epipolar lines rejected); the epipolar check cannot see a "
                     "wrong match along the line (a repeated pattern): look before accepting")
        else:
            self.say(f"suggested {len(items)} of the markers placed elsewhere in {photo} (Shift+N: new markers at "
                     "matched feature points)")
        return len(items)

    def _marker_here(self, photo: str, pix: NDArray[np.uint8], seen: list[tuple[str, Any]],
                     ) -> tuple[tuple[float, float], float, str] | None:
        """Where a marker seen in other calibrated photos is in this one: triangulated from two of
        them and projected (snapped to the image corner there), or from one along its epipolar line
        between the depths the photo's other markers lie at (halved and doubled)."""
        from vebuild.camera import project, world_to_camera

        from .suggest import (
            DEPTH_RANGE_M,
            MAX_PREDICTION_PX,
            along_epipolar,
            prediction_radius,
            search_near,
            triangulate,
        )

        cams = self.cameras
        cam = cams[photo]
        if len(seen) >= 2:
            (o1, uv1), (o2, uv2) = seen[:2]
            X = triangulate(cams[o1], cams[o2], np.asarray([uv1], float), np.asarray([uv2], float))
            depth = float(world_to_camera(cam.R, cam.C, X)[0, 2])
            if depth <= 0:
                return None
            uv = project(cam.K, cam.R, cam.C, X, cam.lens)[0]
            if not (0 <= uv[0] < cam.width and 0 <= uv[1] < cam.height):
                return None
            # Looked for about the prediction, as far as this camera's own uncertainty allows.
            radius = prediction_radius(cam, X[0])
            if radius > MAX_PREDICTION_PX:
                return None
            found = None
            for o, uv_o in seen:
                got = search_near(self.photo_pixels(o), uv_o, pix, uv, radius)
                if got is not None and (found is None or got[1] > found[1]):
                    found = (got[0], got[1], o)
            if found is None:
                return None
            return found[0], found[1], (f"triangulated from {o1} and {o2}, found within {radius:.0f} px of it "
                                        f"(correlation {found[1]:.2f} with {found[2]})")
        best: tuple[tuple[float, float], float, str] | None = None
        for o, uv_o in seen:
            marks = self.photo(o).get("marker_observations") or {}
            pts = [m for n, m in marks.items() if n in self.project.marker_names()]
            depths = DEPTH_RANGE_M
            if len(pts) >= 2 and len(seen) >= 1:
                ds = [d for d in (self._marker_depth(o, n) for n in marks) if d is not None]
                if ds:
                    depths = (max(min(ds) / 2, DEPTH_RANGE_M[0]), min(max(ds) * 2, DEPTH_RANGE_M[1]))
            line = along_epipolar(self.photo_pixels(o), cams[o], uv_o, pix, cam, depths)
            if line is not None and (best is None or line[1] > best[1]):
                best = (line[0], line[1], f"along its epipolar line from {o}, correlation {line[1]:.2f}")
        return best

    def _marker_depth(self, photo: str, name: str) -> float | None:
        """The depth of a marker's calibrated position in front of the photo's camera, or None."""
        from vebuild.camera import world_to_camera

        pos = ((self.data.get("calibration") or {}).get("markers") or {}).get(name)
        X = pos.get("position") if isinstance(pos, dict) else pos
        if X is None or len(X) != 3:
            return None
        cam = self.cameras[photo]
        z = float(world_to_camera(cam.R, cam.C, np.asarray([X], float))[0, 2])
        return z if z > 0 else None

    def suggest_pins(self, photo: str) -> int:
        """For each vertex of the model in view and not fixed here, the image corner near its
        projection, proposed as its pin; returns how many."""
        from .suggest import pin_corner

        pix = self.photo_pixels(photo)
        items = []
        for node, handle, uv, fixed in self.handles(photo):
            if fixed:
                continue
            got = pin_corner(pix, uv)
            if got is not None:
                d = float(np.hypot(got[0] - uv[0], got[1] - uv[1]))
                items.append(Proposal("pin", photo, uv=got, node=node, handle=handle, score=-d,
                                      why=f"the image corner {d:.1f} px from the vertex"))
        self._set_proposals(photo, "pin", items)
        self.say(f"proposed {len(items)} pins in {photo} at the image corners near the model's vertices")
        return len(items)

    def proposal_at(self, photo: str, uv: Sequence[float], radius_px: float) -> int | None:
        """The index of the proposal of this photo nearest uv within radius_px (a segment by its
        path, a point by itself)."""
        q = np.asarray(uv, float)
        best: tuple[float, int] | None = None
        for i, p in enumerate(self.proposals.get(photo, [])):
            if p.kind == "segment":
                a, b = np.asarray(p.segment[:2]), np.asarray(p.segment[2:])
                t = float(np.clip((q - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-12), 0.0, 1.0))
                d = float(np.linalg.norm(q - (a + t * (b - a))))
            else:
                d = float(np.linalg.norm(q - np.asarray(p.uv)))
            if d <= radius_px and (best is None or d < best[0]):
                best = (d, i)
        return best[1] if best else None

    def _apply(self, p: Proposal) -> None:
        """Make proposal p an ordinary mark (inside an edit)."""
        if p.kind == "segment":
            from vebuild.actions.detect import has_segments, record_x_axis

            row = [round(v, 3) for v in (p.points or p.segment)]
            self._check_segment(row, p.axis)
            fresh = not has_segments(self.photo(p.photo))
            segs = self._segments(p.photo, p.axis)
            segs.append(row)
            self._set_segment_sigma(p.photo, p.axis, len(segs) - 1, p.sigma_px)
            record_x_axis(self.photo(p.photo), p.x_unresolved or None, fresh=fresh)
        elif p.kind == "marker":
            if p.name not in self.project.marker_names():
                self.data["markers"].append({"name": p.name})
            for pid, uv in ((p.photo, p.uv), *p.also):
                self.photo(pid).setdefault("marker_observations", {})[p.name] = [float(uv[0]), float(uv[1])]
            if not self.data.get("origin_marker") and len(self.data["markers"]) == 1:
                self.data["origin_marker"] = p.name
        elif p.kind == "pin":
            pins = [q for q in self._pins() if (q["photo"], q["node"], q["handle"]) != (p.photo, p.node, p.handle)]
            pins.append({"photo": p.photo, "node": p.node, "handle": p.handle, "uv": [float(p.uv[0]), float(p.uv[1])],
                         "fixed": True})
            self._model_doc()["pins"] = pins
        else:
            raise EditError(f"no proposal of kind {p.kind!r}")

    def _describe(self, p: Proposal) -> str:
        if p.kind == "segment":
            return f"{p.axis} segment"
        if p.kind == "marker":
            return f"marker {p.name}"
        return f"pin {p.node}:{p.handle}"

    def accept_proposal(self, photo: str, index: int) -> str:
        """Accept one proposal (one undoable edit); returns what it made."""
        items = self.proposals.get(photo, [])
        if not 0 <= index < len(items):
            raise EditError(f"photo '{photo}' has no proposal {index} (it has {len(items)})")
        p = items[index]
        with self._edit(f"accept {self._describe(p)} in {photo}"):
            self._apply(p)
        del items[index]
        self.revision += 1
        self.say(f"accepted {self._describe(p)} in {photo}")
        return self._describe(p)

    def reject_proposal(self, photo: str, index: int) -> None:
        items = self.proposals.get(photo, [])
        if not 0 <= index < len(items):
            raise EditError(f"photo '{photo}' has no proposal {index} (it has {len(items)})")
        p = items.pop(index)
        self.revision += 1
        self.say(f"rejected the proposed {self._describe(p)} in {photo}")

    def accept_all(self, photo: str, kind: str | None = None) -> int:
        """Accept every proposal of the photo (of ``kind``, or all): one undoable edit."""
        items = [p for p in self.proposals.get(photo, []) if kind is None or p.kind == kind]
        if not items:
            self.say(f"no proposals to accept in {photo} (D detects lines, N suggests markers, P pins)")
            return 0
        with self._edit(f"accept {len(items)} proposals in {photo}"):
            for p in items:
                self._apply(p)
        self.proposals[photo] = [p for p in self.proposals.get(photo, []) if p not in items]
        self.revision += 1
        kinds = {k: sum(p.kind == k for p in items) for k in ("segment", "marker", "pin")}
        self.say(f"accepted in {photo}: " + ", ".join(f"{n} {k}{'s' if n != 1 else ''}" for k, n in kinds.items() if n))
        return len(items)

    def accept_everywhere(self) -> int:
        """Q: accept every proposal of every photo (one undoable edit); returns how many."""
        items = [p for pid in self.photo_ids for p in self.proposals.get(pid, [])]
        if not items:
            self.say("no proposals to accept (Shift+D detects lines on every photo, W suggests markers)")
            return 0
        photos = sorted({p.photo for p in items}, key=self.photo_ids.index)
        with self._edit(f"accept {len(items)} proposals in {len(photos)} photos"):
            for p in items:
                self._apply(p)
        for pid in photos:
            self.proposals.pop(pid, None)
        self.revision += 1
        kinds = {k: sum(p.kind == k for p in items) for k in ("segment", "marker", "pin")}
        self.say(f"accepted in {', '.join(photos)}: "
                 + ", ".join(f"{n} {k}{'s' if n != 1 else ''}" for k, n in kinds.items() if n))
        return len(items)

    def suggest_markers_everywhere(self) -> int:
        """W: :meth:`suggest_markers` on every calibrated photo; returns how many in all (the
        photos not calibrated are named)."""
        cams = self.cameras
        done = [pid for pid in self.photo_ids if pid in cams]
        if len(done) < 2:
            raise EditError("markers are suggested once two or more photos are calibrated (calibrate first)")
        per = {pid: self.suggest_markers(pid) for pid in done}
        left = [pid for pid in self.photo_ids if pid not in cams]
        self.say(f"suggested {sum(per.values())} markers: " + ", ".join(f"{n} in {p}" for p, n in per.items())
                 + (f"; not calibrated, so none in {', '.join(left)}" if left else "")
                 + "; Q accepts them all, then calibrate again")
        return sum(per.values())

    def clear_proposals(self, photo: str) -> None:
        self.proposals.pop(photo, None)
        self.revision += 1
