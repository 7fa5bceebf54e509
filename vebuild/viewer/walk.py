"""The walker: a person of eye height 1.6 m moving over the floor, or flying (pure numpy).

Walking keeps the eyes at ``eye_height`` above the floor (z = 0) and moves parallel to it, in
the direction the walker faces; the body is a vertical cylinder of ``radius`` from knee height to
just above the eyes, so furniture lower than the knee (a rug, the floor itself) is stepped over
and anything else stops it. A move that would enter an object is resolved by pushing the body back
out along the object's surface normal, so the walker slides along a wall instead of stopping dead.
Moves are split into steps shorter than half the radius, so a fast walker cannot pass through a
thin wall. Flying moves freely in three dimensions, through everything.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera, fov_to_focal, intrinsic_matrix, rotation_from_ypr
from vebuild.model.collide import Footprint, circle_push, z_overlap

Array = NDArray[np.float64]

EYE_HEIGHT_M = 1.6
WALK_SPEED = 1.4  # m/s, a walking pace
RUN_SPEED = 4.0  # m/s
BODY_RADIUS_M = 0.2
KNEE_HEIGHT_M = 0.3  # objects entirely below this are stepped over
#: Mouse look: radians per pixel of mouse movement.
LOOK_SENSITIVITY = 0.003
PITCH_LIMIT = math.radians(89.0)


@dataclass
class Walker:
    """Where the viewer's eye is and where it looks. ``yaw``/``pitch`` as in camera.rotation_from_ypr."""

    position: Array = field(default_factory=lambda: np.array([0.0, 0.0, EYE_HEIGHT_M]))
    yaw: float = 0.0
    pitch: float = 0.0
    fly: bool = False
    eye_height: float = EYE_HEIGHT_M
    radius: float = BODY_RADIUS_M
    fov_deg: float = 75.0

    def camera(self, width: int, height: int, name: str = "walker") -> ImageCamera:
        f = fov_to_focal(math.radians(self.fov_deg), width)
        K = intrinsic_matrix(f, width / 2, height / 2)
        return ImageCamera(name, K, rotation_from_ypr(self.yaw, self.pitch, 0.0), self.position.copy(), width, height)

    def look(self, dx_px: float, dy_px: float, sensitivity: float = LOOK_SENSITIVITY) -> None:
        """Turn by a mouse movement: right turns right, down looks down (as in games)."""
        self.yaw -= dx_px * sensitivity
        self.pitch = float(np.clip(self.pitch - dy_px * sensitivity, -PITCH_LIMIT, PITCH_LIMIT))

    def set_fly(self, fly: bool) -> None:
        """Switch between flying and walking; landing puts the eyes at eye height again."""
        self.fly = fly
        if not fly:
            self.position[2] = self.eye_height

    def place(self, C: Array, R: Array | None = None) -> None:
        """Stand at a camera's centre (walking: on the floor below it) looking along its axis."""
        from vebuild.camera import ypr_from_rotation

        self.position = np.asarray(C, float).copy()
        if R is not None:
            yaw, pitch, _ = ypr_from_rotation(R)
            self.yaw, self.pitch = float(yaw), float(pitch)
        if not self.fly:
            self.position[2] = self.eye_height

    def move(self, forward: float, right: float, up: float, dt: float, run: bool,
             obstacles: Sequence[Footprint]) -> None:
        """Move for ``dt`` seconds with inputs in [−1, 1] (forward, right, up: fly only)."""
        speed = (RUN_SPEED if run else WALK_SPEED) * dt
        fwd = np.array([math.cos(self.yaw), math.sin(self.yaw), 0.0])
        rgt = np.array([math.sin(self.yaw), -math.cos(self.yaw), 0.0])
        if self.fly:
            look = rotation_from_ypr(self.yaw, self.pitch, 0.0)[2]
            d = forward * look + right * rgt + up * np.array([0.0, 0.0, 1.0])
            n = np.linalg.norm(d)
            if n > 1.0:
                d /= n
            self.position = self.position + speed * d
            return
        d = forward * fwd + right * rgt
        n = np.linalg.norm(d)
        if n == 0.0:
            return
        if n > 1.0:
            d /= n
        self.walk(speed * d[:2], obstacles)

    def walk(self, delta_xy: Array, obstacles: Sequence[Footprint]) -> None:
        """Move the body by ``delta_xy`` over the floor, sliding along what it meets."""
        body_lo, body_hi = KNEE_HEIGHT_M, self.eye_height + 0.1
        solid = [o.hull for o in obstacles if z_overlap(o, body_lo, body_hi)]
        delta = np.asarray(delta_xy, float)
        steps = max(1, math.ceil(np.linalg.norm(delta) / (0.5 * self.radius)))
        p = self.position[:2].copy()
        for _ in range(steps):
            p = p + delta / steps
            for _ in range(4):  # a corner needs two pushes; a few rounds settle any order
                moved = False
                for hull in solid:
                    push = circle_push(p, self.radius, hull)
                    if push.any():
                        p = p + push * (1.0 + 1e-9)
                        moved = True
                if not moved:
                    break
        self.position = np.array([p[0], p[1], self.eye_height])
