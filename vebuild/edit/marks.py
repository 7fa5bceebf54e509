"""The marks a user makes on the photos (paper §2, §3): directed vanishing segments and their
fitted vanishing points, markers and the origin, reference distances, and the user's (red) edge
observations of the model; each mark one undoable edit."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from vebuild.actions.detect import UNRESOLVED, has_segments
from vebuild.calibration.vanishing import MIN_SEGMENT_LENGTH_PX
from vebuild.errors import CalibrationError
from vebuild.model.drag import project_edges
from vebuild.project import decode
from vebuild.project.left_out import rejected_by_calibration

from .history import EditError, History

if TYPE_CHECKING:
    from vebuild.model.scene import Model

Array = NDArray[np.float64]

AXES = ("x", "y", "z")


#: A known length's 1σ when none is typed, metres (FORMAT.md's default: a tape read to 2 mm).
KNOWN_LENGTH_SIGMA_M = 0.002
#: A camera height's 1σ when none is typed, metres: a photographer's eye height or a tripod's
#: setting is known to a few centimetres, not better.
CAMERA_HEIGHT_SIGMA_M = 0.05
#: What the project format accepts (scenes/FORMAT.md; vebuild/schema): lengths 0.1 mm to 10 km, a
#: camera height 1 mm to 10 km, a 1σ 1 µm to 10 km.
LENGTH_RANGE_M = (1e-4, 1e4)
CAMERA_HEIGHT_RANGE_M = (1e-3, 1e4)
SIGMA_RANGE_M = (1e-6, 1e4)


def _blank(value: object) -> bool:
    return value is None or (isinstance(value, str) and not value.strip())


def check_length_ends(ends: Sequence[Sequence[float]]) -> tuple[tuple[float, float], tuple[float, float]]:
    """A known length's two clicked ends as floats; EditError if they are not two distinct points."""
    if len(ends) != 2:
        raise EditError(f"a known length has two ends, not {len(ends)}")
    (u1, v1), (u2, v2) = ((float(p[0]), float(p[1])) for p in ends)
    if not all(math.isfinite(v) for v in (u1, v1, u2, v2)):
        raise EditError("a known length's end is not a number")
    if math.hypot(u2 - u1, v2 - v1) < MIN_SEGMENT_LENGTH_PX:
        raise EditError(f"a known length's two ends are {math.hypot(u2 - u1, v2 - v1):.1f} px apart: press on one "
                        f"end (a vertical's foot on the floor), drag to the other, release (at least "
                        f"{MIN_SEGMENT_LENGTH_PX:g} px apart)")
    return (u1, v1), (u2, v2)


def parse_metres(value: float | str | None, what: str, limits: tuple[float, float]) -> float:
    """A length typed by the user (a number, or text such as "2.03"), metres, within ``limits``;
    EditError saying what was expected and what was typed."""
    lo, hi = limits
    if isinstance(value, str):
        text = value.strip().removesuffix("m").strip().replace(",", ".")
        try:
            number = float(text)
        except ValueError:
            raise EditError(f"{what} must be a number of metres (e.g. 2.03), not {value.strip()!r}") from None
    elif value is None:
        raise EditError(f"{what} is missing: type a number of metres (e.g. 2.03)")
    else:
        number = float(value)
    if not math.isfinite(number) or number <= 0:
        raise EditError(f"{what} must be a positive number of metres, not {number:g}")
    if not lo <= number <= hi:
        raise EditError(f"{what} must lie between {lo:g} m and {hi:g} m, not {number:g} m")
    return number


@dataclass
class VanishingState:
    """One axis of one photo: its segments and, once they allow it, the fitted vanishing point.

    point : (3,) homogeneous pixel coordinates (w = 0 at infinity), or None.
    residuals_px : (n,) each segment's residual, or None.
    problem : why there is no vanishing point yet, or None.
    polylines : each segment's points, (m, 2) (m = 2 for a plain segment, more for a polyline).
    left_out : the segments the photo's calibration left out as not meeting at the point
        (:mod:`vebuild.edit.left_out`): the point is fitted to the others (to all where fewer than
        two remain), and their residuals are to it.
    """

    axis: str
    segments: Array  # (n, 4): each segment's first and last points (a polyline's end points)
    point: Array | None = None
    residuals_px: Array | None = None
    problem: str | None = None
    polylines: list[Array] = field(default_factory=list)
    left_out: frozenset[int] = frozenset()

    @property
    def rms_px(self) -> float | None:
        """The RMS residual of the segments the point is fitted to (None without a point)."""
        if self.residuals_px is None:
            return None
        kept = [i for i in range(len(self.residuals_px)) if i not in self.left_out]
        r = np.asarray(self.residuals_px, float)[kept if len(kept) >= 2 else slice(None)]
        return float(np.sqrt(np.mean(r**2)))


class Marks(History):
    """Segments, markers, distances and edge observations (mixed into the session)."""

    if TYPE_CHECKING:
        def _model_now(self) -> tuple[Model | None, Array | None]: ...

        def _edge_docs(self) -> list[dict[str, Any]]: ...

    def _segments(self, photo: str, axis: str) -> list[list[float]]:
        if axis not in AXES:
            raise EditError(f"a vanishing segment runs along world axis x, y or z, not {axis!r}")
        p = self.photo(photo)
        return p.setdefault("vanishing_segments", {}).setdefault(axis, [])

    def add_segment(self, photo: str, axis: str, p1: Sequence[float], p2: Sequence[float],
                    sigma_px: float | None = None) -> int:
        """Add a directed segment (p1 toward +axis at p2); EditError for one shorter than 2 px.
        ``sigma_px``: its end points' measured 1σ (a segment refined to the image line), or None
        (a click's, ``settings.click_sigma_px``)."""
        return self.add_polyline(photo, axis, [p1, p2], sigma_px)

    def add_polyline(self, photo: str, axis: str, points: Sequence[Sequence[float]],
                     sigma_px: float | None = None) -> int:
        """Add a directed polyline along one straight edge (first point toward +axis at the last):
        its middle points let the calibration measure the lens distortion."""
        seg = [float(v) for p in points for v in (p[0], p[1])]
        self._check_segment(seg, axis)
        with self._edit(f"add {axis} segment in {photo}"):
            segs = self._segments(photo, axis)
            segs.append(seg)
            self._set_segment_sigma(photo, axis, len(segs) - 1, sigma_px)
        return len(segs) - 1

    def _set_segment_sigma(self, photo: str, axis: str, index: int, sigma_px: float | None) -> None:
        """Keep ``vanishing_segment_sigmas`` parallel to the segments: segment ``index`` gets
        ``sigma_px`` (None: a click's), the list made only once some segment has its own."""
        p = self.photo(photo)
        n = len((p.get("vanishing_segments") or {}).get(axis) or [])
        sig = (p.get("vanishing_segment_sigmas") or {}).get(axis)
        if sig is None and sigma_px is None:
            return
        sig = list(sig or [])[:n]
        sig += [None] * (n - len(sig))
        sig[index] = None if sigma_px is None else round(max(float(sigma_px), 1e-3), 4)
        p.setdefault("vanishing_segment_sigmas", {})[axis] = sig

    def segment_sigma(self, photo: str, axis: str, index: int) -> float | None:
        """Segment ``index``'s own measured 1σ (pixels), or None for a click's."""
        sig = (self.photo(photo).get("vanishing_segment_sigmas") or {}).get(axis) or []
        return sig[index] if 0 <= index < len(sig) else None

    def _check_segment(self, seg: Sequence[float], axis: str) -> None:
        if len(seg) < 4 or len(seg) % 2:
            raise EditError(f"a vanishing segment is two points or more (u, v), not {len(seg)} numbers")
        if not all(math.isfinite(v) for v in seg):
            raise EditError("a segment's end point is not a number")
        length = math.hypot(seg[-2] - seg[0], seg[-1] - seg[1])
        if length < MIN_SEGMENT_LENGTH_PX:
            raise EditError(f"that {axis} segment is {length:.1f} px long: a vanishing segment needs two distinct "
                            f"end points at least {MIN_SEGMENT_LENGTH_PX:g} px apart along an edge; press, drag "
                            "along the edge, release")

    def move_segment(self, photo: str, axis: str, index: int, seg: Sequence[float]) -> None:
        """Replace a segment; four numbers given for a polyline move its end points, keeping its middle ones."""
        seg = [float(v) for v in seg]
        old = self._segments(photo, axis)[index]
        if len(old) > 4 and len(seg) == 4:
            seg = [*seg[:2], *old[2:-2], *seg[2:]]
        self._check_segment(seg, axis)
        with self._edit(f"move {axis} segment {index} in {photo}"):
            self._segments(photo, axis)[index] = seg
            self._set_segment_sigma(photo, axis, index, None)  # placed by hand now

    # -- middle points of a polyline segment (plumb-line: the lens distortion) ----------------------

    def _polyline(self, photo: str, axis: str, index: int) -> list[list[float]]:
        segs = self._segments(photo, axis)
        if not 0 <= index < len(segs):
            raise EditError(f"photo '{photo}' has no {axis} segment {index} (it has {len(segs)})")
        row = segs[index]
        return [[row[k], row[k + 1]] for k in range(0, len(row), 2)]

    def insert_segment_point(self, photo: str, axis: str, index: int, uv: Sequence[float]) -> int:
        """Add a middle point at uv to a segment (making it a polyline along its edge as the lens bent
        it), between the points it falls between along the segment; returns its place in the
        polyline (1 for the first middle point)."""
        pts = self._polyline(photo, axis, index)
        q = np.asarray([float(uv[0]), float(uv[1])])
        if not np.all(np.isfinite(q)):
            raise EditError("a middle point's position is not a number")
        a, b = np.asarray(pts[0]), np.asarray(pts[-1])
        d = b - a
        t = float((q - a) @ d / max(float(d @ d), 1e-12))
        if not 0.0 < t < 1.0:
            raise EditError(f"a middle point must lie between the {axis} segment's two ends (this one is "
                            f"{100 * t:.0f} % of the way from its first end); to lengthen the segment, drag its end")
        ts = [float((np.asarray(p) - a) @ d / float(d @ d)) for p in pts]
        at = next(k for k in range(1, len(pts)) if ts[k] >= t)
        pts.insert(at, [float(q[0]), float(q[1])])
        with self._edit(f"add a middle point to {axis} segment {index} in {photo}"):
            self._segments(photo, axis)[index] = [v for p in pts for v in p]
        return at

    def move_segment_point(self, photo: str, axis: str, index: int, point: int, uv: Sequence[float]) -> None:
        """Move one middle point of a polyline segment (its ends move with :meth:`move_segment`)."""
        pts = self._polyline(photo, axis, index)
        if not 0 < point < len(pts) - 1:
            raise EditError(f"{axis} segment {index} has no middle point {point} (it has {len(pts) - 2})")
        pts[point] = [float(uv[0]), float(uv[1])]
        seg = [v for p in pts for v in p]
        self._check_segment(seg, axis)
        with self._edit(f"move a middle point of {axis} segment {index} in {photo}"):
            self._segments(photo, axis)[index] = seg

    def delete_segment_point(self, photo: str, axis: str, index: int, point: int) -> None:
        """Remove one middle point of a polyline segment (with none left it is a plain segment)."""
        pts = self._polyline(photo, axis, index)
        if not 0 < point < len(pts) - 1:
            raise EditError(f"{axis} segment {index} has no middle point {point} (it has {len(pts) - 2})")
        del pts[point]
        with self._edit(f"delete a middle point of {axis} segment {index} in {photo}"):
            self._segments(photo, axis)[index] = [v for p in pts for v in p]

    def segment_point_at(self, photo: str, uv: Sequence[float], radius_px: float) -> tuple[str, int, int] | None:
        """The middle point of a polyline segment nearest uv within radius_px: (axis, index, point)."""
        best: tuple[float, tuple[str, int, int]] | None = None
        for axis, segs in (self.photo(photo).get("vanishing_segments") or {}).items():
            for i, row in enumerate(segs):
                for k in range(1, len(row) // 2 - 1):
                    d = math.dist(row[2 * k:2 * k + 2], uv)
                    if d <= radius_px and (best is None or d < best[0]):
                        best = (d, (axis, i, k))
        return best[1] if best else None

    def nearest_segment(self, photo: str, axis: str, uv: Sequence[float], radius_px: float) -> int | None:
        """The segment of this axis whose path (through its middle points) passes nearest uv, within
        radius_px, or None."""
        q = np.asarray(uv, float)
        best: tuple[float, int] | None = None
        for i, row in enumerate((self.photo(photo).get("vanishing_segments") or {}).get(axis, [])):
            pts = np.asarray(row, float).reshape(-1, 2)
            for a, b in zip(pts[:-1], pts[1:], strict=True):
                t = float(np.clip((q - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-12), 0.0, 1.0))
                d = float(np.linalg.norm(q - (a + t * (b - a))))
                if d <= radius_px and (best is None or d < best[0]):
                    best = (d, i)
        return best[1] if best else None

    def delete_segment(self, photo: str, axis: str, index: int) -> None:
        with self._edit(f"delete {axis} segment {index} in {photo}"):
            segs = self._segments(photo, axis)
            del segs[index]
            sigmas = self.photo(photo).get("vanishing_segment_sigmas") or {}
            if axis in sigmas:
                del sigmas[axis][index:index + 1]
                if not segs:
                    del sigmas[axis]
                if not sigmas:
                    del self.photo(photo)["vanishing_segment_sigmas"]
            if not segs:
                del self.photo(photo)["vanishing_segments"][axis]
            if not has_segments(self.photo(photo)):  # as `vebuild detect --replace` clears it
                self.photo(photo).pop(UNRESOLVED, None)

    def segment_at(self, photo: str, uv: Sequence[float], radius_px: float) -> tuple[str, int, int | None] | None:
        """The segment near uv: (axis, index, 0/1 for an end point or None for its body)."""
        best: tuple[float, tuple[str, int, int | None], int | None] | None = None
        q = np.asarray(uv, float)
        for axis, segs in (self.photo(photo).get("vanishing_segments") or {}).items():
            for i, s in enumerate(segs):
                a, b = np.asarray(s[:2]), np.asarray(s[-2:])
                for end, p in ((0, a), (1, b)):
                    d = float(np.linalg.norm(q - p))
                    if d <= radius_px and (best is None or d < best[0] - 1e-9 or best[2] is None):
                        best = (d, (axis, i, end), end)
                t = np.clip(np.dot(q - a, b - a) / max(np.dot(b - a, b - a), 1e-12), 0, 1)
                d = float(np.linalg.norm(q - (a + t * (b - a))))
                if d <= radius_px and best is None:
                    best = (d, (axis, i, None), None)
        return best[1] if best else None

    def vanishing(self, photo: str, axis: str) -> VanishingState:
        """The segments of one axis and their best-fit vanishing point (or why there is none yet)."""
        key = ("vp", photo, axis)
        if key not in self._cache:
            from vebuild.calibration.vanishing import fit_vanishing_point, segment_residuals

            p = self.photo(photo)
            polys = [np.asarray(r, float).reshape(-1, 2) for r in (p.get("vanishing_segments") or {}).get(axis, [])]
            segs = np.array([np.r_[q[0], q[-1]] for q in polys], float).reshape(-1, 4)
            state = VanishingState(axis, segs, polylines=polys)
            if len(segs) < 2:
                state.problem = (f"{axis}: {len(segs)} segment{'s' if len(segs) != 1 else ''}; a vanishing point needs "
                                 "two or more, along different parallel edges")
            else:
                left_out = set(self._left_out_of(photo, axis, len(segs)))
                kept = [i for i in range(len(segs)) if i not in left_out]
                try:
                    if left_out and len(kept) >= 2:  # the point the calibration found, not the clutter's pull
                        fit = fit_vanishing_point(segs[kept], p["width"], p["height"], axis=axis, photo=photo)
                        state.residuals_px = segment_residuals(fit.point, segs)
                    else:
                        fit = fit_vanishing_point(segs, p["width"], p["height"], axis=axis, photo=photo)
                        state.residuals_px = fit.residuals_px
                    state.point, state.left_out = fit.point, frozenset(left_out)
                except CalibrationError as e:
                    state.problem = f"{axis}: cannot fit a vanishing point yet: {e.detail}"
            self._cache[key] = state
        return self._cache[key]

    def _left_out_of(self, photo: str, axis: str, n_segments: int) -> dict[int, str]:
        """The indices of the axis' segments the photo's calibration left out, and why."""
        vps = (decode.camera_records(self.data).get(photo) or {}).get("vanishing_points") or {}
        return rejected_by_calibration(vps.get(axis), n_segments)

    # -- markers and reference distances ----------------------------------------------------------

    def next_marker_name(self) -> str:
        names = set(self.project.marker_names())
        k = 1
        while f"M{k}" in names:
            k += 1
        return f"M{k}"

    def place_marker(self, photo: str, name: str, uv: Sequence[float]) -> None:
        """Mark marker ``name`` at uv in the photo (a new name makes a new marker)."""
        name = name.strip()
        if not name or ":" in name:
            raise EditError("a marker needs a name (without ':', which names model vertices)")
        uv = [float(uv[0]), float(uv[1])]
        with self._edit(f"place marker {name} in {photo}"):
            if name not in self.project.marker_names():
                self.data["markers"].append({"name": name})
            self.photo(photo).setdefault("marker_observations", {})[name] = uv
            if not self.data.get("origin_marker") and len(self.data["markers"]) == 1:
                self.data["origin_marker"] = name

    def remove_marker(self, photo: str, name: str) -> None:
        """Remove the marker's observation in this photo (and the marker, once nothing refers to it)."""
        obs = self.photo(photo).get("marker_observations") or {}
        if name not in obs:
            raise EditError(f"marker '{name}' is not marked in photo '{photo}'")
        with self._edit(f"remove marker {name} from {photo}"):
            del obs[name]
            used = any(name in (p.get("marker_observations") or {}) for p in self.data["photos"])
            used |= any(name in (d["a"], d["b"]) for d in self.data["reference_distances"])
            nodes = (self.data.get("model") or {}).get("nodes", [])
            used |= any(n.get("joint", {}).get("marker") == name for n in nodes)
            if not used:
                self.data["markers"] = [m for m in self.data["markers"] if m["name"] != name]
                if self.data.get("origin_marker") == name:
                    del self.data["origin_marker"]

    def marker_at(self, photo: str, uv: Sequence[float], radius_px: float) -> str | None:
        obs = self.photo(photo).get("marker_observations") or {}
        best = min(obs.items(), key=lambda kv: math.dist(kv[1], uv), default=None)
        return best[0] if best and math.dist(best[1], uv) <= radius_px else None

    def set_origin(self, name: str) -> None:
        if name not in self.project.marker_names():
            raise EditError(f"no marker is called '{name}'; place it in a photo first")
        with self._edit(f"origin at {name}"):
            self.data["origin_marker"] = name

    def add_distance(self, a: str, b: str, distance_m: float, sigma_m: float = 0.002, role: str = "scale") -> None:
        """A measured distance between two markers (or model vertices ``node:handle``)."""
        a, b = a.strip(), b.strip()
        if role not in ("scale", "check"):
            raise EditError(f"a reference distance's role is 'scale' or 'check', not {role!r}")
        if not (math.isfinite(distance_m) and distance_m > 0):
            raise EditError(f"a reference distance must be a positive number of metres, not {distance_m!r}")
        if not (math.isfinite(sigma_m) and sigma_m > 0):
            raise EditError(f"a reference distance's σ must be a positive number of metres, not {sigma_m!r}")
        if a == b:
            raise EditError("a reference distance needs two different ends")
        with self._edit(f"distance {a}–{b}"):
            self.data["reference_distances"].append({"a": a, "b": b, "distance": float(distance_m),
                                                     "sigma": float(sigma_m), "role": role})

    def remove_distance(self, index: int) -> None:
        with self._edit("remove distance"):
            del self.data["reference_distances"][index]

    # -- a photo's own scale: known lengths, the camera's height, markers on the floor -------------

    def add_known_length(self, photo: str, axis: str, ends: Sequence[Sequence[float]], length_m: float | str,
                         sigma_m: float | str | None = None, description: str | None = None) -> int:
        """A length known at the scene along world axis ``axis``, its two ends clicked in the photo
        (for ``z`` the foot on the floor first, then the top; for ``x`` or ``y`` an edge on the
        floor); ``sigma_m`` None or blank: :data:`KNOWN_LENGTH_SIGMA_M`. Returns its index in
        ``$.known_lengths``."""
        if axis not in AXES:
            raise EditError(f"a known length runs along world axis x, y or z, not {axis!r}")
        self.photo(photo)
        length = parse_metres(length_m, "the known length", LENGTH_RANGE_M)
        sigma = KNOWN_LENGTH_SIGMA_M if _blank(sigma_m) else parse_metres(sigma_m, "the known length's σ",
                                                                         SIGMA_RANGE_M)
        (u1, v1), (u2, v2) = check_length_ends(ends)
        doc: dict[str, Any] = {"photo": photo, "axis": axis, "ends": [[u1, v1], [u2, v2]], "length": length,
                               "sigma": sigma}
        if axis == "z":
            doc["floor_end"] = 0
        if description:
            doc["description"] = description
        with self._edit(f"known length {length:g} m along {axis} in {photo}"):
            self.data.setdefault("known_lengths", []).append(doc)
        return len(self.data["known_lengths"]) - 1

    def remove_known_length(self, index: int) -> None:
        lengths = self.data.get("known_lengths", [])
        if not 0 <= index < len(lengths):
            raise EditError(f"there is no known length {index} (there are {len(lengths)})")
        with self._edit(f"remove known length {index}"):
            del self.data["known_lengths"][index]
            if not self.data["known_lengths"]:
                del self.data["known_lengths"]

    def known_length_at(self, photo: str, uv: Sequence[float], radius_px: float) -> int | None:
        """The index of the known length clicked in this photo whose line passes nearest uv, or None."""
        q = np.asarray(uv, float)
        best: tuple[float, int] | None = None
        for i, k in enumerate(self.data.get("known_lengths", [])):
            if k["photo"] != photo:
                continue
            a, b = np.asarray(k["ends"][0], float), np.asarray(k["ends"][1], float)
            t = float(np.clip((q - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-12), 0.0, 1.0))
            d = float(np.linalg.norm(q - (a + t * (b - a))))
            if d <= radius_px and (best is None or d < best[0]):
                best = (d, i)
        return best[1] if best else None

    def set_camera_height(self, photo: str, value_m: float | str | None,
                          sigma_m: float | str | None = None) -> None:
        """The camera's height above the floor when the photo was taken (``camera_height``), metres,
        with its 1σ (None or blank: :data:`CAMERA_HEIGHT_SIGMA_M`); ``value_m`` None or blank
        removes it."""
        p = self.photo(photo)
        if _blank(value_m):
            if "camera_height" not in p:
                raise EditError(f"photo '{photo}' has no camera height to remove")
            with self._edit(f"remove the camera height of {photo}"):
                del self.photo(photo)["camera_height"]
            return
        h = parse_metres(value_m, "the camera height", CAMERA_HEIGHT_RANGE_M)
        s = CAMERA_HEIGHT_SIGMA_M if _blank(sigma_m) else parse_metres(sigma_m, "the camera height's σ",
                                                                      SIGMA_RANGE_M)
        with self._edit(f"camera height {h:g} m in {photo}"):
            self.photo(photo)["camera_height"] = {"value": h, "sigma": s}

    def set_on_floor(self, name: str, on_floor: bool) -> None:
        """Mark a marker as lying on the floor (z = 0: one photo places it) or not (``on_floor``)."""
        marker = next((m for m in self.data["markers"] if m["name"] == name), None)
        if marker is None:
            raise EditError(f"no marker is called '{name}'; place it in a photo first")
        with self._edit(f"{name} {'on' if on_floor else 'off'} the floor"):
            marker = next(m for m in self.data["markers"] if m["name"] == name)
            if on_floor:
                marker["on_floor"] = True
            else:
                marker.pop("on_floor", None)

    # -- the user's edges (paper §3) ----------------------------------------------------------------

    def nearest_edge(self, photo: str, p1: Sequence[float], p2: Sequence[float],
                     node: str | None = None) -> tuple[str, str] | None:
        """The projected model edge that the stroke p1–p2 follows best (of ``node``, or any)."""
        cam = self._camera(photo)
        model, x = self._model_now()
        if model is None:
            return None
        names = [node] if node else [n.name for n in model.nodes if n.primitive is not None]
        a, b = np.asarray(p1, float), np.asarray(p2, float)
        best = None
        for n, edges in project_edges(model, cam, names, x).items():
            for e, (u1, v1, u2, v2) in edges:
                q1, q2 = np.array([u1, v1]), np.array([u2, v2])
                d = q2 - q1
                L = float(np.linalg.norm(d))
                if L < 1e-6:
                    continue
                nrm = np.array([-d[1], d[0]]) / L
                dist = abs(float((a - q1) @ nrm)) + abs(float((b - q1) @ nrm))
                mid = 0.5 * (a + b)
                t = float((mid - q1) @ d) / L**2
                dist += max(0.0, -t, t - 1.0) * L  # beyond the edge's ends
                if best is None or dist < best[0]:
                    best = (dist, n, e)
        return (best[1], best[2]) if best else None

    def add_edge_observation(self, photo: str, node: str, edge: str, p1: Sequence[float], p2: Sequence[float]) -> None:
        """The user's (red) edge: the model edge must pass through p1 and p2 (paper §3)."""
        self._camera(photo)
        if math.dist(p1, p2) < MIN_SEGMENT_LENGTH_PX:
            raise EditError(f"an edge needs two end points at least {MIN_SEGMENT_LENGTH_PX:g} px apart")
        model = self.model
        prim = model.node(node).primitive if model and node in model.index else None
        if prim is None or edge not in [e for e, _, _ in prim.edges()]:
            raise EditError(f"'{node}' has no edge '{edge}'")
        with self._edit(f"edge {node}:{edge} in {photo}"):
            self._edge_docs().append({"photo": photo, "node": node, "edge": edge,
                                      "points": [[float(p1[0]), float(p1[1])], [float(p2[0]), float(p2[1])]]})

    def remove_edge_observation(self, index: int) -> None:
        with self._edit("remove edge"):
            del self._edge_docs()[index]
