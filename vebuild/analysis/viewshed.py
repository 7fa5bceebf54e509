"""Viewsheds (paper §5.1, witness statement evaluation): the sight line's question
(:mod:`vebuild.analysis.sightline`) asked from every cell of a grid over the floor (the model's
upward faces at z = 0), eyes at a given height: which places see the target point, or how much of
the object each place sees. Cells where a person cannot be (inside the footprint of something that
rises from the floor to below eye height: a wall, a table, a cabinet) are left out of the figures.
The viewshed is drawn as a top-view map, a PNG with its provenance.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from vebuild.analysis.observed import hidden_weights, on_grid, unobserved_at, viewshed_figures
from vebuild.analysis.rays import Occluders
from vebuild.analysis.sightline import SAMPLE_SEED, STANDING_EYE_M, Target, rounded, sample_surface_triangles
from vebuild.errors import VebuildError

if TYPE_CHECKING:
    from vebuild.project import Project

Array = NDArray[np.float64]

#: Samples of an object's surface per cell.
VIEWSHED_OBJECT_SAMPLES = 256
#: Faces within this of z = 0 and facing up are the floor.
FLOOR_TOLERANCE_M = 1e-3
#: Things lower than this (a rug, the floor itself) do not stop a person standing on them.
FLOOR_CLEARANCE_M = 0.02

#: Cell states of a viewshed.
OUTSIDE, OCCUPIED, PLACE = 0, 1, 2


@dataclass
class Viewshed:
    """A viewshed over the floor (see the module's docstring).

    origin : (x, y) of the grid's lower-left corner; cell : its side (m); states (ny, nx): OUTSIDE
    the floor, OCCUPIED (no place to stand) or PLACE; share (ny, nx): the target point seen (1 or
    0) or the object's visible share, NaN where not a place. Row j is y = origin[1] + (j + ½) cell.
    unobserved (ny, nx): of each place's deciding rays (those that reach the target, or, where none
    does, those hidden by a surface), the share resting on surfaces no photo saw
    (:mod:`vebuild.analysis.observed`); None where the scene cannot tell.
    """

    target: Target
    eye_height: float
    origin: tuple[float, float]
    cell: float
    states: NDArray[np.int8]
    share: Array
    samples: int | None = None
    unobserved: Array | None = None  # (ny, nx) share of each place's deciding rays resting on unobserved surfaces

    def centres(self) -> tuple[Array, Array]:
        ny, nx = self.states.shape
        return cell_centres(self.origin, self.cell, nx, ny)

    @property
    def seeing(self) -> NDArray[np.bool_]:
        return (self.states == PLACE) & (np.nan_to_num(self.share) > 0.0)

    def figures(self) -> dict[str, Any]:
        a = self.cell ** 2
        places = self.states == PLACE
        floor_area = float((self.states != OUTSIDE).sum() * a)
        place_area = float(places.sum() * a)
        seeing = float(self.seeing.sum() * a)
        d: dict[str, Any] = {"target": self.target.record(), "eye_height_m": self.eye_height, "cell_m": self.cell,
                             "grid": {"origin_m": rounded(self.origin), "nx": int(self.states.shape[1]),
                                      "ny": int(self.states.shape[0])},
                             "floor_area_m2": round(floor_area, 6), "place_area_m2": round(place_area, 6),
                             "occupied_area_m2": round(floor_area - place_area, 6),
                             "seeing_area_m2": round(seeing, 6),
                             "seeing_share_of_place_area": round(seeing / place_area, 6) if place_area else None}
        if self.target.node is not None:
            d["samples_per_cell"] = self.samples
            d["mean_visible_share"] = round(float(np.nanmean(np.where(places, self.share, np.nan))), 6) \
                if places.any() else None
        d["unobserved"] = viewshed_figures(self.unobserved, self.seeing, places, self.cell)
        return d


def cell_centres(origin: Any, cell: float, nx: int, ny: int) -> tuple[Array, Array]:
    """The x of each column's and the y of each row's centre of a grid whose lower-left corner is at
    ``origin``."""
    return origin[0] + (np.arange(nx) + 0.5) * cell, origin[1] + (np.arange(ny) + 0.5) * cell


def floor_grid(occ: Occluders, cell: float, eye_height: float) -> tuple[tuple[float, float], NDArray[np.int8]]:
    """The grid over the floor (upward faces at z = 0) and each cell's state."""
    from vebuild.model.collide import footprints

    if not cell > 0:
        raise VebuildError(f"--cell: expected a cell size > 0 m, got {cell:g}")
    if not eye_height > 0:
        raise VebuildError(f"--height: expected an eye height > 0 m, got {eye_height:g}")
    P = np.stack([occ.v0, occ.v0 + occ.e1, occ.v0 + occ.e2], axis=1)
    floor = np.flatnonzero(np.all(np.abs(P[:, :, 2]) < FLOOR_TOLERANCE_M, axis=1) & (occ.normal[:, 2] > 0.99))
    if not len(floor):
        raise VebuildError("the model has no floor: no upward face lies at z = 0 (DESIGN.md: the floor is z = 0)")
    lo, hi = P[floor, :, :2].reshape(-1, 2).min(axis=0), P[floor, :, :2].reshape(-1, 2).max(axis=0)
    nx, ny = max(1, math.ceil((hi[0] - lo[0]) / cell - 1e-9)), max(1, math.ceil((hi[1] - lo[1]) / cell - 1e-9))
    if nx * ny > 4_000_000:
        raise VebuildError(f"--cell: {cell:g} m gives {nx}×{ny} cells over the floor; choose a larger cell")
    X, Y = np.meshgrid(*cell_centres(lo, cell, nx, ny))
    Q = np.stack([X.ravel(), Y.ravel()], axis=1)
    on_floor = np.zeros(len(Q), bool)
    for a, b, c in P[floor, :, :2]:
        on_floor |= _in_triangle(Q, a, b, c)
    states = np.where(on_floor, PLACE, OUTSIDE).astype(np.int8)
    for fp in footprints(occ.scene.model):
        if fp.z_hi <= FLOOR_CLEARANCE_M or fp.z_lo >= eye_height:
            continue
        inside = _in_convex(Q, fp.hull)
        states[inside & on_floor] = OCCUPIED
    return (float(lo[0]), float(lo[1])), states.reshape(ny, nx)


def _in_triangle(Q: Array, a: Array, b: Array, c: Array) -> NDArray[np.bool_]:
    def side(p, q):
        return (q[0] - p[0]) * (Q[:, 1] - p[1]) - (q[1] - p[1]) * (Q[:, 0] - p[0])
    s1, s2, s3 = side(a, b), side(b, c), side(c, a)
    tol = 1e-12
    return ((s1 >= -tol) & (s2 >= -tol) & (s3 >= -tol)) | ((s1 <= tol) & (s2 <= tol) & (s3 <= tol))


def _in_convex(Q: Array, hull: Array) -> NDArray[np.bool_]:
    a, b = hull, np.roll(hull, -1, axis=0)
    cross = (b[:, 0] - a[:, 0]) * (Q[:, 1, None] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (Q[:, 0, None] - a[:, 0])
    return np.all(cross > 1e-9, axis=1)


def viewshed(occ: Occluders, target: Target, eye_height: float = STANDING_EYE_M, cell: float = 0.1,
             samples: int = VIEWSHED_OBJECT_SAMPLES, seed: int = SAMPLE_SEED) -> Viewshed:
    """Which places on the floor see ``target`` (see :class:`Viewshed`)."""
    origin, states = floor_grid(occ, cell, eye_height)
    ny, nx = states.shape
    X, Y = np.meshgrid(*cell_centres(origin, cell, nx, ny))
    places = np.flatnonzero(states.ravel() == PLACE)
    E = np.stack([X.ravel()[places], Y.ravel()[places], np.full(len(places), eye_height)], axis=1)
    share = np.full(nx * ny, np.nan)
    if target.point is not None:
        T = np.broadcast_to(target.point, E.shape)
        blocked, t, tri = occ.segments_blocked(E, T)
        share[places] = (~blocked).astype(float)
        w = hidden_weights(occ, E, T, blocked, t, tri)
        return Viewshed(target, eye_height, origin, cell, states, share.reshape(ny, nx),
                        unobserved=on_grid(w, places, ny, nx))
    P, N, on_tri = sample_surface_triangles(occ, target.nodes, samples, seed)
    sample_unobserved = unobserved_at(occ, on_tri, P)
    w = None if sample_unobserved is None else np.zeros(len(places))
    seen = np.zeros(len(places))
    # One cell's eye against all samples per batch: the segments share the eye, so their bounding box
    # (the eye and the object) prunes the triangles well.
    for i, e in enumerate(E):
        facing = np.flatnonzero(np.einsum("ij,ij->i", e - P, N) > 0.0)
        if len(facing):
            b, t, tri = occ.segments_blocked(np.broadcast_to(e, (len(facing), 3)), P[facing])
            seen[i] = float((~b).sum()) / len(P)
            if w is not None and sample_unobserved is not None:  # seen: on what surfaces; hidden: by what
                hid = None if (~b).any() else hidden_weights(occ, e, P[facing], b, t, tri)
                w[i] = float(sample_unobserved[facing[~b]].mean() if hid is None else hid.mean())
    share[places] = seen
    return Viewshed(target, eye_height, origin, cell, states, share.reshape(ny, nx), samples,
                    on_grid(w, places, ny, nx))


def viewshed_image(vs: Viewshed, occ: Occluders, px_per_cell: int | None = None) -> NDArray[np.uint8]:
    """A top-view map of a viewshed: +y up, places that see the target green (an object: shaded by
    its visible share), places that do not dark slate, occupied cells light grey, the footprints of
    the model's objects outlined, the target marked in red, a 1 m scale bar and a caption."""
    from PIL import Image, ImageDraw, ImageFont

    from vebuild.model.collide import footprints
    from vebuild.render.sizes import check_render_size

    ny, nx = vs.states.shape
    s = px_per_cell or int(max(2, min(16, 900 // max(nx, ny))))
    no, yes = np.array([70, 76, 96], float), np.array([60, 185, 90], float)
    share = np.nan_to_num(vs.share)
    if vs.target.node is not None and np.nanmax(np.where(vs.states == PLACE, vs.share, 0.0), initial=0.0) > 0:
        share = share / np.nanmax(np.where(vs.states == PLACE, vs.share, 0.0))  # shade relative to the best place
        share = np.where(np.nan_to_num(vs.share) > 0, 0.25 + 0.75 * share, 0.0)
    rgb = no[None, None] * (1 - share[..., None]) + yes[None, None] * share[..., None]
    rgb[vs.states == OCCUPIED] = (200, 200, 200)
    rgb[vs.states == OUTSIDE] = (250, 250, 250)
    fps = [fp for fp in footprints(occ.scene.model) if fp.z_hi > FLOOR_CLEARANCE_M]
    g_lo = np.array(vs.origin)
    g_hi = g_lo + vs.cell * np.array([nx, ny])
    lo = np.min([g_lo, *(fp.hull.min(axis=0) for fp in fps)], axis=0)
    hi = np.max([g_hi, *(fp.hull.max(axis=0) for fp in fps)], axis=0)
    if vs.target.point is not None:
        lo, hi = np.minimum(lo, vs.target.point[:2]), np.maximum(hi, vs.target.point[:2])
    k = s / vs.cell  # pixels per metre
    pad, top = 20, 48
    W = int(math.ceil((hi[0] - lo[0]) * k)) + 2 * pad
    H = int(math.ceil((hi[1] - lo[1]) * k)) + pad + top + 28
    check_render_size(max(W, 560), H, f"the viewshed map ({nx}×{ny} cells of {vs.cell:g} m, {s} pixels a cell, "
                      f"over {hi[0] - lo[0]:.3g} m × {hi[1] - lo[1]:.3g} m of floor and objects)",
                      advice="choose a larger --cell")
    cells = np.repeat(np.repeat(rgb[::-1].astype(np.uint8), s, axis=0), s, axis=1)
    img = Image.new("RGB", (max(W, 560), H), (255, 255, 255))

    def to_px(xy: Array) -> list[tuple[float, float]]:
        xy = np.atleast_2d(xy)
        return [(pad + (x - lo[0]) * k, top + (hi[1] - y) * k) for x, y in xy]

    (gx, gy), = to_px(np.array([g_lo[0], g_hi[1]]))
    img.paste(Image.fromarray(cells), (int(round(gx)), int(round(gy))))
    d = ImageDraw.Draw(img)
    target_nodes = set(vs.target.nodes)
    for fp in fps:
        if fp.node in target_nodes:
            continue
        d.polygon(to_px(fp.hull), outline=(20, 20, 20))
    red = (220, 30, 30)
    if vs.target.point is not None:
        (u, v), = to_px(vs.target.point[:2])
        r = max(5, s)
        d.ellipse((u - r, v - r, u + r, v + r), outline=red, width=3)
        d.line((u - 2 * r, v, u + 2 * r, v), fill=red, width=2)
        d.line((u, v - 2 * r, u, v + 2 * r), fill=red, width=2)
    else:
        for fp in footprints(occ.scene.model, nodes=target_nodes):
            d.polygon(to_px(fp.hull), outline=red, width=3)
    font = ImageFont.load_default(size=14)
    fig = vs.figures()
    share_txt = "—" if fig["seeing_share_of_place_area"] is None else f"{100 * fig['seeing_share_of_place_area']:.1f} %"
    d.text((pad, 6), f"viewshed of {vs.target.label}, eyes at {vs.eye_height:g} m: {share_txt} of the floor "
                     f"where one can stand sees it", fill=(0, 0, 0), font=font)
    d.text((pad, 26), f"green: sees it · slate: does not · grey: no place to stand · cell {vs.cell:g} m · +y up",
           fill=(80, 80, 80), font=ImageFont.load_default(size=11))
    x0, y0 = pad, H - 16
    d.line((x0, y0, x0 + k, y0), fill=(0, 0, 0), width=3)
    d.text((x0 + k + 6, y0 - 7), "1 m", fill=(0, 0, 0), font=font)
    return np.asarray(img)


def write_viewshed_png(project: Project, vs: Viewshed, occ: Occluders, out: Path) -> None:
    """The viewshed's map as a PNG carrying its provenance and figures."""
    from vebuild import __version__
    from vebuild.project.provenance import inputs_sha256
    from vebuild.render.png import check_output, write_png

    out = check_output(Path(out))
    text = {"Software": f"vebuild {__version__}", "vebuild:project": project.path.name,
            "vebuild:inputs_sha256": inputs_sha256(project.data),
            "vebuild:viewshed": json.dumps(vs.figures(), sort_keys=True, ensure_ascii=False)}
    write_png(out, viewshed_image(vs, occ), text)
