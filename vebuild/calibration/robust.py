"""Robust vanishing points: segments that do not meet at their axis' vanishing point are found and
left out, never averaged in.

A photo's segments of one axis are not all along that axis: detection groups cobblestone edges,
sloping roof and dormer edges, railings and wires with a building's directions, and a user marks
the edges of a second building a few degrees off the first. Least squares averages every one of
them in and then reports a 1σ from the click noise alone: a tight wrong answer. Two steps stop it
(:func:`vebuild.calibration.photo.calibrate_photo` calls them):

1. **Consensus start, per axis** (:func:`consensus`): the vanishing point minimising the h-th
   smallest of the axis' n whitened segment residuals, h = ⌊(n + 3)/2⌋ (least quantile of squares,
   Rousseeuw & Leroy 1987, over the candidate points where two segments' lines meet). Its
   **breakdown point** is the best any estimator with two unknowns has: it stays with the
   segments along the axis while at most ⌊(n − 2)/2⌋ of the n do not belong (2 of 6, 3 of 8,
   4 of 10), whatever those do. The segments within CONSENSUS_CUT robust scales of that point
   start the joint solve.
2. **Outlier test in the joint solve, iterated** (:func:`screened_solve`): every segment, kept
   or not, is tested against the camera the kept ones give (all three axes orthogonal, the lens
   distortion modelled): its whitened residuals' sum of squares T, with m − 1 degrees of freedom
   for m points, against χ²ₘ₋₁'s 1 − OUTLIER_ALPHA / n quantile (a family-wise α over the photo's
   n segments, Bonferroni), times the segments' robust variance factor (the median of T / the
   median of χ²ₘ₋₁, never below 1: the stated noise is trusted unless most segments exceed it,
   so a photo clicked more loosely than stated does not lose its good segments; the least of the
   axes' medians, so that an axis of clutter does not raise it). Each round rejects the worst
   segment beyond it in each axis (data snooping: an outlier biases the solution toward itself, so
   that good segments may fail while it is in), re-admits every segment within, and solves the
   camera again (from where it was and afresh from the axes' consensus points) until the set is
   stable.

An axis that loses more segments than the breakdown point allows (more than ⌊(n − 2)/2⌋, or all
but one) does not say where its vanishing point is: it is left out of the photo's calibration
with its reason (the photo then rests on its other axes, and says so in its mode), and a photo
left with fewer than two axes is refused, never calibrated from clutter.

What remains is tested against the stated noise as a whole (:meth:`.joint.JointProblem.variance_factor`):
where the χ² test rejects it (where segments were rejected: wherever χ² exceeds its degrees of
freedom), every 1σ is widened by the measured excess, with Student's t for its degrees of freedom
(docs/accuracy.md).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vebuild.errors import CalibrationError

from .joint import SEGMENT_RESIDUAL_VARIANCE_FACTOR, JointProblem
from .priors import FocalPrior
from .vanishing import homogeneous, normalising_transform

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]

#: A segment further than this many robust scales (whitened) from its axis' consensus point does
#: not start the joint solve (the usual 2.5 of least-median-of-squares; the joint test that
#: follows re-admits any that the camera, lens distortion modelled, fits).
CONSENSUS_CUT = 2.5
#: Nor does the start leave out a segment whose end-to-end direction is within this angle (degrees)
#: of its line to the consensus point: a real lens (corners moved by up to 3 % of the
#: half-diagonal) turns a long edge's chord near a corner by up to about 2°, which the joint
#: solve, distortion modelled, fits; leaving such edges out of the start would take the
#: distortion's evidence with them. A short edge's allowance is as short (its misfit is half its
#: length times the angle), so short clutter does not pass under it.
CONSENSUS_LENS_DEG = 2.0
#: Above this many pairs of segments in one axis, the consensus tries this many pairs drawn at
#: random (seeded: the same photo gives the same answer); with a quarter of the segments clutter,
#: the chance that no drawn pair is clean is 0.44³⁰⁰ ≈ 10⁻¹⁰⁷.
CONSENSUS_MAX_PAIRS = 300
#: The family-wise chance that the outlier test rejects a segment of a photo whose segments all
#: belong to their axes (Bonferroni over the photo's segments).
OUTLIER_ALPHA = 0.01
#: The most rounds of reject, re-admit and solve again (one rejection per axis a round: the worst
#: segment first, as an outlier biases the solution toward itself and can make good ones fail).
MAX_ROUNDS = 16


@dataclass(frozen=True)
class RejectedSegment:
    """A segment left out of a photo's calibration: its index in its axis' segments as given, its
    misfit (the RMS of its whitened residuals: how many of its 1σ its points lie off the line to
    the vanishing point) and why."""

    index: int
    misfit_sigmas: float
    reason: str


def breakdown_tolerance(n: int) -> int:
    """How many of an axis' n segments may not belong to it and still be found: ⌊(n − 2)/2⌋."""
    return max((n - 2) // 2, 0)


def consensus(segs: Array, sigma_px: Array, width: float, height: float) -> Mask:
    """Which of one axis' segments (n, 4) start the joint solve: those near the point that the
    least quantile of squares over the points where two segments' lines meet gives (module doc).

    sigma_px : each segment's 1σ per point. Fewer than three segments: all (nothing to compare).
    """
    n = len(segs)
    if n < 3:
        return np.ones(n, bool)
    N = normalising_transform(width, height)
    p1 = homogeneous(segs[:, 0:2]) @ N.T
    p2 = homogeneous(segs[:, 2:4]) @ N.T
    mid = 0.5 * (p1 + p2)
    lines = np.cross(p1, p2)
    pairs = np.array(list(combinations(range(n), 2)))
    if len(pairs) > CONSENSUS_MAX_PAIRS:
        pairs = pairs[np.random.default_rng(n).choice(len(pairs), CONSENSUS_MAX_PAIRS, replace=False)]
    cand = np.cross(lines[pairs[:, 0]], lines[pairs[:, 1]])
    norm = np.linalg.norm(cand, axis=1)
    cand = cand[norm > 1e-12 * max(float(norm.max()), 1e-300)]
    if len(cand) == 0:
        return np.ones(n, bool)
    cand /= np.linalg.norm(cand, axis=1)[:, None]
    # Distance (pixels) of each segment's first end to the line through its midpoint and each candidate.
    ell = np.cross(mid[None, :, :], cand[:, None, :])
    d = np.abs(np.einsum("knj,nj->kn", ell, p1)) / np.maximum(np.hypot(ell[..., 0], ell[..., 1]), 1e-300)
    z = d / N[0, 0] / (sigma_px * np.sqrt(SEGMENT_RESIDUAL_VARIANCE_FACTOR))[None, :]
    h = (n + 3) // 2
    score = np.sort(z, axis=1)[:, h - 1]
    best = int(np.argmin(score))
    scale = 1.4826 * (1.0 + 5.0 / (n - 2)) * float(score[best])
    length = np.hypot(*(segs[:, 2:4] - segs[:, 0:2]).T)
    cut = np.maximum(CONSENSUS_CUT * max(scale, 1.0), 0.5 * length * np.radians(CONSENSUS_LENS_DEG) / (
        sigma_px * np.sqrt(SEGMENT_RESIDUAL_VARIANCE_FACTOR)))
    return np.asarray(z[best] <= cut, bool)


def cleanest_two(start: Mapping[str, Mask]) -> list[str] | None:
    """Where the consensus left segments out of some axis, the two axes whose segments it kept the
    largest share of (a rotation to start from that the clutter-ridden axis does not orient);
    None where it left none out (a left-handed frame is then a set drawn backwards)."""
    if all(m.all() for m in start.values()) or len(start) < 3:
        return None
    return sorted(sorted(start, key=lambda a: -float(np.mean(start[a])))[:2], key="xyz".index)


@dataclass
class Screened:
    """The joint problem of a photo's kept segments, solved, and what was left out.

    keep : axis → which of its segments (as given) are in ``problem``; rejected : axis → those
    left out; dropped : axes left out whole (above the breakdown point); variance : the segments'
    robust variance factor (≥ 1) the outlier test used."""

    problem: JointProblem
    y: Array
    R: Array
    keep: dict[str, Mask]
    rejected: dict[str, list[RejectedSegment]]
    dropped: list[str]
    variance: float

    def describe(self) -> str:
        """The mode reason's words for what was left out ('' where nothing was)."""
        parts = []
        for a, rej in self.rejected.items():
            n = len(self.keep[a])
            if a in self.dropped:
                parts.append(f"axis {a} left out: {len(rej)} of its {n} segments do not meet at one vanishing point "
                             f"with the other axes' (more than the {breakdown_tolerance(n)} a robust fit can tell "
                             "from clutter)")
            elif rej:
                parts.append(f"{len(rej)} of {n} {a} segments rejected ({', '.join(str(r.index) for r in rej)}), "
                             "not meeting at the vanishing point")
        return "; ".join(parts)


def screened_solve(polys: Mapping[str, list[Array]], sigmas: Mapping[str, Array], keep: dict[str, Mask],
                   make: Callable[[dict[str, list[Array]], list[str], dict[str, Array]], JointProblem],
                   restart: Callable[[list[str]], tuple[Array, Array]], prior_f: FocalPrior | None,
                   y: Array, R: Array, photo: str) -> Screened:
    """The joint solve over the segments kept, with the outlier test iterated (module doc).

    make(polys, axes, sigmas) : the joint problem of those segments; restart(axes) : a start
    (y, R) from those axes' consensus vanishing points alone; prior_f : the focal prior solved
    with; (y, R) : the start from every axis. Where the consensus left segments out, the solve
    also starts from the two cleanest axes (:func:`cleanest_two`), and where an axis is left out,
    from the others: the solution of least cost is kept (clutter can lead a start astray).
    """
    from scipy.stats import chi2  # imported at first use: docs/start-up.md

    def solve(problem: JointProblem, starts: list[tuple[Array, Array]]) -> tuple[Array, Array]:
        sols = [problem.solve(y0, R0, prior_f) for y0, R0 in starts]
        return min(sols, key=lambda s: problem.cost(s[0], s[1], prior_f))

    axes = [a for a in "xyz" if a in polys]
    full = make(dict(polys), axes, dict(sigmas))
    dof = full.counts - 1.0
    offset = {a: full.polys_of[a][0] for a in axes}
    crit_q = chi2.isf(OUTLIER_ALPHA / len(dof), dof)
    keep = {a: np.array(keep[a], bool) for a in axes}
    dropped: list[str] = []
    problem, stat, s2 = None, np.zeros(len(dof)), 1.0
    def over_limit(y: Array, R: Array, s2: float) -> Array:
        r = full.residuals(full.at_rotation(y), R, None)[: full.n_data]
        return np.asarray(np.bincount(full.pid, r**2, minlength=len(dof)), float) / (s2 * crit_q)

    def fails_without(a: str, live: list[str]) -> int:
        rest = [b for b in live if b != a]
        p = make({b: [q for q, k in zip(polys[b], keep[b], strict=True) if k] for b in rest}, rest,
                 {b: np.asarray(sigmas[b])[keep[b]] for b in rest})
        over = over_limit(*solve(p, [(y, R), restart(rest)]), s2)
        return int(sum(np.sum(over[offset[b]: offset[b] + len(keep[b])] > 1.0) for b in rest))

    two = cleanest_two(keep)
    starts = [(y, R)] + ([restart(two)] if two is not None else [])
    for round_ in range(MAX_ROUNDS + 1):
        live = [a for a in axes if a not in dropped]
        problem = make({a: [p for p, k in zip(polys[a], keep[a], strict=True) if k] for a in live}, live,
                       {a: np.asarray(sigmas[a])[keep[a]] for a in live})
        y, R = solve(problem, starts)
        if round_ == MAX_ROUNDS:  # not yet stable: the last set as solved
            break
        r = full.residuals(full.at_rotation(y), R, None)[: full.n_data]
        stat = np.asarray(np.bincount(full.pid, r**2, minlength=len(dof)), float)
        ratio = stat / chi2.ppf(0.5, dof)
        s2 = max(1.0, min(float(np.median(ratio[offset[a]: offset[a] + len(keep[a])][keep[a]])) for a in live))
        new, fail = {}, {}
        for a in axes:  # re-admit every segment that passes; reject the worst that fails, per axis
            over = stat[offset[a]: offset[a] + len(keep[a])] / (s2 * crit_q[offset[a]: offset[a] + len(keep[a])])
            new[a], fail[a] = keep[a] | (over <= 1.0), over > 1.0
            if np.any(keep[a] & fail[a]):
                new[a][int(np.argmax(np.where(keep[a], over, -np.inf)))] = False
        # Above the breakdown point (more rejected than it allows; then also any axis most of whose
        # segments fail now): one axis a round, the one without which the others agree best (the
        # others' segments may fail only while it pulls the camera).
        over_bd = [a for a in live if new[a].sum() < 2 or (~new[a]).sum() > breakdown_tolerance(len(new[a]))]
        if over_bd:  # an axis most of whose segments fail now is as suspect
            over_bd += [a for a in live if a not in over_bd and fail[a].sum() > len(fail[a]) / 2]
        lost = [min(over_bd, key=lambda a: fails_without(a, live))] if len(over_bd) > 1 else over_bd
        if all(np.array_equal(new[a], keep[a]) for a in axes) and not lost:
            break
        keep = new
        dropped += lost
        if len(axes) - len(dropped) < 2:
            a = lost[0]
            raise CalibrationError(
                photo, f"the {a} segments do not meet at one vanishing point: {int(fail[a].sum())} of "
                f"{len(new[a])} lie off the point the others give, more than the {breakdown_tolerance(len(new[a]))} "
                "a robust fit can tell from clutter, and without them the photo has one axis: check that every "
                f"{a} segment runs along a straight edge in the {a} direction (not a slope, another building or "
                "clutter) and remove those that do not, or mark more along it")
        starts = [(y, R), restart([a for a in axes if a not in dropped])]
    assert problem is not None
    rejected = {}
    for a in axes:
        rows = range(offset[a], offset[a] + len(keep[a]))
        out = [k for k, i in enumerate(rows) if a in dropped or not keep[a][k]]
        limit = [float(np.sqrt(s2 * crit_q[i] / max(dof[i], 1.0))) for i in rows]
        rejected[a] = [RejectedSegment(k, float(np.sqrt(stat[offset[a] + k] / max(dof[offset[a] + k], 1.0))),
                                       "axis left out" if a in dropped and keep[a][k] else
                                       f"off its vanishing point beyond {limit[k]:.1f}σ") for k in out]
        if a in dropped:
            keep[a] = np.zeros(len(keep[a]), bool)
    return Screened(problem, y, R, keep, {a: r for a, r in rejected.items() if r}, dropped, s2)



def segment_sigmas(polys: Mapping[str, list[Array]], axes: list[str], click_sigma_px: float,
                    given: Mapping[str, ArrayLike] | None, photo: str) -> dict[str, Array]:
    """Each segment's 1σ by axis: the given one, else the click's."""
    out = {}
    for a in axes:
        sig = np.full(len(polys[a]), float(click_sigma_px))
        if given is not None and a in given:
            g = np.asarray(given[a], float).ravel()
            if len(g) != len(sig) or not np.all(np.isfinite(g) & (g > 0)):
                raise CalibrationError(photo, f"the 1σ of the {a} segments: expected {len(sig)} finite values > 0 "
                                       f"(one per segment), got {len(g)}")
            sig = g
        out[a] = sig
    return out
