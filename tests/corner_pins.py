"""Click pins on a model's corners: every corner of a node each known camera sees, at its true
pixel plus vebuild.synthetic's click noise (tests/test_hinge_axis.py, tests/test_determination.py)."""

from __future__ import annotations

from typing import Any

import numpy as np

from vebuild.camera import ImageCamera
from vebuild.model.residuals import Pin
from vebuild.synthetic import CLICK_NOISE_PX


def corner_pins(model: Any, cams: dict[str, ImageCamera], node: str, rng: np.random.Generator) -> list[Pin]:
    """Every corner of ``node`` each camera sees, at its true pixel plus the click noise."""
    T = model.world_transforms()[node]
    prim = model.node(node).primitive
    pins = []
    for cam in cams.values():
        for h, X in zip(prim.handle_names(), prim.handles() @ T[:3, :3].T + T[:3, 3], strict=True):
            xc = cam.R @ (X - cam.C)
            uv = (cam.K @ xc)[:2] / xc[2]
            if xc[2] > 0.3 and 0 <= uv[0] <= cam.width and 0 <= uv[1] <= cam.height:
                pins.append(Pin(cam.id, node, h, uv + rng.normal(0.0, CLICK_NOISE_PX, 2)))
    return pins
