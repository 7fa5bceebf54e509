"""The photo on the GPU and its pyramid: one sRGB texture and two half-float textures that stack
the odd and the even levels (the layout ``shaders/pyramid.frag`` and ``texel.frag`` read)."""

from __future__ import annotations

import moderngl
import numpy as np
from numpy.typing import NDArray

from vebuild.gl.shaders import set_uniforms
from vebuild.texture import MAX_LEVELS

GL_SRGB8 = 0x8C41

#: A level's width, height and first row in its stacked texture.
Level = tuple[int, int, int]


def fullscreen_vao(ctx: moderngl.Context, cache: dict[int, moderngl.VertexArray],
                   prog: moderngl.Program) -> moderngl.VertexArray:
    """The attribute-less vertex array that draws ``fullscreen.vert``'s one triangle with ``prog``."""
    if id(prog) not in cache:
        cache[id(prog)] = ctx.vertex_array(prog, [])
    return cache[id(prog)]


class PhotoPyramid:
    """One photo at a time: written, reduced level by level, and freed."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.photo: moderngl.Texture | None = None
        #: (odd levels, even levels, each level's (w, h, y0)); level 0 is the photo itself.
        self.stack: tuple[moderngl.Texture, moderngl.Texture, list[Level]] | None = None
        self._fbos: list[moderngl.Framebuffer] = []
        self.ready = False

    def write(self, pixels: NDArray[np.uint8], finish: bool = False) -> None:
        """Put (height, width, 3) uint8 sRGB pixels in the photo texture (its pyramid is then stale)."""
        h, w = pixels.shape[:2]
        self.ready = False
        if self.photo is None or self.photo.size != (w, h):
            if self.photo is not None:
                self.photo.release()
            self.photo = self.ctx.texture((w, h), 3, internal_format=GL_SRGB8)
            self.photo.repeat_x = self.photo.repeat_y = False
        self.photo.write(np.ascontiguousarray(pixels))
        if finish:
            self.ctx.finish()

    def build(self, prog: moderngl.Program, vao: moderngl.VertexArray) -> None:
        """Reduce the photo into its levels with the ``pyramid`` program drawn by ``vao``."""
        assert self.photo is not None
        w, h = self.photo.size
        sizes = [(w, h)]
        while len(sizes) < MAX_LEVELS and max(sizes[-1]) > 1:
            sizes.append(((sizes[-1][0] + 1) // 2, (sizes[-1][1] + 1) // 2))
        y0 = [0] * len(sizes)
        heights = {1: 0, 0: 0}
        for k in range(1, len(sizes)):
            y0[k] = heights[k & 1]
            heights[k & 1] += sizes[k][1]
        need = ((sizes[1][0] if len(sizes) > 1 else 1, max(1, heights[1])),
                (sizes[2][0] if len(sizes) > 2 else 1, max(1, heights[0])))
        if self.stack is None or (self.stack[0].size, self.stack[1].size) != need:
            self._release_stack()
            odd, even = (self.ctx.texture(s, 4, dtype="f2") for s in need)
            for t in (odd, even):
                t.repeat_x = t.repeat_y = False
            self.stack = (odd, even, [])
            self._fbos = [self.ctx.framebuffer(color_attachments=[t]) for t in (odd, even)]
            for fbo in self._fbos:  # a clamped bilinear sample may touch (at weight 0) a texel
                fbo.clear(0.0, 0.0, 0.0, 0.0)  # no level writes: it must not be NaN
        odd, even, _ = self.stack
        self.stack = (odd, even, [(s[0], s[1], y) for s, y in zip(sizes, y0, strict=True)])
        self.ctx.disable(moderngl.BLEND)
        self.ctx.disable(moderngl.DEPTH_TEST)
        for k in range(1, len(sizes)):
            src = self.photo if k == 1 else (odd if (k - 1) & 1 else even)
            fbo = self._fbos[0 if k & 1 else 1]
            fbo.use()
            fbo.viewport = (0, y0[k], sizes[k][0], sizes[k][1])
            src.use(0)
            set_uniforms(prog, source=0, source_size=(float(sizes[k - 1][0]), float(sizes[k - 1][1])),
                         source_y0=float(y0[k - 1] if k > 1 else 0),
                         source_texture=(float(src.width), float(src.height)), target_y0=float(y0[k]))
            vao.render(moderngl.TRIANGLES, vertices=3)
        self.ready = True

    def bind(self, prog: moderngl.Program, values: dict[str, object]) -> None:
        """Bind the photo (unit 1) and its levels (units 2, 3) and add their uniforms to ``values``,
        if ``prog`` samples the photo and there is a pyramid."""
        if self.stack is None or self.photo is None or "photo" not in prog:
            return
        odd, even, levels = self.stack
        self.photo.use(1)
        odd.use(2)
        even.use(3)
        sizes = np.zeros((MAX_LEVELS, 2), "f4")
        y0 = np.zeros(MAX_LEVELS, "f4")
        for k, (w, h, y) in enumerate(levels):
            sizes[k], y0[k] = (w, h), y
        values.update(photo=1, pyramid_odd=2, pyramid_even=3, odd_size=(float(odd.width), float(odd.height)),
                      even_size=(float(even.width), float(even.height)), levels=len(levels),
                      level_size=sizes, level_y0=y0)

    def _release_stack(self) -> None:
        if self.stack is not None:
            for t in self.stack[:2]:
                t.release()
            for f in self._fbos:
                f.release()
        self.stack, self._fbos = None, []

    def free_photo(self) -> None:
        """Free the photo but keep its levels' targets for the next photo of its size (the caller
        has unbound them); :meth:`write` makes a new one."""
        if self.photo is not None:
            self.photo.release()
            self.photo = None
        self.ready = False

    def release(self) -> None:
        """Free the photo and its levels (the caller has unbound them)."""
        if self.photo is not None:
            self.photo.release()
            self.photo = None
        self._release_stack()
        self.ready = False
