"""The texture extraction's options (``vebuild texture``'s flags, the modelling screen's texture
button): plain data, apart from the GL passes that use them, checked when made and frozen (so
every ``Options`` a stage is given is valid).

A value out of range is a :class:`~vebuild.errors.VebuildError` naming the option and what was
expected (``texture option drop_ratio: expected a number in [0, 1), got 2.0``); the command line
reads its defaults from here.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from vebuild.errors import VebuildError

MODES = ("texture", "average")
FILLS = ("push-pull", "average")


@dataclass(frozen=True)
class Options:
    """The extraction's choices; each improvement over the paper can be switched off."""

    texels_per_metre: float = 200.0
    max_face_texels: int = 2048
    page_size: int = 4096
    erode_px: float = 2.0  # 0: no erosion of the ID mask at id/depth discontinuities
    drop_ratio: float = 0.25  # 0: keep every view; else drop views below this share of the best
    detail_levels: float = 2.0  # the low band is this many pyramid levels coarser
    detail_sharpness: float = 8.0  # 1: the paper's plain weighted average
    exposure: bool = True  # compensate exposure differences between photos
    fill: str = "push-pull"  # or "average" (the paper: the face's average colour)
    mode: str = "texture"  # or "average": one colour per face (paper Figure 9, middle)
    token_charts: bool = True  # a face no photo can see gets a token chart (False: its full one)

    def __post_init__(self) -> None:
        def bad(option: str, expected: str, value: object) -> VebuildError:
            return VebuildError(f"texture option {option}: expected {expected}, got {value!r}")

        def number(x: object) -> bool:
            return isinstance(x, numbers.Real) and not isinstance(x, bool) and math.isfinite(float(x))

        if not (number(self.texels_per_metre) and self.texels_per_metre > 0):
            raise bad("texels_per_metre", "a positive number", self.texels_per_metre)
        if not (number(self.max_face_texels) and int(self.max_face_texels) >= 1):
            raise bad("max_face_texels", "at least 1", self.max_face_texels)
        if not (number(self.page_size) and int(self.page_size) >= 1):
            raise bad("page_size", "at least 1 texel", self.page_size)
        if not (number(self.erode_px) and self.erode_px >= 0.0):
            raise bad("erode_px", "0 or more pixels", self.erode_px)
        if not (number(self.drop_ratio) and 0.0 <= self.drop_ratio < 1.0):
            raise bad("drop_ratio", "a number in [0, 1)", self.drop_ratio)
        if not (number(self.detail_levels) and self.detail_levels >= 0.0):
            raise bad("detail_levels", "0 or more pyramid levels", self.detail_levels)
        if not (number(self.detail_sharpness) and self.detail_sharpness >= 1.0):
            raise bad("detail_sharpness", "at least 1", self.detail_sharpness)
        if self.mode not in MODES:
            raise bad("mode", "'texture' or 'average'", self.mode)
        if self.fill not in FILLS:
            raise bad("fill", "'push-pull' or 'average'", self.fill)
        if not isinstance(self.token_charts, bool):
            raise bad("token_charts", "true or false", self.token_charts)

    def as_dict(self) -> dict[str, object]:
        return dict(self.__dict__)
