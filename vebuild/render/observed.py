"""Observed versus inferred: which texels no photo saw, and how renders mark them (numpy, no GL).

Each atlas page's coverage map (``textures.pages[k].coverage``, written by `vebuild texture`,
colours in :mod:`vebuild.texture.merge`) records per texel whether a photo saw it: texels no photo
saw are :data:`~vebuild.texture.merge.COVERAGE_UNSEEN`; every other opaque colour is a texel some
photo saw (once, twice, …, or only by views far worse than the best); off-face texels are
transparent. :func:`unseen_mask` turns a coverage map into the renderer's per-texel mask: 255
where no photo saw the texel, 0 where one did, off-face texels next to a chart (the gutter, the
corners of a triangle's chart) taking the value of a neighbouring on-face texel so that filtering
at a chart's border never reads a neighbour's answer (the gutter between two charts is split
between them). No second mask page is written: the coverage map is
already recorded with its SHA-256 and holds exactly this information.

The renderer (:mod:`vebuild.render.renderer`, ``shaders/scene.frag``) shows an unseen texel in one
of :data:`UNOBSERVED_MODES`:

- ``hatch`` (the default of every evidence output): diagonal stripes of :data:`UNOBSERVED_SRGB`
  laid on the surface in world space (the planes x + y + z = const, :data:`HATCH_PERIOD_M` apart
  along an axis-aligned face), so that the hatch stays put on the surfaces when the camera moves;
  where the stripes would be finer than a couple of pixels they fade into an even tint of the same
  average strength, so that they never alias;
- ``tint``: the unseen texels mixed evenly with :data:`UNOBSERVED_SRGB`;
- ``off``: the textures as extracted (the filled texels look like photographed ones).

Images carry a legend (:func:`draw_legend`, drawn into the lower left corner after read-back,
and the words of :data:`LEGEND_TEXT` in the PNG's ``vebuild:unobserved`` text chunk).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from vebuild.errors import VebuildError
from vebuild.texture.merge import COVERAGE_UNSEEN, unseen_texels

#: How a render shows the texels no photo saw (the first is the default of evidence outputs).
UNOBSERVED_MODES = ("hatch", "tint", "off")
DEFAULT_UNOBSERVED = "hatch"
#: The mark's colour (sRGB): the coverage maps' colour for texels no photo saw, so that a render
#: and a coverage map speak the same language.
UNOBSERVED_SRGB: tuple[int, int, int] = (int(COVERAGE_UNSEEN[0]), int(COVERAGE_UNSEEN[1]), int(COVERAGE_UNSEEN[2]))
#: Share of the mark's colour mixed (in linear light) into a stripe of the hatch.
HATCH_STRENGTH = 0.7
#: Share of the stripes' period a stripe covers.
HATCH_DUTY = 0.5
#: Distance between stripes along an axis-aligned face (m; the hatch is in world space).
HATCH_PERIOD_M = 0.08
#: Off-face texels this close to a face (4-neighbour steps) take a face texel's value: the gutter's
#: half (vebuild.texture.layout.GUTTER / 2) and one more, all a chart's filtering can reach.
FILL_TEXELS = 3
#: Share of the mark's colour mixed into every unseen texel by ``tint``.
TINT_STRENGTH = 0.45
#: The legend's words, one per mode that marks something.
LEGEND_TEXT = {
    "hatch": "hatched: surface no photo saw (texture filled in)",
    "tint": "tinted: surface no photo saw (texture filled in)",
}
#: The legend's box and text colours (sRGB).
LEGEND_BACKGROUND_SRGB = (20, 20, 24)
LEGEND_TEXT_SRGB = (255, 255, 255)
#: The key is drawn only where it takes at most this share of the image's width.
LEGEND_MAX_WIDTH_SHARE = 0.6


def check_mode(mode: str, option: str = "--unobserved") -> str:
    """``mode`` if it is one of :data:`UNOBSERVED_MODES`; otherwise an error naming ``option``."""
    if mode not in UNOBSERVED_MODES:
        raise VebuildError(f"{option}: expected one of {', '.join(UNOBSERVED_MODES)}, got {mode!r}")
    return mode


def legend(mode: str) -> dict[str, object] | None:
    """What a legend of ``mode`` says: its words, the mark's sRGB colour and how it is drawn
    (None for ``off``: nothing is marked). For the report and the PNG's provenance."""
    check_mode(mode, "unobserved")
    if mode == "off":
        return None
    return {"mode": mode, "text": LEGEND_TEXT[mode], "colour_srgb": list(UNOBSERVED_SRGB),
            "strength": HATCH_STRENGTH if mode == "hatch" else TINT_STRENGTH,
            "hatch_period_m": HATCH_PERIOD_M if mode == "hatch" else None}


def unseen_mask(coverage: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """(h, w) uint8 mask of a coverage map (h, w, 4): 255 where no photo saw the texel, 0 where one
    did; off-face texels within :data:`FILL_TEXELS` of a face texel take a neighbouring face
    texel's value (grown one texel at a time, so that each chart fills its own half of the gutter;
    where both an unseen and a seen texel neighbour, unseen), the rest 0 (no chart reaches them)."""
    cov = np.asarray(coverage)
    if cov.ndim != 3 or cov.shape[2] != 4:
        raise ValueError(f"a coverage map is (h, w, 4) RGBA, got shape {cov.shape}")
    known = cov[..., 3] > 0
    unseen = known & unseen_texels(cov)
    for _ in range(FILL_TEXELS):
        if known.all():
            break
        grown_known, grown_unseen = known.copy(), unseen.copy()
        for axis in (0, 1):
            for step in (1, -1):
                k, u = _shift(known, step, axis), _shift(unseen, step, axis)
                new = ~known & k
                grown_known |= new
                grown_unseen |= new & u
        known, unseen = grown_known, grown_unseen
    return np.where(unseen, 255, 0).astype(np.uint8)


def _shift(a: NDArray[np.bool_], step: int, axis: int) -> NDArray[np.bool_]:
    """``a`` moved ``step`` texels along ``axis``, False shifted in."""
    out = np.zeros_like(a)
    src = [slice(None)] * 2
    dst = [slice(None)] * 2
    src[axis], dst[axis] = (slice(0, -step), slice(step, None)) if step > 0 else (slice(-step, None), slice(0, step))
    out[tuple(dst)] = a[tuple(src)]
    return out


def unseen_fraction(mask: NDArray[np.uint8], coverage: NDArray[np.uint8]) -> float:
    """Share of a page's on-face texels that no photo saw."""
    on = np.asarray(coverage)[..., 3] > 0
    return float((mask[on] > 127).mean()) if on.any() else 0.0


def draw_legend(image: NDArray[np.uint8], mode: str) -> NDArray[np.uint8]:
    """``image`` (h, w, 3) sRGB with a small key in its lower left corner: a swatch of the mark as
    the renderer draws it over mid grey, and :data:`LEGEND_TEXT`'s words. ``off``, or an image too
    small for the key to take at most :data:`LEGEND_MAX_WIDTH_SHARE` of its width (a thumbnail):
    unchanged (the provenance still says what is marked)."""
    from PIL import Image, ImageDraw, ImageFont

    check_mode(mode, "unobserved")
    if mode == "off" or image.shape[0] < 24 or image.shape[1] < 48:
        return image
    img = Image.fromarray(np.ascontiguousarray(image[..., :3]), "RGB")
    size = max(10, min(18, img.height // 36))
    font = ImageFont.load_default(size=size)
    draw = ImageDraw.Draw(img)
    text = LEGEND_TEXT[mode]
    box = [int(round(v)) for v in draw.textbbox((0, 0), text, font=font)]
    pad = max(3, size // 3)
    sw = box[3] - box[1] + pad  # the swatch's side
    w, h = sw + 3 * pad + (box[2] - box[0]), sw + 2 * pad
    if w + pad > LEGEND_MAX_WIDTH_SHARE * img.width:
        return image
    x0, y0 = pad, img.height - h - pad
    draw.rectangle((x0, y0, x0 + w, y0 + h), fill=LEGEND_BACKGROUND_SRGB)
    swatch = swatch_pixels(sw, mode)
    img.paste(Image.fromarray(swatch, "RGB"), (x0 + pad, y0 + pad))
    draw.text((x0 + 2 * pad + sw, y0 + pad + (sw - (box[3] - box[1])) // 2 - box[1]), text, fill=LEGEND_TEXT_SRGB,
              font=font)
    return np.asarray(img)


def swatch_pixels(side: int, mode: str, base_srgb: tuple[int, int, int] = (128, 128, 128)) -> NDArray[np.uint8]:
    """A ``side`` × ``side`` sRGB swatch of ``mode``'s mark over ``base_srgb`` (for legends)."""
    from vebuild.texture.merge import linear_to_srgb8, srgb8_to_linear

    base = srgb8_to_linear(np.array(base_srgb, np.uint8))
    mark = srgb8_to_linear(np.array(UNOBSERVED_SRGB, np.uint8))
    j, i = np.mgrid[0:side, 0:side]
    if mode == "hatch":
        period = max(4.0, side / 3.0)
        k = np.where(np.abs(((i + j) / period) % 1.0 - 0.5) < HATCH_DUTY / 2, HATCH_STRENGTH, 0.0)
    else:
        k = np.full((side, side), TINT_STRENGTH)
    return linear_to_srgb8(base * (1.0 - k[..., None]) + mark * k[..., None])


#: The PNG text chunk that records how a render showed unobserved surfaces.
PROVENANCE_KEY = "vebuild:unobserved"


def provenance_text(mode: str, marked: bool, coverage_hashes: list[str]) -> str:
    """The ``vebuild:unobserved`` text of an image: the mode, whether anything in the image's
    scene was marked (some texel no photo saw, and the mode not ``off``), the legend's words and
    colour, and the SHA-256 of the coverage maps the marks came from."""
    import json

    return json.dumps({"mode": check_mode(mode, "unobserved"), "marked": bool(marked), "legend": legend(mode),
                       "coverage_sha256": list(coverage_hashes)}, sort_keys=True, ensure_ascii=False)


def finish_image(image: NDArray[np.uint8], mode: str, marked: bool, text: dict[str, str],
                 coverage_hashes: list[str]) -> NDArray[np.uint8]:
    """An evidence image's last step: its legend drawn in where something is marked, and its
    ``vebuild:unobserved`` provenance added to ``text`` (in place)."""
    text[PROVENANCE_KEY] = provenance_text(mode, marked, coverage_hashes)
    return draw_legend(image, mode) if marked else image


def add_option(parser: object, default: str = DEFAULT_UNOBSERVED) -> None:
    """The ``--unobserved {hatch,tint,off}`` option of a command that writes evidence images (an
    argparse parser)."""
    parser.add_argument("--unobserved", choices=UNOBSERVED_MODES, default=default,  # type: ignore[attr-defined]
                        help="how surfaces no photo saw are shown: hatched, tinted or as extracted "
                             "(default: %(default)s)")
