"""The ray-caster of the generated CCTV scenes (:mod:`vebuild.synthetic.cctv`): every pixel's ray
is cast exactly through the true lens (:class:`vebuild.synthetic.cctv_lens.TrueLens`, at the
pixel's centre) against the scene's planes, its shelves (solid boxes), and the figure (an upright
cylinder for the body, a sphere for the head).

The scene's straight edges (:meth:`Layout.lines`) are dark painted lines 3 cm wide (tile joints,
kerb joints, string courses, pilaster and door-frame grooves, shelf edges), box-filtered over
each pixel's footprint so that they are not aliased: the line's centre is the 3D edge whose image
the truth samples. The surfaces carry a smooth texture (sums of sines of the world position) and
a simple light (a sun outdoors, a fall-off from the ceiling indoors).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from .cctv_lens import DivisionLens, TrueLens

Array = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Half the width of a painted line (m).
LINE_HALF_WIDTH_M = 0.015
#: The figure: body radius, head radius (m).
BODY_RADIUS_M, HEAD_RADIUS_M = 0.2, 0.115
SKY = np.array([205.0, 218.0, 236.0])


@dataclass(frozen=True)
class Line:
    """A straight painted edge: along ``axis`` (0 x, 1 y, 2 z) through ``at`` (its other two
    coordinates fixed), from ``lo`` to ``hi`` along the axis."""

    axis: int
    at: tuple[float, float, float]
    lo: float
    hi: float

    def point(self, s: Array) -> Array:
        """Points (n, 3) at positions s along the axis."""
        X = np.tile(np.asarray(self.at, float), (len(s), 1))
        X[:, self.axis] = s
        return X


@dataclass
class Layout:
    """The static scene: ``setting`` street or shop, its dimensions (m) and shelves (boxes lo, hi)."""

    setting: str
    dims: dict[str, float]
    pilasters: list[float] = field(default_factory=list)  # street: x of the façade's pilasters
    doors: list[tuple[float, float]] = field(default_factory=list)  # street: x of each door's jambs
    shelves: list[tuple[Array, Array]] = field(default_factory=list)  # shop: solid boxes

    def lines(self) -> list[Line]:
        """The painted edges along the world's axes that a user can mark."""
        d, out = self.dims, list[Line]()
        if self.setting == "street":
            near, far, w, top = d["near_y"], d["far_y"], d["road_w"], d["facade_h"]
            span = (-60.0, 60.0)
            for y in (0.0, w, -1.2, -2.4, w + 1.2, w + 2.4):  # kerb joints, pavement joints
                out.append(Line(0, (0.0, y, 0.0), *span))
            for x in np.arange(-30.0, 30.01, 1.2):  # pavement joints across, on both pavements
                out.append(Line(1, (float(x), 0.0, 0.0), near, -0.15))
                out.append(Line(1, (float(x), 0.0, 0.0), w + 0.15, far))
            for z in np.arange(3.0, top, 3.0):  # string courses of the storeys
                out.append(Line(0, (0.0, far, float(z)), *span))
                out.append(Line(0, (0.0, near, float(z)), *span))
            for x in self.pilasters:
                out.append(Line(2, (x, far, 0.0), 0.0, top))
            for a, b in self.doors:
                out += [Line(2, (a, far, 0.0), 0.0, 2.1), Line(2, (b, far, 0.0), 0.0, 2.1),
                        Line(0, (0.0, far, 2.1), a, b)]
        else:
            lx, ly, h, t = d["lx"], d["ly"], d["h"], d["tile"]
            for y in np.arange(t, ly - 0.01, t):
                out.append(Line(0, (0.0, float(y), 0.0), 0.0, lx))
            for x in np.arange(t, lx - 0.01, t):
                out.append(Line(1, (float(x), 0.0, 0.0), 0.0, ly))
            for z in (0.1, 2.6):  # skirting and picture rail on the four walls
                out += [Line(0, (0.0, ly, z), 0.0, lx), Line(0, (0.0, 0.0, z), 0.0, lx),
                        Line(1, (lx, 0.0, z), 0.0, ly), Line(1, (0.0, 0.0, z), 0.0, ly)]
            for x, y in ((lx, ly), (0.0, ly), (lx, 0.0)):  # the walls' corner beads
                out.append(Line(2, (x, y, 0.0), 0.0, h))
            for s in np.arange(d["panel"], max(lx, ly) - 0.05, d["panel"]):  # the wall panels' joints
                if s < lx:
                    out.append(Line(2, (float(s), ly, 0.0), 0.0, h))
                if s < ly:
                    out.append(Line(2, (lx, float(s), 0.0), 0.0, h))
            for lo, hi in self.shelves:  # the shelves' front edges and uprights
                front_y = lo[1] if hi[1] >= ly - 1e-9 else None
                if front_y is not None:
                    for z in np.arange(0.1, hi[2] + 1e-9, 0.4):
                        out.append(Line(0, (0.0, front_y, float(z)), lo[0], hi[0]))
                    for x in (lo[0], hi[0]):
                        out.append(Line(2, (float(x), front_y, 0.0), 0.0, hi[2]))
                else:
                    for z in np.arange(0.1, hi[2] + 1e-9, 0.4):
                        out.append(Line(1, (lo[0], 0.0, float(z)), lo[1], hi[1]))
                    for y in (lo[1], hi[1]):
                        out.append(Line(2, (lo[0], float(y), 0.0), 0.0, hi[2]))
        return out


def _coverage(q: Array, at: float | Array, fp: Array) -> Array:
    """How much of each pixel (footprint fp, m) a line at coordinate ``at`` covers."""
    return np.clip((LINE_HALF_WIDTH_M - np.abs(q - at)) / fp + 0.5, 0.0, 1.0)


def _grid_coverage(q: Array, step: float, fp: Array, offset: float = 0.0) -> Array:
    d = np.abs((q - offset) - step * np.round((q - offset) / step))
    return np.clip((LINE_HALF_WIDTH_M - d) / fp + 0.5, 0.0, 1.0)


def _texture(X: Array, seed: float) -> Array:
    """A smooth albedo modulation in 0.85–1.15 of the world position (sums of sines)."""
    s = np.zeros(X.shape[:-1])
    for k, (a, b, c, fr) in enumerate(((1.0, 0.3, 0.7, 1.7), (0.2, 1.0, 0.5, 3.1), (0.6, 0.8, 1.0, 7.3),
                                       (1.0, -0.6, 0.4, 13.0))):
        s += np.sin(fr * (a * X[..., 0] + b * X[..., 1] + c * X[..., 2]) + seed * (k + 1)) / (k + 1.5)
    return 1.0 + 0.07 * s


def _box_hits(C: Array, d: Array, lo: Array, hi: Array) -> tuple[Array, Array]:
    """Ray parameter of each ray's entry into the solid box (inf where it misses) and the axis of
    the face it enters by."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - C) / d, (hi - C) / d
    tmin, tmax = np.minimum(t1, t2), np.maximum(t1, t2)
    tmin = np.where(np.isnan(tmin), -np.inf, tmin)
    tmax = np.where(np.isnan(tmax), np.inf, tmax)
    near, far = tmin.max(axis=-1), tmax.min(axis=-1)
    hit = (near < far) & (near > 1e-6)
    return np.where(hit, near, np.inf), tmin.argmax(axis=-1)


def figure_hits(C: Array, d: Array, at: Array, height: float) -> tuple[Array, Array]:
    """Ray parameter of each ray's hit on the figure standing at ``at`` (x, y) and ``height`` tall
    (inf where it misses), and the surface normal there."""
    rb, rh = BODY_RADIUS_M, HEAD_RADIUS_M
    top_body = height - 2.0 * rh
    o = C[:2] - at
    a = d[..., 0] ** 2 + d[..., 1] ** 2
    b = 2.0 * (o[0] * d[..., 0] + o[1] * d[..., 1])
    c = o @ o - rb**2
    disc = b * b - 4.0 * a * c
    with np.errstate(invalid="ignore", divide="ignore"):
        t_cyl = (-b - np.sqrt(np.maximum(disc, 0.0))) / (2.0 * a)
        z = C[2] + t_cyl * d[..., 2]
        t_cyl = np.where((disc > 0) & (t_cyl > 0) & (z >= 0.0) & (z <= top_body), t_cyl, np.inf)
        t_cap = (top_body - C[2]) / d[..., 2]
        Xc = C[:2] + t_cap[..., None] * d[..., :2]
        t_cap = np.where((t_cap > 0) & (np.sum((Xc - at) ** 2, axis=-1) <= rb**2), t_cap, np.inf)
    S = np.array([at[0], at[1], height - rh])
    oc = C - S
    bs = d @ oc
    cs = oc @ oc - rh**2
    ds = bs * bs - cs
    t_sph = np.where(ds > 0, -bs - np.sqrt(np.maximum(ds, 0.0)), np.inf)
    t_sph = np.where(t_sph > 0, t_sph, np.inf)
    t = np.minimum(np.minimum(t_cyl, t_cap), t_sph)
    X = C + np.where(np.isfinite(t), t, 0.0)[..., None] * d
    n = np.zeros_like(d)
    on_cyl, on_cap, on_sph = t == t_cyl, t == t_cap, t == t_sph
    n[..., :2] = np.where(on_cyl[..., None], (X[..., :2] - at) / rb, 0.0)
    n[..., 2] = np.where(on_cap, 1.0, 0.0)
    n = np.where(on_sph[..., None], (X - S) / rh, n)
    return t, n


def cast_static(layout: Layout, C: Array, d: Array) -> tuple[Array, IntArray, IntArray]:
    """Ray parameter, the hit's surface axis (0, 1, 2: the normal's axis) and the kind of surface
    (0 sky, 1 ground/floor, 2 façade/wall, 3 ceiling, 4 shelf) of each ray (…, 3) from C."""
    dims = layout.dims
    with np.errstate(divide="ignore", invalid="ignore"):
        if layout.setting == "street":
            t_g = np.where(d[..., 2] < 0, -C[2] / d[..., 2], np.inf)
            t_far = np.where(d[..., 1] > 0, (dims["far_y"] - C[1]) / d[..., 1], np.inf)
            t_near = np.where(d[..., 1] < 0, (dims["near_y"] - C[1]) / d[..., 1], np.inf)
            t_wall = np.minimum(t_far, t_near)
            z_wall = C[2] + t_wall * d[..., 2]
            t_wall = np.where(z_wall <= dims["facade_h"], t_wall, np.inf)
            t = np.minimum(t_g, t_wall)
            axis = np.where(t == t_g, 2, 1)
            kind = np.where(np.isinf(t), 0, np.where(t == t_g, 1, 2))
            return t, axis, kind
        hi = np.array([dims["lx"], dims["ly"], dims["h"]])
        t_ax = np.where(d > 0, (hi - C) / d, (0.0 - C) / d)
    t_ax = np.where(np.isfinite(t_ax) & (t_ax > 0), t_ax, np.inf)
    axis = np.argmin(t_ax, axis=-1)
    t = np.take_along_axis(t_ax, axis[..., None], -1)[..., 0]
    kind = np.where(axis == 2, np.where(d[..., 2] < 0, 1, 3), 2)
    for lo, hi_b in layout.shelves:
        centre, reach = (lo + hi_b) / 2.0, float(np.linalg.norm(hi_b - lo)) / 2.0 + 0.01
        oc = C - centre
        b = d @ oc
        near = np.flatnonzero((b * b - (oc @ oc - reach**2) > 0).reshape(-1))
        if not len(near):
            continue
        tf, af, kf = t.reshape(-1), axis.reshape(-1), kind.reshape(-1)  # views: written in place
        tb, ab = _box_hits(C, d.reshape(-1, 3)[near], lo, hi_b)
        closer = tb < tf[near]
        idx = near[closer]
        tf[idx], af[idx], kf[idx] = tb[closer], ab[closer], 4
    return t, axis, kind


def _near(q: Array, values: Array, fp: Array) -> Array:
    """How much of each pixel the nearest of the lines at coordinates ``values`` covers."""
    v = np.sort(np.asarray(values, float))
    i = np.clip(np.searchsorted(v, q), 1, len(v) - 1) if len(v) > 1 else np.zeros(q.shape, int)
    d = np.abs(q - v[i]) if len(v) == 1 else np.minimum(np.abs(q - v[i - 1]), np.abs(q - v[i]))
    return np.clip((LINE_HALF_WIDTH_M - d) / fp + 0.5, 0.0, 1.0)


def _dark(layout: Layout, X: Array, axis: IntArray, kind: IntArray, fp: Array) -> Array:
    """The painted lines' coverage of each pixel (0–1); X, axis, kind, fp flat (n, …)."""
    dims, dark = layout.dims, np.zeros(X.shape[:-1])
    x, y, z = X[..., 0], X[..., 1], X[..., 2]
    if layout.setting == "street":
        w = dims["road_w"]
        g = np.flatnonzero(kind == 1)
        gy, gx, gf = y[g], x[g], fp[g]
        pave = (gy < -0.15) | (gy > w + 0.15)
        dark[g] = np.maximum(_near(gy, np.array([0.0, w, -1.2, -2.4, w + 1.2, w + 2.4]), gf),
                             np.where(pave, _grid_coverage(gx, 1.2, gf), 0.0))
        f = np.flatnonzero(kind == 2)
        fx, fz, ff = x[f], z[f], fp[f]
        cov = np.maximum(_grid_coverage(fz, 3.0, ff) * (fz > 1.0), _near(fx, np.array(layout.pilasters), ff))
        if layout.doors:
            jambs = np.array([v for ab in layout.doors for v in ab])
            low = fz < 2.1 + LINE_HALF_WIDTH_M
            cov = np.maximum(cov, np.where(low, _near(fx, jambs, ff), 0.0))
            a = np.array([ab[0] for ab in layout.doors])
            b = np.array([ab[1] for ab in layout.doors])
            k = np.clip(np.searchsorted(a, fx) - 1, 0, len(a) - 1)
            within = (fx >= a[k]) & (fx <= b[k])
            cov = np.maximum(cov, np.where(within, _coverage(fz, 2.1, ff), 0.0))
        dark[f] = cov
        return dark
    t = dims["tile"]
    g = np.flatnonzero(kind == 1)
    dark[g] = np.maximum(_grid_coverage(x[g], t, fp[g]), _grid_coverage(y[g], t, fp[g]))
    along = np.where(axis == 0, y, x)
    w_ = np.flatnonzero(kind == 2)
    wl = np.maximum(_coverage(z[w_], 0.1, fp[w_]), _coverage(z[w_], 2.6, fp[w_]))
    joints = np.r_[np.arange(0.0, max(dims["lx"], dims["ly"]) + 1e-9, dims["panel"]), dims["lx"], dims["ly"]]
    dark[w_] = np.maximum(wl, _near(along[w_], joints, fp[w_]))
    sh = np.flatnonzero(kind == 4)
    if len(sh):
        edges = np.array([v for lo, hi in layout.shelves for v in (lo[0], hi[0], lo[1], hi[1])])
        dark[sh] = np.maximum(_grid_coverage(z[sh], 0.4, fp[sh], 0.1), _near(along[sh], edges, fp[sh]))
    return dark


#: Albedo (RGB, 0–1) of each kind of surface: sky (unused), ground, façade/wall, ceiling, shelf,
#: and the figure's body and head.
ALBEDO = {"street": [(0, 0, 0), (0.55, 0.53, 0.50), (0.72, 0.58, 0.46), (0, 0, 0), (0, 0, 0)],
          "shop": [(0, 0, 0), (0.78, 0.76, 0.70), (0.86, 0.84, 0.78), (0.92, 0.92, 0.92), (0.45, 0.55, 0.70)]}
BODY, HEAD = np.array([0.22, 0.26, 0.38]), np.array([0.70, 0.55, 0.45])


def render_rays(layout: Layout, C: Array, d: Array, fp_ang: Array, figure: tuple[Array, float] | None,
                tex_seed: float) -> tuple[Array, Array]:
    """RGB (n, 3, 0–255 float) of rays d (n, 3, unit, world) from C, each pixel spanning fp_ang
    radians; and the painted lines' coverage (n) for the tests."""
    t, axis, kind = cast_static(layout, C, d)
    X = C + np.where(np.isfinite(t), t, 0.0)[..., None] * d
    normal = np.zeros_like(d)
    np.put_along_axis(normal, axis[..., None], -np.sign(np.take_along_axis(d, axis[..., None], -1)), -1)
    cos_inc = np.abs(np.sum(normal * d, axis=-1))
    fp = np.where(np.isfinite(t), t, 1.0) * fp_ang / np.maximum(cos_inc, 0.1)
    dark = _dark(layout, X, axis, kind, fp)
    if layout.setting == "street":
        w = layout.dims["road_w"]
        road = (kind == 1) & (X[..., 1] > 0.0) & (X[..., 1] < w)
        light = 0.6 + 0.4 * np.clip(normal @ np.array([0.3, -0.5, 0.81]), 0.0, 1.0)
    else:
        road = np.zeros(t.shape, bool)
        lamp = np.array([layout.dims["lx"] / 2, layout.dims["ly"] / 2, layout.dims["h"]])
        light = 0.6 + 0.4 / (1.0 + 0.02 * np.sum((X - lamp) ** 2, axis=-1))
    alb = np.asarray(ALBEDO[layout.setting], float)[kind]
    alb = np.where(road[..., None], np.array([0.30, 0.30, 0.32]), alb)
    rgb = alb * (_texture(X, tex_seed) * light * (1.0 - 0.6 * dark))[..., None] * 250.0
    if figure is not None:
        at, h = figure
        centre = np.array([at[0], at[1], h / 2.0])
        reach = np.hypot(BODY_RADIUS_M, h / 2.0) + 0.01
        oc = C - centre
        b = d @ oc
        near = np.flatnonzero(b * b - (oc @ oc - reach**2) > 0)
        tf, nf = figure_hits(C, d[near], at, h)
        on = tf < t[near]
        head = (C[2] + tf * d[near, 2]) > h - 2.0 * HEAD_RADIUS_M
        shade = 0.45 + 0.55 * np.clip(nf @ np.array([0.3, -0.5, 0.81]), 0.0, 1.0)
        fig = np.where(head[:, None], HEAD, BODY) * shade[:, None] * 250.0
        rgb[near] = np.where(on[:, None], fig, rgb[near])
        dark[near] = np.where(on, 0.0, dark[near])
    rgb = np.where((kind == 0)[..., None], SKY, rgb)
    return rgb, dark


def render(layout: Layout, lens: TrueLens | DivisionLens, R: Array, C: Array, width: int, height: int,
           figure: tuple[Array, float] | None, tex_seed: float, rows: tuple[int, int] | None = None,
           cols: tuple[int, int] | None = None, band_rows: int = 128) -> tuple[Array, Array]:
    """The frame (height, width, 3; float 0–255, before blur and noise) and the lines' coverage,
    cast through the true lens; ``rows``/``cols``: only that window (end exclusive)."""
    r0, r1 = rows if rows is not None else (0, height)
    c0, c1 = cols if cols is not None else (0, width)
    u = np.arange(c0, c1, dtype=np.float64) + 0.5
    img = np.empty((r1 - r0, c1 - c0, 3))
    dark = np.empty((r1 - r0, c1 - c0))
    for b0 in range(r0, r1, band_rows):
        v = np.arange(b0, min(r1, b0 + band_rows), dtype=np.float64) + 0.5
        uu, vv = np.meshgrid(u, v)
        uv = np.stack([uu, vv], axis=-1)
        dc = lens.rays(uv)
        dn = lens.rays(uv + [1.0, 0.0])
        fp_ang = np.linalg.norm(dn - dc, axis=-1)
        got, dk = render_rays(layout, C, (dc @ R).reshape(-1, 3), fp_ang.reshape(-1), figure,
                              tex_seed)  # R: world → camera
        img[b0 - r0:b0 - r0 + len(v)] = got.reshape(len(v), -1, 3)
        dark[b0 - r0:b0 - r0 + len(v)] = dk.reshape(len(v), -1)
    return img, dark
