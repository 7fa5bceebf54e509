"""Whether a photo's marked lines bend: the test that decides if its lens distortion is estimated.

A polyline's middle points (clicked, or a detected segment's, vebuild/calibration/lines.py) let the
joint solve (:class:`.joint.JointProblem`) estimate the lens's k1. Estimating it always fits the
noise of every photo with one more parameter: a photo already undistorted by its author (true
k1 = 0) came out with k1 a few σ from zero, moving its corners by some 15 px, and the distortion
centre being the principal point, that k1 also pulls c. So k1 is estimated only where the lines
ask for it:

- **the test**: a likelihood-ratio test between the joint solve with k1 free (no lens-profile
  prior) and the joint solve with k1 held at 0, or at the lens profile's k1 where there is one.
  Both carry the same priors (principal point, focal length), so the statistic
  T = (cost_held − cost_free) / max(σ0², 1) is χ²₁ when the lines are straight (or bend as the
  profile says), with σ0² the free solve's variance factor (:meth:`.joint.JointProblem.variance_factor`:
  1 unless the marks fit worse than their stated noise, then χ²/dof), so that marks noisier than
  stated do not pass for bending. k1 is estimated where T exceeds χ²₁'s quantile at
  :data:`DISTORTION_TEST_LEVEL`, else held;
- **held**: k1 = 0 (or the profile's k1), reported with a 1σ of 0; the rest of the camera solved
  with k1 there, its covariance that of k1 as a *consider* parameter (:func:`consider_covariance`:
  the uncertainty of a k1 the test could not tell from the held one stays in f's, c's and R's);
  placement and ``vebuild solve --recalibrate`` hold k1 there (the calibration record's
  ``distortion.k1.sigma`` is 0) and the camera by that covariance;
- **reported either way**: the mode reason's distortion clause and the record's ``source`` give
  T and its p-value.

**The second term** (nested: only where k1 is estimated): one term cannot straighten a wide
(90°) to fisheye (150° diagonal) lens's lines (docs/lenses.md). A second likelihood-ratio test, the
joint solve with k2 free against k2 held at 0 (both with k1 free, the same priors, the same level),
decides whether k2 is estimated (:func:`second_term_test`); it is reported as the first is. Where the
test asks for k2 but the lines cannot determine the lens (the corner displacement's 95 % interval
with k2 free reaches 0, or the solve's information is singular: too few bent lines, or none near
the edges, where k2 acts), the photo is refused rather than given a wild lens.

What the test costs: a lens that bends less than the test detects is held at 0 and moves f and c;
its power is measured in docs/accuracy.md ("Lens distortion: estimated only where the lines bend")
and tests/test_bending.py.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import Lens, distortion_displacement_px, intrinsic_matrix
from vebuild.errors import CalibrationError

from .joint import JointProblem
from .lsq import numeric_jacobian
from .priors import DistortionPrior, FocalPrior

Array = NDArray[np.float64]

#: The test's level: the share of photos whose lines are straight (or bend as their lens profile
#: says) that nonetheless get k1 estimated. 5 %: T > 3.84 (1.96σ for one parameter). A false
#: estimate is not wrong (k1 comes with its 1σ), it only spends one parameter; a missed bend moves
#: the principal point and f. On tests/test_calibration_coverage.py's 600 photos (barrel lenses of
#: 1–3 %, two middle points on long edges only) 1 % held 76 lenses at 0 and, with the covariance of
#: k1 fixed, 91.7 % of principal points fell inside their 95 % ellipses; 5 % held 30, and with
#: :func:`consider_covariance` 94.5 % (94.5 % with k1 always estimated).
DISTORTION_TEST_LEVEL = 0.05


def lr_words(statistic: float, p_value: float, level: float) -> str:
    """A likelihood-ratio test's figures in words: "LR test: Δχ² = 0.42, p = 0.52, level 0.05"."""
    p = f"{p_value:.2g}" if p_value >= 1e-4 else "< 0.0001"
    eq = "" if p.startswith("<") else "= "
    return f"LR test: Δχ² = {statistic:.2f}, p {eq}{p}, level {level:g}"


@dataclass(frozen=True)
class DistortionTest:
    """The likelihood-ratio test of bending lines against k1 held at ``held_k1``.

    statistic : T = (cost_held − cost_free) / max(σ0², 1), χ²₁ under the held model.
    p_value : P(χ²₁ ≥ T).
    held_k1, held_source : the k1 held under the null (0, or a lens profile's) and where it came from.
    free_k1 : the k1 the lines give with k1 free (no lens-profile prior).
    """

    statistic: float
    p_value: float
    held_k1: float
    held_source: str
    free_k1: float
    level: float = DISTORTION_TEST_LEVEL

    @property
    def bends(self) -> bool:
        """Whether the lines bend otherwise than held: k1 is then estimated."""
        return self.p_value < self.level

    @property
    def words(self) -> str:
        """The test's figures: "LR test: Δχ² = 0.42, p = 0.52, level 0.05"."""
        return lr_words(self.statistic, self.p_value, self.level)

    @property
    def held_words(self) -> str:
        """What was held and why: "held at 0: the lines do not bend (LR test: …)"."""
        if self.held_source == "none":
            return f"held at 0: the lines do not bend ({self.words})"
        return (f"held at {self.held_source}'s k1 {self.held_k1:+.4f}: the lines bend no differently "
                f"({self.words})")


#: k2 is tested only where one term moves the photo's corners by more than this share of the half
#: diagonal (a wide lens). Below it one term fits a true fisheye's mapping to within a fraction of
#: a pixel (scripts/lens_models.py: at 10 %, 0.24 px worst over a 1280×720 frame for an equidistant
#: lens, 0.41 px for an equisolid one), less than the clicks' noise: the second test could only
#: add false positives (5 % of ordinary photos, each moving k1 by trading it against k2).
SECOND_TERM_MIN_CORNER_REL = 0.10
#: The lens is undetermined where the 1σ of its corner displacement exceeds this share of it: its
#: 95 % interval (± 1.96σ) then reaches a straight lens (as FOCAL_UNDETERMINED_REL_SIGMA for f).
LENS_UNDETERMINED_REL_SIGMA = 1.0 / 1.96


@dataclass(frozen=True)
class SecondTermTest:
    """The likelihood-ratio test of k2 free against k2 held at 0, k1 free in both.

    statistic, p_value : as :class:`DistortionTest`'s; free_k2 : the k2 the lines give.
    """

    statistic: float
    p_value: float
    free_k2: float
    level: float = DISTORTION_TEST_LEVEL

    @property
    def needed(self) -> bool:
        """Whether one term leaves the lines bent: k2 is then estimated."""
        return self.p_value < self.level

    @property
    def words(self) -> str:
        """The test's figures, as :class:`DistortionTest`'s."""
        return lr_words(self.statistic, self.p_value, self.level)


def wide_lens(problem: JointProblem, y: Array, scale: float, width: int, height: int) -> bool:
    """Whether the lens of ``problem``'s solution y moves the corners by more than
    :data:`SECOND_TERM_MIN_CORNER_REL` of the half diagonal: where its second term is tested."""
    K = intrinsic_matrix(*(np.asarray(y[:3], float) * scale))
    corner = distortion_displacement_px(K, width, height, problem.lens_of(y))
    return corner > SECOND_TERM_MIN_CORNER_REL * 0.5 * float(np.hypot(width, height))


def second_term_test(problem: JointProblem, y: Array, R: Array, prior_f: FocalPrior | None,
                     polys: Mapping[str, list], axes: list[str], sigmas: Mapping[str, Array], scale: float,
                     c0: Array, sigma_c: float, photo: str, width: int, height: int
                     ) -> tuple[SecondTermTest, JointProblem, Array, Array, JointProblem]:
    """The test of k2 at ``problem``'s solution (y, R), k1 estimated there, and the problem and
    solution to go on with: with k2 free where the test asks for it, else ``problem``'s; and the
    problem with k2 free (for :func:`consider_second_term` where k2 is held).

    Raises CalibrationError where the test asks for k2 but the lines cannot determine the lens
    (:data:`LENS_UNDETERMINED_REL_SIGMA`)."""
    from scipy.stats import chi2  # imported at first use: docs/start-up.md

    free = JointProblem(polys, axes, sigmas, scale, c0, sigma_c, problem.k1_prior, True, estimate_k2=True)
    y2, R2 = free.solve(np.r_[y[:7], 0.0], R, prior_f)
    J = free.jacobian(y2, R2, prior_f)
    vf = free.variance_factor(J, free.residuals(free.at_rotation(y2), R2, prior_f))
    t = max(problem.cost(y, R, prior_f) - free.cost(y2, R2, prior_f), 0.0) / max(vf, 1.0)
    test = SecondTermTest(float(t), float(chi2.sf(t, 1)), free.k2_of(y2))
    if not test.needed:
        return test, problem, y, R, free
    cov = free.covariance(J, max(vf, 1.0))
    corner, sigma = corner_displacement_sigma(cov, y2, scale, width, height)
    if not (np.isfinite(sigma) and sigma <= LENS_UNDETERMINED_REL_SIGMA * corner):
        raise CalibrationError(
            photo,
            f"the lens bends the marked lines more than one distortion term can straighten ({test.words}), "
            f"but the lines cannot determine a second term: the lens would move the photo's corners by "
            f"{corner:.0f} ± {sigma:.0f} px. Mark more long lines near the photo's edges, where a wide lens "
            "bends them most, each with middle points along its curve")
    return test, free, y2, R2, free


def consider_second_term(free: JointProblem, y: Array, R: Array, prior_f: FocalPrior | None, held_cov: Array,
                         test: SecondTermTest, vf: float) -> Array:
    """(8, 8) covariance of a solution with k2 held at 0, k2's row and column 0: k2 as a consider
    parameter, as :func:`consider_covariance` does for k1. With P the covariance with k2 held
    (``held_cov``) and M that with k2 free at the held point, the covariance is P + (1 + T)(M − P),
    T the second test's statistic: the uncertainty of a k2 the test could not tell from 0 stays in
    f's, c's, R's and k1's (and so in the corner displacement's)."""
    z = np.r_[np.asarray(y, float)[:7], 0.0]
    M = free.covariance(free.jacobian(z, R, prior_f), vf)
    M[7, :] = M[:, 7] = 0.0
    return held_cov + (1.0 + test.statistic) * (M - held_cov)


def corner_displacement_sigma(cov: Array, y: Array, scale: float, width: int, height: int) -> tuple[float, float]:
    """The corner displacement (px) of the joint solve's y and its 1σ from the (8, 8) covariance of
    y (f/s, cx/s, cy/s, ω, k1, k2), first order."""
    idx = [0, 1, 2, 6, 7]

    def disp(z: Array) -> Array:
        return np.array([distortion_displacement_px(intrinsic_matrix(*(z[:3] * scale)), width, height,
                                                    Lens(float(z[3]), float(z[4])))])

    z0 = np.asarray(y, float)[idx]
    J = numeric_jacobian(disp, z0, np.r_[1e-6, 1e-6, 1e-6, 1e-7, 1e-7])
    C = cov[np.ix_(idx, idx)]
    if not np.all(np.isfinite(C)):
        return float(disp(z0)[0]), float("inf")
    return float(disp(z0)[0]), float(np.sqrt(max(float((J @ C @ J.T)[0, 0]), 0.0)))


def held_problem(polys: Mapping[str, list], axes: list[str], sigmas: Mapping[str, Array], scale: float,
                 c0: Array, sigma_c: float, profile: DistortionPrior | None) -> JointProblem:
    """The joint problem with k1 held at 0, or at the lens profile's k1."""
    problem = JointProblem(polys, axes, sigmas, scale, c0, sigma_c, None, False)
    problem.k1_fixed = float(profile.k1) if profile is not None else 0.0
    return problem


def bending_test(problem: JointProblem, y: Array, R: Array, prior_f: FocalPrior | None,
                 polys: Mapping[str, list], axes: list[str], sigmas: Mapping[str, Array], scale: float,
                 c0: Array, sigma_c: float, profile: DistortionPrior | None
                 ) -> tuple[DistortionTest, JointProblem, Array, Array, JointProblem]:
    """The test of a photo whose marks have middle points, from ``problem``'s solution (y, R) with
    k1 free; with the held problem and its solution (where the test holds k1, the caller goes on
    with those) and ``problem`` (k1 estimated, with the lens profile's prior if any) for
    :func:`consider_covariance`."""
    from scipy.stats import chi2  # imported at first use: docs/start-up.md

    free = problem
    if profile is not None:  # the free model has no profile prior: the lines alone
        free = JointProblem(polys, axes, sigmas, scale, c0, sigma_c, None, True)
        y, R = free.solve(y, R, prior_f)
    held = held_problem(polys, axes, sigmas, scale, c0, sigma_c, profile)
    y_h, R_h = held.solve(y[:6], R, prior_f)
    J = free.jacobian(y, R, prior_f)
    vf = free.variance_factor(J, free.residuals(free.at_rotation(y), R, prior_f))
    t = max(held.cost(y_h, R_h, prior_f) - free.cost(y, R, prior_f), 0.0) / max(vf, 1.0)
    test = DistortionTest(float(t), float(chi2.sf(t, 1)), held.k1_fixed,
                          profile.source if profile is not None else "none", free.k1_of(y))
    return test, held, y_h, R_h, problem


def consider_covariance(free: JointProblem, y: Array, R: Array, prior_f: FocalPrior | None, k1: float,
                        held_cov: Array, test: DistortionTest, vf: float) -> Array:
    """(8, 8) covariance of the held solution (y, R), k1's own row and column 0 since it is held.

    k1 is a *consider* parameter: held, not estimated, but as uncertain as the lines (and the lens
    profile) leave it. With P the covariance of (f, c, ω) with k1 fixed (``held_cov``) and M their
    marginal with k1 estimated (``free`` at the held point), M − P is what a k1 of 1σ would add. The
    held solution's error also holds the bias of the k1 it holds: k1's mean square error about the
    held value, σ² + k̂², is σ² (1 + T) with T the test's statistic (Wald's form of it), so the
    covariance is P + (1 + T)(M − P). Holding k1 at 0 where a lens bends less than the test detects
    moves c and f (:data:`DISTORTION_TEST_LEVEL`: with P alone, too few principal points lie inside
    their ellipses). ``vf`` is the variance factor P was widened by (the marks' excess noise), M's
    too: with another, M − P would mix two noise levels and could narrow P.
    """
    z = np.r_[y[:6], k1]
    J = free.jacobian(z, R, prior_f)
    M = free.covariance(J, vf)
    M[6, :] = M[:, 6] = 0.0
    return held_cov + (1.0 + test.statistic) * (M - held_cov)


def distortion_clause(k1: float, k1_sigma: float, straightness: bool, prior: DistortionPrior | None,
                      test: DistortionTest | None, K: Array, width: int, height: int,
                      second: SecondTermTest | None = None, k2: float = 0.0, k2_sigma: float = 0.0) -> str:
    """The mode reason's clause on the lens distortion (and its second term, where it was tested)."""
    if not straightness and prior is None:
        return "no lens distortion modelled (no segment has middle points, no lens profile)"
    corner = distortion_displacement_px(K, width, height, Lens(k1, k2))
    if test is not None and not test.bends:
        return f"lens distortion k1 {test.held_words}"
    src = "the segments' straightness" if straightness else prior.source  # type: ignore[union-attr]
    if straightness and prior is not None:
        src += f" combined with {prior.source} (k1 {prior.k1:+.4f} ± {prior.sigma:.4f})"
    text = f"lens distortion k1 = {k1:+.4f} ± {k1_sigma:.4f} from {src}, moving the corners by {corner:.1f} px"
    text += f"; estimated: the lines bend ({test.words})" if test is not None else ""
    if second is not None and second.needed:
        text += (f"; second term k2 = {k2:+.4f} ± {k2_sigma:.4f} estimated: one term leaves the lines bent "
                 f"({second.words})")
    elif second is not None:
        text += f"; second term k2 held at 0: one term straightens the lines ({second.words})"
    return text


def k1_source(straightness: bool, prior: DistortionPrior | None, test: DistortionTest | None) -> str:
    """The calibration's ``k1_source``: what gave k1 (FORMAT.md ``distortion.source``)."""
    if test is not None and not test.bends:
        return f"k1 {test.held_words}"
    if straightness:
        return "segments + " + prior.source if prior else "segments"
    return prior.source if prior else "none"
