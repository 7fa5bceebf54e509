"""Statistical constants shared by calibration, the solver, the analyses and the screens.

Each value is stated once, with the reason for it; a module that needs one imports it from here
rather than writing the number again.
"""

from __future__ import annotations

#: Two-sided 95 % quantile of a standard Gaussian (Φ⁻¹(0.975)): a 95 % interval is value ± Z95 σ.
Z95 = 1.959963984540054

#: A whitened residual (error / stated noise) beyond this is reported as an outlier. For a 2-D
#: click with Gaussian noise the norm exceeds 4σ with probability e^(−8) ≈ 3.4 × 10⁻⁴: about one
#: false flag in 3000 honest clicks, while a click on the wrong corner (tens of pixels, 10σ and
#: more at 1–2 px noise) is always caught. Calibration, the solver and the modelling screen flag
#: with this one value, so a mark flagged on screen is the one the report names.
OUTLIER_SIGMAS = 4.0

#: Scale of the robust (soft-L1) loss, in units of the stated noise: residuals below it are
#: weighed as in plain least squares (99.7 % of honest clicks per coordinate), larger ones grow
#: only linearly so that one wrong click cannot drag the solution.
ROBUST_SCALE = 3.0

#: A check distance whose measurement differs from the tape by more than this many σ (σ² the
#: measurement's variance from the placement's covariance plus the tape's) fails the calibration:
#: for honest Gaussian errors |z| > 5 has probability 5.7 × 10⁻⁷, so a failure means the cameras
#: or the tape are wrong (a photo placed with its axes turned was −24σ), not noise. Between 3σ
#: and this limit the calibration warns.
CHECK_FAIL_SIGMAS = 5.0

__all__ = ["Z95", "OUTLIER_SIGMAS", "ROBUST_SCALE", "CHECK_FAIL_SIGMAS"]
