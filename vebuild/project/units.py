"""The unit of a project's lengths: metres, or relative units where no scale was given.

A one-photo project calibrated with no scale (no camera height, known length or scale distance)
is placed with its camera's height above the floor taken as 1 (``calibration.lengths ==
"relative"``, and the camera's ``placement.lengths``; FORMAT.md). Every length derived from such a
calibration (positions, distances, heights, dimensions, the solved model) is then in units of that
height, not metres. Every output that shows or writes a length asks :func:`length_unit` and
writes what it says, so that no relative length is ever shown as metres: one place decides.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from vebuild.errors import VebuildError

#: How a relative length is labelled wherever it is shown.
RELATIVE_UNITS = "relative units: the camera height is 1"
#: What a user does to have metres instead.
FOR_METRES = ("give the photo a scale (its camera_height, a known length in it, or a scale distance between two "
              "floor markers) and run `vebuild calibrate` again for metres")


@dataclass(frozen=True)
class LengthUnit:
    """The unit of lengths in one project; ``relative``: no scale was given (the camera's height
    above the floor is 1)."""

    relative: bool

    @property
    def word(self) -> str:
        """What records write as ``lengths``: ``"metres"`` or ``"relative"``."""
        return "relative" if self.relative else "metres"

    @property
    def symbol(self) -> str:
        """A table's column unit: ``"m"``, or ``"rel."`` for relative units."""
        return "rel." if self.relative else "m"

    @property
    def key_suffix(self) -> str:
        """The unit in a figure's key (``value_m``, ``value_relative``)."""
        return "_relative" if self.relative else "_m"

    def key(self, name: str) -> str:
        """``name`` with the unit in it, as figures are keyed: ``distance_m`` or ``distance_relative``."""
        return name + self.key_suffix

    def length(self, value: float, digits: int = 3) -> str:
        """One length in words: ``"1.234 m"`` or ``"1.234 (relative units: the camera height is 1)"``."""
        return f"{value:.{digits}f} m" if not self.relative else f"{value:.{digits}f} ({RELATIVE_UNITS})"

    def after(self, text: str) -> str:
        """``text`` (numbers) followed by the unit: ``"(1, 2, 3) m"`` or ``"(1, 2, 3) (relative units: …)"``."""
        return f"{text} m" if not self.relative else f"{text} ({RELATIVE_UNITS})"

    @property
    def note(self) -> str:
        """A line for a table of lengths: empty in metres; else what the unit is and how to get metres."""
        if not self.relative:
            return ""
        return (f"lengths are RELATIVE ({RELATIVE_UNITS}: no scale was given, so every length is in units of the "
                f"camera's height above the floor, not metres); {FOR_METRES}")

    def refuse(self, what: str) -> None:
        """Raise a VebuildError for ``what`` (a length the user gave in metres, such as an eye
        height) in a relative project, where it has no meaning; nothing in metres."""
        if self.relative:
            raise VebuildError(f"{what} is in metres, but this project's lengths are relative ({RELATIVE_UNITS}: "
                               f"no scale was given), so it has no meaning here; {FOR_METRES}")


    def keyed(self, figures: Any) -> Any:
        """``figures`` (nested dicts and lists) with every key that says metres (``*_m``, ``*_m2``,
        ``*_m3``) saying relative units instead (``*_relative``, ``*_relative2``, ``*_relative3``)
        where the lengths are relative; unchanged in metres."""
        if not self.relative:
            return figures
        if isinstance(figures, dict):
            return {_relative_key(k): self.keyed(v) for k, v in figures.items()}
        if isinstance(figures, list | tuple):
            return [self.keyed(v) for v in figures]
        return figures


def _relative_key(key: Any) -> Any:
    if isinstance(key, str):
        for suffix, to in (("_m", "_relative"), ("_m2", "_relative2"), ("_m3", "_relative3")):
            if key.endswith(suffix):
                return key[: -len(suffix)] + to
    return key


METRES = LengthUnit(False)
RELATIVE = LengthUnit(True)


def length_unit(data: Mapping[str, Any]) -> LengthUnit:
    """The unit of the lengths of the project document ``data``: relative where its calibration
    says so (``calibration.lengths``, or any calibrated camera's ``placement.lengths``), else
    metres (also before calibration: lengths the user gives are metres)."""
    cal = data.get("calibration") or {}
    if cal.get("lengths") == "relative":
        return RELATIVE
    cameras = {**(cal.get("cameras") or {}), **((data.get("model_solution") or {}).get("cameras") or {})}
    if any(((c or {}).get("placement") or {}).get("lengths") == "relative" for c in cameras.values()):
        return RELATIVE
    return METRES


def record_unit(record: Mapping[str, Any]) -> LengthUnit:
    """The unit a result record states in its ``lengths`` (``calibration``, ``model_solution``,
    a camera's ``placement``, figures): relative where it says ``"relative"``, else metres."""
    return RELATIVE if record.get("lengths") == "relative" else METRES
