"""Lighting comparisons (paper §5.1): one view under several lighting presets, side by side, with
the luminance of a target region under each, so that an investigator can judge whether a witness
could have seen it.

Luminance is relative: the mean relative luminance Y = 0.2126 R + 0.7152 G + 0.0722 B (linear
light, Rec. 709 primaries) over the pixels where the target is seen, on the renderer's scale, on
which a white surface facing a light of irradiance 1 has Y = 1 and the textures show as extracted.
It compares conditions with each other; it is not a photometric measurement in cd/m². Under
``as-photographed`` it is the luminance the photos recorded (their exposure, averaged).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageDraw, ImageFont

from vebuild.camera import ImageCamera
from vebuild.errors import VebuildError
from vebuild.project.decode import find_preset
from vebuild.render.renderer import Renderer
from vebuild.render.scene import RenderScene
from vebuild.texture.merge import srgb8_to_linear

from .sightline import lighting_target

#: Rec. 709 / sRGB luminance weights of linear R, G, B.
LUMINANCE_WEIGHTS = np.array([0.2126, 0.7152, 0.0722])


@dataclass
class LightingResult:
    preset: str
    luminance: float  # mean relative luminance over the target's pixels
    luminance_p10: float  # its 10th and 90th percentiles: how even the target is lit
    luminance_p90: float
    image: NDArray[np.uint8]


def relative_luminance(srgb: NDArray[np.uint8]) -> NDArray[np.float64]:
    """Relative luminance (linear light) of sRGB pixels (..., 3)."""
    return srgb8_to_linear(srgb) @ LUMINANCE_WEIGHTS


def compare_lighting(project, scene: RenderScene, renderer: Renderer, cam: ImageCamera, presets: Sequence[str],
                     target: str) -> list[LightingResult]:
    """Render ``cam``'s view under each preset and measure the target's luminance in each. The
    luminance is measured on a render without the marks of unobserved surfaces; each result's
    image shows them as the renderer's ``unobserved`` says."""
    lighting_target(scene.model, target)
    if not presets:
        raise VebuildError("a lighting comparison needs at least one preset")
    mask = renderer.node_mask(cam, target)
    if not mask.any():
        raise VebuildError(f"the target {target!r} is not seen from this view (hidden or outside the image); "
                           "choose a view that shows it")
    out = []
    for name in presets:
        renderer.set_lighting(find_preset(project, name))
        mode = renderer.unobserved
        marked = renderer.marks_unobserved
        renderer.unobserved = "off"
        try:
            img = renderer.render(cam)
        finally:
            renderer.unobserved = mode
        y = relative_luminance(img[mask])
        out.append(LightingResult(name, float(y.mean()), float(np.percentile(y, 10)), float(np.percentile(y, 90)),
                                  renderer.render(cam) if marked else img))
    return out


def side_by_side(results: Sequence[LightingResult], target_mask: NDArray[np.bool_] | None = None,
                 caption_px: int = 0) -> NDArray[np.uint8]:
    """The renders in a row, each captioned with its preset and the target's luminance, the target
    outlined in each."""
    h, w = results[0].image.shape[:2]
    size = max(12, h // 24)
    band = caption_px or int(size * 2.2)
    font = ImageFont.load_default(size=size)
    strip = Image.new("RGB", (w * len(results), h + band), (255, 255, 255))
    draw = ImageDraw.Draw(strip)
    for k, r in enumerate(results):
        img = r.image.copy()
        if target_mask is not None:
            edge = target_mask & ~(np.roll(target_mask, 1, 0) & np.roll(target_mask, -1, 0)
                                   & np.roll(target_mask, 1, 1) & np.roll(target_mask, -1, 1))
            img[edge] = (255, 200, 0)
        strip.paste(Image.fromarray(img), (k * w, band))
        draw.text((k * w + size // 2, size // 2), f"{r.preset}: target luminance {r.luminance:.4f}",
                  fill=(0, 0, 0), font=font)
    return np.asarray(strip)
