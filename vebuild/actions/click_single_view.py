"""Single-view measuring by clicking on one calibrated photo, for the windows (no GL here).

Where a project has no solved model, a photo that is calibrated and placed (its camera's K, R, C
and covariance; a one-photo project, or any calibrated photo) is measured on its own against the
floor (:mod:`vebuild.analysis.single_view`): the user clicks the points
:data:`~vebuild.analysis.single_view.SINGLE_VIEW_CLICKS` names for one measurement, in order.

The clicks become the saved words of :func:`~vebuild.analysis.single_view.single_view_command`
(pixels rounded to 1/100 px) and the measurement is the request those words parse to
(:func:`vebuild.analysis.recorded.parse_recorded`), run on the project: the figure the window shows
is the one ``vebuild analyse PROJECT WORDS…`` prints, to the last digit, and the report runs the
same words again.
"""

from __future__ import annotations

from functools import cache
from typing import TYPE_CHECKING, Any

import numpy as np

from vebuild.errors import VebuildError

from .click_measure import ClickError, Measured

if TYPE_CHECKING:
    from vebuild.project import Project

#: The quantity each kind measures, as its label begins.
WHAT = {"photo-height": "height", "floor-distance": "floor distance", "wall-length": "length on the wall",
        "raised-height": "height above the raised surface", "plane-length": "length on the plane",
        "person-height": "person's height"}
#: A person's height: its own command (:mod:`vebuild.analysis.requests_person`), clicked as the top
#: of the head then the point between the feet.
PERSON_HEIGHT = "person-height"


#: How a relative length is said on the photo: no scale was given.
RELATIVE_WORDS = "in relative units (no length was given: the camera's height above the floor is 1)"


def check_click(width: int, height: int, uv: Any) -> None:
    """A click of a single-view measurement must lie on the photo (``width`` × ``height`` pixels)."""
    u, v = float(uv[0]), float(uv[1])
    if not (0 <= u <= width and 0 <= v <= height):
        raise ClickError(f"({u:.1f}, {v:.1f}) lies outside the {width}×{height} photo: click on the photo")


@cache
def kinds() -> tuple[str, ...]:
    """The single-view measurements the command line accepts, in
    :data:`~vebuild.analysis.single_view.SINGLE_VIEW_CLICKS` order (a kind whose clicks are named but
    that ``vebuild analyse`` does not yet take is left out)."""
    from vebuild.analysis.recorded import parse_recorded
    from vebuild.analysis.single_view import SINGLE_VIEW_CLICKS, single_view_command

    out = []
    for kind, prompts in SINGLE_VIEW_CLICKS.items():
        try:
            parse_recorded(single_view_command(kind, "p", [(1.0, 1.0)] * len(prompts)))
        except VebuildError:
            continue
        out.append(kind)
    return (*out, PERSON_HEIGHT)


def prompts(kind: str) -> tuple[str, ...]:
    """The points to click for one measurement of ``kind``, in order, in words."""
    from vebuild.analysis.person import PERSON_CLICKS
    from vebuild.analysis.single_view import SINGLE_VIEW_CLICKS

    if kind == PERSON_HEIGHT:
        return PERSON_CLICKS
    if kind not in SINGLE_VIEW_CLICKS:
        raise ClickError(f"no single-view measurement '{kind}'; they are {', '.join(kinds())}")
    return SINGLE_VIEW_CLICKS[kind]


def prompt(kind: str, done: int) -> str:
    """What to click next, in words, after ``done`` clicks of a ``kind`` measurement."""
    todo = prompts(kind)
    return f"{WHAT.get(kind, kind)}: click {todo[done]} (point {done + 1} of {len(todo)})"


def figure_words(row: dict[str, Any], unit: str) -> str:
    """One measurement's figure in plain words: the value, its 1σ and its 95 % interval, in metres
    or, where no length was given, relative units (the camera's height above the floor is 1)."""
    if unit == "relative":
        v, s, ci = row["value_relative"], row["sigma_relative"], row["ci95_relative"]
        if s is None:
            return f"{v:.4f} {RELATIVE_WORDS}, its uncertainty undetermined"
        return f"{v:.4f} ± {s:.4f} (1σ), 95 % between {ci[0]:.4f} and {ci[1]:.4f}, {RELATIVE_WORDS}"
    v, s, ci = row["value_m"], row["sigma_m"], row["ci95_m"]
    if s is None:
        return f"{v:.4f} m, its uncertainty undetermined"
    return f"{v:.4f} m ± {1000 * s:.1f} mm (1σ), 95 % between {ci[0]:.4f} and {ci[1]:.4f} m"


def measure_on_photo(project: Project, kind: str, photo: str, clicks: list[Any]) -> Measured:
    """The single-view measurement ``kind`` clicked at ``clicks`` (photo pixels, in the order
    :func:`prompts` names them): the request its saved words parse to, run on the project. The
    result's ``pixels`` are the saved (rounded) pixels, to draw on ``photo``."""
    from vebuild.analysis.recorded import measure_clicked, parse_recorded

    if kind not in kinds():
        raise ClickError(f"no single-view measurement '{kind}'; they are {', '.join(kinds())}")
    try:
        words, result = measure_clicked(project, kind, photo, [(float(u), float(v)) for u, v in clicks])
        request = parse_recorded(words)
    except VebuildError as e:
        raise ClickError(str(e)) from None
    if kind == PERSON_HEIGHT:  # the frame's height with the allowances entered (none by clicking)
        row = result.figures["frame"]
        label = f"{WHAT[kind]} {figure_words(row, 'metres')} (no allowance entered: footwear, posture…)"
    else:
        rows = result.figures["measurements"]
        label = f"{WHAT.get(kind, kind)} {figure_words(rows[0], result.figures.get('lengths', 'metres'))}"
    _, saved = saved_clicks(words)
    pixels = [np.array(p) for p in saved]
    return Measured(kind, request, result, words, label, [], photo=photo, pixels=pixels)


def saved_clicks(words: list[str]) -> tuple[str, list[tuple[float, float]]]:
    """The photo and the pixels clicked (in :func:`prompts` order) of a saved single-view command or
    person-height; ValueError where its pixels are not numbers."""
    if words[:1] == [PERSON_HEIGHT]:
        from vebuild.analysis.requests_person import parse_pixel, parse_words

        try:
            r = parse_words(words)
            if r.photo is None or r.head is None:
                raise ValueError("no photo or no head-top")
            feet = [r.foot] if r.foot is not None else list(r.feet or ())
            return r.photo, [parse_pixel(p, "pixel") for p in [r.head, *feet]]
        except VebuildError as e:
            raise ValueError(str(e)) from None
    nums = [float(w) for w in words[3:]]
    if len(nums) % 2:
        raise ValueError("an odd count of pixel numbers")
    return words[2], list(zip(nums[::2], nums[1::2], strict=True))


def drawn_pairs(kind: str, pixels: list[Any]) -> list[tuple[Any, Any]]:
    """The lines drawn for a measurement: foot → top or end → end (its last two clicks), and, for
    the kinds that mark a reference (a wall's foot, a raised surface, a plane), their clicks in
    pairs."""
    pairs = [(pixels[k], pixels[k + 1]) for k in range(0, len(pixels) - 2, 2)]
    return [(pixels[-2], pixels[-1]), *pairs] if len(pixels) >= 2 else []
