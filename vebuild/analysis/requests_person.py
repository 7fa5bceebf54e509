"""``vebuild analyse PROJECT person-height``: a person's height from a calibrated still
(:mod:`vebuild.analysis.person`), and the frames of one person combined
(:mod:`vebuild.analysis.person_combine`).

One command measures one frame: ``--photo ID --head U,V --foot U,V`` (or ``--feet U,V U,V``), with
``--term`` allowances and ``--person NAME``. With ``--person``, the frame is combined with every
person-height the project records (``analyses``) for that person; ``--person NAME`` alone combines
the recorded frames only.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from vebuild.errors import ProjectError, VebuildError
from vebuild.project.decode import camera_records

from .quiet_parser import QuietParser
from .requests import AnalysisResult, _NoImage, single_view_camera

if TYPE_CHECKING:
    from vebuild.project import Project

    from .person import PersonFrame
    from .person_combine import Combined

#: The first word of a recorded person-height command.
WORD = "person-height"


def parse_pixel(text: str, what: str) -> tuple[float, float]:
    """A pixel written ``U,V``."""
    parts = text.replace(" ", "").split(",")
    try:
        u, v = (float(p) for p in parts)
    except ValueError:
        raise VebuildError(f"person-height: {what} {text!r}: expected a pixel written U,V (e.g. 812.5,233)") from None
    if not (np.isfinite(u) and np.isfinite(v)):
        raise VebuildError(f"person-height: {what} {text!r}: expected a pixel written U,V (finite numbers)")
    return u, v


PERSON_HELP = ("a person's height measured on one calibrated photo: the top of the head, then the point between "
               "the feet on the floor (or each foot), with the allowances entered (--term) and their 1σ; --person "
               "NAME combines the frames of one person; no model needed")


def add_person_arguments(q: argparse.ArgumentParser) -> None:
    """The words of ``person-height`` (the command line's and a recorded command's)."""
    from .person_terms import TERM_SYNTAX, TERMS

    P = PersonHeightRequest
    q.add_argument("--photo", metavar="ID", help="the calibrated photo (a frame); left out with --person: combine "
                   "the frames the project records for that person")
    q.add_argument("--head", metavar="U,V", help="the pixel of the top of the head")
    feet = q.add_mutually_exclusive_group()
    feet.add_argument("--foot", metavar="U,V", help="the pixel of the floor point between the feet")
    feet.add_argument("--feet", nargs="+", metavar="U,V", help="the pixels of the left foot and the right foot "
                      "where they meet the floor (their midpoint is the foot point)")
    q.add_argument("--floor-height", type=float, default=P.floor_height, metavar="M",
                   help="the height in metres of the floor the person stands on, above z = 0 (a step, a platform; "
                   "default: %(default)g)")
    q.add_argument("--term", dest="terms", action="append", default=[], metavar="NAME=VALUE±SIGMA:SOURCE",
                   help="an allowance, once per allowance: " + TERM_SYNTAX.replace("%", "%%") + ". The names: "
                   + "; ".join(f"{n}: {k.words}, {k.says}" for n, k in TERMS.items()) + ". None entered: none "
                   "allowed for, and the result says so")
    q.add_argument("--click-sigma", type=float, metavar="PX", help="the 1σ of these clicks in pixels, where the "
                   "head-top or the feet are harder to place than the project's click 1σ says (a blurred or "
                   "low-resolution frame; default: the project's settings.click_sigma_px)")
    q.add_argument("--person", metavar="NAME", help="who this is: the frames of one person are combined (their "
                   "spread counted; footwear and head covering added once)")


def person_request(a: argparse.Namespace) -> PersonHeightRequest:
    """The request of parsed ``person-height`` words."""
    return PersonHeightRequest(a.photo, a.head, a.foot, tuple(a.feet) if a.feet is not None else None,
                               a.floor_height, tuple(a.terms), a.person, a.click_sigma)


def parse_words(words: list[str]) -> PersonHeightRequest:
    """The request of a recorded ``person-height`` command's words (the first word ``person-height``),
    by the command line's own grammar (:func:`add_person_arguments`)."""
    q = QuietParser(prog=f"vebuild analyse PROJECT {WORD}")
    q.add_argument("--json")
    add_person_arguments(q)
    try:
        return person_request(q.parse_args(words[1:]))
    except argparse.ArgumentError as e:
        raise VebuildError(str(e)) from None


def person_command(photo: str, head: Any, feet: list[Any], person: str | None = None) -> list[str]:
    """The saved words of a person-height clicked on ``photo``: the head-top, then the foot point
    (or the two feet), pixels to 1/100 px as every single-view command saves them."""
    from .single_view import PIXEL_DECIMALS

    def px(p: Any) -> str:
        return f"{float(p[0]):.{PIXEL_DECIMALS}f},{float(p[1]):.{PIXEL_DECIMALS}f}"

    words = [WORD, "--photo", photo, "--head", px(head)]
    words += ["--foot", px(feet[0])] if len(feet) == 1 else ["--feet", *(px(f) for f in feet)]
    return words + (["--person", person] if person else [])


@dataclass(frozen=True)
class PersonHeightRequest(_NoImage):
    """One frame's person-height (``photo`` and its clicks), combined with the project's recorded
    frames of ``person`` where one is named; or, with no photo, the recorded frames of ``person``."""

    name: ClassVar[str] = WORD
    photo: str | None = None
    head: str | None = None
    foot: str | None = None
    feet: tuple[str, ...] | None = None
    floor_height: float = 0.0
    terms: tuple[str, ...] = ()
    person: str | None = None
    click_sigma: float | None = None  # px; None: the project's click_sigma_px

    def frame(self, project: Project) -> PersonFrame:
        """The frame this request measures."""
        from .person import measure_person
        from .person_terms import parse_terms

        if self.photo is None:
            raise VebuildError("person-height: no photo: give --photo ID with --head and --foot (or --feet)")
        if self.head is None:
            raise VebuildError("person-height: the top of the head is missing: give --head U,V")
        if (self.foot is None) == (self.feet is None):
            raise VebuildError("person-height: give the foot point (--foot U,V, the floor between the feet) or "
                               "the two feet (--feet U,V U,V), one of them")
        if self.feet is not None and len(self.feet) != 2:
            raise VebuildError(f"person-height: --feet takes the two feet, U,V U,V; got {len(self.feet)}")
        head = parse_pixel(self.head, "--head")
        feet = [parse_pixel(self.foot, "--foot")] if self.foot is not None else \
            [parse_pixel(f, "--feet") for f in self.feet or ()]
        terms = parse_terms(self.terms)
        cam, lens_sigma, relative = single_view_camera(project, self.photo)
        if relative:
            raise VebuildError(f"person-height: photo '{cam.id}' has no scale (its lengths are relative), so a "
                               "person's height cannot be measured on it; give it a known length or the camera's "
                               "height and calibrate again")
        click = project.settings["click_sigma_px"] if self.click_sigma is None else self.click_sigma
        if not (np.isfinite(click) and click >= 0):
            raise VebuildError(f"person-height: --click-sigma {click:g}: expected a click's 1σ in pixels, 0 or more")
        frame = measure_person(cam, head, feet, floor_height=self.floor_height, terms=terms, person=self.person,
                               click_sigma_px=click, **lens_sigma)
        fixed = camera_records(project.data)[cam.id].get("fixed_camera") or {}
        stills = list(fixed.get("stills") or [])
        return replace(frame, camera=stills[0]) if stills else frame

    def run(self, project: Project) -> AnalysisResult:
        frames = recorded_frames(project, self.person) if self.person else []
        mine = None
        if self.photo is not None or self.head is not None or self.foot is not None or self.feet is not None:
            mine = self.frame(project)
            frames = [f for f in frames if not _same(f, mine)] + [mine]  # as entered now, once
        elif not self.person:
            raise VebuildError("person-height: give --photo ID --head U,V --foot U,V, or --person NAME to combine "
                               "the frames the project records for that person")
        elif not frames:
            known = sorted({f.person for f in recorded_frames(project, None) if f.person})
            raise VebuildError(f"person-height: the project records no person-height of a person called "
                               f"{self.person!r}; " + (f"it records: {', '.join(known)}" if known else
                                                       "it records none with --person"))
        combined = None
        if self.person:
            from .person_combine import combine  # imported at first use: docs/start-up.md (scipy's t)

            combined = combine(self.person, frames)
        figures: dict[str, Any] = {"lengths": "metres", "click_sigma_px": project.settings["click_sigma_px"]
                                   if self.click_sigma is None else self.click_sigma}
        if mine is not None:
            figures["frame"] = mine.to_json()
        if combined is not None:
            figures["combined"] = combined.to_json()
        return AnalysisResult(table(mine, combined), figures)


def _same(a: PersonFrame, b: PersonFrame) -> bool:
    return a.photo == b.photo and a.clicks.shape == b.clicks.shape and bool(np.all(a.clicks == b.clicks)) \
        and a.floor_height == b.floor_height


def recorded_frames(project: Project, person: str | None) -> list[PersonFrame]:
    """The frames of every person-height the project records with a photo (of ``person``; None:
    all), each measured again. A record that no longer measures is a ProjectError naming it."""
    return [f for _, f in recorded_person_frames(project) if person is None or f.person == person]


def recorded_person_frames(project: Project) -> list[tuple[int, PersonFrame]]:
    """Every person-height the project records with a photo, measured again, with its index in
    ``analyses``. A record that no longer measures is a ProjectError naming it."""
    out = []
    for i, rec in enumerate(project.data.get("analyses") or []):
        words = rec.get("command")
        if not (isinstance(words, list) and words[:1] == [WORD]):
            continue
        try:
            request = parse_words(words)
            if request.photo is not None:
                out.append((i, request.frame(project)))
        except VebuildError as e:
            raise ProjectError(project.path, f"$.analyses[{i}].command", str(e)) from None
    return out


def frame_lines(f: PersonFrame) -> list[str]:
    """One frame in words."""
    from .person_terms import not_entered

    head = f"({f.clicks[0][0]:.1f}, {f.clicks[0][1]:.1f})"
    foot = (f"the foot point ({f.clicks[1][0]:.1f}, {f.clicks[1][1]:.1f})" if len(f.clicks) == 2 else
            f"the feet ({f.clicks[1][0]:.1f}, {f.clicks[1][1]:.1f}) and ({f.clicks[2][0]:.1f}, {f.clicks[2][1]:.1f})")
    floor = "the floor (z = 0)" if f.floor_height == 0 else f"a floor {f.floor_height:g} m above z = 0"
    lo, hi = f.ci95
    lines = [f"photo '{f.photo}'{f' (person {f.person})' if f.person else ''}: the top of the head {head} above "
             f"{foot} on {floor}",
             f"  height in the image (sole to head-top) {f.image_height:.4f} m ± {1000 * f.sigma_image:.1f} mm (1σ: "
             f"calibration {1000 * f.sigma_calibration:.1f}, clicks {1000 * f.sigma_clicks:.1f} at "
             f"{f.click_sigma_px:g} px)"]
    lines += [f"  {t.words()}" for t in f.terms]
    missing = not_entered(f.terms)
    if missing:
        lines.append(f"  no allowance entered for {', '.join(missing)}")
    lines.append(f"  height {f.value:.4f} m ± {1000 * f.sigma:.1f} mm (1σ), between {lo:.3f} and {hi:.3f} m (95 %)")
    return lines


def table(mine: PersonFrame | None, combined: Combined | None) -> str:
    """The text `vebuild analyse … person-height` prints."""
    from .person import WHAT_IT_IS

    lines = frame_lines(mine) if mine is not None else []
    if combined is not None:
        c = combined
        lines.append(f"person {c.person}: {len(c.frames)} frame{'s' if len(c.frames) != 1 else ''} on photo"
                     f"{'s' if len({f.photo for f in c.frames}) != 1 else ''} "
                     f"{', '.join(sorted({f.photo for f in c.frames}))}")
        if len(c.frames) > 1:
            lines.append(f"  frames combined {c.frames_value:.4f} m (between-frame spread {1000 * c.tau:.1f} mm, "
                         f"{c.dof} degree{'s' if c.dof != 1 else ''} of freedom)")
        lines += [f"  {t.words()}, once for the person" for t in c.person_terms]
        lines.append(f"  height {c.value:.4f} m, {c.words()}")
    lines.append(f"Each height is {WHAT_IT_IS}.")
    return "\n".join(lines)
