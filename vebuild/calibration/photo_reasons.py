"""The mode reason's words on a photo's focal length and principal point
(:func:`vebuild.calibration.photo.calibrate_photo`), and the limits they cite."""

from __future__ import annotations

import numpy as np

from .priors import ExifCheck, FocalPrior

#: The segments say nothing usable about f when their own 1σ on it exceeds this share of f: the
#: 95 % interval f ± 1.96σ then reaches f ≤ 0. Only then, with no focal length from the user or
#: EXIF, is a photo refused; below it, however wide, the result is given with its 1σ.
FOCAL_UNDETERMINED_REL_SIGMA = 1.0 / 1.96
#: The limit of EXIF as evidence: where EXIF's focal length and the segments' alone are more than
#: this many σ apart, EXIF is not combined and the photo is calibrated from its segments alone, the
#: disagreement said in the mode reason and as a warning. The σ count (.priors.ExifCheck) is the
#: smaller of the likelihood ratio's and |f_EXIF − f_segments| / √(σ_EXIF² + σ_segments²), with
#: σ_segments the wider of the segments' linearised 1σ at their own estimate and at EXIF's: the two
#: agree for Gaussian estimates, and where weak segments' likelihood is skewed (a frontal view's f
#: grows far more readily than it shrinks) neither alone is to be trusted to call EXIF wrong. Two
#: honest estimates of one focal length are more than 3σ apart in 0.27 % of photos; EXIF's 1σ
#: already holds its nominal errors (vebuild/calibration/exif.py), so beyond that it describes
#: another focal length (a crop, a digital zoom, a fixed-lens camera writing one value at every zoom
#: step), and their weighted mean would be neither, with a 1σ narrower than either's.
EXIF_DISAGREEMENT_SIGMAS = 3.0


def _pct(rel: float) -> str:
    """A relative 1σ as a percentage with two significant figures ("0.84 %", "5.0 %", "37 %")."""
    v = 100.0 * rel
    if not np.isfinite(v):
        return "∞ %"
    return f"{v:.0f} %" if v >= 10 else f"{v:.1f} %" if v >= 1 else f"{v:.2f} %"


def focal_reason(rel_seg: float, focal: FocalPrior | None, exif: FocalPrior | None, check: ExifCheck | None,
                  exif_combined: bool, exif_rejected: bool, prior_dominates: bool) -> str:
    seg = (f"the vanishing points (1σ {_pct(rel_seg)})" if rel_seg <= FOCAL_UNDETERMINED_REL_SIGMA
           else f"the vanishing points, which barely determine it (1σ {_pct(rel_seg)})")
    cross = ""
    if check is not None:
        cross = (f"EXIF's f = {check.exif.value:.1f} px differs from the vanishing points' by "
                 f"{100 * check.difference_rel:+.1f} % ({check.sigmas:.1f}σ)")
        if check.sigmas > EXIF_DISAGREEMENT_SIGMAS:
            cross += ": probably not this photo's focal length (cropped, or a zoom EXIF does not record)"
    if focal is not None:
        what = (f"f from the user's focal length (1σ {_pct(focal.sigma / focal.value)}) combined with {seg}"
                if prior_dominates else
                f"f from {seg} combined with the user's focal length (1σ {_pct(focal.sigma / focal.value)})")
        if exif is not None:
            what += f"; EXIF not used ({cross})" if cross else "; EXIF not used"
        return what
    if exif is None:
        return f"f from {seg}; no EXIF focal length to cross-check"
    e = f"EXIF (1σ {_pct(exif.sigma / exif.value)})"
    if exif_combined:
        what = f"f from {e} combined with {seg}" if prior_dominates else f"f from {seg} combined with {e}"
        return what + (f"; {cross}" if cross else "; the vanishing points cannot cross-check EXIF")
    if exif_rejected:
        return (f"f from {seg} alone; {e} not combined, the vanishing points contradicting it by more than "
                f"{EXIF_DISAGREEMENT_SIGMAS:g}σ: {cross}")
    return f"f from {seg}; {e} not combined, the vanishing points being surer, only a cross-check: {cross}"


def principal_point_reason(mode: str, sigma_c_seg: float, sigma_c: float, where: str, vf: float) -> str:
    prior = f"its prior (1σ {sigma_c:.0f} px at {where})"
    if mode == "3vp":
        text = f"the principal point from three vanishing points (1σ {sigma_c_seg:.0f} px) combined with {prior}"
    elif np.isfinite(sigma_c_seg):
        text = f"the principal point from {prior}, the vanishing points fixing it only to {sigma_c_seg:.0f} px"
    else:
        text = f"the principal point from {prior}, which the vanishing points do not fix"
    if vf > 1.0:
        text += f"; the marks fit {np.sqrt(vf):.2f}× worse than the stated click noise, so every 1σ is widened as much"
    return text
