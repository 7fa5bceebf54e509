"""Calibrate one photo's intrinsics, rotation and lens distortion from its vanishing segments
(paper §2).

The paper fits each vanishing point alone, then reads K and R off them. vebuild starts there
(:mod:`.vanishing`, :mod:`.intrinsics`) and then refines f, the principal point c, R and (where
the marks say how straight the edges are) the lens distortion k1 jointly, with every clicked
point's residual measured against the vanishing point K R eᵢ that the camera predicts. That
single solve:

- keeps the three vanishing points consistent (orthogonal directions) instead of fitting each
  alone;
- treats a vanishing point at infinity like any other (it is just K R eᵢ with zero third row), so
  a frontal or corridor view is an ordinary case: what it leaves undetermined shows in the
  covariance, not in a cut-off;
- undistorts every clicked point in closed form (the division model of :mod:`vebuild.camera`)
  before measuring it, so that a polyline's middle points (plumb-line) estimate k1;
- adds a prior pulling c toward the image centre (or a given point) with a stated 1σ (3 % of the
  longer side by default, :data:`.priors.PRINCIPAL_POINT_SIGMA_REL`), so that the orthocentre's
  notorious instability cannot drag c far away, while three good vanishing points still override
  it (maximum a posteriori rather than either pure mode);
- yields the covariance of (f, cx, cy, ω, k1) from its Jacobian.

The *mode* says what determined the intrinsics, judged from the information the segments alone
carry: ``3vp`` (the segments fix c better than its prior), ``2vp`` (f from the segments; c from
its prior), ``1vp`` (f mostly from EXIF or the user). ``mode_reason`` says exactly what was
combined with what, each with its 1σ.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vebuild.camera import AXES, Lens, distortion_displacement_px, exp_so3, intrinsic_matrix, ypr_from_rotation
from vebuild.determinism import deterministic
from vebuild.errors import CalibrationError

from .bending import (
    DistortionTest,
    SecondTermTest,
    bending_test,
    consider_covariance,
    consider_second_term,
    distortion_clause,
    held_problem,
    k1_source,
    second_term_test,
    wide_lens,
)
from .intrinsics import focal_squared, orthocentre, rotation_from_vanishing_points
from .joint import JointProblem, check_orthogonal_pairs, lines_alone
from .lsq import numeric_jacobian, photo_numeric_failures
from .photo_reasons import (
    EXIF_DISAGREEMENT_SIGMAS,
    FOCAL_UNDETERMINED_REL_SIGMA,
    _pct,
    focal_reason,
    principal_point_reason,
)
from .priors import (
    PRINCIPAL_POINT_SIGMA_REL,
    DistortionPrior,
    ExifCheck,
    FocalPrior,
    check_focal_prior,
    check_principal_point,
)
from .robust import RejectedSegment, cleanest_two, consensus, screened_solve, segment_sigmas
from .vanishing import (
    VanishingPointFit,
    as_polylines,
    end_segments,
    fit_vanishing_point,
    normalising_transform,
)

__all__ = ["PRINCIPAL_POINT_SIGMA_REL", "DistortionPrior", "FocalPrior", "PhotoCalibration", "calibrate_photo",
           "closed_form_calibration", "ypr_with_sigma"]

Array = NDArray[np.float64]

#: EXIF's focal length is combined with the segments' where the segments' own 1σ on f is at least
#: this share of EXIF's: EXIF then carries at least 20 % of the weight (σs²/(σs² + σe²) at
#: σs = σe/2). Where the segments are surer still, EXIF would move f by under a fifth of its own
#: error and narrow the 1σ by under 11 %, while exposing the result to EXIF's failures that no
#: Gaussian σ describes (a fixed-lens camera reporting one focal length at every zoom step, a
#: crop, digital zoom): it is then a cross-check only, reported in the mode reason.
EXIF_COMBINE_MIN_SIGMA_RATIO = 0.5
#: Two axes whose vanishing points are closer than this (degrees, seen from a nominal camera with
#: f = the image's longer side) are the same direction: the user has mislabelled a set.
SAME_VANISHING_POINT_DEG = 3.0
#: A vanishing point farther than this many half-image-sizes from the centre is not used for the
#: closed-form start (the joint solve itself needs no such cut, and no message depends on it).
FINITE_VP_MAX_RADIUS = 30.0
#: Where no pair of vanishing points gives a start for f (a frontal or corridor view) and nothing
#: else does, the joint solve starts from f = this × the longer side (a 53° field across it).
NOMINAL_FOCAL_REL = 1.0
#: A pair that check_orthogonal_pairs (.joint) finds significantly non-orthogonal is refused only
#: where the joint solve, forced to orthogonal directions, also fits the marks this many times worse
#: (in variance) than the click noise: 3× in RMS, which no lens distortion of a real photo causes
#: once it is modelled.
MISLABEL_FIT_FACTOR = 9.0


@dataclass(frozen=True)
class PhotoCalibration:
    """Intrinsics, rotation and lens distortion of one photo with their uncertainty.

    covariance : (6, 6) over (f, cx, cy, ωx, ωy, ωz), pixels and radians, where ω is a small
        rotation on the camera side: R_true = exp([ω]×) R; the marginal of ``covariance_k1``.
    covariance_k1 : (7, 7) over (f, cx, cy, ωx, ωy, ωz, k1); k1's row and column are 0 where k1
        is fixed (``k1_source`` ``"none"`` or ``"k1 held at …"``).
    k1, k1_sigma, k1_source : the division model's coefficient (vebuild/camera.py), its 1σ (0 when
        held) and what gave it: ``"segments"``, ``"segments + <prior>"``, ``"<prior>"`` (a lens
        profile or the user), ``"k1 held at 0: …"`` / ``"k1 held at <profile>'s k1 …"`` (the lines
        do not bend, :mod:`.bending`), ``"none"``.
    k2, k2_sigma, k2_source : the division model's second term, its 1σ (0 when held) and what gave
        it: ``"segments"`` where the second test (:func:`.bending.second_term_test`) found one term
        not enough, ``"k2 held at 0: …"`` where it did not, ``"none"`` where it was not tested.
    covariance_lens : (8, 8) over (f, cx, cy, ω, k1, k2); ``covariance_k1`` is its (7, 7) corner.
    second_term_test : that test, where k1 was estimated from segments.
    distortion_test : the test of whether the lines bend (:class:`.bending.DistortionTest`), where
        segments have middle points.
    exif_check : EXIF's focal length against the vanishing points' alone (one sign convention:
        :class:`.priors.ExifCheck`), where EXIF gives one and the vanishing points alone fix f.
    vanishing_points, segment_residuals_px : those of the undistorted marks; one residual per
        segment (rejected ones too, index for index with the marks), the RMS of its points'
        distances to its line through the vanishing point, signed as its first point's (for a
        two-point segment, the paper's residual).
    rejected_segments : axis → the segments left out as not meeting at its vanishing point, or
        the whole axis (:mod:`.robust`); absent axes lost none.
    """

    photo: str
    width: int
    height: int
    mode: str
    mode_reason: str
    focal_source: str
    K: Array
    R: Array
    covariance: Array
    vanishing_points: dict[str, Array]
    segment_residuals_px: dict[str, Array]
    k1: float = 0.0
    k1_sigma: float = 0.0
    k1_source: str = "none"
    covariance_k1: Array = field(default_factory=lambda: np.zeros((7, 7)))
    exif_check: ExifCheck | None = None
    distortion_test: DistortionTest | None = None
    k2: float = 0.0
    k2_sigma: float = 0.0
    k2_source: str = "none"
    covariance_lens: Array = field(default_factory=lambda: np.zeros((8, 8)))
    second_term_test: SecondTermTest | None = None
    rejected_segments: dict[str, tuple[RejectedSegment, ...]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not np.any(self.covariance_k1):  # built with the (6, 6) only: k1 fixed at 0
            cov = np.zeros((7, 7))
            cov[:6, :6] = self.covariance
            object.__setattr__(self, "covariance_k1", cov)
        if not np.any(self.covariance_lens):  # built with k2 held at 0
            cov8 = np.zeros((8, 8))
            cov8[:7, :7] = self.covariance_k1
            object.__setattr__(self, "covariance_lens", cov8)

    @property
    def lens(self) -> Lens:
        """The lens distortion (camera.Lens) as calibrated."""
        return Lens(self.k1, self.k2)

    @property
    def f(self) -> float:
        return float(self.K[0, 0])

    @property
    def principal_point(self) -> Array:
        return self.K[:2, 2].copy()

    @property
    def f_sigma(self) -> float:
        return float(np.sqrt(self.covariance[0, 0]))

    @property
    def principal_point_sigma(self) -> Array:
        return np.sqrt(np.diag(self.covariance)[1:3])

    @property
    def rotation_sigma_rad(self) -> Array:
        """1σ of the small rotation ω about the camera's x, y, z axes."""
        return np.sqrt(np.diag(self.covariance)[3:6])

    def ypr(self) -> tuple[Array, Array]:
        """(yaw, pitch, roll) in radians and their 1σ."""
        return ypr_with_sigma(self.R, self.covariance[3:6, 3:6])

    def kept_residuals_px(self, axis: str) -> Array:
        """The residuals of the axis' segments that were not rejected."""
        out = {r.index for r in self.rejected_segments.get(axis, ())}
        return np.array([v for k, v in enumerate(self.segment_residuals_px[axis]) if k not in out])

    @property
    def rms_px(self) -> float:
        """RMS residual of the segments kept (``rejected_segments`` left out)."""
        r = np.concatenate([self.kept_residuals_px(a) for a in self.segment_residuals_px])
        return float(np.sqrt(np.mean(r**2)))

    @property
    def distortion_corner_px(self) -> float:
        """How far the lens moves the photo's corners, pixels (camera.distortion_displacement_px)."""
        return distortion_displacement_px(self.K, self.width, self.height, self.lens)

    @property
    def distortion_corner_px_sigma(self) -> float:
        """1σ of :attr:`distortion_corner_px`, propagated from the covariance of (f, c, k1, k2)."""
        if self.k1_sigma == 0.0 and self.k2_sigma == 0.0:
            return 0.0

        def disp(y: Array) -> Array:
            return np.array([distortion_displacement_px(intrinsic_matrix(*y[:3]), self.width, self.height,
                                                        Lens(float(y[3]), float(y[4])))])

        y0 = np.r_[self.f, self.principal_point, self.k1, self.k2]
        J = numeric_jacobian(disp, y0, np.r_[1e-3, 1e-3, 1e-3, 1e-7, 1e-7])
        idx = [0, 1, 2, 6, 7]
        cov = self.covariance_lens[np.ix_(idx, idx)]
        return float(np.sqrt(max(float((J @ cov @ J.T)[0, 0]), 0.0)))


def ypr_with_sigma(R: Array, cov_omega: Array) -> tuple[Array, Array]:
    """Yaw, pitch, roll of R and their 1σ propagated from the covariance of ω (R = exp(ω) R̂)."""
    ypr0 = ypr_from_rotation(R)

    def f(w: Array) -> Array:
        d = ypr_from_rotation(exp_so3(w) @ R) - ypr0
        return (d + np.pi) % (2 * np.pi) - np.pi

    J = numeric_jacobian(f, np.zeros(3), 1e-7)
    return ypr0, np.sqrt(np.maximum(np.diag(J @ cov_omega @ J.T), 0.0))


#: World +z may point down the photo by this much (the sine of its angle below the image plane's
#: horizontal at the centre) before the world is called upside down: a camera held level or tilted
#: sees +z pointing up the photo; one looking straight down sees it along the view (about 0); only a
#: reversed axis (or a photo turned upside down) gives more. 0.17: 10°.
UPSIDE_DOWN_SINE = 0.17


@deterministic
@photo_numeric_failures("its calibration from the vanishing lines", "check its vanishing segments (each along "
                        "its axis and in its direction, not all parallel, of some length)")
def calibrate_photo(
    segments: Mapping[str, ArrayLike],
    width: int,
    height: int,
    *,
    photo: str = "photo",
    click_sigma_px: float = 1.0,
    segment_sigma_px: Mapping[str, ArrayLike] | None = None,
    principal_point: tuple[ArrayLike, float] | None = None,
    principal_point_sigma_rel: float = PRINCIPAL_POINT_SIGMA_REL,
    focal: FocalPrior | None = None,
    exif_focal: FocalPrior | None = None,
    distortion: DistortionPrior | None = None,
) -> PhotoCalibration:
    """Intrinsics, rotation and lens distortion of one photo from its directed vanishing segments.

    Parameters
    ----------
    segments : axis ('x', 'y', 'z') → directed segments, pixels: an (n, 4) array of rows
        u1, v1, u2, v2, or polylines [u1, v1, ..., um, vm] (m ≥ 2 points along one straight edge,
        first → last in the axis' positive sense); axes with no segments may be absent or empty.
    width, height : image size in pixels.
    photo : name used in error messages.
    click_sigma_px : 1σ of one clicked point.
    segment_sigma_px : axis → each segment's own 1σ per point (a detected segment's measured
        noise, vebuild.calibration.lines), in the order of ``segments``; absent: click_sigma_px.
    principal_point : a known principal point and its 1σ (pixels); default the image centre
        with 1σ = principal_point_sigma_rel × the longer side.
    focal : a focal length the user gives (always combined).
    exif_focal : the focal length EXIF records, with a realistic 1σ: combined where the segments
        determine f weakly (EXIF_COMBINE_MIN_SIGMA_RATIO) unless they contradict it by more than
        EXIF_DISAGREEMENT_SIGMAS, needed where they determine nothing, and always compared with
        the segments' own estimate (``exif_check``, the mode reason).
    distortion : a lens distortion known beforehand (a lens profile, the user): a prior on k1. k1
        is estimated where segments have middle points and bend (:mod:`.bending`), else held at 0
        or at this prior's k1; with neither middle points nor a prior, it is fixed at 0.

    Raises
    ------
    CalibrationError : when the marks cannot determine the camera; the message names the photo,
        what is missing and what to do.
    """
    check_focal_prior(photo, "focal_px", focal)
    check_focal_prior(photo, "the EXIF focal length", exif_focal)
    if distortion is not None and not (np.isfinite(distortion.k1) and np.isfinite(distortion.sigma)
                                       and distortion.sigma > 0):
        raise CalibrationError(photo, f"the lens distortion ({distortion.source}): expected a finite k1 with a "
                               f"σ > 0, got {distortion.k1!r} ± {distortion.sigma!r}")
    check_principal_point(photo, principal_point)
    polys = {a: as_polylines(s, a, photo) for a, s in segments.items() if len(_flat(s)) > 0}
    if len(polys) < 2:
        marked = ", ".join(sorted(polys)) or "none"
        raise CalibrationError(
            photo,
            f"vanishing segments are marked on {len(polys)} axis ({marked}); the rotation needs two "
            "axes at least: mark a second direction, such as the horizon (x or y) or verticals (z)",
        )
    axes = [a for a in AXES if a in polys]
    sigmas = segment_sigmas(polys, axes, click_sigma_px, segment_sigma_px, photo)
    # The start from each axis' consensus (.robust): clutter grouped into an axis does not move it.
    start = {a: consensus(end_segments(polys[a]), sigmas[a], width, height) for a in axes}
    segs = {a: end_segments(polys[a])[start[a]] for a in axes}
    fits = {a: fit_vanishing_point(segs[a], width, height, axis=a, photo=photo) for a in axes}
    N = normalising_transform(width, height)
    unit = {}
    for a in axes:
        x = N @ fits[a].point
        unit[a] = x / np.linalg.norm(x)
    for a, b in combinations(axes, 2):
        # Points on the sphere up to sign: the angle between the two lines through the origin.
        ang = np.degrees(np.arccos(min(1.0, abs(float(unit[a] @ unit[b])))))
        if ang < SAME_VANISHING_POINT_DEG:
            raise CalibrationError(
                photo,
                f"the segments of axes {a} and {b} meet at the same vanishing point ({ang:.1f}° apart); "
                "orthogonal directions cannot: one of the two sets is labelled with the wrong axis",
            )

    c0 = np.array([width / 2.0, height / 2.0])
    sigma_c = principal_point_sigma_rel * max(width, height)
    c_where = "the image centre"
    if principal_point is not None:
        c0 = np.asarray(principal_point[0], float)
        sigma_c = float(principal_point[1])
        c_where = "the given point"
    not_orthogonal = check_orthogonal_pairs(fits, segs, axes, N, c0, sigma_c, click_sigma_px, photo,
                                             given_principal_point=principal_point is not None)

    finite = [a for a in axes if abs(unit[a][2]) > 1.0 / FINITE_VP_MAX_RADIUS]
    scale = float(max(width, height))
    start_prior = focal or exif_focal
    f0, c_init = _closed_form_start(fits, finite, c0, start_prior.value if start_prior else NOMINAL_FOCAL_REL * scale)
    K0 = intrinsic_matrix(f0, *c_init)
    R0, handedness = rotation_from_vanishing_points(K0, {a: fits[a].point for a in axes}, segs)
    if handedness < 0 and (two := cleanest_two(start)) is not None:  # clutter, not a set drawn backwards
        R0, handedness = rotation_from_vanishing_points(K0, {a: fits[a].point for a in two}, segs)
    if handedness < 0:
        raise CalibrationError(
            photo,
            "the directions of the x, y and z segments form a left-handed frame; each segment must "
            "run toward the positive end of its axis: one set is drawn backwards",
        )

    straightness = any(len(p) > 2 for a in axes for p in polys[a])
    estimate_k1 = straightness or distortion is not None
    estimate_k2 = False  # only where the second test asks for it (.bending)
    def make(p: Mapping[str, list], ax: list[str], s: Mapping[str, Array]) -> JointProblem:
        return JointProblem(p, ax, s, scale, c0, sigma_c, distortion if estimate_k1 else None, estimate_k1,
                            estimate_k2)

    # Solve with every prior first (a focal prior keeps a weakly determined f from wandering), then
    # judge what the segments alone say about f there, and drop EXIF where it is not wanted; the
    # segments off their vanishing points are left out there (.robust).
    prior_f = focal if focal is not None else exif_focal
    f_fallback = start_prior.value if start_prior else NOMINAL_FOCAL_REL * scale

    def restart(ax: list[str]) -> tuple[Array, Array]:  # a start from these axes alone
        f, c = _closed_form_start(fits, [a for a in finite if a in ax], c0, f_fallback)
        R, _ = rotation_from_vanishing_points(intrinsic_matrix(f, *c), {a: fits[a].point for a in ax}, segs)
        return make(polys, axes, sigmas).start(f, c), R

    try:
        screened = screened_solve(polys, sigmas, start, make, restart, prior_f,
                                  make(polys, axes, sigmas).start(f0, c_init), R0, photo)
    except CalibrationError:
        if not_orthogonal is not None:  # the sharper reason: no real f makes two of them orthogonal
            raise not_orthogonal from None
        raise
    problem, y, R = screened.problem, screened.y, screened.R
    bend = None
    second = None
    if straightness:  # k1 estimated only where the kept segments bend (.bending)
        live = [a for a in axes if a not in screened.dropped]
        kept = {a: [p for p, k in zip(polys[a], screened.keep[a], strict=True) if k] for a in live}
        kept_sigmas = {a: np.asarray(sigmas[a])[screened.keep[a]] for a in live}
        bend, held, y_h, R_h, free = bending_test(problem, y, R, prior_f, kept, live, kept_sigmas, scale, c0,
                                                  sigma_c, distortion)
        if not bend.bends:
            problem, y, R, estimate_k1 = held, y_h, R_h, False
        elif wide_lens(problem, y, scale, width, height):  # nested: is one term enough?
            second, problem, y, R, free2 = second_term_test(problem, y, R, prior_f, kept, live, kept_sigmas, scale,
                                                            c0, sigma_c, photo, width, height)
            estimate_k2 = second.needed
    sigma_f_seg, sigma_c_seg = problem.segment_information(y, R)
    rel_seg = sigma_f_seg / (y[0] * scale)
    if not_orthogonal is not None:
        # Refused only where orthogonal directions cannot fit the marks, or fit them only with an
        # undetermined f (a camera at infinite f makes any two directions "orthogonal"), or, at a
        # principal point the user gave, only by rejecting segments (the point is what is wrong).
        J = problem.jacobian(y, R, prior_f)
        vf = problem.variance_factor(J, problem.residuals(problem.at_rotation(y), R, prior_f))
        if vf > MISLABEL_FIT_FACTOR or not rel_seg <= FOCAL_UNDETERMINED_REL_SIGMA or (
                principal_point is not None and screened.rejected):
            raise not_orthogonal
    exif_combined = exif_rejected = False
    exif_check = None
    if exif_focal is not None:
        # What the lines alone say about f, to compare EXIF with (ExifCheck): solved from here
        # without any focal prior.
        exif_combined = focal is None and sigma_f_seg >= EXIF_COMBINE_MIN_SIGMA_RATIO * exif_focal.sigma
        # Lines that fix f to no better than FOCAL_UNDETERMINED_REL_SIGMA here, with the prior, cannot
        # cross-check it: no solve without it is needed (frontal and corridor views, mostly).
        alone = None if exif_combined and not rel_seg <= FOCAL_UNDETERMINED_REL_SIGMA else lines_alone(problem, y, R)
        if alone is not None and alone.rel_sigma_f_seg <= FOCAL_UNDETERMINED_REL_SIGMA:
            # How far apart (ExifCheck): the solution with EXIF's prior is this one, unless the user's
            # prior was used; the lines' 1σ the wider of theirs alone and theirs where EXIF puts f.
            y_e, R_e = (y, R) if focal is None else problem.solve(alone.y, alone.R, exif_focal)
            sigma_e = (sigma_f_seg if focal is None else problem.segment_information(y_e, R_e)[0]) \
                * np.sqrt(max(alone.vf, 1.0))
            sigma_lines = max(alone.sigma_f, float(sigma_e))
            t = (problem.cost(y_e, R_e, exif_focal) - alone.cost) / max(alone.vf, 1.0)
            z = min(float(np.sqrt(max(t, 0.0))), abs(exif_focal.value - alone.f) / float(np.hypot(exif_focal.sigma,
                                                                                                   sigma_lines)))
            if exif_combined and z > EXIF_DISAGREEMENT_SIGMAS:
                # Evidence, not truth: EXIF that the lines contradict is not this photo's focal length.
                exif_combined, exif_rejected = False, True
            exif_check = ExifCheck(exif_focal, alone.f, sigma_lines, z, exif_combined)
        if focal is None and not exif_combined and alone is not None:
            prior_f = None
            y, R, sigma_f_seg, sigma_c_seg, rel_seg = alone.y, alone.R, alone.sigma_f_seg, alone.sigma_c_seg, \
                alone.rel_sigma_f_seg
    if prior_f is None and not rel_seg <= FOCAL_UNDETERMINED_REL_SIGMA:
        raise CalibrationError(
            photo,
            f"the focal length is not determined: from these segments its 1σ would be {_pct(rel_seg)}, more than "
            f"the {100 * FOCAL_UNDETERMINED_REL_SIGMA:.1f} % at which its 95 % interval reaches f = 0 (the "
            "vanishing points lie near infinity or too close to the image centre), and the photo has no EXIF "
            "focal length: give its focal length (the photo's focal_px, in pixels, with a 1σ)",
        )

    _refuse_upside_down(R, axes, photo)
    J = problem.jacobian(y, R, prior_f)
    r = problem.residuals(problem.at_rotation(y), R, prior_f)
    vf = problem.variance_factor(J, r)
    vf_intervals = problem.variance_factor(J, r, intervals=True, tested=not screened.rejected)
    cov_y = problem.covariance(J, vf_intervals)
    if bend is not None and not bend.bends:  # k1 held, as uncertain as the lines leave it
        cov_y = consider_covariance(free, y, R, prior_f, problem.k1_fixed, cov_y, bend, vf_intervals)
    elif second is not None and not second.needed:  # k2 held at 0, as uncertain as the lines leave it
        cov_y = consider_second_term(free2, y, R, prior_f, cov_y, second, vf_intervals)
    S = np.diag([scale, scale, scale, 1.0, 1.0, 1.0, 1.0, 1.0])
    cov8 = S @ cov_y @ S
    cov7 = cov8[:7, :7].copy()
    f, cx, cy = y[:3] * scale
    k1 = problem.k1_of(y)
    K = intrinsic_matrix(f, cx, cy)
    k1_sigma = float(np.sqrt(max(cov7[6, 6], 0.0))) if estimate_k1 else 0.0
    k2 = problem.k2_of(y)
    k2_sigma = float(np.sqrt(max(cov8[7, 7], 0.0))) if estimate_k2 else 0.0

    # What determined what, said exactly.
    prior_dominates = prior_f is not None and not sigma_f_seg <= prior_f.sigma
    if prior_f is None:
        focal_source = "vanishing points"
    elif prior_dominates:
        focal_source = prior_f.source
    else:
        focal_source = f"vanishing points + {prior_f.source}"
    if sigma_c_seg <= sigma_c:
        mode = "3vp"
    elif prior_dominates:
        mode = "1vp"
    else:
        mode = "2vp"
    reason = "; ".join([
        focal_reason(rel_seg, focal, exif_focal, exif_check, exif_combined, exif_rejected, prior_dominates),
        principal_point_reason(mode, sigma_c_seg, sigma_c, c_where, vf),
        distortion_clause(k1, k1_sigma, straightness, distortion, bend, K, width, height, second, k2, k2_sigma),
    ] + ([screened.describe()] if screened.rejected else []))
    # residuals of every segment, index for index with the marks (k1 as solved, or as held)
    every = (held_problem(polys, axes, sigmas, scale, c0, sigma_c, distortion) if bend is not None and not bend.bends
             else make(polys, axes, sigmas))
    U = every.undistorted(y)
    vps = {a: K @ R[:, "xyz".index(a)] for a in axes}
    return PhotoCalibration(
        photo=photo,
        width=int(width),
        height=int(height),
        mode=mode,
        mode_reason=reason,
        focal_source=focal_source,
        K=K,
        R=R,
        covariance=cov7[:6, :6].copy(),
        vanishing_points=vps,
        segment_residuals_px={a: every.reported_residuals(U, a, vps[a]) for a in axes},
        k1=float(k1),
        k1_sigma=k1_sigma,
        k1_source=k1_source(straightness, distortion, bend),
        covariance_k1=cov7,
        exif_check=exif_check,
        distortion_test=bend,
        k2=float(k2),
        k2_sigma=k2_sigma,
        k2_source=("none" if second is None else "segments" if second.needed
                   else f"k2 held at 0: one term straightens the lines ({second.words})"),
        covariance_lens=cov8,
        second_term_test=second,
        rejected_segments={a: tuple(r) for a, r in screened.rejected.items()},
    )


def _refuse_upside_down(R: Array, axes: Sequence[str], photo: str) -> None:
    """Refuse a world whose +z points toward the bottom of the photo (R maps world to camera, whose
    y runs down the image): its floor would be overhead, and every placement on it wrong."""
    if R[1, 2] <= UPSIDE_DOWN_SINE:
        return
    why = ("its z segments point down the photo (each is drawn toward the positive end of z, which is up): "
           "draw them from the floor upward" if "z" in axes else
           "z, which is x × y, points down the photo: reverse the direction of the x or the y segments")
    raise CalibrationError(photo, f"its world would be upside down, the floor overhead: {why}")


def _flat(s: ArrayLike) -> list:
    """The numbers of one axis' marks, flattened (an empty list for no marks)."""
    if isinstance(s, np.ndarray):
        return list(s.reshape(-1))
    return [v for row in s for v in np.asarray(row, float).reshape(-1)]  # type: ignore[union-attr]


@deterministic
def closed_form_calibration(
    segments: Mapping[str, ArrayLike], width: int, height: int, *, photo: str = "photo",
    focal: FocalPrior | None = None,
) -> tuple[Array, Array]:
    """The paper's method alone (§2): per-axis vanishing points, then K and R in closed form.

    Principal point at the orthocentre when three vanishing points are finite, else at the image
    centre; f from two finite vanishing points, else the given focal length. A pinhole: no lens
    distortion (a polyline counts by its end points), no prior, no joint refinement, no
    uncertainty: the reference that ``vebuild bench calibration`` compares with.
    """
    polys = {a: as_polylines(s, a, photo) for a, s in segments.items() if len(_flat(s)) > 0}
    axes = [a for a in AXES if a in polys]
    segs = {a: end_segments(polys[a]) for a in axes}
    fits = {a: fit_vanishing_point(segs[a], width, height, axis=a, photo=photo) for a in axes}
    N = normalising_transform(width, height)
    finite = [a for a in axes if abs((N @ fits[a].point)[2]) / np.linalg.norm(N @ fits[a].point)
              > 1.0 / FINITE_VP_MAX_RADIUS]
    f0 = focal.value if focal is not None else NOMINAL_FOCAL_REL * max(width, height)
    f, c = _closed_form_start(fits, finite, np.array([width / 2.0, height / 2.0]), f0)
    K = intrinsic_matrix(f, *c)
    R, _ = rotation_from_vanishing_points(K, {a: fits[a].point for a in axes}, segs)
    return K, R


def _closed_form_start(fits: Mapping[str, VanishingPointFit], finite: list[str], c0: Array,
                       f_fallback: float) -> tuple[float, Array]:
    """Focal length and principal point to start from (paper §2 closed forms), else f_fallback at c0."""
    pts: dict[str, Array] = {}
    for a in finite:
        p = fits[a].finite_point()
        if p is not None:
            pts[a] = p
    finite = [a for a in finite if a in pts]
    if len(finite) == 3:
        c = orthocentre(pts["x"], pts["y"], pts["z"])
        f2 = focal_squared(pts["x"], pts["y"], c)
        if f2 > 0 and np.linalg.norm(c - c0) < np.linalg.norm(c0):  # inside the image's circumcircle
            return float(np.sqrt(f2)), c
    for a, b in combinations(finite, 2):
        f2 = focal_squared(pts[a], pts[b], c0)
        if f2 > 0:
            return float(np.sqrt(f2)), c0
    return float(f_fallback), c0
