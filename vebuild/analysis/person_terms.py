"""The allowances a person's height from a still rests on, each entered by the user as a value
with its own 1σ and the source it comes from (the forensic literature's terms: stance and stride,
footwear, head covering, the head-top's visibility).

What a photo measures is the **image's sole-to-head-top line**: from the floor under the feet to
the highest point of the head the photo shows, of a figure in the posture of that frame. Standing
height is that, less what the shoes and anything on the head add, plus what the posture and a
hidden crown take away. vebuild has no table of typical values it could vouch for: each value, its
1σ and its source are the user's (docs/person-height.md says how to choose them), and where none is
entered the report says "no allowance entered for …".

Written on the command line as ``--term NAME=VALUE±SIGMA:SOURCE`` (:data:`TERM_SYNTAX`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from vebuild.errors import VebuildError


class TermError(VebuildError):
    """An allowance written in a way vebuild cannot read."""


@dataclass(frozen=True)
class TermKind:
    """One kind of allowance: its name in words, whether it is added to or subtracted from the
    measured line (``sign``), whether it is the same in every frame of the person (``per_person``:
    added once after the frames are combined) or the posture of one frame, and what it is."""

    words: str
    sign: int
    per_person: bool
    says: str


#: The allowances, by the name written on the command line. Each value is entered in the sense
#: its name says (a sole's height, a crown hidden by so much), never negative: vebuild adds or
#: subtracts it.
TERMS: dict[str, TermKind] = {
    "stride": TermKind("stance and stride", +1, False,
                       "how much lower the head is in this frame than when standing upright (a walking stride, "
                       "bent knees, a slouch): added"),
    "footwear": TermKind("footwear", -1, True, "how much the shoes raise the person (sole and heel): subtracted"),
    "head-covering": TermKind("head covering", -1, True,
                              "how much a hat, a hood or piled-up hair adds above the crown: subtracted"),
    "head-top": TermKind("head-top visibility", +1, False,
                         "how far the crown lies above the top clicked where the photo does not show it (a cap's "
                         "peak, hair, the frame's edge, seen from above): added"),
}

TERM_SYNTAX = ("NAME=VALUE±SIGMA:SOURCE, NAME one of " + ", ".join(TERMS) + "; VALUE and SIGMA in metres (or "
               "with cm or mm after the number), VALUE ≥ 0 in the sense its name says (vebuild adds or subtracts "
               "it); ± may be written +/- or +-; SOURCE: where the value comes from (e.g. "
               "\"footwear=0.025±0.010:trainers, typical sole\")")

_NUMBER = r"([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(m|cm|mm)?"
_TERM = re.compile(rf"^\s*([A-Za-z-]+)\s*=\s*([-+]?)\s*{_NUMBER}\s*(?:±|\+/-|\+-)\s*([-+]?)\s*{_NUMBER}\s*(?::(.*))?$",
                   re.S)
_SCALE = {None: 1.0, "m": 1.0, "cm": 0.01, "mm": 0.001}


@dataclass(frozen=True)
class Term:
    """One allowance entered: its name (a key of :data:`TERMS`), value and 1σ in metres, source."""

    name: str
    value: float
    sigma: float
    source: str

    @property
    def kind(self) -> TermKind:
        return TERMS[self.name]

    @property
    def signed(self) -> float:
        """What it adds to the measured line (negative: what it takes off)."""
        return self.kind.sign * self.value

    def words(self) -> str:
        """In plain words: "footwear −0.025 m ± 10.0 mm ('trainers')"."""
        sign = "+" if self.kind.sign > 0 else "−"
        src = f" ('{self.source}')" if self.source else " (no source given)"
        return f"{self.kind.words} {sign}{self.value:.3f} m ± {1000 * self.sigma:.1f} mm{src}"

    def to_json(self) -> dict[str, object]:
        return {"term": self.name, "words": self.kind.words, "value_m": self.value, "sigma_m": self.sigma,
                "added_m": self.signed, "source": self.source,
                "applies": "once per person" if self.kind.per_person else "per frame"}


def parse_term(text: str) -> Term:
    """One ``--term`` (:data:`TERM_SYNTAX`)."""
    m = _TERM.match(text)
    if not m:
        name = text.split("=", 1)[0].strip()
        if "=" in text and name not in TERMS:
            raise TermError(f"--term {text!r}: no allowance called {name!r}; expected one of {', '.join(TERMS)}")
        raise TermError(f"--term {text!r}: expected {TERM_SYNTAX}")
    name, vsign, v, vu, ssign, s, su, source = m.groups()
    if name not in TERMS:
        raise TermError(f"--term {text!r}: no allowance called {name!r}; expected one of {', '.join(TERMS)}")
    value, sigma = float(v) * _SCALE[vu], float(s) * _SCALE[su]
    kind = TERMS[name]
    if vsign == "-" and value > 0:
        raise TermError(f"--term {text!r}: the {kind.words} is entered as a size, not negative ({kind.says}); "
                        f"write {name}={v}±{s}")
    if ssign == "-":
        raise TermError(f"--term {text!r}: the 1σ must not be negative")
    if not (math.isfinite(value) and math.isfinite(sigma)) or value > 1.0 or sigma > 1.0:
        raise TermError(f"--term {text!r}: expected a value and a 1σ in metres, each at most 1 m (an allowance "
                        "on a person's height); was a length in cm or mm written without its unit?")
    return Term(name, value, sigma, (source or "").strip())


def parse_terms(texts: tuple[str, ...] | list[str]) -> tuple[Term, ...]:
    """The ``--term`` options of one measurement: each allowance at most once."""
    terms = tuple(parse_term(t) for t in texts)
    seen: set[str] = set()
    for t in terms:
        if t.name in seen:
            raise TermError(f"--term: the {t.kind.words} ({t.name}) is entered twice; enter each allowance once")
        seen.add(t.name)
    return terms


def not_entered(terms: tuple[Term, ...] | list[Term]) -> list[str]:
    """The allowances' names in words that ``terms`` leave out."""
    given = {t.name for t in terms}
    return [k.words for n, k in TERMS.items() if n not in given]
