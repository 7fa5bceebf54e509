"""Generated CCTV scenes with known answers: a street or a shop seen from a camera 2.5–4 m high.

A **street** (:data:`SETTINGS`): the camera hangs on a façade over the near pavement (y = −3 m)
and looks across a road 6–9 m wide (kerb joints at y = 0 and y = road width), the far pavement 3 m
deep and the far façade (storeys 3 m high with string courses, pilasters, doors). A **shop**: a
room 8–14 × 6–10 m, 0.3–1 m higher than the camera, floor tiles, skirting and picture rails,
corner beads, shelves against the two far walls; the camera hangs in the near corner. In both, the
camera looks down 15–45°, across the scene's axes (30–60° off them, so that its three vanishing
points are all finite), rolled a little. Every edge the user may mark lies along a world axis
(:meth:`vebuild.synthetic.cctv_render.Layout.lines`).

The lens is a TRUE lens, not vebuild's model (:mod:`vebuild.synthetic.cctv_lens`): equidistant
or equisolid fisheye, or a rectilinear wide lens with a little barrel distortion, 90–150° across
the diagonal; frames 1280 × 720, 704 × 576 or 1920 × 1080; the principal point a few pixels off
the centre. A figure the size of a person (an upright cylinder for the body, a sphere for the
head, 1.50–1.95 m tall) stands at several places on the ground in view.

:func:`cctv_case` draws a case (deterministic from its seed); :func:`truth_record` is what the
generator knows (K-equivalent, R, C, the true lens, the figure's heights, head-top and foot pixels
through the true lens, the 3D edges and their image polylines); :func:`mark_edges` the polylines a
user clicks along the edges' images (several points each, with click noise), as a user marks a
bending line. Frames and video: :mod:`vebuild.synthetic.cctv_video`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import rotation
from .cctv_lens import LENS_KINDS, DivisionLens, TrueLens, lens_for_field
from .cctv_render import Layout, Line, cast_static, figure_hits

Array = NDArray[np.float64]

SETTINGS = ("street", "shop")
FRAME_SIZES = ((1280, 720), (704, 576), (1920, 1080))
#: Camera height (m), pitch down (degrees), heading off the scene's axes (degrees).
CAMERA_HEIGHT_M, PITCH_DEG, OFF_AXIS_DEG = (2.5, 4.0), (15.0, 45.0), (30.0, 60.0)
#: The diagonal field (degrees) of each kind of lens; the rectilinear lens's barrel pulls the
#: corners in by this share of where a pinhole would put them.
FIELD_DEG = {"rectilinear": (90.0, 110.0), "equidistant": (110.0, 150.0), "equisolid": (110.0, 150.0)}
BARREL_CORNER_REL = (0.03, 0.08)
#: How far the principal point lies off the frame's centre, each coordinate (px).
PRINCIPAL_POINT_OFF_PX = 6.0
#: The figure: its height (m) and how many places it stands at.
FIGURE_HEIGHT_M, PLACES = (1.50, 1.95), (3, 4)
#: The marked points' least distance from the frame's edge (px).
MARGIN_PX = 10.0
#: Samples along an edge when its image is traced (the truth's polyline).
EDGE_SAMPLES = 160
#: A marked edge's image spans at least this share of the frame's longer side; a case shows at
#: least MIN_EDGES_PER_AXIS such edges along each axis.
MIN_SPAN_REL, MIN_EDGES_PER_AXIS = 0.12, 3


@dataclass
class CctvCase:
    """One generated CCTV camera, its scene and its figure."""

    seed: tuple[int, ...]
    setting: str
    width: int
    height: int
    lens: TrueLens | DivisionLens
    R: Array  # world → camera
    C: Array
    layout: Layout
    figure_height: float
    places: list[Array] = field(default_factory=list)  # (x, y) of the figure's places
    tex_seed: float = 0.0
    blur_px: float = 0.7
    noise_grey: float = 2.0
    interlaced: bool = False

    def pixels(self, X: Array) -> tuple[Array, Array]:
        """Pixels (n, 2) of world points X (n, 3) through the true lens, and their depths along
        the optical axis."""
        Xc = (np.asarray(X, float).reshape(-1, 3) - self.C) @ self.R.T
        return self.lens.pixels(Xc), Xc[:, 2]

    def sees(self, X: Array, margin: float = MARGIN_PX) -> Array:
        """Whether each point lies in front of the camera, inside the frame by ``margin``, and is
        not hidden by the scene's surfaces (the figure aside)."""
        uv, z = self.pixels(X)
        inside = (z > 0.3) & (uv[:, 0] >= margin) & (uv[:, 0] <= self.width - margin) & \
                 (uv[:, 1] >= margin) & (uv[:, 1] <= self.height - margin)
        d = np.asarray(X, float).reshape(-1, 3) - self.C
        dist = np.linalg.norm(d, axis=1)
        t, _, _ = cast_static(self.layout, self.C, d / dist[:, None])
        return np.asarray(inside & (t >= dist - 0.02), bool)

    def foot(self, k: int) -> Array:
        return np.r_[self.places[k], 0.0]

    def top(self, k: int) -> Array:
        return np.r_[self.places[k], self.figure_height]


def _layout(rng: np.random.Generator, setting: str, cam_h: float) -> Layout:
    if setting == "street":
        w = float(rng.uniform(6.0, 9.0))
        dims = {"near_y": -3.0, "road_w": w, "far_y": w + 3.0, "facade_h": float(rng.uniform(7.0, 12.0))}
        pil = [float(v) for v in np.cumsum(rng.uniform(4.0, 7.0, 16)) - 45.0]
        doors = []
        for a, b in zip(pil[:-1], pil[1:], strict=True):
            x = float(rng.uniform(a + 0.5, b - 1.6))
            doors.append((x, x + float(rng.uniform(0.9, 1.1))))
        return Layout(setting, dims, pil, doors)
    lx, ly = float(rng.uniform(8.0, 14.0)), float(rng.uniform(6.0, 10.0))
    dims = {"lx": lx, "ly": ly, "h": cam_h + float(rng.uniform(0.3, 1.0)), "tile": float(rng.choice([0.4, 0.5, 0.6])),
            "panel": float(rng.uniform(1.0, 1.6))}
    shelves: list[tuple[Array, Array]] = []
    x = 1.5
    while x < lx - 1.5:  # along the far wall y = ly
        length = float(rng.uniform(1.5, 3.0))
        top = float(rng.uniform(1.6, 2.2))
        shelves.append((np.array([x, ly - 0.45, 0.0]), np.array([min(x + length, lx - 0.6), ly, top])))
        x += length + float(rng.uniform(0.8, 1.8))
    y = 1.5
    while y < ly - 1.5:  # along the side wall x = lx
        length = float(rng.uniform(1.5, 3.0))
        top = float(rng.uniform(1.6, 2.2))
        shelves.append((np.array([lx - 0.45, y, 0.0]), np.array([lx, min(y + length, ly - 0.6), top])))
        y += length + float(rng.uniform(0.8, 1.8))
    return Layout(setting, dims, shelves=shelves)


def _camera(rng: np.random.Generator, setting: str, layout: Layout, cam_h: float) -> tuple[Array, Array]:
    """The camera's R (world → camera) and centre: on the near façade, or in the shop's corner."""
    off = np.radians(rng.uniform(*OFF_AXIS_DEG))
    pitch = -np.radians(rng.uniform(*PITCH_DEG))
    roll = np.radians(rng.normal(0.0, 1.0))
    if setting == "street":
        C = np.array([0.0, layout.dims["near_y"] + 0.3, cam_h])
        yaw = np.radians(90.0) + off * rng.choice([-1.0, 1.0])  # across the road, off its axis
    else:
        C = np.array([0.4, 0.4, cam_h])
        yaw = off  # into the room from its corner (x, y both > 0)
    return rotation(yaw, pitch, roll), C


def _places(rng: np.random.Generator, case: CctvCase, n: int, tries: int = 400) -> list[Array]:
    """n ground points where the whole figure stands in view, 1 m apart or more."""
    out: list[Array] = []
    d = case.layout.dims
    lo, hi = ((-25.0, d["near_y"] + 0.6), (25.0, d["far_y"] - 0.6)) if case.setting == "street" else \
        ((0.8, 0.8), (d["lx"] - 1.0, d["ly"] - 1.0))
    for _ in range(tries):
        if len(out) == n:
            break
        xy = rng.uniform(lo, hi)
        if np.hypot(*(xy - case.C[:2])) < 1.5 or any(np.hypot(*(xy - p)) < 1.0 for p in out):
            continue
        if case.layout.setting == "shop" and any(np.all(xy > b[0][:2] - 0.3) and np.all(xy < b[1][:2] + 0.3)
                                                 for b in case.layout.shelves):
            continue
        pts = np.array([np.r_[xy, 0.0], np.r_[xy, case.figure_height]])
        if bool(np.all(case.sees(pts))):
            out.append(xy)
    return out


def cctv_case(seed: tuple[int, ...], setting: str | None = None, lens_kind: str | None = None,
              size: tuple[int, int] | None = None, interlaced: bool = False) -> CctvCase:
    """A case drawn from ``seed`` (module docstring); setting, lens and frame size drawn unless
    given: one that shows the figure at all its places and MIN_EDGES_PER_AXIS edges along each
    axis. Raises RuntimeError where no draw of 50 does."""
    rng = np.random.default_rng(list(seed))
    setting = setting or str(rng.choice(SETTINGS))
    lens_kind = lens_kind or str(rng.choice(LENS_KINDS))
    width, height = size or FRAME_SIZES[int(rng.integers(len(FRAME_SIZES)))]
    for _ in range(50):
        cam_h = float(rng.uniform(*CAMERA_HEIGHT_M))
        layout = _layout(rng, setting, cam_h)
        R, C = _camera(rng, setting, layout, cam_h)
        c = (width / 2.0 + float(rng.uniform(-1, 1)) * PRINCIPAL_POINT_OFF_PX,
             height / 2.0 + float(rng.uniform(-1, 1)) * PRINCIPAL_POINT_OFF_PX)
        lens = lens_for_field(lens_kind, float(rng.uniform(*FIELD_DEG[lens_kind])), width, height, c,
                              float(rng.uniform(*BARREL_CORNER_REL)) if lens_kind == "rectilinear" else 0.0)
        case = CctvCase(tuple(seed), setting, width, height, lens, R, C, layout,
                        float(rng.uniform(*FIGURE_HEIGHT_M)), tex_seed=float(rng.uniform(0, 10)),
                        blur_px=float(rng.uniform(0.5, 0.9)), noise_grey=float(rng.uniform(1.0, 3.0)),
                        interlaced=interlaced)
        want = int(rng.integers(PLACES[0], PLACES[1] + 1))
        case.places = _places(rng, case, want)
        if len(case.places) == want and all(len(v) >= MIN_EDGES_PER_AXIS for v in edge_candidates(case).values()):
            return case
    raise RuntimeError(f"no {setting} camera drawn from seed {seed} shows the figure at enough places")


def trace_edge(case: CctvCase, line: Line, samples: int = EDGE_SAMPLES) -> tuple[Array, Array] | None:
    """The longest run of the 3D edge the camera sees whole (in front, inside the frame, not
    hidden), as world points and their pixels through the true lens; None where it sees none."""
    X = line.point(np.linspace(line.lo, line.hi, samples))
    seen = case.sees(X)
    best, run, start = (0, 0), 0, 0
    for j, v in enumerate(seen):
        run = run + 1 if v else 0
        if run == 1:
            start = j
        if run > best[1] - best[0]:
            best = (start, start + run)
    if best[1] - best[0] < 2:
        return None
    # Refine the run densely between its ends: the edge seen, sampled finely.
    s = np.linspace(line.lo, line.hi, samples)
    X = line.point(np.linspace(s[best[0]], s[best[1] - 1], samples))
    uv, _ = case.pixels(X)
    return X, uv


def _figure_hides(case: CctvCase, X: Array, place: int) -> Array:
    """Whether the figure at ``place`` hides each world point X (n, 3)."""
    d = X - case.C
    dist = np.linalg.norm(d, axis=1)
    t, _ = figure_hits(case.C, d / dist[:, None], case.places[place], case.figure_height)
    return np.asarray(t < dist - 0.02, bool)


def edge_candidates(case: CctvCase, min_span_rel: float = MIN_SPAN_REL) -> dict[str, list[tuple[Line, Array]]]:
    """Per axis, the edges whose seen run spans at least min_span_rel of the frame's longer side
    on the still (the figure at its first place, which must not hide them), each with its
    traced pixels (the truth's polyline)."""
    out: dict[str, list[tuple[Line, Array]]] = {a: [] for a in "xyz"}
    longer = max(case.width, case.height)
    for line in case.layout.lines():
        got = trace_edge(case, line)
        if got is None or np.any(_figure_hides(case, got[0], 0)):
            continue
        if float(np.sum(np.linalg.norm(np.diff(got[1], axis=0), axis=1))) >= min_span_rel * longer:
            out["xyz"[line.axis]].append((line, got[1]))
    return out


def marked_edges(case: CctvCase, rng: np.random.Generator,
                 candidates: dict[str, list[tuple[Line, Array]]] | None = None,
                 per_axis: tuple[int, int] = (4, 6)) -> dict[str, list[tuple[Line, Array]]]:
    """The edges a user marks on the still: per axis 4–6 of :func:`edge_candidates` (all of them
    where fewer), drawn at random."""
    cands = edge_candidates(case) if candidates is None else candidates
    out = {}
    for axis in "xyz":
        want = int(rng.integers(per_axis[0], per_axis[1] + 1))
        order = rng.permutation(len(cands[axis]))[:want]
        out[axis] = [cands[axis][j] for j in sorted(order)]
    return out


def clicks_along(uv: Array, rng: np.random.Generator, sigma_px: float, longer: int) -> Array:
    """The points a user clicks along an edge's image (its traced pixels uv): its two ends and
    middle points evenly along its length (3 on an edge spanning under a third of the frame's
    longer side, 5 beyond), each off by the click noise (1σ per coordinate)."""
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(uv, axis=0), axis=1))]
    middle = 3 if arc[-1] < longer / 3.0 else 5
    at = np.linspace(0.0, arc[-1], middle + 2)
    pts = np.stack([np.interp(at, arc, uv[:, 0]), np.interp(at, arc, uv[:, 1])], axis=1)
    return pts + rng.normal(0.0, sigma_px, pts.shape)


def lens_record(lens: TrueLens | DivisionLens, width: int, height: int) -> dict[str, Any]:
    """A lens as JSON values: its kind and parameters, its field and corner displacement (px)."""
    rec: dict[str, Any] = {"f_px": lens.f, "principal_point": list(lens.c),
                           "diagonal_fov_deg": lens.diagonal_fov_deg(width, height),
                           "corner_displacement_px": lens.corner_displacement_px(width, height)}
    if isinstance(lens, TrueLens):
        return {"kind": lens.kind, "barrel_a": lens.barrel, **rec}
    return {"kind": "division", "k1": lens.k1, **rec}


def truth_record(case: CctvCase, edges: dict[str, list[tuple[Line, Array]]] | None = None) -> dict[str, Any]:
    """What the generator knows of a case, as JSON values (module docstring)."""
    lens = case.lens
    places = []
    for k in range(len(case.places)):
        (foot, top), _ = case.pixels(np.array([case.foot(k), case.top(k)]))
        places.append({"foot_world": case.foot(k).tolist(), "top_world": case.top(k).tolist(),
                       "foot_px": foot.tolist(), "top_px": top.tolist()})
    rec: dict[str, Any] = {
        "seed": list(case.seed), "setting": case.setting, "width": case.width, "height": case.height,
        "K_equivalent": lens.K.tolist(), "R": case.R.tolist(), "C": case.C.tolist(),
        "lens": lens_record(lens, case.width, case.height),
        "figure_height_m": case.figure_height, "places": places, "interlaced": case.interlaced,
        "blur_px": case.blur_px, "noise_grey": case.noise_grey}
    if edges is not None:
        rec["edges"] = {axis: [{"axis": ln.axis, "at": list(ln.at), "lo": ln.lo, "hi": ln.hi,
                                "polyline_px": uv[:: max(1, len(uv) // 32)].tolist()} for ln, uv in got]
                        for axis, got in edges.items()}
    return rec
