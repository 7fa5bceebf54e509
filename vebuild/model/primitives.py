"""Parametric primitives: the shapes a user places over the photographs (paper §3).

A primitive is a few named sizes in metres (``PARAMS``) and nothing else. Its handles, edges,
restable faces, outlines and textured mesh are all derived from the parameters on demand, so the
solver can try new parameters and ask again (as trimesh's primitives keep their parameters apart
from their mesh). Instances are immutable: ``with_params`` returns a new one.

Local frame (scenes/FORMAT.md, "The model"): origin at the centre of the bottom face (a quad's
centre; a sphere's lowest point), +z up, metres. Names, fixed by the file format:

=========  ===============================================  ==========================================
type       handles                                          edges
=========  ===============================================  ==========================================
quad       v0 (−x,−y), v1 (+x,−y), v2 (+x,+y), v3 (−x,+y)  e0 v0-v1, e1 v1-v2, e2 v2-v3, e3 v3-v0
           at z = 0 (counter-clockwise seen from +z)
box        v0…v3 bottom ring as the quad, v4…v7 the same     e0…e3 bottom ring, e4…e7 top ring
           ring at z = height                               (v4-v5, v5-v6, v6-v7, v7-v4), e8…e11
                                                            verticals v0-v4, v1-v5, v2-v6, v3-v7
wedge      v0…v3 bottom ring as the quad, v4 above v3 and   e0…e3 bottom ring, e4 v4-v5 (top edge),
           v5 above v2: the top edge is the back (+y) edge  e5 v2-v5, e6 v3-v4 (back verticals),
           and the ramp rises from the front edge v0-v1     e7 v0-v4, e8 v1-v5 (sides of the slope)
cylinder   b0…b3 bottom rim at 0°, 90°, 180°, 270° from     e0…e3 b_i-t_i (the circles come from
           +x, t0…t3 the top rim likewise, bc, tc centres   ``outline_points``)
frustum    as the cylinder (radius_top = 0 is a cone)       as the cylinder
sphere     bottom, top, px, nx, py, ny (equator at z = r)   none (``outline_points``: equator, meridian)
=========  ===============================================  ==========================================

Restable flat faces (``faces``): quad ``top``; box ``top``, ``bottom``; wedge ``bottom``, ``back``
(it has no top; its tilted slope is not named); cylinder and frustum ``top`` (not for a cone) and
``bottom``; sphere none.

Planes (``planes``: every flat face, named as its mesh face, for relations between faces): the
restable faces, box ``front``, ``right``, ``back``, ``left``, wedge ``right``, ``left``, ``slope``;
side faces have y up and x to the right seen from outside, the slope y up the slope.

Logical mesh faces (``Mesh.face_ids``, 1-based): quad 1 top; box 1 front (−y), 2 right (+x),
3 back (+y), 4 left (−x), 5 top, 6 bottom (side face i + 1 stands on bottom edge e_i); wedge
1 right, 2 back, 3 left, 4 slope, 5 bottom; cylinder and frustum 1 side, 2 top, 3 bottom (a cone:
1 side, 2 bottom); sphere 1 surface.

Every handle here is a linear function of the parameters (rim angles are fixed), so
``handles(p) = A p`` exactly and ``handle_jacobian`` is the constant tensor A. A future primitive
whose handles are not linear must override ``handle_jacobian``; the tests compare it with finite
differences for every type.

Layer 1 (DESIGN.md): numpy only; no GL, no file I/O.
"""

from __future__ import annotations

import abc
import functools
import numbers
from collections.abc import Mapping
from typing import Any, ClassVar, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .mesh import Mesh, Patch, assemble, circle, kept_mesh, polygon_patch, revolution_patch
from .shapes import EX as _EX
from .shapes import EY as _EY
from .shapes import EZ as _EZ
from .shapes import Frame  # noqa: F401  (re-exported: a face frame, as every primitive returns it)
from .shapes import level_frame as _level_frame
from .shapes import points as _points
from .shapes import rim as _rim
from .shapes import ring as _ring
from .shapes import side_frame as _side_frame

Array = NDArray[np.float64]

_REGISTRY: dict[str, type[Primitive]] = {}
#: Sizes never go below this (metres): "sizes stay positive" with a margin the solver can use.
MIN_SIZE_M = 1e-3


def _param_value(self: Primitive, index: int) -> float:
    """Parameter ``index`` of a primitive (the read-only attribute of each parameter name)."""
    return float(self._p[index])


@functools.cache
def _handle_matrix(cls: type[Primitive]) -> Array:
    """The constant A (n, 3, k) with handles(p) = A p: the handle formulas at the unit vectors."""
    A = np.moveaxis(cls._handles_of(np.eye(len(cls.PARAMS))), 0, -1)
    A.flags.writeable = False
    return A


# ----------------------------------------------------------------------------------------------
# The primitives


class Primitive(abc.ABC):
    """Base of all primitives: parameters in, geometry out.

    Subclasses set ``TYPE``, ``PARAMS``, ``HANDLE_NAMES``, ``EDGES``, ``_RESTABLE``, the facts a
    new one needs (``DEFAULT_PARAMS``, ``ANCHOR_HANDLE``, ``VARIANTS``) and implement
    ``_handles_of``, ``_face_frame``, ``_patches`` (and ``_outlines`` when they are curved). Each parameter is also
    a read-only float attribute (``box.height``).
    """

    TYPE: ClassVar[str] = ""
    PARAMS: ClassVar[tuple[str, ...]] = ()
    HANDLE_NAMES: ClassVar[tuple[str, ...]] = ()
    EDGES: ClassVar[tuple[tuple[str, str, str], ...]] = ()
    _RESTABLE: ClassVar[tuple[str, ...]] = ()  # names of the flat faces others can rest on
    _PLANES: ClassVar[tuple[str, ...]] = ()  # every flat face (``planes``), if not just the restable
    _MAY_BE_ZERO: ClassVar[frozenset[str]] = frozenset()  # sizes allowed to be 0 (a cone's top)
    #: Sizes (metres) of a new primitive of this type: something of furniture scale to drag into place.
    DEFAULT_PARAMS: ClassVar[Mapping[str, float]] = {}
    #: The handle a first primitive puts on the origin marker (paper §3.1: the floor's corner).
    ANCHOR_HANDLE: ClassVar[str] = ""
    #: Named variants a user can add: kind → the default parameters it changes (a cone is a frustum).
    VARIANTS: ClassVar[Mapping[str, Mapping[str, float]]] = {}
    #: Whether the handles are linear in the parameters (``handles(p) = A p``, A from
    #: ``handle_jacobian``); a primitive whose are not (a room) is asked ``handles(p)`` at each trial.
    LINEAR: ClassVar[bool] = True

    _p: Array

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        for i, name in enumerate(cls.PARAMS):
            setattr(cls, name, property(functools.partial(_param_value, index=i), doc=f"The {name} parameter."))
        if cls.TYPE:
            _REGISTRY[cls.TYPE] = cls

    def __init__(self, *args: float, **kwargs: float) -> None:
        if len(args) > len(self.PARAMS):
            raise TypeError(f"{self.TYPE} takes {len(self.PARAMS)} params ({', '.join(self.PARAMS)}), got {len(args)}")
        named = dict(zip(self.PARAMS, args, strict=False))
        if twice := named.keys() & kwargs.keys():
            raise TypeError(f"{self.TYPE}: {', '.join(sorted(twice))} given twice")
        object.__setattr__(self, "_p", self._checked(self._from_mapping({**named, **kwargs})))

    # -- parameters ----------------------------------------------------------------------------

    @classmethod
    def _from_mapping(cls, params: Mapping[str, Any]) -> list[float]:
        """Parameter values in PARAMS order from a name → value mapping; ValueError names the problem."""
        if unknown := [k for k in params if k not in cls.PARAMS]:
            raise ValueError(f"{cls.TYPE}: unknown param {unknown[0]!r}; expected {', '.join(cls.PARAMS)}")
        if missing := [k for k in cls.PARAMS if k not in params]:
            raise ValueError(f"{cls.TYPE} needs params {', '.join(cls.PARAMS)}; missing {', '.join(missing)}")
        for name in cls.PARAMS:
            v = params[name]
            if isinstance(v, bool) or not isinstance(v, numbers.Real):
                raise ValueError(f"{cls.TYPE}: {name} must be a number, got {v!r}")
        return [float(params[name]) for name in cls.PARAMS]

    @classmethod
    def _checked(cls, values: ArrayLike) -> Array:
        """A read-only float array of valid sizes: finite, > 0 (>= 0 where allowed)."""
        p = np.array(values, dtype=float)
        if p.shape != (len(cls.PARAMS),):
            names = ", ".join(cls.PARAMS)
            raise ValueError(f"{cls.TYPE}: expected {len(cls.PARAMS)} params ({names}), got shape {p.shape}")
        for name, v in zip(cls.PARAMS, p, strict=True):
            if not np.isfinite(v):
                raise ValueError(f"{cls.TYPE}: {name} must be a finite number, got {v}")
            if name in cls._MAY_BE_ZERO and v < 0:
                raise ValueError(f"{cls.TYPE}: {name} must be >= 0, got {v}")
            if name not in cls._MAY_BE_ZERO and v <= 0:
                raise ValueError(f"{cls.TYPE}: {name} must be > 0, got {v}")
        p.flags.writeable = False
        return p

    @property
    def params(self) -> Array:
        """(k,) the parameters in PARAMS order, a read-only view."""
        return self._p.view()

    def with_params(self, params: ArrayLike | Mapping[str, float]) -> Self:
        """A new primitive of this type: a full (k,) array, or a mapping of the names to change."""
        if isinstance(params, Mapping):
            params = self._from_mapping({**self.to_dict()["params"], **params})
        return type(self)(*self._checked(params))

    def _as_params(self, params: ArrayLike | None) -> Array:
        """Trial parameters for the geometry methods (not validated: the solver may probe anything)."""
        if params is None:
            return self._p
        p = np.asarray(params, dtype=float)
        if p.shape != (len(self.PARAMS),):
            raise ValueError(f"{self.TYPE}: expected params of shape ({len(self.PARAMS)},), got {p.shape}")
        return p

    def to_dict(self) -> dict[str, Any]:
        """``{"type": ..., "params": {name: value}}`` as in the project file."""
        return {"type": self.TYPE, "params": {n: float(v) for n, v in zip(self.PARAMS, self._p, strict=True)}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Primitive:
        """The primitive a project-file dict describes; on a subclass the type must be that subclass's."""
        prim = primitive_from_dict(d)
        if cls is not Primitive and not isinstance(prim, cls):
            raise ValueError(f"expected type {cls.TYPE!r}, got {prim.TYPE!r}")
        return prim

    def param_kinds(self) -> tuple[str, ...]:
        """The kind (DOF_KINDS) of each parameter in PARAMS order: all sizes here; a room's corner
        coordinates are positions (no least value, the solver's pull of a position)."""
        return ("size",) * len(self.PARAMS)

    @classmethod
    def minimum_size(cls, name: str) -> float:
        """The least value parameter ``name`` may take in a solve (metres): 0 where a size may
        vanish (a cone's top radius), MIN_SIZE_M for every other size."""
        return 0.0 if name in cls._MAY_BE_ZERO else MIN_SIZE_M

    @classmethod
    def _from_file(cls, d: Mapping[str, Any], params: Mapping[str, Any]) -> Primitive:
        """The primitive of a project-file dict whose ``params`` are checked to be an object; a
        primitive with more than params in the file (a room's corners and openings) reads them here."""
        return cls(**params)

    @classmethod
    def minimum_sizes(cls) -> Array:
        """(k,) :meth:`minimum_size` of every parameter, in PARAMS order."""
        return np.array([cls.minimum_size(n) for n in cls.PARAMS])

    # -- handles -------------------------------------------------------------------------------

    @classmethod
    def handle_names(cls) -> tuple[str, ...]:
        return cls.HANDLE_NAMES

    @classmethod
    @abc.abstractmethod
    def _handles_of(cls, P: Array) -> Array:
        """Handle positions (..., n, 3) of parameter vectors P (..., k); linear in P."""

    def handles(self, params: ArrayLike | None = None) -> Array:
        """(n, 3) local handle positions in ``handle_names()`` order, for ``params`` (k,) or our own."""
        return self._handles_of(self._as_params(params))

    def handles_batch(self, P: ArrayLike) -> Array:
        """(m, n, 3) handle positions of m parameter vectors P (m, k) in one vectorised call."""
        P = np.asarray(P, dtype=float)
        if P.ndim != 2 or P.shape[1] != len(self.PARAMS):
            raise ValueError(f"{self.TYPE}: expected params of shape (m, {len(self.PARAMS)}), got {P.shape}")
        return self._handles_of(P)

    def handle_jacobian(self, params: ArrayLike | None = None) -> Array:
        """(n, 3, k) ∂handle/∂param at ``params``; exact (the handles are linear in the params)."""
        self._as_params(params)  # the same shape check as everywhere; the value does not matter
        return _handle_matrix(type(self)).copy()

    # -- edges, outlines, faces ----------------------------------------------------------------

    @classmethod
    def edges(cls) -> list[tuple[str, str, str]]:
        """[(name, handle_a, handle_b)]: the straight edges an overlay draws and an edge observation names."""
        return list(cls.EDGES)

    def outline_points(self, n: int = 48, params: ArrayLike | None = None) -> list[Array]:
        """Closed polylines (n + 1, 3) (last point = first) of curved outlines; [] for flat primitives."""
        return self._outlines(self._as_params(params), int(n))

    def _outlines(self, p: Array, n: int) -> list[Array]:
        return []

    def _restable(self) -> tuple[str, ...]:
        return self._RESTABLE

    def faces(self) -> dict[str, Frame]:
        """{name: (origin, x_axis, y_axis, normal)} of the restable faces at our own params.

        The origin is the face's centre, the axes are unit, x × y = normal, the normal points out.
        """
        return {name: self.face_frame(name) for name in self._restable()}

    def face_frame(self, name: str, params: ArrayLike | None = None) -> Frame:
        """The frame of face ``name`` (as in ``faces``) at trial ``params`` (k,), or at our own."""
        if name not in self._restable():
            have = ", ".join(self._restable()) or "none"
            raise ValueError(f"{self.TYPE} has no face {name!r}; its faces: {have}")
        return self._face_frame(name, self._as_params(params))

    def _face_frame(self, name: str, p: Array) -> Frame:
        """The frame of a flat face; primitives with flat faces override this (a sphere has none)."""
        raise ValueError(f"{self.TYPE} has no flat face {name!r}")

    def _plane_names(self) -> tuple[str, ...]:  # by default the restable faces (a cone: no top)
        return self._PLANES or self._restable()

    def planes(self) -> dict[str, Frame]:
        """{name: frame} of every flat face (what relations name), as ``faces``: centre (a triangle's
        centroid), unit axes, x × y = the outward normal."""
        return {name: self.plane_frame(name) for name in self._plane_names()}

    def plane_frame(self, name: str, params: ArrayLike | None = None) -> Frame:
        """The frame of flat face ``name`` (as in ``planes``) at trial ``params`` (k,), or at our own."""
        if name not in self._plane_names():
            have = ", ".join(self._plane_names()) or "none"
            raise ValueError(f"{self.TYPE} has no flat face {name!r}; its flat faces: {have}")
        return self._plane_frame(name, self._as_params(params))

    def _plane_frame(self, name: str, p: Array) -> Frame:  # by default the restable face's
        return self._face_frame(name, p)

    # -- mesh ----------------------------------------------------------------------------------

    def mesh(self, texels_per_metre: float | None = None, segments: int = 32) -> Mesh:
        """The triangle mesh with its texture atlas (see ``Mesh``).

        Parameters
        ----------
        texels_per_metre : the intended texture density; when given, the atlas gutter is
            ``GUTTER_TEXELS`` texels and charts start on texel boundaries.
        segments : facets around curved surfaces (a sphere has segments // 2 bands of latitude).
            Curved surfaces are inscribed polyhedra: a cylinder's or frustum's volume falls short
            by the fraction 1 − sin(2π/s)/(2π/s) ≈ (2π/s)²/6 (0.64 % at s = 32), a sphere's by
            about 2.5 times that (1.6 % at 32).
        """
        if segments < 3:
            raise ValueError(f"segments must be at least 3, got {segments}")
        if texels_per_metre is not None and not (np.isfinite(texels_per_metre) and texels_per_metre > 0):
            raise ValueError(f"texels_per_metre must be > 0, got {texels_per_metre}")
        key = (self, int(segments), None if texels_per_metre is None else float(texels_per_metre))
        return kept_mesh(key, lambda: assemble(self._patches(self._p, int(segments)), texels_per_metre))

    @abc.abstractmethod
    def _patches(self, p: Array, segments: int) -> list[Patch | None]:
        """Each concrete primitive defines this."""

    # -- value semantics -----------------------------------------------------------------------

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"{type(self).__name__} is immutable; use with_params")

    def __reduce__(self) -> tuple[Any, ...]:  # copy, deepcopy and pickle go through __init__
        return type(self), tuple(self._p.tolist())

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and np.array_equal(self._p, other._p)

    def __hash__(self) -> int:
        return hash((self.TYPE, tuple(self._p.tolist())))

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(f'{n}={v:g}' for n, v in zip(self.PARAMS, self._p, strict=True))})"


def primitive_from_dict(d: Mapping[str, Any]) -> Primitive:
    """Build a primitive from ``{"type": T, "params": {...}}``; ValueError says what is wrong."""
    if not isinstance(d, Mapping):
        raise ValueError(f"expected an object {{type, params}}, got {type(d).__name__}")
    kind = d.get("type")
    cls = _REGISTRY.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise ValueError(f"expected one of {', '.join(_REGISTRY)}; got {kind!r}")
    params = d.get("params", {})
    if not isinstance(params, Mapping):
        raise ValueError(f"{kind}: params must be an object {{{', '.join(cls.PARAMS)}}}, got {type(params).__name__}")
    return cls._from_file(d, params)


class Quad(Primitive):
    """A flat rectangle in z = 0, ``width`` along x, ``depth`` along y, centred on the origin (a floor)."""

    TYPE = "quad"
    PARAMS = ("width", "depth")
    HANDLE_NAMES = ("v0", "v1", "v2", "v3")
    EDGES = (("e0", "v0", "v1"), ("e1", "v1", "v2"), ("e2", "v2", "v3"), ("e3", "v3", "v0"))
    _RESTABLE = ("top",)
    DEFAULT_PARAMS = {"width": 2.0, "depth": 2.0}
    ANCHOR_HANDLE = "v0"

    @classmethod
    def _handles_of(cls, P):
        return _ring(P[..., 0], P[..., 1], np.zeros_like(P[..., 0]))

    def _face_frame(self, name, p):
        return _level_frame(0.0)

    def _patches(self, p, segments):
        return [polygon_patch("top", self._handles_of(p))]


class _Prism(Primitive):
    """Box and wedge: a bottom ring v0…v3 and a 'top ring' over it, joined by four sides.

    A wedge is the box whose top front edge has collapsed onto the bottom front edge, so one
    builder makes both meshes (collapsed faces disappear).
    """

    PARAMS = ("width", "depth", "height")
    DEFAULT_PARAMS = {"width": 0.5, "depth": 0.5, "height": 0.5}
    ANCHOR_HANDLE = "v0"
    _MESH_FACES: ClassVar[tuple[str, ...]]  # names for sides 0…3, top, bottom; "" for a collapsed one

    @classmethod
    @abc.abstractmethod
    def _top_ring(cls, P: Array) -> Array:
        """Each concrete primitive defines this."""

    def _patches(self, p, segments):
        b = _ring(p[0], p[1], np.zeros(()))
        t = self._top_ring(p)
        polys = [np.array([b[i], b[(i + 1) % 4], t[(i + 1) % 4], t[i]]) for i in range(4)] + [t, b[::-1]]
        return [polygon_patch(name, c) for name, c in zip(self._MESH_FACES, polys, strict=True) if name]


class Box(_Prism):
    """An axis-aligned box: ``width`` (x) × ``depth`` (y) × ``height`` (z), standing on z = 0."""

    TYPE = "box"
    HANDLE_NAMES = tuple(f"v{i}" for i in range(8))
    EDGES = tuple((f"e{i}", f"v{i}", f"v{(i + 1) % 4}") for i in range(4)) + tuple(
        (f"e{i + 4}", f"v{i + 4}", f"v{(i + 1) % 4 + 4}") for i in range(4)) + tuple(
        (f"e{i + 8}", f"v{i}", f"v{i + 4}") for i in range(4))
    _RESTABLE = ("top", "bottom")
    _MESH_FACES = ("front", "right", "back", "left", "top", "bottom")
    _PLANES = _MESH_FACES

    @classmethod
    def _handles_of(cls, P):
        w, d, h = P[..., 0], P[..., 1], P[..., 2]
        return np.concatenate([_ring(w, d, np.zeros_like(h)), _ring(w, d, h)], axis=-2)

    @classmethod
    def _top_ring(cls, P):
        return cls._handles_of(P)[..., 4:, :]

    def _face_frame(self, name, p):
        return _level_frame(p[2]) if name == "top" else _level_frame(0.0, up=False)

    def _plane_frame(self, name, p):
        w, d, h = (float(v) for v in p)
        sides = {"front": ([0.0, -d / 2, h / 2], -_EY), "right": ([w / 2, 0.0, h / 2], _EX),
                 "back": ([0.0, d / 2, h / 2], _EY), "left": ([-w / 2, 0.0, h / 2], -_EX)}
        return _side_frame(*sides[name]) if name in sides else self._face_frame(name, p)


class Wedge(_Prism):
    """A ramp on a ``width`` × ``depth`` base, rising from its front (−y) edge to ``height`` at its back (+y)."""

    TYPE = "wedge"
    HANDLE_NAMES = tuple(f"v{i}" for i in range(6))
    EDGES = (("e0", "v0", "v1"), ("e1", "v1", "v2"), ("e2", "v2", "v3"), ("e3", "v3", "v0"), ("e4", "v4", "v5"),
             ("e5", "v2", "v5"), ("e6", "v3", "v4"), ("e7", "v0", "v4"), ("e8", "v1", "v5"))
    _RESTABLE = ("bottom", "back")
    _MESH_FACES = ("", "right", "back", "left", "slope", "bottom")
    _PLANES = ("right", "back", "left", "bottom", "slope")

    @classmethod
    def _handles_of(cls, P):
        w, d, h = P[..., 0], P[..., 1], P[..., 2]
        top = _ring(w, d, h)[..., [3, 2], :]  # v4 above v3, v5 above v2: the back top edge
        return np.concatenate([_ring(w, d, np.zeros_like(h)), top], axis=-2)

    @classmethod
    def _top_ring(cls, P):
        v = cls._handles_of(P)
        return v[..., [0, 1, 5, 4], :]  # the slope: front edge stays down, back edge is up

    def _face_frame(self, name, p):
        if name == "bottom":
            return _level_frame(0.0, up=False)
        # The back wall seen from behind (+y): x runs toward −x so that x × up = +y.
        return np.array([0.0, p[1] / 2, p[2] / 2]), -_EX, _EZ.copy(), _EY.copy()

    def _plane_frame(self, name, p):
        w, d, h = (float(v) for v in p)
        sign = {"right": 1.0, "left": -1.0}.get(name)  # triangles v1 v2 v5, v0 v3 v4: their centroids
        if sign is not None:
            return _side_frame([sign * w / 2, d / 6, h / 3], sign * _EX)
        L = float(np.hypot(d, h))  # the slope: y up it, from the front bottom edge to the back top edge
        return (np.array([0.0, 0.0, h / 2]), _EX.copy(), np.array([0.0, d, h]) / L,
                np.array([0.0, -h, d]) / L) if name == "slope" else self._face_frame(name, p)


class _Round(Primitive):
    """Cylinder and frustum: a solid of revolution between a bottom and a top circle."""

    HANDLE_NAMES = ("b0", "b1", "b2", "b3", "t0", "t1", "t2", "t3", "bc", "tc")
    EDGES = tuple((f"e{i}", f"b{i}", f"t{i}") for i in range(4))
    ANCHOR_HANDLE = "bc"

    @classmethod
    @abc.abstractmethod
    def _radii(cls, P: Array) -> tuple[Array, Array, Array]:
        """(radius_bottom, radius_top, height), each (...,)."""

    @classmethod
    def _handles_of(cls, P):
        rb, rt, h = cls._radii(P)
        zero = np.zeros_like(h)
        centres = np.stack([_points(zero, zero, zero), _points(zero, zero, h)], axis=-2)
        return np.concatenate([_rim(rb, zero), _rim(rt, h), centres], axis=-2)

    def _restable(self):
        # A cone has no top face to rest on.
        return ("top", "bottom") if self._radii(self._p)[1] > 0 else ("bottom",)

    def _face_frame(self, name, p):
        return _level_frame(float(self._radii(p)[2])) if name == "top" else _level_frame(0.0, up=False)

    def _outlines(self, p, n):
        rb, rt, h = (float(v) for v in self._radii(p))
        _, c, s = circle(n)
        return [_points(r * c, r * s, z) for r, z in ((rb, 0.0), (rt, h)) if r > 0]

    def _patches(self, p, segments):
        rb, rt, h = (float(v) for v in self._radii(p))
        slant = np.hypot(h, rb - rt)
        side = revolution_patch("side", np.array([rb, rt]), np.array([0.0, h]), np.full(2, h / slant),
                                 np.full(2, (rb - rt) / slant), segments)
        _, c, s = circle(segments)
        c, s = c[:-1], s[:-1]  # the caps' rings, the very same numbers as the side's rims
        top = polygon_patch("top", _points(rt * c, rt * s, h), _EX)  # None for a cone
        bottom = polygon_patch("bottom", _points(rb * c, rb * s, 0.0)[::-1], _EX)
        return [side, top, bottom]


class Cylinder(_Round):
    """An upright cylinder of ``radius`` and ``height`` standing on z = 0."""

    TYPE = "cylinder"
    PARAMS = ("radius", "height")
    DEFAULT_PARAMS = {"radius": 0.25, "height": 0.5}

    @classmethod
    def _radii(cls, P):
        return P[..., 0], P[..., 0], P[..., 1]


class Frustum(_Round):
    """An upright truncated cone; ``radius_top`` = 0 makes a cone."""

    TYPE = "frustum"
    PARAMS = ("radius_bottom", "radius_top", "height")
    _MAY_BE_ZERO = frozenset({"radius_top"})
    DEFAULT_PARAMS = {"radius_bottom": 0.25, "radius_top": 0.15, "height": 0.5}
    VARIANTS = {"cone": {"radius_top": 0.0}}

    @classmethod
    def _radii(cls, P):
        return P[..., 0], P[..., 1], P[..., 2]


class Sphere(Primitive):
    """A sphere of ``radius`` resting on z = 0: its lowest point is the origin, its centre (0, 0, r)."""

    TYPE = "sphere"
    PARAMS = ("radius",)
    HANDLE_NAMES = ("bottom", "top", "px", "nx", "py", "ny")
    DEFAULT_PARAMS = {"radius": 0.25}
    ANCHOR_HANDLE = "bottom"
    _UNIT_HANDLES = np.array([[0, 0, 0], [0, 0, 2], [1, 0, 1], [-1, 0, 1], [0, 1, 1], [0, -1, 1]], float)

    @classmethod
    def _handles_of(cls, P):
        return P[..., 0, None, None] * cls._UNIT_HANDLES

    def _outlines(self, p, n):
        r = float(p[0])
        _, c, s = circle(n)
        return [_points(r * c, r * s, r), _points(r * c, 0.0, r + r * s)]  # equator, meridian in xz

    def _patches(self, p, segments):
        r = float(p[0])
        phi = np.linspace(-np.pi / 2, np.pi / 2, max(2, segments // 2) + 1)
        cos_phi, sin_phi = np.cos(phi), np.sin(phi)
        cos_phi[[0, -1]] = 0.0  # exact poles, so their triangles collapse and are dropped
        return [revolution_patch("surface", r * cos_phi, r * (1.0 + sin_phi), cos_phi, sin_phi, segments)]


#: The primitive types by their project-file name, in the order FORMAT.md lists them.
PRIMITIVE_TYPES: Mapping[str, type[Primitive]] = _REGISTRY


def primitive_kinds() -> dict[str, tuple[type[Primitive], dict[str, float]]]:
    """Every kind of primitive a user can add, each with its type and default parameters: the
    types in PRIMITIVE_TYPES order, each followed by its named variants (``cone`` after ``frustum``)."""
    out: dict[str, tuple[type[Primitive], dict[str, float]]] = {}
    for name, cls in _REGISTRY.items():
        out[name] = (cls, dict(cls.DEFAULT_PARAMS))
        for variant, changes in cls.VARIANTS.items():
            out[variant] = (cls, {**cls.DEFAULT_PARAMS, **changes})
    return out
