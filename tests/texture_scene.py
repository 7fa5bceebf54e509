"""The example room's ground truth for texture tests: see vebuild.actions.example_truth."""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
from PIL import Image

from vebuild.actions.example_truth import (  # noqa: F401
    TRUTH_SUPERSAMPLE,
    generator,
    ground_truth,
    photo_path,
    psnr,
    texture_psnr,
    true_cameras,
    true_model,
    truth_texels,
)


def recorded_result(folder: Path, record: dict) -> SimpleNamespace:
    """A project's texture record (FORMAT.md "textures") and its page files, read back in the shape
    texture_psnr takes: the photos' order, the faces' layout, each page's atlas and coverage."""
    from vebuild.texture.layout import Face

    faces = [Face(int(f["id"]), f["node"], f["face"], tuple(f["size_m"]), int(f["page"]), tuple(f["rect"]))
             for f in record["faces"]]
    pages = record["pages"]
    with_rgb = [np.asarray(Image.open(folder / p["atlas"]).convert("RGB")) for p in pages]
    coverage = [np.asarray(Image.open(folder / p["coverage"]).convert("RGBA")) for p in pages]
    order = [p["id"] for p in sorted(record["photos"], key=lambda p: p["order"])]
    return SimpleNamespace(order=order, faces=faces, atlases=with_rgb, coverage=coverage)
