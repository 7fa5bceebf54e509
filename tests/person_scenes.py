"""A generated one-photo scene with an upright figure of known height standing on the floor
(tests/test_person_height.py): the single-view scene of tests/single_view_scenes.py (its camera,
its door the known length), with a person 2.5–5 m ahead, the clicks of its head-top, of the point
between its feet and of each foot, with the clicks' noise."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from single_view_scenes import H, W, pixel, scene

#: The figures generated: 1.50–1.95 m tall, the feet 0.1–0.3 m apart.
HEIGHTS_M = (1.50, 1.95)


@dataclass
class PersonScene:
    sc: Any  # the single-view scene (its camera, marks, …)
    height: float  # the figure's true height (its head-top above the floor)
    foot: np.ndarray  # the true foot point (the feet's midpoint) on the floor
    head_px: np.ndarray  # the exact pixels
    foot_px: np.ndarray
    feet_px: tuple[np.ndarray, np.ndarray]


def person_scene(rng: np.random.Generator, noise_px: float, extra: float = 0.0) -> PersonScene:
    """One scene whose figure (head, feet) lies wholly on the photo, at least 5 px inside;
    ``extra``: what the figure's shoes add, so that its head-top is imaged ``extra`` higher
    (``height`` stays the standing height)."""
    for _ in range(200):
        sc = scene(rng, noise_px)
        cam = sc.cam
        yaw = np.arctan2(cam.R[2, 1], cam.R[2, 0])  # the optical axis' heading (third row of R)
        fwd = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        side = np.array([-fwd[1], fwd[0], 0.0])
        foot = cam.C * [1, 1, 0] + rng.uniform(2.5, 5.0) * fwd + rng.uniform(-0.8, 0.8) * side
        h = rng.uniform(*HEIGHTS_M)
        half = rng.uniform(0.05, 0.15) * (np.cos(a := rng.uniform(0, np.pi)) * fwd + np.sin(a) * side)
        try:
            px = [pixel(cam, X) for X in (foot + [0, 0, h + extra], foot, foot - half, foot + half)]
        except ValueError:
            continue
        if all(5 < u < W - 5 and 5 < v < H - 5 for u, v in px):
            return PersonScene(sc, float(h), foot, px[0], px[1], (px[2], px[3]))
    raise RuntimeError("no figure on the photo")


def binomial_acceptance(n: int, p: float = 0.95, alpha: float = 0.01) -> tuple[int, int]:
    """The counts (lo, hi) of successes out of ``n`` trials of probability ``p`` outside which a
    count falls with probability at most ``alpha`` / 2 on each side."""
    from math import comb

    pmf = [comb(n, k) * p**k * (1 - p) ** (n - k) for k in range(n + 1)]
    lo, tail = 0, 0.0
    while tail + pmf[lo] <= alpha / 2:
        tail, lo = tail + pmf[lo], lo + 1
    hi, tail = n, 0.0
    while tail + pmf[hi] <= alpha / 2:
        tail, hi = tail + pmf[hi], hi - 1
    return lo, hi
