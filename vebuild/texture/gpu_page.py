"""One atlas page's render targets on the GPU, made by :class:`vebuild.texture.gpu.Extractor` and
read by its exposure statistics (:mod:`vebuild.texture.gpu_exposure`)."""

from __future__ import annotations

from dataclasses import dataclass

import moderngl


@dataclass
class Page:
    """One atlas page's targets: the sums (MODE 0's four) and the best weight (MODE 2)."""

    size: tuple[int, int]
    acc: list[moderngl.Texture]
    fbo: moderngl.Framebuffer
    best: moderngl.Texture | None  # None once the photos are all in (release_best_weights)
    best_fbo: moderngl.Framebuffer | None
