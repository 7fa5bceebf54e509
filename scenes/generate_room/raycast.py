"""The ray caster: ray–quad intersection, Lambertian shading, supersampled photos, visibility."""

from __future__ import annotations

import numpy as np

from .cameras import pinhole_pixels, pixel_rays, project
from .parameters import VISIBILITY_EPS_M
from .textures import TEXTURES, srgb_to_linear, to_8bit


def _geometry(scene: dict) -> dict:
    """Per-quad arrays for the ray caster, cached in the scene."""
    g = scene.get("_geometry")
    if g is None:
        P = np.array([q["corner"] for q in scene["quads"]])
        E1 = np.array([q["edge1"] for q in scene["quads"]])
        E2 = np.array([q["edge2"] for q in scene["quads"]])
        N = np.cross(E1, E2)
        nn = np.sum(N * N, axis=1, keepdims=True)
        G1 = np.cross(E2, N) / nn  # dual basis: (X − P)·G1 = a, (X − P)·G2 = b
        G2 = np.cross(N, E1) / nn
        g = {"P": P, "N": N, "G1": G1, "G2": G2, "M": np.hstack([N.T, G1.T, G2.T])}
        scene["_geometry"] = g
    return g


def trace(scene: dict, origin: np.ndarray, dirs: np.ndarray, t_min: float = 1e-9,
          subset: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hit of rays origin + t·dirs (t > t_min) against the quads (all, or those in subset).

    Returns (index (n,) of the quad hit, −1 for none; t (n,), inf for none). Memory is
    n × (number of quads) × a few float64: callers chunk.
    """
    g = _geometry(scene)
    sel = np.arange(len(g["P"])) if subset is None else np.asarray(subset, dtype=np.int64)
    if len(sel) == 0:
        return np.full(len(dirs), -1), np.full(len(dirs), np.inf)
    Q = len(sel)
    M = g["M"].reshape(3, 3, -1)[:, :, sel].reshape(3, -1)
    DM = dirs @ M
    dn, d1, d2 = DM[:, :Q], DM[:, Q:2 * Q], DM[:, 2 * Q:]
    rel = g["P"][sel] - origin  # (Q, 3)
    cn = np.sum(rel * g["N"][sel], axis=1)
    c1 = -np.sum(rel * g["G1"][sel], axis=1)
    c2 = -np.sum(rel * g["G2"][sel], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = cn / dn
        a = c1 + t * d1
        b = c2 + t * d2
        ok = (t > t_min) & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)
    t = np.where(ok, t, np.inf)
    k = np.argmin(t, axis=1)
    tbest = t[np.arange(len(t)), k]
    idx = sel[k]
    idx[~np.isfinite(tbest)] = -1
    return idx, tbest


def quad_image_bounds(scene: dict, cam: dict, z_near: float = 1e-4) -> np.ndarray:
    """Conservative image bounding boxes (Q, 4) = (u_min, v_min, u_max, v_max) of every quad, in
    the pinhole's image (before the lens: see render_photo).

    Each quad is clipped to the half-space z_cam ≥ z_near before projecting (a quad wholly behind
    the camera gets an empty box), so rays of an image tile can only hit quads whose box meets it.
    """
    K = cam["K"]
    out = np.empty((len(scene["quads"]), 4))
    for k, q in enumerate(scene["quads"]):
        corners = q["corner"] + np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) @ np.array([q["edge1"], q["edge2"]])
        xc = (corners - cam["C"]) @ cam["R"].T
        poly = []  # Sutherland–Hodgman against z = z_near
        for i in range(4):
            p, n = xc[i], xc[(i + 1) % 4]
            if p[2] >= z_near:
                poly.append(p)
            if (p[2] >= z_near) != (n[2] >= z_near):
                poly.append(p + (z_near - p[2]) / (n[2] - p[2]) * (n - p))
        if not poly:
            out[k] = (np.inf, np.inf, -np.inf, -np.inf)
            continue
        poly = np.array(poly)
        u = K[0, 0] * poly[:, 0] / poly[:, 2] + K[0, 2]
        v = K[1, 1] * poly[:, 1] / poly[:, 2] + K[1, 2]
        out[k] = (u.min(), v.min(), u.max(), v.max())
    return out


def shade_hits(scene: dict, idx: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Linear-light colour (n, 3) of surface points X (n, 3) on quads idx (n,), before exposure."""
    out = np.zeros((len(idx), 3))
    quads = scene["quads"]
    for q in np.unique(idx):
        if q < 0:
            continue
        sel = idx == q
        quad = quads[q]
        rel = X[sel] - quad["tex_origin"]
        s, t = rel @ quad["tex_u"], rel @ quad["tex_v"]
        albedo = TEXTURES[quad["texture"]](s, t, *quad["tex_size"])
        out[sel] = srgb_to_linear(np.clip(albedo, 0, 1)) * quad["shade"]
    return out


def render_photo(scene: dict, cam: dict, width: int, height: int, supersample: int = 2,
                 return_ids: bool = False, tile: int = 64):
    """Ray-cast the photo: (height, width, 3) uint8 sRGB; with return_ids also the (height,
    width) int array of the quad seen through each pixel centre (−1 for none).

    Pixel (i, j) averages s × s stratified samples at (i + (k + ½)/s, j + (l + ½)/s); for s = 1
    that is the pixel centre (i + ½, j + ½); its ray leaves through the pinhole's normalised
    coordinate of that sample, undistorted by the lens (cameras.pixel_rays). The image is cast in
    tiles of tile × tile pixels, each against only the quads whose (pinhole) image bounds meet the
    box of the tile's samples as a pinhole would have put them. cam's K is for cam["width"] ×
    cam["height"]; it is rescaled if width × height differs.
    """
    s = int(supersample)
    if (width, height) != (cam["width"], cam["height"]):
        k = width / cam["width"]
        cam = dict(cam, K=cam["K"] * np.array([[k, 1, k], [1, k, k], [1, 1, 1]]), width=width, height=height)
    bounds = quad_image_bounds(scene, cam)
    img = np.zeros((height, width, 3), dtype=np.float32)
    ids = np.full((height, width), -1, dtype=np.int32) if return_ids else None
    offs = (np.arange(s) + 0.5) / s
    for j0 in range(0, height, tile):
        j1 = min(height, j0 + tile)
        for i0 in range(0, width, tile):
            i1 = min(width, i0 + tile)
            u_s = (np.arange(i0, i1)[:, None] + offs[None, :]).reshape(-1)
            v_s = (np.arange(j0, j1)[:, None] + offs[None, :]).reshape(-1)
            uu, vv = np.meshgrid(u_s, v_s)
            uv = np.column_stack([uu.ravel(), vv.ravel()])
            if cam.get("k1", 0.0) == 0.0:
                lo, hi = (i0, j0), (i1, j1)
            else:  # every sample's ray is its pinhole position's: the box of those is exact
                pin = pinhole_pixels(cam, uv)
                lo, hi = pin.min(axis=0), pin.max(axis=0)
            pad = 1.0  # pixels: the boxes are exact up to rounding; a margin costs nothing
            cand = np.flatnonzero((bounds[:, 0] <= hi[0] + pad) & (bounds[:, 2] >= lo[0] - pad)
                                  & (bounds[:, 1] <= hi[1] + pad) & (bounds[:, 3] >= lo[1] - pad))
            d = pixel_rays(cam, uv)
            idx, t = trace(scene, cam["C"], d, subset=cand)
            X = cam["C"] + np.where(np.isfinite(t), t, 0.0)[:, None] * d
            col = shade_hits(scene, idx, X) * cam["exposure"]
            img[j0:j1, i0:i1] = col.reshape(j1 - j0, s, i1 - i0, s, 3).mean(axis=(1, 3))
            if return_ids:
                if s == 1:
                    ids[j0:j1, i0:i1] = idx.reshape(j1 - j0, i1 - i0)
                else:
                    uc, vc = np.meshgrid(np.arange(i0, i1) + 0.5, np.arange(j0, j1) + 0.5)
                    dc = pixel_rays(cam, np.column_stack([uc.ravel(), vc.ravel()]))
                    ids[j0:j1, i0:i1] = trace(scene, cam["C"], dc, subset=cand)[0].reshape(j1 - j0, i1 - i0)
    out = to_8bit(img)
    return (out, ids) if return_ids else out


def visible(scene: dict, cam: dict, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """True where a world point (n, 3) is in front of the camera, projects inside the image
    (at least margin px from its border) and nothing lies between it and the camera centre
    (an occluder must be more than VISIBILITY_EPS_M nearer than the point)."""
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    uv, z = project(cam, points)
    inside = ((z > 1e-6) & (uv[:, 0] >= margin) & (uv[:, 0] <= cam["width"] - margin)
              & (uv[:, 1] >= margin) & (uv[:, 1] <= cam["height"] - margin))
    d = points - cam["C"]
    dist = np.linalg.norm(d, axis=1)
    _, t = trace(scene, cam["C"], d)  # t = 1 at the point itself
    return inside & (t * dist >= dist - VISIBILITY_EPS_M)


