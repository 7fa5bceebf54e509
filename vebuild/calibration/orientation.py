"""Whether each calibrated photo's world axes agree with the others', tested with the markers.

A photo's vanishing points fix its rotation up to the choice of world x among its horizontal
directions (:mod:`.axes_choice`). A photo whose x was chosen wrongly (segments directed along the
wrong horizontal axis, or ``vebuild detect`` unable to choose) is placed with the others all the
same, metres off, its markers far from their clicks: the joint placement cannot turn it back,
its vanishing-point prior holds the rotation. Before placing, the calibrated rotations and the
markers' rays are compared as ``vebuild detect --x-axis auto`` compares them (:func:`choose_turns`),
from the reference photo that most others agree with: a photo that the markers clearly put at
another turn, and a photo whose x ``detect`` could not choose that the markers cannot orient
either, are named here with the one action that fixes each.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .axes_choice import MIN_SHARED_MARKERS, TurnDecision, choose_turns, rz, turn_between
from .lines import X_AXIS_CHOICES, orient_axes

Array = NDArray[np.float64]

#: The references tried (those seeing the origin marker and the most markers first): the one that
#: the most photos agree with is kept, so one turned photo cannot turn all the others.
MAX_REFERENCES = 6


@dataclass(frozen=True)
class Unoriented:
    """A photo whose world axes do not agree with the others': the turn k about z its axes need
    (``R · Rz(k·90°)``), where the markers say it, the ``--x-axis`` choice that gives it, and the
    photo sharing the most markers with it with how many."""

    photo: str
    turn: int | None
    choice: str | None
    partner: str | None
    shared: int
    reason: str


def check_orientation(rotations: Mapping[str, Array], rays: Mapping[str, Mapping[str, Array]],
                      unresolved: Mapping[str, str], origin: str | None = None) -> dict[str, Unoriented]:
    """The photos (of ``rotations``, world→camera) whose axes disagree with the others': those the
    markers' rays (``rays``: photo → marker → camera-frame ray) clearly put at another turn, and
    those in ``unresolved`` (photo → why its x axis was not chosen) that they cannot orient.

    The reference is the photo not in ``unresolved`` that the most others agree with (then: the
    one seeing ``origin``, then the most markers); a photo the markers cannot orient and not in
    ``unresolved`` keeps its axes (the user directed its segments)."""
    ids = [p for p in rotations if p in rays]
    if len(ids) < 2:
        return {p: _unoriented(p, None, rotations, rays, set(), why)
                for p, why in unresolved.items() if p in rotations and len(rotations) >= 2}
    candidates = sorted([p for p in ids if p not in unresolved] or ids,
                        key=lambda p: (origin in rays[p], len(rays[p])), reverse=True)[:MAX_REFERENCES]
    best: tuple[tuple[int, bool, int], dict[str, TurnDecision]] | None = None
    for ref in candidates:
        decided = choose_turns({p: rotations[p] for p in ids}, rays, {ref: 0})
        agree = sum(1 for d in decided.values() if d.turn == 0)
        key = (agree, origin in rays[ref], len(rays[ref]))
        if best is None or key > best[0]:
            best = (key, decided)
        if agree == len(ids):  # every photo agrees with it: no other reference can do better
            break
    assert best is not None
    decided = best[1]
    oriented = {p for p, d in decided.items() if d.turn == 0}
    out: dict[str, Unoriented] = {}
    for p, d in decided.items():
        if d.turn is not None and d.turn != 0:
            out[p] = _unoriented(p, d.turn, rotations, rays, oriented,
                                 f"its markers' rays meet the other photos' with its world axes turned by "
                                 f"{90 * d.turn}° about z ({d.message}; RMS miss as it is "
                                 f"{d.residual_deg[0]:.1f}°): its x axis was chosen wrongly")
        elif d.turn is None and p in unresolved:
            out[p] = _unoriented(p, None, rotations, rays, oriented,
                                 f"{unresolved[p]}; nor can the calibration orient it: {d.message}")
    for p, why in unresolved.items():
        if p in rotations and p not in rays and p not in out:
            out[p] = _unoriented(p, None, rotations, rays, oriented, f"{why}; it shows no markers")
    return out


def _unoriented(p: str, turn: int | None, rotations: Mapping[str, Array], rays: Mapping[str, Mapping[str, Array]],
                oriented: set[str], reason: str) -> Unoriented:
    mine = set(rays.get(p, {}))
    shared = {q: len(mine & set(rays[q])) for q in (oriented or set(rays) - {p}) if q != p}
    partner = max(shared, key=lambda q: (shared[q], q)) if shared else None
    choice = None
    if turn is not None:
        R = rotations[p]
        choice = next((c for c in X_AXIS_CHOICES if turn_between(R @ rz(turn), orient_axes(R, c)[0]) == 0), None)
    return Unoriented(p, turn, choice, partner, shared.get(partner, 0) if partner else 0, reason)


def fix_words(u: Unoriented, project: str, detected: bool) -> str:
    """The one action that orients ``u``: its ``--x-axis`` choice where the markers tell it; more
    markers shared with its best partner where it shares too few; else choosing x by looking."""
    if u.turn is not None and u.choice is not None and detected:
        return f"`vebuild detect {project} {u.photo} --replace --x-axis {u.photo}={u.choice}` orients it"
    if u.turn is not None:
        k = u.turn % 4
        along = ["x", "y", "x", "y"][k]
        sign = "" if k in (0, 1) else "reversed "
        return (f"re-mark its horizontal segments turned: the direction it marks as {sign}{along} is the other "
                "photos' +x")
    need = max(MIN_SHARED_MARKERS - u.shared, 0)
    if u.partner is not None and need > 0:
        return f"mark {need} more marker(s) that photo '{u.partner}' also shows (it shares {u.shared})"
    return (f"`vebuild detect {project} {u.photo} --replace --x-axis {u.photo}=CHOICE`, CHOICE the direction "
            "(right, left, away or toward) in which the other photos' world x runs in it")
