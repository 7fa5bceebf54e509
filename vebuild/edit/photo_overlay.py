"""What an edit session draws over a photo (:class:`~vebuild.edit.overlay.Overlay`, plain data in
photo pixels): segments with their residuals (outliers beyond :data:`vebuild.constants.OUTLIER_SIGMAS`
click σ, the solver's threshold), vanishing rays, the horizon and axes, markers, the model's
projected edges and handles, the user's edges and the solved residuals; cached per revision, and
split during a drag into what stays put and what moves. Whatever is projected goes through the
photo's lens (its camera's k1): markers and handles where the lens puts them, each model edge as
the curve it makes in the photo (:func:`vebuild.model.drag.project_edge_curves`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from vebuild import camera as cam_math
from vebuild.actions.detect import UNRESOLVED
from vebuild.camera import ImageCamera
from vebuild.constants import OUTLIER_SIGMAS
from vebuild.model.drag import project_edge_curves
from vebuild.project import decode

from .left_out import LeftOut, legend_line
from .marks import AXES, KNOWN_LENGTH_SIGMA_M
from .modelling import Modelling
from .names import corner_directions, face_places, facing, shown
from .overlay import (
    AXIS_COLOURS,
    CYAN,
    GREY,
    MAGENTA,
    ORANGE,
    RED,
    WHITE,
    YELLOW,
    Line,
    Overlay,
    Point,
    horizon_and_axes,
    polyline_points,
    vanishing_rays,
)


class SessionOverlays(Modelling, LeftOut):
    """The overlay of a photo (mixed into the session)."""

    def overlay(self, photo: str, selected: str | None = None) -> Overlay:
        """Everything drawn over one photo (see :mod:`vebuild.edit.overlay`)."""
        key = ("overlay", photo, selected, self.revision)
        if key not in self._cache:
            if self._drag is None:
                self._cache[key] = self._overlay(photo, selected)
            else:
                still, moving = self.overlay_layers(photo, selected)
                self._cache[key] = Overlay(photo, still.lines + moving.lines, still.points + moving.points,
                                           still.notes + moving.notes)
        return self._cache[key]

    def overlay_layers(self, photo: str, selected: str | None = None) -> tuple[Overlay, Overlay]:
        """The overlay as what stays put and what moves: during a drag, everything but the moving
        primitives (kept from the drag's first frame) and their edges and handles now; otherwise
        the whole overlay and nothing."""
        d = self._drag
        if d is None:
            return self.overlay(photo, selected), Overlay(photo)
        still = ("overlay-still", photo, selected, id(d))
        if still not in self._cache:
            self._cache[still] = self._still_overlay(photo, selected, set(d.session.moved), d.start_revision)
        key = ("overlay-moving", photo, selected, self.revision)
        if key not in self._cache:
            moving = Overlay(photo)
            cam = self.cameras.get(photo)
            if cam is not None:
                self._primitives_overlay(moving, photo, cam, selected, d.session.moved)
            self._cache[key] = moving
        return self._cache[still], self._cache[key]

    def _still_overlay(self, photo: str, selected: str | None, moved: set[str], start: int) -> Overlay:
        """What stays put during a drag of ``moved``: the overlay as it was when the drag began
        (revision ``start``) less the moving nodes' edges and handles and the pins' residuals
        (drawn only at rest). The nodes that do not move are as they were, so their projected
        edges, handles and corner names are taken from it rather than worked out again (on a house
        of 522 primitives, 0.2 s at the start of every drag); made afresh where it was not drawn."""
        parts = self._cache.get(("overlay-parts", photo, selected, start))
        if parts is None:
            return self._overlay(photo, selected, skip=moved)
        base, prims, observed, _ = parts
        kept = Overlay(photo, [ln for ln in prims.lines if ln.key[0] not in moved],
                       [pt for pt in prims.points if pt.key[0] not in moved], prims.notes)
        return _joined(photo, base, kept, observed)

    def _overlay(self, photo: str, selected: str | None, skip: set[str] | frozenset[str] = frozenset()) -> Overlay:
        carried = self._cache.get(("overlay-carried", photo, selected, self.revision)) if not skip else None
        parts = self._overlay_parts(photo, selected, skip, carried)
        if self._drag is None:  # kept for the still layer of a drag that begins at this revision
            self._cache[("overlay-parts", photo, selected, self.revision)] = parts
        return _joined(photo, *parts)

    def _overlay_parts(self, photo: str, selected: str | None, skip: set[str] | frozenset[str],
                       carried: tuple[Overlay, set[str]] | None = None) -> tuple[Overlay, Overlay, Overlay, Overlay]:
        """The overlay in four parts, drawn in this order: what the model does not draw (segments,
        vanishing rays, horizon and axes, known lengths, markers); the primitives' edges and handles
        (each keyed by its node), those of ``skip`` left out; the user's edges; the pins'
        residuals (at rest only). ``carried``: the primitives' part from before a kept drag and the
        nodes it moved (:meth:`end_drag`): only those are worked out again."""
        ov = Overlay(photo)
        p = self.photo(photo)
        sigma = self.settings["click_sigma_px"]
        for axis in AXES:
            vs = self.vanishing(photo, axis)
            colour = AXIS_COLOURS[axis]
            rejected = self._left_out_of(photo, axis, len(vs.segments))
            for i, s in enumerate(vs.segments):
                r = None if vs.residuals_px is None else float(vs.residuals_px[i])
                outlier = r is not None and abs(r) > OUTLIER_SIGMAS * sigma
                if i in rejected:  # left out by the calibration: grey, crossed, whatever this fit says
                    ov.lines.append(Line(_ends(s), GREY, 2.0, "segment", (axis, i),
                                         f"{axis}{i}: left out by the calibration: {rejected[i]}", arrow=True,
                                         cross=colour))
                    continue
                ov.lines.append(Line(_ends(s), YELLOW if outlier else colour, 3.0 if outlier else 2.0,
                                     "segment", (axis, i), None if r is None else
                                     (f"{axis}{i}: {r:+.2f} px" + (" outlier" if outlier else "")), arrow=True))
            if rejected:
                ov.notes.append(legend_line(axis, len(rejected)))
            polyline_points(ov, vs)  # with or without a vanishing point yet
            if vs.point is not None:  # no ray from a segment left out: it does not run to the point
                vanishing_rays(ov, vs, p["width"], p["height"], skip=set(vs.left_out))
            elif vs.problem and len(vs.segments):
                ov.notes.append(vs.problem)
        if p.get(UNRESOLVED):  # its segments were detected with an x axis not chosen (FORMAT.md)
            ov.notes.append("x axis not chosen when this photo's segments were detected (the markers did not tell "
                            "it): if the red arrows do not run along your world x, delete its segments and press D "
                            "until they do; as it is, calibration leaves this photo out unless its markers orient it")
        cam = self.cameras.get(photo)
        if cam is not None:
            horizon_and_axes(ov, cam, p["width"], p["height"])
        self._known_lengths_overlay(ov, photo)
        self._markers_overlay(ov, photo, cam)
        prims, observed, residuals = Overlay(photo), Overlay(photo), Overlay(photo)
        model, _ = self._model_now()
        if model is None:
            return ov, prims, observed, residuals
        if cam is None:
            prims.notes.append("this photo has no camera yet: the model is drawn in calibrated photos only")
            return ov, prims, observed, residuals
        names = [n.name for n in model.nodes if n.name not in skip]
        if carried is None:
            self._primitives_overlay(prims, photo, cam, selected, names)
        else:
            before, moved = carried
            self._primitives_overlay(prims, photo, cam, selected, [n for n in names if n in moved])
            prims = _in_node_order(photo, names, before, prims, moved)
        self._observations_overlay(observed, residuals, photo)
        return ov, prims, observed, residuals

    def end_drag(self) -> None:
        """Keep the dragged result (:meth:`Modelling.end_drag`). The overlays drawn when the drag
        began hold the edges and handles of the nodes it did not move as they still are: the
        overlays after it take them from there (on a house of 522 primitives, 0.2 s a release)."""
        d = self._drag
        moved = set(d.session.moved) if d is not None and d.moved else set()
        carried = {(k[1], k[2]): v[1] for k, v in self._cache.items()
                   if moved and isinstance(k, tuple) and k[0] == "overlay-parts" and k[3] == d.start_revision}
        super().end_drag()  # an edit refused raises: nothing is carried
        for (photo, selected), prims in carried.items():
            self._cache[("overlay-carried", photo, selected, self.revision)] = (prims, moved)

    def _known_lengths_overlay(self, ov: Overlay, photo: str) -> None:
        """Each known length clicked in this photo: a thick line in its axis' colour labelled with the
        length and its 1σ, its foot on the floor (a z length's first end) a filled dot, its top a ring."""
        for i, k in enumerate(self.data.get("known_lengths", [])):
            if k["photo"] != photo:
                continue
            (u1, v1), (u2, v2) = k["ends"]
            colour = AXIS_COLOURS[k["axis"]]
            sigma = k.get("sigma", KNOWN_LENGTH_SIGMA_M)
            ov.lines.append(Line((u1, v1, u2, v2), colour, 4.0, "known-length", i,
                                 f"L{i}: {k['length']:g} m ± {1e3 * sigma:g} mm along {k['axis']}"))
            foot = k.get("floor_end", 0) if k["axis"] == "z" else None
            for e, (u, v) in enumerate(k["ends"]):
                ov.points.append(Point((u, v), colour, 4.0, e == foot or foot is None, "known-length-end", (i, e)))

    def _markers_overlay(self, ov: Overlay, photo: str, cam: ImageCamera | None) -> None:
        placed = decode.markers(self.data, "final")  # re-calibrated where the solution has them
        origin = self.data.get("origin_marker")
        res = (decode.camera_records(self.data).get(photo) or {}).get("marker_residuals_px", {})
        for name, uv in (self.photo(photo).get("marker_observations") or {}).items():
            label = name + (" (origin)" if name == origin else "")
            if name in res:
                label += f"  {np.linalg.norm(res[name]):.2f} px"
            ov.points.append(Point((float(uv[0]), float(uv[1])), ORANGE, 5.0, False, "marker", name, label))
            if cam is not None and name in placed:
                X = placed[name]
                if cam_math.world_to_camera(cam.R, cam.C, X)[2] > 0:
                    q = cam_math.project(cam.K, cam.R, cam.C, X, cam.lens)
                    ov.points.append(Point((float(q[0]), float(q[1])), GREY, 2.5, True, "marker-projected", name))
                    ov.lines.append(Line((float(uv[0]), float(uv[1]), float(q[0]), float(q[1])), MAGENTA, 1.0,
                                         "residual", ("marker", name)))

    def _primitives_overlay(self, ov: Overlay, photo: str, cam: ImageCamera, selected: str | None,
                            nodes: Sequence[str]) -> None:
        """The projected edges (white; the selected node's yellow) and handles (fixed: red) of nodes."""
        model, x = self._model_now()
        if model is None:
            return
        names = [n for n in nodes if model.node(n).primitive is not None]
        for node, edges in project_edge_curves(model, cam, names, x, self._transforms()).items():
            colour = YELLOW if node == selected else WHITE
            for e, q in edges:  # a curve through a distorting lens: its pieces share the key
                for i in range(len(q) - 1):
                    ov.lines.append(Line(_ends((*q[i], *q[i + 1])), colour, 2.0 if node == selected else 1.5,
                                         "edge", (node, e)))
        corners = {n: self.corner_names(photo, n) for n in names}
        for n, h, uv, fixed in self.handles(photo, names):
            ov.points.append(Point(uv, RED if fixed else (YELLOW if n == selected else WHITE),
                                   5.0 if fixed or n == selected else 3.0, fixed or n == selected,
                                   "pin" if fixed else "handle", (n, h), f"{n}: {corners[n].get(h, h)}"))

    def _observations_overlay(self, ov: Overlay, residuals: Overlay, photo: str) -> None:
        """The user's edges (red) into ``ov`` and, after a solve and at rest, each fixed vertex's
        residual (outliers magenta) into ``residuals``."""
        for i, e in enumerate(self._edge_docs()):
            if e["photo"] == photo:
                (u1, v1), (u2, v2) = e["points"]
                ov.lines.append(Line((u1, v1, u2, v2), RED, 2.0, "user-edge", i, f"{e['node']}:{e['edge']}"))
        sol = self.data.get("model_solution") or {}
        outliers = " ".join(sol.get("outliers", []))
        if self._drag is None:
            for pin, r in zip(self._pins(), sol.get("pins", []), strict=False):
                if pin["photo"] != photo or (pin["node"], pin["handle"]) != (r["node"], r["handle"]):
                    continue
                u, v = pin["uv"]
                bad = f"pin {r['node']}:{r['handle']} in photo '{photo}'" in outliers
                scale = 10.0  # residuals are a pixel or two: drawn ten times longer to be seen
                residuals.lines.append(Line((u, v, u + scale * r["residual_px"][0], v + scale * r["residual_px"][1]),
                                     MAGENTA if bad else CYAN, 3.0 if bad else 1.0, "residual",
                                     (r["node"], r["handle"]),
                                     f"{np.hypot(*r['residual_px']):.2f} px" + (" outlier" if bad else "")))


    # -- what the screen names and hides -----------------------------------------------------------

    def edge_world_ends(self, nodes: Sequence[str] | None = None) -> dict[tuple[str, str],
                                                                          tuple[np.ndarray, np.ndarray]]:
        """Each primitive edge's world ends as shown, (node, edge) → (a, b) (of ``nodes``, or all)."""
        model, x = self._model_now()
        if model is None or x is None:
            return {}
        T = self._transforms()
        out = {}
        for node in model.nodes if nodes is None else [model.node(n) for n in nodes]:
            prim = node.primitive
            if prim is None:
                continue
            hs = prim.handles(x[model.slices[node.name][1]]) @ T[node.name][:3, :3].T + T[node.name][:3, 3]
            idx = {h: i for i, h in enumerate(prim.handle_names())}
            for e, a, b in prim.edges():
                out[(node.name, e)] = (hs[idx[a]], hs[idx[b]])
        return out

    def corner_names(self, photo: str | None, node: str) -> dict[str, str]:
        """What the screen calls each handle of ``node`` (:mod:`vebuild.edit.names`) from the
        camera of ``photo`` (the world's axes where it has none): handle → shown name."""
        world = self.corners_world(node)
        if not world:
            return {}
        cam = self.cameras.get(photo) if photo is not None else None
        places = corner_directions(np.array(list(world.values())), None if cam is None else cam.R)
        return {h: shown(p, h) for h, p in zip(world, places, strict=True)}

    def corners_world(self, node: str) -> dict[str, np.ndarray]:
        """The handles of ``node`` in the world as shown: handle → (3,)."""
        model, x = self._model_now()
        if model is None or x is None or node not in model.index:
            return {}
        prim = model.node(node).primitive
        if prim is None:
            return {}
        T = self._transforms()[node]
        hs = prim.handles(x[model.slices[node][1]]) @ T[:3, :3].T + T[:3, 3]
        return dict(zip(prim.handle_names(), hs, strict=True))

    def face_names(self, photo: str | None, node: str) -> dict[str, str]:
        """What the screen calls each face of ``node``: stored face name → shown name."""
        cam = self.cameras.get(photo) if photo is not None else None
        meshes: list[Any] = getattr(self, "_world_meshes", list)()  # the session's (relating.py), per revision
        for n, tri, face_ids, _, names in meshes:
            if n == node:
                places = face_places(tri, face_ids, names, None if cam is None else cam.R)
                return {k: shown(v, k) for k, v in places.items()}
        return {}


    def faces_facing(self, photo: str, node: str) -> set[str]:
        """The faces of ``node`` whose outer side faces the camera of ``photo`` (none without one)."""
        cam = self.cameras.get(photo)
        meshes: list[Any] = getattr(self, "_world_meshes", list)()
        for n, tri, face_ids, _, names in meshes:
            if n == node and cam is not None:
                return facing(tri, face_ids, names, np.asarray(cam.C, float))
        return set()


def _ends(v: Sequence[float]) -> tuple[float, float, float, float]:
    """A segment's end points (u1, v1, u2, v2) as floats."""
    return float(v[0]), float(v[1]), float(v[2]), float(v[3])


def _joined(photo: str, *parts: Overlay) -> Overlay:
    """One overlay of ``parts``, drawn in their order."""
    return Overlay(photo, [ln for p in parts for ln in p.lines], [pt for p in parts for pt in p.points],
                   [n for p in parts for n in p.notes])


def _in_node_order(photo: str, names: Sequence[str], before: Overlay, fresh: Overlay, moved: set[str]) -> Overlay:
    """The primitives' part of an overlay, node by node in ``names``' order: the nodes of
    ``moved`` from ``fresh``, the others from ``before`` (each node's items are together in both,
    so this is the order in which they are worked out afresh)."""
    def grouped(items: Sequence[Any]) -> dict[str, list[Any]]:
        out: dict[str, list[Any]] = {}
        for it in items:
            out.setdefault(it.key[0], []).append(it)
        return out

    old_l, old_p, new_l, new_p = (grouped(x) for x in (before.lines, before.points, fresh.lines, fresh.points))
    lines = [ln for n in names for ln in (new_l if n in moved else old_l).get(n, [])]
    points = [pt for n in names for pt in (new_p if n in moved else old_p).get(n, [])]
    return Overlay(photo, lines, points, list(fresh.notes))
