"""The accuracy the calibration and modelling issues claim, for clicks with 0.7 px of noise: one
statement, which every test of those claims imports."""

from __future__ import annotations

#: A camera's focal length, relative.
FOCAL_TOL_REL = 0.01
#: A camera's rotation, degrees.
ROTATION_TOL_DEG = 0.3
#: A camera's position, as a share of the room's diagonal.
POSITION_TOL_REL = 0.01


def dimension_tolerance(size_m: float) -> float:
    """A primitive's dimension: 1 cm per metre of the dimension, 1 cm below a metre."""
    return 0.01 * max(size_m, 1.0)
