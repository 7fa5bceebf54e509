"""Several frames of one person combined into one height with its 95 % interval.

Each frame gives y_i = its height in the image + its own allowances (stance and stride, head-top
visibility: the posture and the view of that frame), with covariance V: on the diagonal the frame's
σ² (calibration, clicks, its allowances), off it the calibration's share common to two frames
measured on the same photo, or on stills of one fixed camera calibrated as one (σ_cal,i σ_cal,j:
the same camera's error moves both alike; frames on photos calibrated apart are taken as
independently calibrated).

The frames of a person also differ by more than their σ says (the head bobs over a stride, the
posture changes): a **random-effects** combination. The between-frame variance τ² is estimated by
the method of moments of DerSimonian and Laird (1986), generalised to a full V:
Q = rᵀ V⁻¹ r with r the residuals of the generalised least-squares mean, E[Q] = (n − 1) + τ² tr(P),
P = V⁻¹ − V⁻¹11ᵀV⁻¹ / 1ᵀV⁻¹1, so τ² = max(0, (Q − (n − 1)) / tr(P)). The mean weighs each frame by
W = (V + τ² I)⁻¹. Its interval is the Hartung–Knapp–Sidik–Jonkman one: variance
q / 1ᵀW1 with q = rᵀ W r / (n − 1) the spread of the frames about the mean, and Student's t with
n − 1 degrees of freedom in place of the Gaussian's 1.96: the interval then covers at its stated
rate however large the between-frame spread, which the Gaussian interval with DerSimonian–Laird's
τ² does not with few frames (tests/test_person_height.py draws such frames). With two frames the
spread is known poorly and the interval is wide (t = 12.7): measure more frames.

The allowances that are the same in every frame (footwear, head covering) are then added once, as
they are fully correlated across frames and no number of frames averages them down: the 95 %
half-width is the combined frames' and the allowances' (1.96 σ) added in quadrature.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vebuild.constants import Z95
from vebuild.errors import VebuildError

from .person import PersonFrame
from .person_terms import Term

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Combined:
    """A person's height from ``frames``: the frames' random-effects mean (``frames_value``, with
    its 95 % half-width ``frames_half95`` and effective 1σ), the between-frame spread τ, the
    allowances added once (``person_terms``), and the height with its 95 % interval."""

    person: str
    frames: tuple[PersonFrame, ...]
    frames_value: float
    frames_sigma: float  # the 1σ the interval rests on
    frames_half95: float
    tau: float
    dof: int
    person_terms: tuple[Term, ...]

    @property
    def value(self) -> float:
        return self.frames_value + sum(t.signed for t in self.person_terms)

    @property
    def half95(self) -> float:
        return float(np.hypot(self.frames_half95, Z95 * np.sqrt(sum(t.sigma**2 for t in self.person_terms))))

    @property
    def sigma(self) -> float:
        """The interval's half-width in Gaussian 1σ (half95 / 1.96), for tables beside other 1σ."""
        return self.half95 / Z95

    @property
    def ci95(self) -> tuple[float, float]:
        return self.value - self.half95, self.value + self.half95

    def words(self) -> str:
        lo, hi = self.ci95
        return f"between {lo:.2f} and {hi:.2f} m (95 %)"

    def to_json(self) -> dict[str, object]:
        lo, hi = self.ci95
        return {"person": self.person, "frames": len(self.frames), "photos": sorted({f.photo for f in self.frames}),
                "frames_value_m": self.frames_value, "frames_sigma_m": self.frames_sigma,
                "between_frames_sigma_m": self.tau, "degrees_of_freedom": self.dof,
                "terms_once": [t.to_json() for t in self.person_terms], "value_m": self.value, "sigma_m": self.sigma,
                "ci95_m": [lo, hi], "method": METHOD}


METHOD = ("random effects: DerSimonian–Laird between-frame variance, Hartung–Knapp–Sidik–Jonkman interval "
          "(Student's t, n − 1 degrees of freedom); footwear and head covering added once")


def random_effects(y: Array, V: Array, shared: Array | None = None) -> tuple[float, float, float, float, int]:
    """The random-effects mean of ``y`` (n,) with known covariance ``V`` (n, n), of which ``shared``
    (n, n) is common to frames measured on one photo (its calibration's error, which their spread
    cannot show): (mean, its 1σ, its 95 % half-width, τ, degrees of freedom) (module docstring). One
    value: itself, its σ, the Gaussian's 95 %."""
    n = len(y)
    if n == 1:
        s = float(np.sqrt(V[0, 0]))
        return float(y[0]), s, Z95 * s, 0.0, 0
    C = np.zeros((n, n)) if shared is None else shared
    one = np.ones(n)
    W0 = np.linalg.inv(V)
    a0 = float(one @ W0 @ one)
    r0 = y - float(one @ W0 @ y) / a0
    Q = float(r0 @ W0 @ r0)
    P = W0 - np.outer(W0 @ one, one @ W0) / a0
    tau2 = max(0.0, (Q - (n - 1)) / float(np.trace(P)))
    W = np.linalg.inv(V + tau2 * np.eye(n))
    w = W @ one / float(one @ W @ one)  # the frames' weights in the mean
    mean = float(w @ y)
    r = y - mean
    q = float(r @ W @ r) / (n - 1)
    var_seen = float(w @ (V - C + tau2 * np.eye(n)) @ w)  # what the frames' spread shows: scaled by q, t's
    var_shared = float(w @ C @ w)  # known, not shown by the spread: the Gaussian's
    from scipy.special import stdtrit  # imported at first use: docs/start-up.md (one frame needs none)

    half = float(np.hypot(float(stdtrit(n - 1, 0.975)) * np.sqrt(q * var_seen), Z95 * np.sqrt(var_shared)))
    return mean, float(np.sqrt(q * var_seen + var_shared)), half, float(np.sqrt(tau2)), n - 1


def _person_terms(person: str, frames: Sequence[PersonFrame]) -> tuple[Term, ...]:
    """The allowances the same in every frame: each entered on any frame, the same wherever entered."""
    out: dict[str, tuple[Term, str]] = {}
    for f in frames:
        for t in f.terms:
            if not t.kind.per_person:
                continue
            if t.name in out and (out[t.name][0].value, out[t.name][0].sigma) != (t.value, t.sigma):
                raise VebuildError(f"person '{person}': the {t.kind.words} is entered as {out[t.name][0].words()} "
                                   f"on photo '{out[t.name][1]}' and as {t.words()} on photo '{f.photo}'; it is "
                                   "the same in every frame of one person: enter one value")
            out.setdefault(t.name, (t, f.photo))
    return tuple(t for t, _ in out.values())


def combine(person: str, frames: Sequence[PersonFrame]) -> Combined:
    """The frames of ``person`` combined (module docstring)."""
    if not frames:
        raise VebuildError(f"person '{person}': no frame measured")
    n = len(frames)
    y = np.array([f.image_height + sum(t.signed for t in f.terms if not t.kind.per_person) for f in frames])
    V = np.zeros((n, n))
    shared = np.zeros((n, n))
    for i, fi in enumerate(frames):
        V[i, i] = fi.sigma_image**2 + sum(t.sigma**2 for t in fi.terms if not t.kind.per_person)
        for j, fj in enumerate(frames):
            if i != j and fi.calibrated_as == fj.calibrated_as:
                V[i, j] = shared[i, j] = fi.sigma_calibration * fj.sigma_calibration
                shared[i, i] = fi.sigma_calibration**2
    if np.linalg.matrix_rank(V) < n:
        raise VebuildError(f"person '{person}': two frames are the same measurement on one photo with no click "
                           "uncertainty; record each frame once")
    mean, s, half, tau, dof = random_effects(y, V, shared)
    return Combined(person, tuple(frames), mean, s, half, tau, dof, _person_terms(person, frames))
