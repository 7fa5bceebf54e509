"""The example room's ground truth, for texture tests and benchmarks.

The true model (ground_truth.json's nodes), the true cameras (with each photo's lens distortion and
how far its EXIF focal length is off), the photos, and the true texture of every texel, from the
scene's own generator (scenes/generate_room/, imported by path: it does not import vebuild, so it
is an independent witness).
"""

from __future__ import annotations

import importlib.util
import json
import sys
from functools import cache
from pathlib import Path
from types import ModuleType

import numpy as np

from vebuild.camera import ImageCamera, Lens
from vebuild.model.scene import Model, model_from_dict
from vebuild.resources import data_dir, example_project_dir

ROOM = example_project_dir()


@cache
def generator() -> ModuleType:
    """The scenes/generate_room package, imported by path (it is data, not part of the vebuild package)."""
    folder = data_dir("scenes/generate_room")
    spec = importlib.util.spec_from_file_location("generate_room", folder / "__init__.py",
                                                  submodule_search_locations=[str(folder)])
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["generate_room"] = mod
    spec.loader.exec_module(mod)
    return mod


@cache
def ground_truth() -> dict:
    return json.loads((ROOM / "ground_truth.json").read_text())


def true_model() -> Model:
    gt = ground_truth()
    markers = {k: np.asarray(v, float) for k, v in gt["markers"].items()}
    return model_from_dict(gt["model"]["nodes"], markers, gt["model"].get("relations"))


def true_cameras() -> list[ImageCamera]:
    """The photos' true cameras, each with its lens's true distortion (k1 = 0: a pinhole)."""
    gt = ground_truth()
    return [ImageCamera(pid, np.asarray(p["K"], float), np.asarray(p["R"], float), np.asarray(p["C"], float),
                        int(p["width"]), int(p["height"]),
                        lens=Lens(float(true_k1(p)), float((p.get("distortion") or {}).get("k2", 0.0))))
            for pid, p in gt["photos"].items()]


def true_k1(photo: dict) -> float:
    """A ground-truth photo's lens distortion (the division model's k1); 0 in a truth written
    before the example had a lens."""
    return float((photo.get("distortion") or {}).get("k1", 0.0))


def true_corner_displacement_px(photo: dict) -> float:
    """How far a ground-truth photo's lens moves its farthest corner from where a pinhole would put it."""
    return float((photo.get("distortion") or {}).get("corner_displacement_px", 0.0))


def true_exif_error_rel(photo: dict) -> float:
    """How far a ground-truth photo's EXIF focal length is off its true f, relative."""
    return float(photo.get("exif_focal_error_rel", 0.0))


def photo_path(photo_id: str) -> Path:
    return ROOM / "photos" / f"{photo_id}.jpg"


#: Samples per texel side when averaging the true texture over a texel's area.
TRUTH_SUPERSAMPLE = 4
#: A PSNR estimated from every n-th texel (:func:`truth_texels`): with n = 7, some 10⁵ texels fix
#: it within a few hundredths of a dB, at a seventh of the cost of the whole page (the true texture
#: costs TRUTH_SUPERSAMPLE² shadings per texel: most of the demo's time, shading every one).
PSNR_SAMPLE_EVERY = 7


def truth_texels(mesh, geometry: dict, faces, every: int = 1,
                 keep: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The true linear colour (before exposure) of every texel of one page, averaged over the
    texel's square (TRUTH_SUPERSAMPLE² samples): the ideal texel at this density. Also the mask of
    texels that lie on a quad of the generator's scene (every model face does, except hidden ones).

    ``geometry`` is an extractor's ``geometry(page)`` (position, face, normal per texel); the
    texel's steps along atlas x and y come from its face's rectangle. ``every``: shade only every
    n-th texel of the page in raster order (the mask leaves the others out), for a PSNR estimated
    from a sample: with n = 7 (prime, so the sample does not beat with the textures' periods) the
    sample still holds some 10⁵ texels, which fixes the mean square error within a few tenths of a
    percent (a few hundredths of a dB). ``keep``: only these texels (h, w) are shaded (the others
    are left out of the mask, as texels off every face are): the ones a caller will compare.
    """
    gen = generator()
    scene = gen.build_scene()
    X = geometry["position"].astype(float)
    F = geometry["face"]
    N = geometry["normal"].astype(float)
    h, w = F.shape
    e_u = np.zeros((h, w, 3))
    e_v = np.zeros((h, w, 3))
    for f in faces:  # flat faces: one step per face, from its chart's corners
        x0, y0, fw, fh = f.rect
        P = X[y0:y0 + fh, x0:x0 + fw]
        on = F[y0:y0 + fh, x0:x0 + fw] == f.id
        if on.sum() < 4 or fw < 2 or fh < 2:
            continue
        du = (P[:, 1:] - P[:, :-1])[on[:, 1:] & on[:, :-1]]
        dv = (P[1:] - P[:-1])[on[1:] & on[:-1]]
        if len(du) and len(dv):
            e_u[y0:y0 + fh, x0:x0 + fw] = np.median(du, axis=0)
            e_v[y0:y0 + fh, x0:x0 + fw] = np.median(dv, axis=0)
    flat = (F > 0).ravel()
    if keep is not None:
        flat &= np.asarray(keep, bool).ravel()
    if every > 1:
        flat &= np.arange(flat.size) % every == 0
    Xf, Nf, eu, ev = X.reshape(-1, 3)[flat], N.reshape(-1, 3)[flat], e_u.reshape(-1, 3)[flat], e_v.reshape(-1, 3)[flat]
    quad = np.full(len(Xf), -1)
    for qi, q in enumerate(scene["quads"]):
        rel = Xf - q["corner"]
        a = rel @ q["edge1"] / (q["edge1"] @ q["edge1"])
        b = rel @ q["edge2"] / (q["edge2"] @ q["edge2"])
        on = (np.abs(rel @ q["normal"]) < 2e-3) & (Nf @ q["normal"] > 0.99)
        on &= (a >= -1e-3) & (a <= 1 + 1e-3) & (b >= -1e-3) & (b <= 1 + 1e-3)
        quad[on & (quad < 0)] = qi
    ok = quad >= 0
    colour = np.zeros((len(Xf), 3))
    offs = (np.arange(TRUTH_SUPERSAMPLE) + 0.5) / TRUTH_SUPERSAMPLE - 0.5
    for du in offs:
        for dv in offs:
            colour[ok] += gen.shade_hits(scene, quad[ok], Xf[ok] + du * eu[ok] + dv * ev[ok])
    colour /= TRUTH_SUPERSAMPLE**2
    out = np.zeros((h * w, 3))
    mask = np.zeros(h * w, bool)
    out[flat], mask[flat] = colour, ok
    return out.reshape(h, w, 3), mask.reshape(h, w)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """Peak signal-to-noise ratio of two 8-bit colour arrays (n, 3), in dB."""
    mse = np.mean((a.astype(float) - b.astype(float)) ** 2)
    return float(10 * np.log10(255.0**2 / mse))


def texture_psnr(model: Model, result, exposures: dict[str, float], every: int = 1) -> float:
    """PSNR (dB) of an extraction's atlases against the true textures over the texels some photo
    saw, the truth scaled to the photos' geometric-mean exposure (the level the merge normalises
    to; absolute exposure is not observable from the photos). ``every``: estimate it from every
    n-th texel (:func:`truth_texels`)."""
    from vebuild.gl import headless_context
    from vebuild.texture import layout as lay
    from vebuild.texture.gpu import Extractor
    from vebuild.texture.merge import linear_to_srgb8, unseen_texels
    from vebuild.texture.options import Options

    G = float(np.exp(np.mean(np.log([exposures[c] for c in result.order]))))
    mesh = lay.scene_mesh(model, result.faces)
    ex = Extractor(headless_context(), mesh, Options())
    try:
        geo = [ex.geometry(p) for p in range(len(mesh.pages))]
    finally:
        ex.release()
    got, want = [], []
    for p, g in enumerate(geo):
        cov = result.coverage[p]
        compared = (cov[..., 3] > 0) & ~unseen_texels(cov)
        colour, on_quad = truth_texels(mesh, g, [f for f in result.faces if f.page == p], every, compared)
        seen = on_quad & compared
        got.append(result.atlases[p][seen])
        want.append(linear_to_srgb8(colour * G)[seen])
    return psnr(np.concatenate(got), np.concatenate(want))
