"""What the joint placement (:mod:`.positions`) checks of its own result before it reports it.

- **Each photo's fit against the stated noise** (variance component estimation, Förstner): the
  photo's share of χ² (its marker rows, whitened by the click noise, and its prior rows, whitened by
  its vanishing-point covariance) over its share of the redundancy, Σ (1 − hᵢᵢ) over those rows
  (hᵢᵢ the hat matrix's diagonal, so the shares add up to the solve's degrees of freedom). Where the
  χ² exceeds its :data:`PHOTO_CHI2_P` quantile, the photo's markers and vanishing lines contradict
  each other: a warning names it, and its camera's covariance is widened by its own variance
  factor (never narrowed: the solve's global factor is the least).
- **The lens distortion within what real lenses have** (:data:`K1_CORNER_RANGE`): a refined k1
  beyond it is not a lens but a misfit absorbed (a wrong rotation or focal length held by an
  overconfident prior); the placement is solved again with that photo's k1 held at its
  calibration's value, and a warning says so.
- **A covariance that can be computed**: a camera whose block is not finite (the markers do not
  determine it) is not reported with a null σ; :func:`check_camera_covariances` raises a
  CalibrationError naming the photo, which ``vebuild calibrate`` leaves out of the joint placement.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.errors import CalibrationError

from .placement_types import PhotoInput, ReferenceDistance

Array = NDArray[np.float64]

#: A photo's χ² beyond this upper-tail probability (on its share of the redundancy) is a contradiction
#: between its markers and its vanishing lines, not noise: 1 photo in 1,000 honest ones is warned about.
PHOTO_CHI2_P = 0.001

#: The relative radial displacement at the image corner, k1·ρc² (ρc: the half diagonal over f; the
#: division model of vebuild/camera.py displaces a point by the factor ≈ 1 + k1ρ²), that real
#: rectilinear lenses span. Fitted (as :func:`.exif.lens_distortion_prior` fits one profile) to
#: every rectilinear distortion profile of lensfun's database (lensfunpy 1.18, 1,925 profiles at
#: their shortest and longest focal lengths, on a 3:2 frame): −0.72 (action cameras) to +0.32,
#: 99 % within −0.24…+0.06. The bound holds those extremes with a margin; fisheye lenses (to −5.3)
#: are not the division model's one-parameter business.
K1_CORNER_RANGE = (-0.8, 0.4)

#: Rows of the Jacobian made dense at a time for the leverages (a house's placement has thousands).
LEVERAGE_ROWS = 1024


def k1_in_range(k1: float, corner_px: float, f: float) -> bool:
    """Whether k1 displaces the corner (``corner_px`` from the principal point, focal length ``f``
    in pixels) within :data:`K1_CORNER_RANGE`; True where the corner is not known (0)."""
    if not corner_px > 0 or not f > 0:
        return True
    d = k1 * (corner_px / f) ** 2
    return bool(np.isfinite(d) and K1_CORNER_RANGE[0] <= d <= K1_CORNER_RANGE[1])


def leverages(J: Any, cov: Array) -> Array:
    """hᵢᵢ = Jᵢ (JᵀJ)⁻¹ Jᵢᵀ of every row of a whitened Jacobian, ``cov`` = (JᵀJ)⁻¹ unscaled; a row
    touching an undetermined (infinite) column counts as fully used (h = 1)."""
    from scipy import sparse

    Js = sparse.csr_matrix(J)
    finite = np.all(np.isfinite(cov), axis=0)
    c = np.where(np.isfinite(cov), cov, 0.0)
    h = np.empty(Js.shape[0])
    for a in range(0, Js.shape[0], LEVERAGE_ROWS):  # a block of rows at a time: J dense would not fit
        Jd = Js[a : a + LEVERAGE_ROWS].toarray()
        hb = np.einsum("ij,ij->i", Jd @ c, Jd)
        hb[np.any(Jd[:, ~finite] != 0.0, axis=1)] = 1.0
        h[a : a + LEVERAGE_ROWS] = hb
    return np.clip(h, 0.0, 1.0)


def photo_variance_factors(res: Array, h: Array, rows: Sequence[Array]) -> list[tuple[float, float]]:
    """(χ², redundancy) of each photo's rows ``rows[k]`` (indices into the whitened residuals)."""
    return [(float(res[r] @ res[r]), float(np.sum(1.0 - h[r]))) for r in rows]


def contradicts(chi2: float, dof: float) -> bool:
    """Whether χ² on ``dof`` degrees of freedom lies beyond the :data:`PHOTO_CHI2_P` tail."""
    from scipy.stats import chi2 as chi2_dist

    return dof > 0.5 and chi2 > float(chi2_dist.isf(PHOTO_CHI2_P, dof))


def contradiction_warning(photo: str, chi2: float, dof: float, rms_px: float, click_sigma: float,
                          prior_sigmas: float, widened: float) -> str:
    """The warning for a photo whose markers and vanishing lines contradict each other."""
    return (f"photo '{photo}': its markers and its vanishing lines contradict each other: the placement's residuals "
            f"give χ² = {chi2:.1f} on {dof:.1f} degrees of freedom (p < {PHOTO_CHI2_P:g}; its markers fit to "
            f"{rms_px:.1f} px RMS against {click_sigma:g} px of click noise, and its camera moved {prior_sigmas:.1f}σ "
            f"from its vanishing-point calibration); its σ are widened {widened:.1f}×. Check its vanishing lines "
            "(segments on clutter or slopes, a wrong axis) and its markers' clicks")


def check_camera_covariances(ids: Sequence[str], cov: Array, blocks: Sequence[Array], markers: Sequence[int]
                             ) -> None:
    """Raise a CalibrationError naming the first photo whose camera block of ``cov`` (its columns
    ``blocks[k]``) is not finite: the marks do not determine that camera, and a σ of null is no answer."""
    for pid, cols, n in zip(ids, blocks, markers, strict=True):
        sub = cov[np.ix_(cols, cols)]
        if not np.all(np.isfinite(sub)):
            raise CalibrationError(
                pid, f"the joint placement cannot determine this camera (its covariance is not finite: its {n} "
                "markers, its vanishing lines and the other photos do not fix its focal length, rotation and "
                "position together: too few markers, or markers that cannot tell its focal length from its distance, "
                "as where its vanishing lines give a focal length far too long); check its vanishing lines, and mark "
                "more markers it shares with the other photos, spread over it and at different depths (6 or more)")


def contradictions(ids: Sequence[str], res: Array, J: Any, cov0: Array, s2: float, mark_rows: Sequence[Array],
                   prior_rows: Sequence[Array], click_sigma: float) -> tuple[list[str], Array, Array]:
    """The warnings for the photos whose χ² share contradicts the stated noise; each photo's
    widening of its covariance (1 where it does not): its variance factor over the global ``s2``;
    and where it does, its prior's own variance factor (its prior rows' χ² over their redundancy,
    at least 1): what its prior's covariance is to be widened by before solving again."""
    h = leverages(J, cov0)
    shares = photo_variance_factors(res, h, [np.r_[m, p].astype(int) for m, p in zip(mark_rows, prior_rows,
                                                                                    strict=True)])
    notes, widen, prior_factor = [], np.ones(len(ids)), np.ones(len(ids))
    for k, (chi2, dof) in enumerate(shares):
        if contradicts(chi2, dof):
            widen[k] = max(1.0, chi2 / dof / s2)
            p_chi2, p_dof = photo_variance_factors(res, h, [prior_rows[k]])[0]
            prior_factor[k] = max(1.0, p_chi2 / max(p_dof, 0.5))
            mark = res[mark_rows[k]] * click_sigma
            pr = res[prior_rows[k]]
            rms = float(np.sqrt(np.mean(mark**2))) if mark.size else 0.0
            notes.append(contradiction_warning(ids[k], chi2, dof, rms, click_sigma, float(np.sqrt(pr @ pr)),
                                               float(np.sqrt(widen[k]))))
    return notes, widen, prior_factor


def check_finite_inputs(photos: Sequence[PhotoInput], known: Mapping[str, Array],
                         distances: Sequence[ReferenceDistance]) -> None:
    """Every number going into the placement is finite, else a CalibrationError naming its owner."""
    for p in photos:
        for what, v in (("focal length and principal point (K)", p.K), ("rotation (R)", p.R),
                        ("calibration covariance", p.covariance)):
            if not np.all(np.isfinite(np.asarray(v, float))):
                raise CalibrationError(p.id, f"its {what} from the vanishing points is not a finite number; check its "
                                       "vanishing lines (a near-degenerate set gives an infinite focal length)")
        for name, uv in p.markers.items():
            if np.shape(uv) != (2,) or not np.all(np.isfinite(np.asarray(uv, float))):
                raise CalibrationError(p.id, f"marker '{name}': expected a finite pixel (u, v), got {uv!r}")
    for name, pos in known.items():
        if np.shape(pos) != (3,) or not np.all(np.isfinite(pos)):
            raise CalibrationError(None, f"marker '{name}': its surveyed position is not three finite numbers")
    for d in distances:
        if not (np.isfinite(d.distance) and d.distance > 0 and np.isfinite(d.sigma) and d.sigma > 0):
            raise CalibrationError(None, f"reference distance {d.a}–{d.b}: expected a length > 0 m and a σ > 0 m, "
                                   f"got {d.distance!r} ± {d.sigma!r}")


def check_finite_start(C: Mapping[str, Array], X: Mapping[str, Array]) -> None:
    """The construction's camera and marker positions must be finite numbers (a photo's
    vanishing points or clicks can make a ray parallel to a baseline)."""
    for pid, c in C.items():
        if not np.all(np.isfinite(c)):
            raise CalibrationError(pid, "the camera's position from the construction is not a finite number: its "
                                   "rays to the markers it shares with other photos are parallel to the baseline; "
                                   "check its vanishing lines and marker clicks, or mark another shared marker")
    for name, x in X.items():
        if not np.all(np.isfinite(x)):
            raise CalibrationError(None, f"marker '{name}': its position from the photos is not a finite number "
                                   "(its rays from two photos are parallel); check its clicks, or mark it in a "
                                   "photo taken from elsewhere")
