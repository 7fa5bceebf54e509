"""The lens of the tests: a known barrel distortion in the division model of vebuild/camera.py
(tests/test_distortion_solver.py, tests/test_register.py)."""

from __future__ import annotations

import numpy as np

#: The lens of the tests: barrel distortion moving the photo's corners by this share of their
#: distance from the principal point (1–3 % on a wide-angle lens).
CORNER_SHARE = 0.03


def barrel_k1(K: np.ndarray, width: int, height: int, share: float = CORNER_SHARE) -> float:
    """The division model's k1 (< 0) that moves the farthest corner of the photo inward by
    ``share`` of its distance from the principal point: x_u = x_d / (1 + k1 r²) = (1 + share) x_d."""
    c = K[:2, 2]
    r = max(np.hypot(*(np.array(corner) - c)) for corner in ((0, 0), (width, 0), (0, height), (width, height)))
    return float((1.0 / (1.0 + share) - 1.0) / (r / K[0, 0]) ** 2)
