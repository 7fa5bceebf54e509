"""The room primitive: a floor polygon of N corners, walls of one thickness up to a height, an
optional ceiling, and doorways and windows as parametric holes in the walls (scenes/FORMAT.md,
"The room primitive").

Unlike the other primitives a room's parameters depend on its structure (how many corners,
rectilinear or not, which openings), so ``PARAMS`` is per instance and the handles are not linear
in the parameters (the outer corners are mitred, the walls' directions follow the corners):
``LINEAR`` is False and the solver asks :meth:`Room.handles` at each trial.

Local frame: the floor at z = 0, inner floor corner 0 at the origin, corner 1 on +x, the corners
counter-clockwise seen from above. Wall i runs from corner i to corner i + 1 (mod N); its inner
face is the polygon's side, its outer face lies ``thickness`` further out, the outer corners
mitred. Openings are placed on a wall's inner face by their offset from corner i.

Layer 1 (DESIGN.md): numpy only; no GL, no file I/O.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, ClassVar, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .mesh import Patch
from .primitives import MIN_SIZE_M, Frame, Primitive
from .room_checks import OPENING_KINDS, Opening, RoomError, check_room, structure, wall_presence
from .room_mesh import room_patches

__all__ = ["OPENING_KINDS", "Opening", "Room", "RoomError", "corner_param_names"]

Array = NDArray[np.float64]

_EX, _EY, _EZ = np.eye(3)
_OPENING_SUFFIXES = ("offset", "width", "height", "sill")
_OPENING_HANDLES = ("sb", "st", "eb", "et", "osb", "ost", "oeb", "oet")
#: Relative step of the central differences of :meth:`Room.handle_jacobian`; the handles are
#: smooth (rational) in the params, so the truncation error is ~step² of their curvature.
_JACOBIAN_STEP = 1e-6


def corner_param_names(n: int, rectilinear: bool) -> tuple[str, ...]:
    """The corner parameters of an N-cornered room (FORMAT.md): rectilinear ``c1_x``, ``c2_y``,
    ``c3_x``, … ``c{N-2}_y``; general ``c1_x`` then ``c{i}_x``, ``c{i}_y`` for i = 2…N−1."""
    if rectilinear:
        return tuple(f"c{i}_{'x' if i % 2 else 'y'}" for i in range(1, n - 1))
    return ("c1_x",) + tuple(f"c{i}_{a}" for i in range(2, n) for a in "xy")


def _corners_of(p: Array, n: int, rectilinear: bool) -> Array:
    """(N, 2) inner floor corners from the corner params (the first entries of p)."""
    c = np.zeros((n, 2), dtype=np.result_type(p, float))
    if rectilinear:
        # Corner i = (c_i_x, c_{i-1}_y) for odd i, (c_{i-1}_x, c_i_y) for even i; c0 = (0, 0),
        # c_{N-1} = (0, c_{N-2}_y): the walls alternate along x and y.
        for i in range(1, n - 1):
            v = p[i - 1]
            if i % 2:
                c[i, 0] = v
                c[i, 1] = c[i - 1, 1]
            else:
                c[i, 0] = c[i - 1, 0]
                c[i, 1] = v
        c[n - 1, 1] = c[n - 2, 1]
    else:
        c[1, 0] = p[0]
        c[2:, :] = np.reshape(p[1 : 1 + 2 * (n - 2)], (n - 2, 2))
    return c


class Room(Primitive):
    """A room shell: floor polygon, walls with openings, optional ceiling (module docstring).

    Build one with ``Room.from_corners`` or ``Room(corners=N, rectilinear=…, ceiling=…,
    openings=[…], **params)``; each parameter is also read as an attribute (``room.height``).
    """

    TYPE = "room"
    LINEAR = False
    ANCHOR_HANDLE = "f0"
    DEFAULT_PARAMS: ClassVar[Mapping[str, float]] = {"c1_x": 4.0, "c2_y": 3.0, "height": 2.5, "thickness": 0.1}
    _RESTABLE = ("floor",)

    n_corners: int
    rectilinear: bool
    ceiling: bool
    openings: tuple[Opening, ...]
    walls_present: tuple[bool, ...]
    _handle_names: tuple[str, ...]
    _edges: tuple[tuple[str, str, str], ...]

    def __init__(self, *args: float, corners: int = 4, rectilinear: bool = True, ceiling: bool = False,
                 openings: Iterable[Opening | Mapping[str, Any] | Sequence[Any]] = (),
                 walls: Sequence[bool] | None = None, **params: float) -> None:
        structure_ = structure(corners, rectilinear, ceiling, openings)
        n, rect, ops = structure_
        present = wall_presence(walls, n, ops)
        names = corner_param_names(n, rect) + ("height", "thickness") + tuple(
            f"{o.name}_{s}" for o in ops for s in _OPENING_SUFFIXES)
        set_ = object.__setattr__
        set_(self, "n_corners", n)
        set_(self, "rectilinear", rect)
        set_(self, "ceiling", bool(ceiling))
        set_(self, "openings", ops)
        set_(self, "walls_present", present)
        set_(self, "PARAMS", names)
        handles = tuple(f"{k}{i}" for k in ("f", "t", "fo", "to") for i in range(n)) + tuple(
            f"{o.name}_{h}" for o in ops for h in _OPENING_HANDLES)
        set_(self, "_handle_names", handles)
        edges = []
        for kind, a, b, step in (("floor", "f", "f", 1), ("top", "t", "t", 1), ("corner", "f", "t", 0),
                                 ("ofloor", "fo", "fo", 1), ("otop", "to", "to", 1), ("ocorner", "fo", "to", 0)):
            # An absent wall has no top nor outer face: only its floor edge (the floor's side) is
            # drawn, and a corner's vertical where a wall meets it.
            edges += [(f"{kind}{i}", f"{a}{i}", f"{b}{(i + step) % n}") for i in range(n)
                      if kind == "floor" or (present[i] if step else present[i] or present[i - 1])]
        for o in ops:
            m = o.name
            edges += [(f"{m}_start", f"{m}_sb", f"{m}_st"), (f"{m}_end", f"{m}_eb", f"{m}_et"),
                      (f"{m}_top", f"{m}_st", f"{m}_et"), (f"{m}_sill", f"{m}_sb", f"{m}_eb")]
        set_(self, "_edges", tuple(edges))
        if len(args) > len(names):
            raise RoomError(f"room takes {len(names)} params ({', '.join(names)}), got {len(args)}")
        named = dict(zip(names, args, strict=False))
        if twice := named.keys() & params.keys():
            raise RoomError(f"room: {', '.join(sorted(twice))} given twice")
        set_(self, "_p", self._checked(self._from_mapping({**named, **params})))
        self._validate_geometry()

    # -- parameters ----------------------------------------------------------------------------

    def __getattr__(self, name: str) -> float:
        # Only called when normal lookup fails: the per-instance parameter names.
        try:
            names = object.__getattribute__(self, "PARAMS")
        except AttributeError:
            raise AttributeError(name) from None
        if name in names:
            return float(self._p[names.index(name)])
        raise AttributeError(f"room has no attribute or param {name!r}")

    def param(self, name: str) -> float:
        """The value of parameter ``name`` (as the attribute ``room.<name>``)."""
        if name not in self.PARAMS:
            raise ValueError(f"room has no param {name!r}; its params: {', '.join(self.PARAMS)}")
        return float(self._p[self.PARAMS.index(name)])

    def _from_mapping(self, params: Mapping[str, Any]) -> list[float]:  # type: ignore[override]
        if unknown := [k for k in params if k not in self.PARAMS]:
            raise RoomError(f"room: unknown param {unknown[0]!r}; expected {', '.join(self.PARAMS)}",
                            f"params.{unknown[0]}")
        if missing := [k for k in self.PARAMS if k not in params]:
            raise RoomError(f"room needs params {', '.join(self.PARAMS)}; missing {', '.join(missing)}", "params")
        for name in self.PARAMS:
            v = params[name]
            if isinstance(v, bool) or not isinstance(v, numbers.Real):
                raise RoomError(f"room: {name} must be a number, got {v!r}", f"params.{name}")
        return [float(params[name]) for name in self.PARAMS]

    def _checked(self, values: ArrayLike) -> Array:  # type: ignore[override]
        p = np.array(values, dtype=float)
        if p.shape != (len(self.PARAMS),):
            raise RoomError(f"room: expected {len(self.PARAMS)} params ({', '.join(self.PARAMS)}), got shape {p.shape}")
        for name, v, least in zip(self.PARAMS, p, self.minimum_sizes(), strict=True):
            if not np.isfinite(v):
                raise RoomError(f"room: {name} must be a finite number, got {v}", f"params.{name}")
            if least > 0 and v <= 0:
                raise RoomError(f"room: {name} must be > 0, got {v:g}", f"params.{name}")
            if v < least:
                raise RoomError(f"room: {name} must be at least {least:g} m, got {v:g}", f"params.{name}")
        p.flags.writeable = False
        return p

    @classmethod
    def minimum_size(cls, name: str) -> float:
        """Corner coordinates are positions (any value); an opening's offset and sill may be 0;
        heights, widths and the thickness are sizes (at least MIN_SIZE_M)."""
        if re.fullmatch(r"c\d+_[xy]", name):
            return -math.inf
        if name.endswith(("_offset", "_sill")):
            return 0.0
        return MIN_SIZE_M

    def minimum_sizes(self) -> Array:  # type: ignore[override]
        return np.array([self.minimum_size(n) for n in self.PARAMS])

    def param_kinds(self) -> tuple[str, ...]:
        """Corner coordinates are positions; the rest (height, thickness, openings) sizes."""
        return tuple("position" if re.fullmatch(r"c\d+_[xy]", n) else "size" for n in self.PARAMS)

    def with_params(self, params: ArrayLike | Mapping[str, float]) -> Self:
        if isinstance(params, Mapping):
            params = self._from_mapping({**self.to_dict()["params"], **params})
        return type(self)(*self._checked(params), **self._structure_kwargs())

    def _structure_kwargs(self) -> dict[str, Any]:
        return {"corners": self.n_corners, "rectilinear": self.rectilinear, "ceiling": self.ceiling,
                "openings": self.openings, "walls": self.walls_present}

    # -- construction --------------------------------------------------------------------------

    @classmethod
    def from_corners(cls, corners: ArrayLike, height: float, thickness: float, *, rectilinear: bool = True,
                     ceiling: bool = False, openings: Iterable[Mapping[str, Any]] = (),
                     walls: Sequence[bool] | None = None) -> Room:
        """A room from its inner floor corners (N, 2) in room coordinates (corner 0 at the origin,
        corner 1 on +x, counter-clockwise); ``openings`` are dicts name, wall, kind, offset, width,
        height, sill."""
        c = np.asarray(corners, float)
        if c.ndim != 2 or c.shape[1] != 2 or len(c) < 3:
            raise RoomError(f"room: expected corners (N, 2) with N >= 3, got shape {c.shape}", "corners")
        if np.any(c[0] != 0.0) or c[1, 1] != 0.0:
            raise RoomError("room: corner 0 must be the origin and corner 1 on the x axis (y = 0); got "
                            f"{c[0].tolist()}, {c[1].tolist()}", "corners")
        n = len(c)
        if rectilinear:
            vals = [c[i, 0] if i % 2 else c[i, 1] for i in range(1, n - 1)]
            if n % 2 or not np.allclose(_corners_of(np.array(vals), n, True), c, atol=1e-12, rtol=0):
                raise RoomError("room: these corners are not rectilinear (walls alternating along x and y from "
                                "corner 0); pass rectilinear=False", "rectilinear")
        else:
            vals = [c[1, 0]] + c[2:].ravel().tolist()
        ops = list(openings)
        params = dict(zip(corner_param_names(n, rectilinear), (float(v) for v in vals), strict=True))
        params |= {"height": float(height), "thickness": float(thickness)}
        for o in ops:
            params |= {f"{o['name']}_{s}": float(o[s]) for s in _OPENING_SUFFIXES}
        return cls(corners=n, rectilinear=rectilinear, ceiling=ceiling,
                   openings=[{"name": o["name"], "wall": o["wall"], "kind": o["kind"]} for o in ops], walls=walls,
                   **params)

    def with_walls(self, walls: Sequence[bool]) -> Room:
        """This room with the walls ``walls`` (one true or false per wall) present."""
        return Room(*self._p, **{**self._structure_kwargs(), "walls": tuple(walls)})

    def with_opening(self, name: str, wall: int, kind: str, offset: float, width: float, height: float,
                     sill: float) -> Room:
        """This room with one more opening (validated as every opening)."""
        params = {**self.to_dict()["params"], f"{name}_offset": offset, f"{name}_width": width,
                  f"{name}_height": height, f"{name}_sill": sill}
        return Room(corners=self.n_corners, rectilinear=self.rectilinear, ceiling=self.ceiling,
                    openings=[*self.openings, Opening(name, wall, kind)], walls=self.walls_present, **params)

    def with_corner(self, after_corner: int, depth: float | None = None) -> Room:
        """This room with wall ``after_corner`` split: a general room gets a corner at the wall's
        middle; a rectilinear one a step (two corners) there, ``depth`` metres into the room
        (default a quarter of the wall, at most 0.5 m), so its walls still alternate along x and y.
        Openings beyond the split move to the new wall; one across it is an error."""
        n = self.n_corners
        if not (isinstance(after_corner, int) and 0 <= after_corner < n):
            raise RoomError(f"room: corner {after_corner!r} is not one of 0…{n - 1}", "corners")
        i = after_corner
        c = self.corners()
        a, b = c[i], c[(i + 1) % n]
        length = float(np.linalg.norm(b - a))
        d = (b - a) / length
        mid = a + d * (length / 2)
        if self.rectilinear:
            step = min(0.25 * length, 0.5) if depth is None else float(depth)
            inward = np.array([-d[1], d[0]])
            new = [mid, mid + inward * step]
            if i + 1 == n:  # the step would move corner 0, which is the room's origin
                raise RoomError("room: a rectilinear room's last wall (back to corner 0) cannot be split; split "
                                "another wall", "corners")
            moved = [c[j] for j in range(n)]
            # The rest of wall i steps in by s: corner i + 1 moves with it (its other wall stays put).
            moved[i + 1] = b + inward * step
            pts = moved[: i + 1] + new + moved[i + 1 :]
            extra = 2
        else:
            pts = [c[j] for j in range(i + 1)] + [mid] + [c[j] for j in range(i + 1, n)]
            extra = 1
        params: dict[str, Any] = {k: v for k, v in self.to_dict()["params"].items()
                                  if not re.fullmatch(r"c\d+_[xy]", k)}
        ops: list[dict[str, Any]] = []
        for o in self.openings:
            off, w = self.param(f"{o.name}_offset"), self.param(f"{o.name}_width")
            wall = o.wall if o.wall <= i else o.wall + extra
            if o.wall == i and off + w > length / 2:
                if off < length / 2:
                    raise RoomError(f"room: opening '{o.name}' spans the middle of wall {i}, where the new corner "
                                    "goes; move it first", f"openings[{self.openings.index(o)}]")
                wall, params[f"{o.name}_offset"] = i + extra, off - length / 2
            ops.append({"name": o.name, "wall": wall, "kind": o.kind, **{
                suffix: params[f"{o.name}_{suffix}"] for suffix in _OPENING_SUFFIXES}})
        for op in ops:
            for suffix in _OPENING_SUFFIXES:
                params.pop(f"{op['name']}_{suffix}")
        walls = list(self.walls_present)
        walls[i + 1:i + 1] = [walls[i]] * extra  # the split wall's parts are there where it was
        return Room.from_corners(np.array(pts), params["height"], params["thickness"], rectilinear=self.rectilinear,
                                 ceiling=self.ceiling, openings=ops, walls=walls)

    def opening_names(self) -> list[str]:
        return [o.name for o in self.openings]

    def opening(self, name: str) -> Opening:
        for o in self.openings:
            if o.name == name:
                return o
        have = ", ".join(self.opening_names()) or "none"
        raise ValueError(f"the room has no opening {name!r}; its openings: {have}")

    # -- geometry ------------------------------------------------------------------------------

    def corners(self, params: ArrayLike | None = None) -> Array:
        """(N, 2) inner floor corners, counter-clockwise seen from above."""
        return _corners_of(self._as_params(params), self.n_corners, self.rectilinear)

    def _value(self, p: Array, name: str) -> Any:
        return p[self.PARAMS.index(name)]

    def walls(self, params: ArrayLike | None = None) -> dict[str, Array]:
        """Per wall i: ``start`` corner (N, 2), unit ``dir`` (N, 2), ``length`` (N,), outward unit
        ``normal`` (N, 2), mitred ``outer`` corners (N, 2) (outer corner i at inner corner i),
        ``outer_u`` (N, 2): where the outer face starts and ends along the wall, measured from
        inner corner i."""
        p = self._as_params(params)
        c = self.corners(p)
        t = self._value(p, "thickness")
        e = np.roll(c, -1, axis=0) - c
        length = np.hypot(e[:, 0], e[:, 1])
        d = e / np.where(length > 0, length, 1.0)[:, None]
        nrm = np.stack([d[:, 1], -d[:, 0]], axis=1)  # outward for a counter-clockwise polygon
        prev = np.roll(nrm, 1, axis=0)
        # The mitre: the outer faces of walls i−1 and i meet at c_i + t (n_{i−1} + n_i) / (1 + n_{i−1}·n_i).
        denom = 1.0 + np.sum(prev * nrm, axis=1)
        outer = c + t * (prev + nrm) / np.where(np.abs(denom) > 1e-12, denom, 1e-12)[:, None]
        nxt = np.roll(outer, -1, axis=0)
        u = np.stack([np.sum((outer - c) * d, axis=1), np.sum((nxt - c) * d, axis=1)], axis=1)
        return {"start": c, "dir": d, "length": length, "normal": nrm, "outer": outer, "outer_u": u}

    def _opening_geometry(self, p: Array, name: str) -> tuple[Opening, Any, Any, Any, Any]:
        o = self.opening(name)
        return o, *(self._value(p, f"{name}_{s}") for s in _OPENING_SUFFIXES)

    def handle_names(self) -> tuple[str, ...]:  # type: ignore[override]
        return self._handle_names

    def edges(self) -> list[tuple[str, str, str]]:  # type: ignore[override]
        return list(self._edges)

    @classmethod
    def _handles_of(cls, P: Array) -> Array:
        raise TypeError("a room's handles depend on its corners and openings: ask room.handles(params)")

    def handles(self, params: ArrayLike | None = None) -> Array:
        p = self._as_params(params)
        w = self.walls(p)
        h, t = self._value(p, "height"), self._value(p, "thickness")
        n = self.n_corners
        c, outer = w["start"], w["outer"]
        zero = np.zeros(n)
        rows = [np.column_stack([c, zero]), np.column_stack([c, zero + h]),
                np.column_stack([outer, zero]), np.column_stack([outer, zero + h])]
        for o in self.openings:
            _, off, width, oh, sill = self._opening_geometry(p, o.name)
            a, d, nrm = w["start"][o.wall], w["dir"][o.wall], w["normal"][o.wall]
            s, e = a + d * off, a + d * (off + width)
            inner = [(s, sill), (s, sill + oh), (e, sill), (e, sill + oh)]
            rows.append(np.array([[q[0], q[1], z] for q, z in inner]
                                 + [[q[0] + t * nrm[0], q[1] + t * nrm[1], z] for q, z in inner]))
        return np.concatenate(rows, axis=0)

    def handles_batch(self, P: ArrayLike) -> Array:
        P = np.asarray(P, dtype=float)
        if P.ndim != 2 or P.shape[1] != len(self.PARAMS):
            raise ValueError(f"room: expected params of shape (m, {len(self.PARAMS)}), got {P.shape}")
        return np.array([self.handles(q) for q in P]).reshape(len(P), len(self._handle_names), 3)

    def handle_jacobian(self, params: ArrayLike | None = None) -> Array:
        """(n, 3, k) ∂handle/∂param at ``params`` by central differences (the handles are smooth)."""
        p = np.array(self._as_params(params), float)
        out = np.zeros((len(self._handle_names), 3, len(p)))
        for j in range(len(p)):
            step = _JACOBIAN_STEP * max(1.0, abs(p[j]))
            hi, lo = p.copy(), p.copy()
            hi[j] += step
            lo[j] -= step
            out[:, :, j] = (self.handles(hi) - self.handles(lo)) / (2 * step)
        return out

    # -- points tied to the room (analysis: a stain on a wall) --------------------------------

    def to_coords(self, local: ArrayLike) -> Array:
        """A local point's coordinates that follow the walls when the room's params change:
        (i + t, s, z / height) with wall i the nearest (in plan), t ∈ [0, 1] the fraction along
        it from corner i, s the distance out from its inner face (metres: 0 on the inner face,
        ``thickness`` on the outer, negative into the room). i + t is continuous round the room
        (the end of wall i is the start of wall i + 1)."""
        X = np.asarray(local, float)
        w = self.walls()
        c, e = w["start"], np.roll(w["start"], -1, axis=0) - w["start"]
        t = np.clip(np.einsum("ij,ij->i", X[:2] - c, e) / np.einsum("ij,ij->i", e, e), 0.0, 1.0)
        i = int(np.argmin(np.linalg.norm(c + t[:, None] * e - X[:2], axis=1)))
        return np.array([i + t[i], float((X[:2] - c[i]) @ w["normal"][i]), X[2] / self.param("height")])

    def from_coords(self, coords: ArrayLike, params: ArrayLike | None = None) -> Array:
        """The local point of :meth:`to_coords`'s ``coords`` at trial ``params``."""
        q = np.asarray(coords, float)
        p = self._as_params(params)
        w = self.walls(p)
        n = self.n_corners
        i = min(int(np.floor(q[0])), n - 1)
        t = q[0] - i
        a, b = w["start"][i % n], w["start"][(i + 1) % n]
        xy = a + t * (b - a) + q[1] * w["normal"][i % n]
        return np.array([xy[0], xy[1], q[2] * self._value(p, "height")])

    # -- faces and frames ----------------------------------------------------------------------

    def _plane_names(self) -> tuple[str, ...]:
        n = self.n_corners
        return ("floor",) + (("ceiling",) if self.ceiling else ()) + tuple(f"wall{i}" for i in range(n)) + tuple(
            f"outer{i}" for i in range(n))

    def planes(self) -> dict[str, Frame]:
        """{name: frame} of every flat face: ``floor``, ``ceiling`` (with a ceiling), ``wall{i}``
        (inner face of wall i, its normal into the room), ``outer{i}``."""
        return {name: self.plane_frame(name) for name in self._plane_names()}

    def plane_frame(self, name: str, params: ArrayLike | None = None) -> Frame:
        if name not in self._plane_names():
            raise ValueError(f"room has no flat face {name!r}; its flat faces: {', '.join(self._plane_names())}")
        return self._plane_frame(name, self._as_params(params))

    def _plane_frame(self, name: str, p: Array) -> Frame:
        h = float(self._value(p, "height"))
        if name == "floor":
            # The room's origin (inner corner 0), not the polygon's centroid: what rests on the
            # floor keeps its place when a far wall is solved, in the room's own x, y.
            return np.zeros(3), _EX.copy(), _EY.copy(), _EZ.copy()
        if name == "ceiling":
            return np.array([0.0, 0.0, h]), _EX.copy(), -_EY, -_EZ
        m = re.fullmatch(r"(wall|outer)(\d+)", name)
        assert m is not None
        i = int(m.group(2))
        w = self.walls(p)
        d = np.r_[w["dir"][i], 0.0]
        nrm = np.r_[w["normal"][i], 0.0]
        if m.group(1) == "wall":
            mid = (w["start"][i] + w["start"][(i + 1) % self.n_corners]) / 2
            return np.r_[mid, h / 2], -d, _EZ.copy(), -nrm
        mid = (w["outer"][i] + w["outer"][(i + 1) % self.n_corners]) / 2
        return np.r_[mid, h / 2], d, _EZ.copy(), nrm

    def _face_frame(self, name: str, p: Array) -> Frame:
        return self._plane_frame(name, p)

    def opening_frame(self, name: str, params: ArrayLike | None = None) -> Array:
        """4×4 room_from_opening: origin at the sill's centre on the wall's inner face, x along the
        wall (corner i → i + 1), y into the room, z up."""
        p = self._as_params(params)
        o, off, width, _, sill = self._opening_geometry(p, name)
        return self._wall_frame(p, o.wall, off + width / 2, sill)

    def jamb_frame(self, name: str, side: str, params: ArrayLike | None = None) -> Array:
        """4×4 room_from_jamb: as :meth:`opening_frame`, its origin at the bottom of the start
        (offset) or end (offset + width) jamb."""
        if side not in ("start", "end"):
            raise ValueError(f"a jamb's side is 'start' or 'end', not {side!r}")
        p = self._as_params(params)
        o, off, width, _, sill = self._opening_geometry(p, name)
        return self._wall_frame(p, o.wall, off + (width if side == "end" else 0.0), sill)

    def _wall_frame(self, p: Array, wall: int, u: float, z: float) -> Array:
        w = self.walls(p)
        d, nrm = w["dir"][wall], w["normal"][wall]
        F = np.eye(4)
        F[:2, 0] = d
        F[:2, 1] = -nrm
        F[:2, 3] = w["start"][wall] + d * u
        F[2, 3] = z
        return F

    # -- validation ----------------------------------------------------------------------------

    def _validate_geometry(self) -> None:
        check_room(self)

    # -- mesh ----------------------------------------------------------------------------------

    def _patches(self, p: Array, segments: int) -> list[Patch | None]:
        return room_patches(self, p)

    # -- file form and value semantics ---------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"type": "room", "corners": self.n_corners, "rectilinear": self.rectilinear,
                             "ceiling": self.ceiling,
                             "params": {n: float(v) for n, v in zip(self.PARAMS, self._p, strict=True)}}
        if self.openings:
            d["openings"] = [o.to_dict() for o in self.openings]
        if not all(self.walls_present):
            d["walls"] = list(self.walls_present)
        return d

    @classmethod
    def _from_file(cls, d: Mapping[str, Any], params: Mapping[str, Any]) -> Room:
        """The room a project-file dict describes: ``corners``, ``rectilinear``, ``ceiling``,
        ``openings`` besides ``params``; RoomError.at names the field."""
        unknown = [k for k in d if k not in ("type", "params", "corners", "rectilinear", "ceiling", "openings",
                                             "walls")]
        if unknown:
            raise RoomError(f"room: unknown field {unknown[0]!r}; expected type, corners, rectilinear, ceiling, "
                            "params, openings, walls", unknown[0])
        return cls(corners=d.get("corners", 4), rectilinear=d.get("rectilinear", True), ceiling=d.get("ceiling", False),
                   openings=d.get("openings", ()), walls=d.get("walls"), **params)

    def __reduce__(self) -> tuple[Any, ...]:
        return _room_from_dict, (self.to_dict(),)

    def __eq__(self, other: object) -> bool:
        return (type(other) is type(self) and isinstance(other, Room) and np.array_equal(self._p, other._p)
                and self._structure_kwargs() == other._structure_kwargs())

    def __hash__(self) -> int:
        return hash((self.TYPE, self.n_corners, self.rectilinear, self.ceiling, self.openings, self.walls_present,
                     tuple(self._p.tolist())))

    def __repr__(self) -> str:
        ops = ", ".join(f"{o.name}@{o.wall}" for o in self.openings)
        return f"Room({self.n_corners} corners{', rectilinear' if self.rectilinear else ''}, openings [{ops}])"


def _room_from_dict(d: Mapping[str, Any]) -> Room:
    return Room._from_file(d, d["params"])


