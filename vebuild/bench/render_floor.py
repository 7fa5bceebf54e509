"""The floor of ``vebuild bench render``: the least a frame of the same triangles can cost here.

A minimal moderngl program, in the same process and context as the renderer: every triangle of
the scene's mesh (in the mesh's order, none culled), positions and atlas coordinates only, one
texture (the scene's first atlas page, 8-bit RGB with mipmaps, sampled as the frame loop samples:
bilinear within the nearest level), no lighting, no sRGB encoding, depth-tested into a
1280×720 RGBA target like the frame loop's. The renderer's frame loop is reported as a share of
its fps: a share measured frame by frame beside the floor, so that other work on the machine,
which slows both alike, cancels out.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import moderngl
import numpy as np

from vebuild.camera import ImageCamera, depth_range, gl_projection, view_matrix
from vebuild.render.scene import RenderScene

VERTEX = """#version 330 core
uniform mat4 mvp;
in vec3 in_position;
in vec2 in_uv;
out vec2 v_uv;
void main() { v_uv = in_uv; gl_Position = mvp * vec4(in_position, 1.0); }
"""
FRAGMENT = """#version 330 core
uniform sampler2D page;
in vec2 v_uv;
out vec4 out_colour;
void main() { out_colour = texture(page, v_uv); }
"""


class Floor:
    """The floor program drawing ``scene`` from ``cam`` (see the module's docstring)."""

    def __init__(self, ctx: moderngl.Context, scene: RenderScene, cam: ImageCamera):
        self.ctx = ctx
        mesh = scene.mesh
        if scene.pages:
            page = np.ascontiguousarray(scene.pages[0])
            h, w = page.shape[:2]
            uv = mesh.atlas / np.array([w, h], float)
        else:
            page, (h, w), uv = np.full((1, 1, 3), 190, np.uint8), (1, 1), np.zeros((len(mesh.vertices), 2))
        self.texture = ctx.texture((w, h), 3, page.tobytes())
        self.texture.build_mipmaps()
        self.texture.filter = (moderngl.LINEAR_MIPMAP_NEAREST, moderngl.LINEAR)
        self.program = ctx.program(vertex_shader=VERTEX, fragment_shader=FRAGMENT)
        data = np.hstack([mesh.vertices, uv]).astype("f4")
        self.vbo = ctx.buffer(data.tobytes())
        self.ibo = ctx.buffer(mesh.triangles.astype("i4").tobytes())
        self.vao = ctx.vertex_array(self.program, [(self.vbo, "3f 2f", "in_position", "in_uv")], index_buffer=self.ibo)
        self.n = int(mesh.triangles.size)
        lo, hi = scene.bounds()
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        near, far = depth_range(cam.R, cam.C, corners)
        mvp = gl_projection(cam.K, cam.width, cam.height, near, far) @ view_matrix(cam.R, cam.C)
        self.program["mvp"].write(mvp.T.astype("f4").tobytes())  # type: ignore[union-attr]
        self.colour = ctx.texture((cam.width, cam.height), 4)
        self.depth = ctx.depth_renderbuffer((cam.width, cam.height))
        self.fbo = ctx.framebuffer([self.colour], self.depth)

    def frame(self) -> None:
        """One frame, finished (no read-back)."""
        self.fbo.use()
        self.fbo.clear(0.15, 0.15, 0.17, 0.0, depth=1.0)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.texture.use(location=0)
        self.vao.render(moderngl.TRIANGLES, vertices=self.n)
        self.ctx.disable(moderngl.DEPTH_TEST)
        self.ctx.finish()

    def release(self) -> None:
        for r in (self.vao, self.vbo, self.ibo, self.fbo, self.colour, self.depth, self.texture, self.program):
            r.release()


def paired_fps(draw: Callable[[], object], floor: Callable[[], object], frames: int, seconds: float,
               max_frames: int) -> tuple[float, float, float]:
    """(fps of ``draw``, fps of ``floor``, their ratio): frames of the two alternate (after one
    warm-up each), each fps from its fastest frame, the ratio the median of the frame pairs' ratios
    (each pair drawn under the same load)."""
    draw()
    floor()
    a: list[float] = []
    b: list[float] = []
    end = time.perf_counter() + seconds
    while len(a) < frames or (time.perf_counter() < end and len(a) < max_frames):
        for sink, f in ((a, draw), (b, floor)):
            t = time.perf_counter()
            f()
            sink.append(time.perf_counter() - t)
    ratio = float(np.median(np.array(b) / np.array(a)))
    return 1.0 / min(a), 1.0 / min(b), ratio
