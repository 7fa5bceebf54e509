"""The example room at its true geometry and cameras, for texture tests (no calibration noise).

``truth()`` gives the true model (ground_truth.json's nodes), the true cameras, the photo paths and
the generator module (scenes/generate_room.py, imported by path: it does not import vebuild).
"""

from __future__ import annotations

import importlib.util
import json
import sys
from functools import cache
from pathlib import Path
from types import ModuleType

import numpy as np

from vebuild.model.scene import Model, model_from_dict
from vebuild.texture.gpu import PhotoCamera

ROOT = Path(__file__).resolve().parent.parent
ROOM = ROOT / "scenes" / "room"


@cache
def generator() -> ModuleType:
    spec = importlib.util.spec_from_file_location("generate_room", ROOT / "scenes" / "generate_room.py")
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
    return model_from_dict(gt["model"]["nodes"], markers)


def true_cameras() -> list[PhotoCamera]:
    gt = ground_truth()
    return [PhotoCamera(pid, np.asarray(p["K"], float), np.asarray(p["R"], float), np.asarray(p["C"], float),
                        int(p["width"]), int(p["height"])) for pid, p in gt["photos"].items()]


def photo_path(photo_id: str) -> Path:
    return ROOM / "photos" / f"{photo_id}.jpg"
