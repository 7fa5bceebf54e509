"""The scene of the render tests and the camera they look at it with (tests/test_render.py,
tests/test_window.py, tests/test_distortion_gl.py)."""

from __future__ import annotations

import numpy as np

from vebuild.camera import ImageCamera, look_rotation
from vebuild.model.scene import model_from_dict


def box_on_floor_model():
    """A 4 × 3 m floor and a box resting on it, turned 25°: the scene of the render tests."""
    return model_from_dict([
        {"name": "floor", "primitive": {"type": "quad", "params": {"width": 4.0, "depth": 3.0}},
         "joint": {"type": "fixed", "translation": [2.0, 1.5, 0.0], "rotation_deg": [0, 0, 0]}},
        {"name": "box", "parent": "floor", "primitive": {"type": "box", "params": {"width": 0.8, "depth": 0.6,
                                                                                   "height": 0.7}},
         "joint": {"type": "rests_on", "face": "top", "position": [0.3, -0.1], "yaw_deg": 25.0}},
    ])


def off_centre_camera(position, target, f=300.0, w=320, h=240, name="test"):
    """A camera at ``position`` looking at ``target``, its principal point a few pixels off centre."""
    R = look_rotation(np.subtract(target, position))
    return ImageCamera(name, np.array([[f, 0, w / 2 + 3.3], [0, f, h / 2 - 2.1], [0, 0, 1]]), R,
                       np.asarray(position, float), w, h)
