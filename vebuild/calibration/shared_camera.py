"""Photos from one camera calibrated together: one focal length, principal point and lens distortion.

A photographer's photos of a scene are mostly taken with one body, one lens and one zoom setting
(:mod:`.camera_groups` says which photos are one camera). Calibrated apart, a near-frontal photo
whose vanishing points barely fix f gets a wide or no answer while an oblique photo of the same
camera knows f to a per cent. Calibrated together, as PhotoModeler, COLMAP and OpenSfM do, every
photo lends its lines to the camera's intrinsics:

- one least-squares problem over the group's photos: the shared y = (f, cx, cy, [k1]) and one
  small rotation ω per photo, R = exp([ω]×) R̂; every photo's residuals are those of its own
  :class:`.joint.JointProblem` (each clicked point against the vanishing point K R eₐ, over its
  segment's 1σ), and the priors enter once per group: the principal point's (the image centre,
  1σ ``principal_point_sigma_rel`` × the longer side), the lens profile's, EXIF's focal length;
- EXIF's focal length is evidence as for one photo (.photo): compared with what the group's lines
  alone give, combined where the lines fix f no better than twice EXIF's 1σ and do not contradict
  it by more than EXIF_DISAGREEMENT_SIGMAS, never where they do;
- a photo whose lines alone contradict the group's focal length by more than
  :data:`GROUP_DISAGREEMENT_SIGMAS` is released from the group (calibrated on its own, with a
  warning): a zoom moved, a crop, another body of the same model;
- the marks' variance factor (χ² over its degrees of freedom, where χ² fails the global test)
  widens every 1σ, as for one photo.

What it costs: one solve over 3 + 3N (+1) unknowns whose Jacobian is N blocks of 7 columns (each
photo's residuals depend on the shared intrinsics and its own rotation only), after each photo's
own calibration (its start and the release test).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import exp_so3, intrinsic_matrix
from vebuild.errors import CalibrationError

from .joint import VARIANCE_TEST_QUANTILE, JointProblem
from .lsq import covariance_from_jacobian, numeric_jacobian
from .photo import (
    EXIF_COMBINE_MIN_SIGMA_RATIO,
    EXIF_DISAGREEMENT_SIGMAS,
    FOCAL_UNDETERMINED_REL_SIGMA,
    PhotoCalibration,
    _flat,
    _pct,
    calibrate_photo,
)
from .priors import PRINCIPAL_POINT_SIGMA_REL, DistortionPrior, ExifCheck, FocalPrior
from .robust import segment_sigmas
from .vanishing import as_polylines

Array = NDArray[np.float64]

#: A photo's own focal length (from its lines alone) more than this many σ from its group's is
#: not that camera's (a zoom moved, a crop, another body of the model): the photo is released from
#: the group. The σ is that of the difference, √(σᵢ² − σ_g²) (the group's estimate contains the
#: photo's: for the inverse-variance mean the two are correlated by σ_g²). Two honest estimates
#: are more than 3σ apart in 0.27 % of photos, the limit EXIF is held to (.photo).
GROUP_DISAGREEMENT_SIGMAS = 3.0
#: The 1σ (relative) of the start focal length a photo that cannot be calibrated alone is given to
#: find its rotation: a start only; the shared solve replaces it.
START_FOCAL_SIGMA_REL = 0.2


@dataclass(frozen=True)
class GroupMember:
    """One photo of a camera group: what :func:`.photo.calibrate_photo` is called with for it
    (``segments``, ``width``, ``height``, ``photo``, ``click_sigma_px``, ``segment_sigma_px``,
    ``principal_point``, ``principal_point_sigma_rel``, ``focal``, ``exif_focal``, ``distortion``)."""

    photo: str
    kwargs: Mapping[str, Any]


@dataclass(frozen=True)
class SharedCalibration:
    """The shared intrinsics of one camera group and its photos' calibrations.

    covariance : (4, 4) over (f, cx, cy, k1), pixels (k1's row and column 0 where it is fixed).
    photos : the photos calibrated with the group's intrinsics (each its own rotation).
    released : photo → why it left the group (its lines contradict the group's f); the caller
        calibrates it alone.
    failed : photo → its error, where neither alone nor with the group's f it could be calibrated.
    """

    group: str
    photos: dict[str, PhotoCalibration]
    f: float
    principal_point: Array
    k1: float
    covariance: Array
    mode: str
    reason: str
    focal_source: str
    k1_source: str
    variance_factor: float
    exif_check: ExifCheck | None = None
    released: dict[str, str] = field(default_factory=dict)
    failed: dict[str, CalibrationError] = field(default_factory=dict)
    #: covariance of (f, cx, cy[, k1], ω of each photo of ``photos`` in its order): pixels, radians
    joint_covariance: Array = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def f_sigma(self) -> float:
        return float(np.sqrt(max(self.covariance[0, 0], 0.0)))

    @property
    def principal_point_sigma(self) -> Array:
        return np.sqrt(np.maximum(np.diag(self.covariance)[1:3], 0.0))

    @property
    def k1_sigma(self) -> float:
        return float(np.sqrt(max(self.covariance[3, 3], 0.0)))


class SharedProblem:
    """x = (f/s, cx/s, cy/s, [k1], ω₁, …, ω_N): each photo's JointProblem data rows, then the
    principal point's prior once, the lens profile's once and each focal prior once."""

    def __init__(self, problems: Sequence[JointProblem], scale: float, c0: Array, sigma_c: float,
                 k1_prior: DistortionPrior | None, estimate_k1: bool):
        self.problems, self.scale, self.c0, self.sigma_c = list(problems), scale, c0, sigma_c
        self.k1_prior, self.estimate_k1 = k1_prior, estimate_k1
        self.n_shared = 4 if estimate_k1 else 3
        self.n_params = self.n_shared + 3 * len(self.problems)
        self.n_data = int(sum(p.n_data for p in self.problems))
        self.n_independent = int(sum(p.n_independent for p in self.problems))

    def member_y(self, x: Array, i: int) -> Array:
        o = self.n_shared + 3 * i
        return np.r_[x[:3], x[o:o + 3], [x[3]] if self.estimate_k1 else []]

    def _columns(self, i: int) -> list[int]:
        o = self.n_shared + 3 * i
        return [0, 1, 2, o, o + 1, o + 2, *([3] if self.estimate_k1 else [])]

    def start(self, f0: float, c: Array, k1: float) -> Array:
        return np.r_[f0 / self.scale, np.asarray(c) / self.scale, [k1] if self.estimate_k1 else [],
                     np.zeros(3 * len(self.problems))]

    def residuals(self, x: Array, R0: Sequence[Array], priors: Sequence[FocalPrior]) -> Array:
        parts = [p.residuals(self.member_y(x, i), R0[i], None)[:p.n_data] for i, p in enumerate(self.problems)]
        parts.append((x[1:3] * self.scale - self.c0) / self.sigma_c)
        if self.k1_prior is not None and self.estimate_k1:
            parts.append(np.array([(x[3] - self.k1_prior.k1) / self.k1_prior.sigma]))
        parts += [np.array([(x[0] * self.scale - p.value) / p.sigma]) for p in priors]
        return np.concatenate(parts)

    def jacobian(self, x: Array, R0: Sequence[Array], priors: Sequence[FocalPrior]) -> Array:
        """Block by block: a photo's rows depend on the shared intrinsics and its own ω only."""
        J = np.zeros((self.n_data + 2 + (1 if self.k1_prior is not None and self.estimate_k1 else 0)
                      + len(priors), self.n_params))
        row = 0
        for i, jp in enumerate(self.problems):
            def fun(y: Array, jp: JointProblem = jp, i: int = i) -> Array:
                return jp.residuals(y, R0[i], None)[:jp.n_data]

            J[row:row + jp.n_data, self._columns(i)] = numeric_jacobian(fun, self.member_y(x, i), 1e-7)
            row += jp.n_data
        J[row, 1] = J[row + 1, 2] = self.scale / self.sigma_c
        row += 2
        if self.k1_prior is not None and self.estimate_k1:
            J[row, 3] = 1.0 / self.k1_prior.sigma
            row += 1
        for p in priors:
            J[row, 0] = self.scale / p.sigma
            row += 1
        return J

    def solve(self, x0: Array, R0: Sequence[Array], priors: Sequence[FocalPrior]) -> tuple[Array, list[Array]]:
        from scipy.optimize import least_squares  # imported at first use: docs/start-up.md

        n = len(self.problems)
        lower = np.r_[1e-3, -np.inf, -np.inf, [-np.inf] if self.estimate_k1 else [], np.full(3 * n, -np.pi)]
        upper = np.r_[1e3, np.inf, np.inf, [np.inf] if self.estimate_k1 else [], np.full(3 * n, np.pi)]
        sol = least_squares(self.residuals, x0, jac=self.jacobian, args=(R0, priors), bounds=(lower, upper),
                            method="trf", x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12)
        x = np.array(sol.x, float)
        R = [exp_so3(x[self.n_shared + 3 * i:self.n_shared + 3 * i + 3]) @ R0[i] for i in range(n)]
        x[self.n_shared:] = 0.0
        return x, R

    def variance_factor(self, J: Array, r: Array) -> float:
        """σ0² by the global test, as JointProblem.variance_factor, over all the group's marks."""
        from scipy.stats import chi2  # imported at first use: docs/start-up.md

        n = self.n_data
        cov = _inverse(J.T @ J)
        if cov is None:
            return 1.0
        dof = self.n_independent - float(np.trace(J[:n] @ cov @ J[:n].T))
        if dof <= 0.5:
            return 1.0
        x2 = float(r[:n] @ r[:n])
        return 1.0 if x2 <= chi2.ppf(VARIANCE_TEST_QUANTILE, dof) else x2 / dof

    def covariance(self, J: Array, vf: float) -> Array:
        """Covariance of x with the data rows widened by vf (the priors' σ are stated, not scaled)."""
        Jw = np.array(J, float)
        Jw[:self.n_data] /= np.sqrt(vf)
        return covariance_from_jacobian(Jw)

    def segment_information(self, x: Array, R: Sequence[Array]) -> tuple[float, float]:
        """1σ (pixels) of f from the segments with the principal point's and lens profile's priors,
        and of c (largest axis) from the segments with the lens profile's only (inf: undetermined)."""
        J = self.jacobian(x, R, ())
        cov = _inverse(J.T @ J)
        sigma_f = float(np.sqrt(cov[0, 0])) * self.scale if cov is not None else np.inf
        rows = np.r_[np.arange(self.n_data), np.arange(self.n_data + 2, len(J))]
        cov_c = _inverse(J[rows].T @ J[rows])
        sigma_c = (float(np.sqrt(max(np.linalg.eigvalsh(cov_c[1:3, 1:3]).max(), 0.0))) * self.scale
                   if cov_c is not None else np.inf)
        return sigma_f, sigma_c


def _inverse(info: Array) -> Array | None:
    w = np.linalg.eigvalsh(info)
    if w.min() <= 1e-12 * max(w.max(), 1e-300):
        return None
    return np.asarray(np.linalg.inv(info), float)


@dataclass(frozen=True)
class _Own:
    """A photo's own calibrations: with all its priors (``alone``) and from its lines only."""

    alone: PhotoCalibration | None
    error: CalibrationError | None
    lines: PhotoCalibration | None


def _own(member: GroupMember) -> _Own:
    kw = dict(member.kwargs)
    try:
        alone, error = calibrate_photo(**kw), None
    except CalibrationError as e:
        alone, error = None, e
    if kw.get("focal") is None and kw.get("exif_focal") is None:
        return _Own(alone, error, alone)
    try:
        lines = calibrate_photo(**{**kw, "focal": None, "exif_focal": None})
    except CalibrationError:
        lines = None
    return _Own(alone, error, lines)


def _determined(cal: PhotoCalibration | None) -> bool:
    return cal is not None and cal.f_sigma / cal.f <= FOCAL_UNDETERMINED_REL_SIGMA


def calibrate_shared(group: str, members: Sequence[GroupMember], *,
                     exif_focal: FocalPrior | None = None) -> SharedCalibration | None:
    """The group's shared intrinsics and its photos' rotations, or None where fewer than two of its
    photos can share them (the caller then calibrates each alone).

    exif_focal : the group's EXIF focal length (one camera, one value), compared with the lines
        and combined once where they allow it; each member's own ``exif_focal`` is not used here.
    """
    own = {m.photo: _own(m) for m in members}
    kw0 = members[0].kwargs
    width, height = int(kw0["width"]), int(kw0["height"])
    scale = float(max(width, height))
    lines = [o.lines for o in own.values() if _determined(o.lines)]
    if lines:
        w = np.array([1.0 / c.f_sigma**2 for c in lines if c is not None])
        f_start = float(np.sum(w * np.array([c.f for c in lines if c is not None])) / w.sum())
    elif exif_focal is not None:
        f_start = exif_focal.value
    else:
        f_start = scale
    starts: dict[str, PhotoCalibration] = {}
    failed: dict[str, CalibrationError] = {}
    for m in members:
        o = own[m.photo]
        start = o.alone or o.lines
        if start is None:
            try:  # what its rotation is, at the group's focal length: a start only
                start = calibrate_photo(**{**m.kwargs, "focal": FocalPrior(f_start, START_FOCAL_SIGMA_REL * f_start,
                                                                           "group"), "exif_focal": None})
            except CalibrationError:
                failed[m.photo] = o.error or CalibrationError(m.photo, "it cannot be calibrated")
                continue
        starts[m.photo] = start
    active = [m for m in members if m.photo in starts]
    released: dict[str, str] = {}
    while len(active) >= 2:
        solved = _solve(active, starts, f_start, exif_focal, scale, width, height)
        if solved is None:
            return None
        worst, z_worst = None, GROUP_DISAGREEMENT_SIGMAS
        for m in active:
            c = own[m.photo].lines
            if not _determined(c) or c is None or solved.lines_sigma is None:
                continue
            sd = float(np.sqrt(max(c.f_sigma**2 - solved.lines_sigma**2, 1e-6 * c.f_sigma**2)))
            z = abs(c.f - solved.lines_f) / sd
            if z > z_worst:
                worst, z_worst = m.photo, z
        if worst is None:
            return _result(group, solved, active, failed, released, exif_focal)
        c = own[worst].lines
        assert c is not None
        released[worst] = (f"its own lines give f = {c.f:.1f} ± {c.f_sigma:.1f} px, {z_worst:.1f}σ from the camera "
                           f"group's {solved.lines_f:.1f} px (limit {GROUP_DISAGREEMENT_SIGMAS:g}σ): not this camera's "
                           "focal length (a zoom moved, a crop, another body of the same model), so it is "
                           "calibrated on its own")
        active = [m for m in active if m.photo != worst]
    return None


@dataclass(frozen=True)
class _Solved:
    problem: SharedProblem
    problems: list[JointProblem]
    x: Array
    R: list[Array]
    priors: list[FocalPrior]
    lines_f: float
    lines_sigma: float | None  # the lines' 1σ on f (no focal prior), None where they do not fix it
    sigma_f_seg: float
    sigma_c_seg: float
    sigma_c: float
    exif_check: ExifCheck | None
    exif_combined: bool
    user_priors: list[FocalPrior]


def _polys(m: GroupMember) -> dict[str, list[Array]]:
    return {a: as_polylines(s, a, m.photo) for a, s in m.kwargs["segments"].items() if len(_flat(s)) > 0}


def _straightness(m: GroupMember) -> bool:
    """Whether any of the photo's segments has middle points (a plumb line: k1 is estimated)."""
    return any(len(q) > 2 for ps in _polys(m).values() for q in ps)


def _problem_of(m: GroupMember, own: PhotoCalibration | None, estimate_k1: bool, scale: float, c0: Array,
                sigma_c: float) -> JointProblem:
    """The photo's rows of the group's problem: its segments less those its own calibration rejected
    (.robust: clutter, slopes; an axis left out whole goes)."""
    kw = m.kwargs
    polys = _polys(m)
    axes = [a for a in "xyz" if a in polys]
    sigmas = segment_sigmas(polys, axes, float(kw.get("click_sigma_px", 1.0)), kw.get("segment_sigma_px"), m.photo)
    rejected = own.rejected_segments if own is not None else {}
    for a in list(axes):
        out = {r.index for r in rejected.get(a, ())}
        kept = [k for k in range(len(polys[a])) if k not in out]
        if len(kept) < 2:
            axes.remove(a)
            continue
        polys[a] = [polys[a][k] for k in kept]
        sigmas[a] = np.asarray(sigmas[a])[kept]
    return JointProblem({a: polys[a] for a in axes}, axes, {a: sigmas[a] for a in axes}, scale, c0, sigma_c, None,
                        estimate_k1)


def _bends(m: GroupMember, own: PhotoCalibration | None) -> bool:
    """Whether the photo's lines ask for k1: polylines, and its own calibration's test (.bending)
    did not hold k1 (a photo that could not be calibrated alone counts by its polylines)."""
    if not _straightness(m):
        return False
    return own is None or own.distortion_test is None or own.distortion_test.bends


def _solve(active: Sequence[GroupMember], starts: Mapping[str, PhotoCalibration], f_start: float,
           exif_focal: FocalPrior | None, scale: float, width: int, height: int) -> _Solved | None:
    kw0 = active[0].kwargs
    given = [m.kwargs["principal_point"] for m in active if m.kwargs.get("principal_point") is not None]
    if given:
        c0, sigma_c = np.array(given[0][0], dtype=np.float64), float(given[0][1])
    else:
        c0 = np.array([width / 2.0, height / 2.0])
        sigma_c = float(kw0.get("principal_point_sigma_rel", PRINCIPAL_POINT_SIGMA_REL)) * scale
    distortion = next((m.kwargs.get("distortion") for m in active if m.kwargs.get("distortion") is not None), None)
    estimate_k1 = distortion is not None or any(_bends(m, starts.get(m.photo)) for m in active)
    problems = [_problem_of(m, starts.get(m.photo), estimate_k1, scale, c0, sigma_c) for m in active]
    problem = SharedProblem(problems, scale, c0, sigma_c, distortion, estimate_k1)
    R0 = [starts[m.photo].R for m in active]
    k1_0 = distortion.k1 if distortion is not None else 0.0
    user = [m.kwargs["focal"] for m in active if m.kwargs.get("focal") is not None]
    x, R = problem.solve(problem.start(f_start, c0, k1_0), R0, user)
    sigma_f_seg, sigma_c_seg = problem.segment_information(x, R)
    f_lines = float(x[0] * scale)
    determined = sigma_f_seg / f_lines <= FOCAL_UNDETERMINED_REL_SIGMA
    lines_sigma = None
    if not user and determined:
        J = problem.jacobian(x, R, ())
        vf = problem.variance_factor(J, problem.residuals(x, R, ()))
        lines_sigma = sigma_f_seg * float(np.sqrt(max(vf, 1.0)))
    check, combined = None, False
    priors = list(user)
    if exif_focal is not None and not user:
        if lines_sigma is None:
            combined = True
        else:
            z = abs(exif_focal.value - f_lines) / float(np.hypot(exif_focal.sigma, lines_sigma))
            combined = lines_sigma >= EXIF_COMBINE_MIN_SIGMA_RATIO * exif_focal.sigma and z <= EXIF_DISAGREEMENT_SIGMAS
            check = ExifCheck(exif_focal, f_lines, lines_sigma, z, combined)
        if combined:
            priors.append(exif_focal)
            x, R = problem.solve(x, R, priors)
    if not priors and not determined:
        return None
    return _Solved(problem, problems, x, R, priors, f_lines, lines_sigma, sigma_f_seg, sigma_c_seg, sigma_c, check,
                   combined, user)


def _result(group: str, s: _Solved, active: Sequence[GroupMember], failed: dict[str, CalibrationError],
            released: dict[str, str], exif_focal: FocalPrior | None) -> SharedCalibration:
    problem, scale = s.problem, s.problem.scale
    J = problem.jacobian(s.x, s.R, s.priors)
    vf = problem.variance_factor(J, problem.residuals(s.x, s.R, s.priors))
    cov = problem.covariance(J, vf)
    f, cx, cy = s.x[:3] * scale
    k1 = float(s.x[3]) if problem.estimate_k1 else 0.0
    K = intrinsic_matrix(f, cx, cy)
    shared = [0, 1, 2, 3] if problem.estimate_k1 else [0, 1, 2]
    S = np.array([scale, scale, scale, 1.0])[: len(shared)]
    cov4 = np.zeros((4, 4))
    cov4[np.ix_(range(len(shared)), range(len(shared)))] = cov[np.ix_(shared, shared)] * np.outer(S, S)
    prior_sigma = min((p.sigma for p in s.priors), default=np.inf)
    prior_dominates = bool(s.priors) and not s.sigma_f_seg <= prior_sigma
    mode = "3vp" if s.sigma_c_seg <= s.sigma_c else "1vp" if prior_dominates else "2vp"
    sources = sorted({p.source for p in s.priors})
    focal_source = ("vanishing points" if not s.priors else " + ".join(sources) if prior_dominates
                    else "vanishing points + " + " + ".join(sources))
    names = ", ".join(f"'{m.photo}'" for m in active)
    rel = s.sigma_f_seg / f
    reason = [f"f, principal point and lens distortion shared by the {len(active)} photos of camera group "
              f"'{group}' ({names}): f from the vanishing points of all of them (1σ {_pct(rel)})"]
    if s.exif_check is not None:
        c = s.exif_check
        reason.append(f"EXIF's f = {c.exif.value:.1f} px differs from the vanishing points' by "
                      f"{100 * c.difference_rel:+.1f} % ({c.sigmas:.1f}σ)"
                      + (": combined" if c.combined else
                         f": not combined, beyond {EXIF_DISAGREEMENT_SIGMAS:g}σ" if c.sigmas > EXIF_DISAGREEMENT_SIGMAS
                         else ": not combined, the vanishing points being surer, only a cross-check"))
    elif s.exif_combined and exif_focal is not None:
        reason.append(f"EXIF (1σ {_pct(exif_focal.sigma / exif_focal.value)}) combined, the vanishing points "
                      "cannot cross-check it")
    reason.append(f"the principal point from three vanishing points (1σ {s.sigma_c_seg:.0f} px) combined with its prior"
                  if mode == "3vp" else f"the principal point from its prior (1σ {s.sigma_c:.0f} px)")
    if vf > 1.0:
        reason.append(f"the marks fit {np.sqrt(vf):.2f}× worse than the stated click noise, so every 1σ is widened "
                      "as much")
    distortion = next((m.kwargs.get("distortion") for m in active if m.kwargs.get("distortion") is not None), None)
    straight = any(_straightness(m) for m in active)
    k1_source = ("segments" + (f" + {distortion.source}" if distortion is not None else "") if straight
                 else distortion.source if distortion is not None else "none")
    if problem.estimate_k1:
        reason.append(f"lens distortion k1 = {k1:+.4f} ± {np.sqrt(max(cov4[3, 3], 0.0)):.4f} shared")
    text = "; ".join(reason)
    photos = {}
    for i, (m, p) in enumerate(zip(active, s.problems, strict=True)):
        o = problem.n_shared + 3 * i
        idx = [0, 1, 2, o, o + 1, o + 2, *([3] if problem.estimate_k1 else [])]
        Si = np.array([scale, scale, scale, 1.0, 1.0, 1.0, 1.0])[: len(idx)]
        cov7 = np.zeros((7, 7))
        cov7[np.ix_(range(len(idx)), range(len(idx)))] = cov[np.ix_(idx, idx)] * np.outer(Si, Si)
        y = problem.member_y(s.x, i)
        U = p.undistorted(y)
        vps = {a: K @ s.R[i][:, "xyz".index(a)] for a in p.axes}
        photos[m.photo] = PhotoCalibration(
            photo=m.photo, width=int(m.kwargs["width"]), height=int(m.kwargs["height"]), mode=mode,
            mode_reason=text, focal_source=focal_source, K=K, R=s.R[i], covariance=cov7[:6, :6].copy(),
            vanishing_points=vps, segment_residuals_px={a: p.reported_residuals(U, a, vps[a]) for a in p.axes},
            k1=k1, k1_sigma=float(np.sqrt(max(cov7[6, 6], 0.0))), k1_source=k1_source, covariance_k1=cov7,
            exif_check=s.exif_check)
    S_all = np.r_[scale, scale, scale, np.ones(problem.n_params - 3)]
    return SharedCalibration(group, photos, float(f), np.array([cx, cy]), k1, cov4, mode, text, focal_source,
                             k1_source, vf, s.exif_check, released, failed, cov * np.outer(S_all, S_all))


def with_group(cal: PhotoCalibration, note: str) -> PhotoCalibration:
    """A photo's own calibration with a note on its group appended to its mode reason."""
    return replace(cal, mode_reason=f"{cal.mode_reason}; {note}")
