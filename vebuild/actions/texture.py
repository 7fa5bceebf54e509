"""``vebuild texture``: extract the model's textures from the photos and record them in the project.

Writes ``textures/atlas_K.png`` (sRGB) and ``textures/coverage_K.png`` (RGBA, see
:mod:`vebuild.texture.merge`) next to the project file, one pair per atlas page, and the
``textures`` record (FORMAT.md). Nothing is written unless the whole extraction succeeds; every
file is written to a temporary name first and moved into place.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from vebuild import __version__
from vebuild.actions.solve import cameras_from_calibration, load_model
from vebuild.camera import ImageCamera
from vebuild.errors import VebuildError
from vebuild.project import Project, canonical_input_hash, sha256_file
from vebuild.texture.extract import PhotoSource, TextureResult, extract
from vebuild.texture.gpu import Options, Timings
from vebuild.texture.merge import linear_to_srgb8

TEXTURE_DIR = "textures"


@contextmanager
def progress_bar(enabled: bool, desc: str = "texturing",
                 unit: str = "photo") -> Iterator[Callable[[int, int, str], None]]:
    """A tqdm bar, as a ``progress(done, total, label)`` callback: over photos for
    :func:`texture_project`, over frames for a video (``desc``, ``unit``)."""
    from tqdm import tqdm

    bar = tqdm(total=None, desc=desc, unit=unit, disable=not enabled)

    def step(done: int, total: int, photo: str) -> None:
        bar.total, bar.n = total, done
        bar.set_postfix_str(photo)
        bar.refresh()

    try:
        yield step
    finally:
        bar.close()


def texture_project(project: Project, options: Options | None = None,
                    progress: Callable[[int, int, str], None] | None = None,
                    timings: Timings | None = None) -> tuple[dict[str, Any], TextureResult]:
    """Extract, write the PNGs and set ``project.data['textures']``; returns (record, result)."""
    options = options or Options()
    _check_options(project, options)
    data = project.data
    cams = cameras_from_calibration(project)
    model, _, _ = load_model(project)
    if not any(n.primitive is not None for n in model.nodes):
        raise VebuildError(f"{project.path}: $.model.nodes: the model has no primitives to texture")
    cameras, sources = [], {}
    for i, p in enumerate(data["photos"]):
        if p["id"] not in cams:
            continue
        c = cams[p["id"]]
        cameras.append(ImageCamera(p["id"], c.K, c.R, c.C, p["width"], p["height"]))
        sources[p["id"]] = PhotoSource(p["id"], project.photo_path(p), p["sha256"], f"$.photos[{i}]", str(project.path))
    result = extract(model, cameras, sources, options, progress, timings)
    record = _write(project, result, options)
    data["textures"] = record
    return record, result


def _check_options(project: Project, o: Options) -> None:
    def bad(field: str, expected: str, value: object) -> VebuildError:
        return VebuildError(f"{project.path}: texture option {field}: expected {expected}, got {value!r}")
    if not (np.isfinite(o.texels_per_metre) and o.texels_per_metre > 0):
        raise bad("texels_per_metre", "a positive number", o.texels_per_metre)
    if int(o.max_face_texels) < 1:
        raise bad("max_face_texels", "at least 1", o.max_face_texels)
    if o.mode not in ("texture", "average"):
        raise bad("mode", "'texture' or 'average'", o.mode)
    if o.fill not in ("push-pull", "average"):
        raise bad("fill", "'push-pull' or 'average'", o.fill)
    if not (0.0 <= o.drop_ratio < 1.0):
        raise bad("drop_ratio", "a number in [0, 1)", o.drop_ratio)
    if not (o.detail_sharpness >= 1.0):
        raise bad("detail_sharpness", "at least 1", o.detail_sharpness)
    if not (o.erode_px >= 0.0):
        raise bad("erode_px", "0 or more pixels", o.erode_px)


def _write(project: Project, result: TextureResult, options: Options) -> dict[str, Any]:
    folder = project.folder / TEXTURE_DIR
    folder.mkdir(exist_ok=True)
    old = project.data.get("textures") or {}
    pages = []
    written: list[tuple[Path, Path]] = []
    try:
        for k, (atlas, cov) in enumerate(zip(result.atlases, result.coverage, strict=True)):
            entry: dict[str, Any] = {"width": int(atlas.shape[1]), "height": int(atlas.shape[0])}
            for key, img, mode in (("atlas", atlas, "RGB"), ("coverage", cov, "RGBA")):
                final = folder / f"{key}_{k}.png"
                tmp = final.with_name(final.name + ".tmp")
                Image.fromarray(img, mode).save(tmp, format="PNG", optimize=False)
                written.append((tmp, final))
                entry[key] = f"{TEXTURE_DIR}/{final.name}"
                entry[f"{key}_sha256"] = sha256_file(tmp)
            pages.append(entry)
    except OSError as e:
        for tmp, _ in written:
            tmp.unlink(missing_ok=True)
        raise VebuildError(f"{folder}: cannot write the textures: {e.strerror or e}") from None
    for tmp, final in written:
        os.replace(tmp, final)
    keep = {final.name for _, final in written}
    for page in old.get("pages", []):  # pages of an earlier, larger extraction
        for key in ("atlas", "coverage"):
            name = Path(str(page.get(key, ""))).name
            if name and name not in keep and name.endswith(".png"):
                (folder / name).unlink(missing_ok=True)
    faces = []
    for f in result.faces:
        st = result.face_stats[f.id]
        mean = st.mean_linear
        faces.append({
            "id": f.id, "node": f.node, "face": f.name, "page": f.page, "rect": list(f.rect),
            "size_m": [round(v, 6) for v in f.size_m],
            "texels_per_metre": [round(v, 3) for v in f.texels_per_metre],
            "seen_fraction": round(st.seen_fraction, 6),
            "photos": result.face_photos[f.id],
            "average_colour_srgb": [int(v) for v in linear_to_srgb8(mean)] if np.isfinite(mean).all() else None,
        })
    photos = [{"id": pid, "sha256": project.photo(pid)["sha256"], "order": k,
               "gain": [round(float(g), 6) for g in result.gains[pid]], "overlap_texels": result.overlap.get(pid, 0)}
              for k, pid in enumerate(result.order)]
    unseen = [f"{f.node}.{f.name}" for f in result.unseen_faces]
    warnings = [f"{len(unseen)} face(s) seen by no photo, filled with their node's average colour: "
                + ", ".join(unseen)] if unseen else []
    warnings += [f"photo {p['id']}: too little overlap with the photos before it to compensate its exposure"
                 for p in photos[1:] if options.exposure and p["overlap_texels"] < 64]
    return {
        "software": f"vebuild {__version__}",
        "input_hash": canonical_input_hash(project.data),
        "options": options.as_dict(),
        "page_size_limit": result.page_size,
        "exposure_scale": round(result.exposure_scale, 6),
        "pages": pages,
        "photos": photos,
        "faces": faces,
        "warnings": warnings,
    }
