"""The generated house's photos, rendered and cached for ``vebuild bench house``.

The house and its marks are :func:`vebuild.synthetic.house_layout.house_scene`'s; each photo is a render
of the true model by vebuild's renderer (lit by a sun and the sky, no shadows, one sample per
pixel), from the photo's true camera at its full size, over a procedural atlas (each face its own
colour under a checker of 8 cm squares and fine grain), then blurred (Gaussian, σ 0.7 px), given
sensor noise (2 grey levels) and written as a JPEG (quality 90). The project file (the first guess
as its model) and ``truth.json`` (true nodes, cameras, markers) lie beside the photos.

Cached under ``~/.cache/vebuild/bench-house`` (``VEBUILD_CACHE`` overrides ``~/.cache/vebuild``),
never in the repository; a folder is complete once ``complete.json`` is written (last).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vebuild.project.atomic import write_bytes
from vebuild.resources import cache_dir
from vebuild.synthetic.house import House, write_house_project
from vebuild.synthetic.house_layout import house_scene

#: Bump when the house or its rendering changes: old caches are then not reused.
GENERATOR_VERSION = 1
#: The full house (8 rooms, 13 photos each of 24 MP) and the quick one (the same, 1.5 MP photos).
FULL = {"rows": 2, "cols": 4, "per_room": 13, "width": 6000, "height": 4000}
QUICK = {**FULL, "width": 1500, "height": 1000}
SEED = 2026
TEXELS_PER_METRE = 100.0
BLUR_PX, NOISE_GREY, JPEG_QUALITY = 0.7, 2.0, 90


@dataclass
class CachedHouse:
    folder: Path
    project: Path
    truth: dict[str, Any]
    timings: dict[str, float]


def cache_folder() -> Path:
    return cache_dir() / "bench-house" / f"v{GENERATOR_VERSION}"


def truth_record(house: House) -> dict[str, Any]:
    return {"nodes": house.nodes, "markers": {k: v.tolist() for k, v in house.markers.items()},
            "rooms": {k: {"origin": r.origin.tolist(), "size": list(r.size)} for k, r in house.rooms.items()},
            "cameras": {p.id: {"K": p.K.tolist(), "R": p.R.tolist(), "C": p.C.tolist(), "width": p.width,
                               "height": p.height, "room": house.photo_room[p.id]} for p in house.photos},
            "primitives": house.primitives, "pins": len(house.pins)}


def procedural_pages(model: Any, density: float, seed: int = 5) -> tuple[list[Any], list[np.ndarray]]:
    """The model's faces laid out at ``density`` texels per metre and pages painted with a colour
    per face under a checker and grain."""
    from vebuild.texture import layout as lay

    faces = lay.layout(model, density, 2048, 4096)
    rng = np.random.default_rng(seed)
    pages = [np.full((h, w, 3), 128, np.uint8) for w, h in lay.page_sizes(faces)]
    step = max(1, int(round(0.08 * density)))
    for f in faces:
        x0, y0, fw, fh = f.rect
        checker = ((np.arange(fh)[:, None] // step) + (np.arange(fw)[None, :] // step)) & 1
        colour = rng.uniform(70.0, 220.0, 3)
        grain = rng.normal(0.0, 6.0, (fh, fw, 1))
        pages[f.page][y0:y0 + fh, x0:x0 + fw] = np.clip(colour * (0.8 + 0.2 * checker[..., None]) + grain, 0,
                                                        255).astype(np.uint8)
    return faces, pages


def _lighting() -> Any:
    from vebuild.project.decode import preset_from_record

    return preset_from_record({"name": "sun", "ambient": [0.45, 0.45, 0.45],
                               "lights": [{"type": "directional", "direction": [0.4, 0.25, -1.0], "intensity": 0.7,
                                           "shadows": False}]})


def render_photos(house: House, folder: Path, progress: Callable[[int, int], None] | None = None) -> dict[str, Path]:
    """Render every photo of the house into ``folder`` (JPEG); their paths by id."""
    import cv2

    from vebuild.camera import ImageCamera
    from vebuild.gl.context import headless_context
    from vebuild.render.renderer import Renderer, RenderOptions
    from vebuild.render.scene import scene_from_model

    folder.mkdir(parents=True, exist_ok=True)
    model = house.model()
    faces, pages = procedural_pages(model, TEXELS_PER_METRE)
    record = {"faces": [{"id": f.id, "node": f.node, "face": f.name, "size_m": list(f.size_m), "page": f.page,
                         "rect": list(f.rect)} for f in faces]}
    ctx = headless_context()
    renderer = Renderer(ctx, scene_from_model(model, record, pages), RenderOptions(samples=1, anisotropy=1.0,
                                                                                   shadows=False))
    renderer.set_lighting(_lighting())
    out = {}
    rng = np.random.default_rng(SEED)
    try:
        for k, p in enumerate(house.photos):
            path = folder / f"{p.id}.jpg"
            out[p.id] = path
            if progress:
                progress(k, len(house.photos))
            if path.exists():
                continue
            rendered = renderer.render(ImageCamera(p.id, p.K, p.R, p.C, p.width, p.height)).astype(np.float32)
            img = np.asarray(cv2.GaussianBlur(rendered, (0, 0), BLUR_PX), np.float32)
            img += rng.normal(0.0, NOISE_GREY, img.shape[:2])[..., None].astype(np.float32)
            ok, data = cv2.imencode(".jpg", np.clip(img, 0, 255).astype(np.uint8)[..., ::-1],
                                    [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            if not ok:
                raise RuntimeError(f"could not encode {path}")
            write_bytes(path, data.tobytes())
    finally:
        renderer.release()
    return out


def build(folder: Path, spec: dict[str, Any], seed: int = SEED, furniture: str = "full",
          progress: Callable[[str, int, int], None] | None = None) -> CachedHouse:
    """Generate the house of ``spec`` into ``folder``: photos, project, truth; timed."""
    t0 = time.perf_counter()
    house = house_scene(np.random.default_rng(seed), spec["rows"], spec["cols"], spec["per_room"], spec["width"],
                        spec["height"], furniture=furniture)
    t1 = time.perf_counter()
    files = render_photos(house, folder / "photos", (lambda k, n: progress("rendering photos", k, n)) if progress
                          else None)
    t2 = time.perf_counter()
    project = write_house_project(folder, house, files)
    t3 = time.perf_counter()
    truth = truth_record(house)
    write_bytes(folder / "truth.json", json.dumps(truth).encode())
    timings = {"marks_s": t1 - t0, "render_s": t2 - t1, "project_s": t3 - t2, "total_s": time.perf_counter() - t0}
    return CachedHouse(folder, project, truth, timings)


def cached_house(quick: bool = False, progress: Callable[[str, int, int], None] | None = None) -> CachedHouse:
    """The house of ``vebuild bench house`` (QUICK with ``quick``), generated once and cached."""
    spec = QUICK if quick else FULL
    folder = cache_folder() / f"{'quick' if quick else 'full'}-s{SEED}"
    done = folder / "complete.json"
    if done.exists():
        info = json.loads(done.read_text())
        return CachedHouse(folder, folder / "house.vebuild.json", json.loads((folder / "truth.json").read_text()),
                           info["timings"])
    house = build(folder, spec, SEED, progress=progress)
    write_bytes(done, json.dumps({"spec": spec, "seed": SEED, "timings": house.timings}).encode())
    return house
