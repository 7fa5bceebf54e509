"""Exposure statistics on the GPU: one photo's texels drawn alone (texel.frag MODE 1) beside the
sums so far, and the photo's gain from them. A part of :class:`vebuild.texture.gpu.Extractor`."""

from __future__ import annotations

from typing import TYPE_CHECKING

import moderngl
import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera
from vebuild.gl.shaders import set_uniforms
from vebuild.texture.gpu_page import Page
from vebuild.texture.layout import SceneMesh

#: Exposure statistics are taken on the atlas reduced this much per side.
STATS_SCALE = 0.25
#: Fewer overlapping (reduced) texels than this and a photo's gain is not estimated.
MIN_OVERLAP = 64
#: Texels darker than this (linear) are left out of exposure statistics.
DARK = 0.01


class ExposureView:
    """The Extractor's view pass and exposure gain (mixed into it)."""

    ctx: moderngl.Context
    mesh: SceneMesh
    gains: dict[str, NDArray[np.float64]]
    overlap: dict[str, int]
    _pages: list[Page]
    _programs: dict[str, moderngl.Program]
    _view_fbo: moderngl.Framebuffer | None

    if TYPE_CHECKING:
        def _unbind(self, free_now: bool = False) -> None: ...

        def _texel_uniforms(self, prog: moderngl.Program, cam: ImageCamera, id_tex: moderngl.Texture,
                            page_size: tuple[int, int], atlas_scale: float = 1.0,
                            weight_scale: float = 1.0) -> None: ...

        def _draw_texels(self, mode: str, page: int, faces: set[int] | None,
                         queries: dict[int, moderngl.Query] | None = None) -> None: ...

    def _exposure_gain(self, cam: ImageCamera, id_tex: moderngl.Texture, faces: set[int]) -> NDArray[np.float64]:
        """This photo's exposure relative to the sums so far: the median ratio of its low band to
        the accumulated low band over texels both saw, on the atlas reduced by STATS_SCALE (1 for
        the first photo, or with fewer than MIN_OVERLAP such texels)."""
        if not self.gains:
            self.overlap[cam.id] = 0
            return np.ones(3)
        ratios = []
        for k in range(len(self._pages)):
            view = self.view(cam, id_tex, k, faces, STATS_SCALE, with_accumulated=True, crop=True)
            ok = (view["seen"] > 0) & (view["accumulated_seen"] > 0)
            low, acc = view["low"][ok], view["accumulated"][ok]
            ok = (low.min(axis=-1) > DARK) & (acc.min(axis=-1) > DARK)
            ratios.append(np.log(low[ok]) - np.log(acc[ok]))
        r = np.concatenate(ratios) if ratios else np.zeros((0, 3))
        self.overlap[cam.id] = len(r)
        if len(r) < MIN_OVERLAP:
            return np.ones(3)
        # One gain for all three channels: an exposure is a scalar, and per channel the medians
        # scatter by a few percent (measured on the example room: 0.94/0.95/0.98 for a true 0.97).
        return np.full(3, np.exp(np.median(r.mean(axis=1))))

    def view(self, cam: ImageCamera, id_tex: moderngl.Texture, page: int, faces: set[int] | None = None,
             atlas_scale: float = 1.0, with_accumulated: bool = False,
             crop: bool = False) -> dict[str, NDArray[np.float32]]:
        """One photo's texels on one page (MODE 1): colour c, weight w, low band l, and in 'seen'
        the face id where the texel is seen (0 elsewhere). ``crop``: only the low band, 'seen' and
        the accumulated ones, over the rectangle that holds the charts of ``faces`` (what the
        exposure statistics need; a photo's charts are a small part of a house's atlas)."""
        p = self._pages[page]
        size = (max(1, round(p.size[0] * atlas_scale)), max(1, round(p.size[1] * atlas_scale)))
        fbo = self._view_target(size)
        fbo.use()
        fbo.viewport = (0, 0, *size)
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        self.ctx.disable(moderngl.BLEND)
        prog = self._programs["view"]
        p.acc[0].use(5)
        self._texel_uniforms(prog, cam, id_tex, p.size, atlas_scale=atlas_scale)
        set_uniforms(prog, accumulated=5)
        # The atlas is drawn at its full page_size extent in NDC; the viewport scales it.
        self._draw_texels("view", page, faces)
        x0, y0, w, h = 0, 0, *size
        if crop:
            rects = np.array([f.rect for f in self.mesh.faces if f.page == page and (faces is None or f.id in faces)]
                             or [(0, 0, 0, 0)], float)
            x0, y0 = (np.floor(rects[:, :2].min(axis=0) * atlas_scale).astype(int) - 1).clip(0)
            x1, y1 = np.minimum(np.ceil((rects[:, :2] + rects[:, 2:]).max(axis=0) * atlas_scale).astype(int) + 1,
                                size)
            w, h = max(0, int(x1) - int(x0)), max(0, int(y1) - int(y0))
        out = {i: np.frombuffer(fbo.read(viewport=(int(x0), int(y0), w, h), components=4, dtype="f4", attachment=i),
                                "f4").reshape(h, w, 4)
               for i in ((1, 2) if crop else (0, 1, 2) if with_accumulated else (0, 1))}
        res = {"low": out[1][..., :3], "seen": out[1][..., 3]}
        if 0 in out:
            res["colour"], res["weight"] = out[0][..., :3], out[0][..., 3]
        if 2 in out:
            res["accumulated"], res["accumulated_seen"] = out[2][..., :3], out[2][..., 3]
        return res

    def _view_target(self, size: tuple[int, int]) -> moderngl.Framebuffer:
        """MODE 1's three targets of ``size``, kept for the next photo (one size at a time)."""
        if self._view_fbo is not None and self._view_fbo.size != size:
            self._release_view_target()
        if self._view_fbo is None:
            self._view_fbo = self.ctx.framebuffer(color_attachments=[self.ctx.texture(size, 4, dtype="f4")
                                                                     for _ in range(3)])
        return self._view_fbo

    def _release_view_target(self) -> None:
        if self._view_fbo is not None:
            self._unbind()
            for t in self._view_fbo.color_attachments:
                t.release()
            self._view_fbo.release()
            self._view_fbo = None
