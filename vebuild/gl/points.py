"""Points drawn as GL points over a rendered frame: a registered laser scan in the walk-through
and the modelling screen (:func:`vebuild.analysis.scans.scan_points_world` gives them).

The frame's depth buffer, where the frame was drawn into the same target with the same camera and
depth range, hides the points behind the model; each point is pulled toward the eye along its
ray by ``DEPTH_PULL`` of its distance (its pixel unchanged), so that a point on a face, or a
scan's noise behind it, is not hidden by that face: 1.5 cm at 3 m.
"""

from __future__ import annotations

import moderngl
import numpy as np
from numpy.typing import ArrayLike

from vebuild.camera import ImageCamera, gl_projection, view_matrix
from vebuild.gl.shaders import load_program, uniform

#: Side of a drawn point, pixels.
POINT_PX = 2.0
#: The share of its distance a point is pulled toward the eye before the depth test.
DEPTH_PULL = 0.005


class PointLayer:
    """A set of coloured points on the GPU, drawn with :meth:`draw`."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.program = load_program(ctx, "points")
        self._vbo: moderngl.Buffer | None = None
        self._vao: moderngl.VertexArray | None = None
        self.count = 0

    def set_points(self, points: ArrayLike, colours: ArrayLike) -> None:
        """(n, 3) world points and (n, 3) sRGB colours (0–255)."""
        P = np.asarray(points, np.float32).reshape(-1, 3)
        C = np.asarray(colours, np.float32).reshape(-1, 3) / 255.0
        self.release()
        self.count = len(P)
        if not self.count:
            return
        self._vbo = self.ctx.buffer(np.hstack([P, C]).astype("f4").tobytes())
        self._vao = self.ctx.vertex_array(self.program, [(self._vbo, "3f 3f", "in_position", "in_colour")])

    def draw(self, cam: ImageCamera, near: float, far: float, flip: bool = True, depth_test: bool = True,
             point_px: float = POINT_PX) -> None:
        """Draw the points as ``cam`` sees them into the bound framebuffer's viewport."""
        if self._vao is None:
            return
        prog = self.program
        uniform(prog, "view").write(view_matrix(cam.R, cam.C).T.astype("f4").tobytes())
        P = gl_projection(cam.K, cam.width, cam.height, near, far, flip_y=flip)
        uniform(prog, "projection").write(P.T.astype("f4").tobytes())
        uniform(prog, "point_size").value = float(point_px)
        uniform(prog, "depth_pull").value = DEPTH_PULL if depth_test else 0.0
        self.ctx.enable(moderngl.PROGRAM_POINT_SIZE)
        if depth_test:
            self.ctx.enable(moderngl.DEPTH_TEST)
        self._vao.render(moderngl.POINTS, vertices=self.count)
        self.ctx.disable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.PROGRAM_POINT_SIZE)

    def release(self) -> None:
        if self._vao is not None:
            self._vao.release()
        if self._vbo is not None:
            self._vbo.release()
        self._vao = self._vbo = None
        self.count = 0
