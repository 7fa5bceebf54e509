"""Segments that do not belong to the axis they are grouped into, for tests and benchmarks.

Real photographs give a vanishing-point fit more than its edges: automatic detection groups
cobblestone edges, sloping roof and dormer edges, railings and wires with a building's directions,
and a user marks the edges of a second building a few degrees off square to the first. The kinds
:func:`add_clutter` adds to a :class:`vebuild.synthetic.SyntheticPhoto`, each labelled with the
axis it is (wrongly) grouped into and directed as that axis' segments are there (as detection
directs them), each recorded in ``photo.clutter`` (axis → indices into ``photo.segments[axis]``):

- ``cobblestones``: many short edges (15–60 px) in random directions in the photo's lower third,
  where the pavement is;
- ``slopes``: long roof or dormer edges, along the axis tilted 25–45° up or down in the vertical
  plane through it (for ``z``: tilted 10–25° off the vertical): parallel among themselves, so they
  meet at a vanishing point of their own, off the axis' one;
- ``not_square``: long edges of a second building turned by ``turn_deg`` (a few degrees) about
  the vertical: parallel among themselves, their vanishing point near the axis' true one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from . import SyntheticPhoto, distort, inside_image, project_points, projection_matrix

Array = NDArray[np.float64]

CLUTTER_KINDS = ("cobblestones", "slopes", "not_square")


def _direction(kind: str, axis: str, rng: np.random.Generator, turn_deg: float) -> Array:
    """The world direction of one clutter edge (unit), for slopes and a second building."""
    e = np.eye(3)["xyz".index(axis)]
    if kind == "not_square":
        t = np.radians(turn_deg)
        Rz = np.array([[np.cos(t), -np.sin(t), 0.0], [np.sin(t), np.cos(t), 0.0], [0.0, 0.0, 1.0]])
        return np.asarray(Rz @ e, float)
    if axis == "z":
        tilt = np.radians(rng.uniform(10.0, 25.0))
        side = np.eye(3)[0]
        return np.cos(tilt) * e + np.sin(tilt) * side
    tilt = np.radians(rng.uniform(25.0, 45.0)) * rng.choice([-1.0, 1.0])
    return np.cos(tilt) * e + np.sin(tilt) * np.eye(3)[2]


def add_clutter(photo: SyntheticPhoto, rng: np.random.Generator, kind: str, axis: str, n: int,
                noise_px: float = 0.7, turn_deg: float = 4.0, min_length_rel: float = 0.2) -> list[int]:
    """Add n clutter segments of ``kind`` (module doc) to ``photo.segments[axis]``; returns their
    indices there (also recorded in ``photo.clutter[axis]``). Slopes and a second building are
    long edges (min_length_rel of the longer side or more) 1.5–7 m ahead, clicked with noise_px;
    a slope keeps one tilt per photo (one roof pitch)."""
    if kind not in CLUTTER_KINDS:
        raise ValueError(f"kind must be one of {', '.join(CLUTTER_KINDS)}, got {kind!r}")
    P = projection_matrix(photo.K, photo.R, photo.C)
    i = "xyz".index(axis)
    vp = photo.K @ photo.R[:, i]  # the axis' true vanishing point: which way its segments run
    existing = photo.segments.get(axis, np.zeros((0, 4)))
    rows: list[Array] = [np.asarray(s, float).reshape(-1) for s in existing]
    first = len(rows)
    direction = _direction(kind, axis, rng, turn_deg)
    longer = max(photo.width, photo.height)
    for _ in range(200000):
        if len(rows) - first == n:
            break
        if kind == "cobblestones":
            mid = np.array([rng.uniform(0, photo.width), rng.uniform(2 * photo.height / 3, photo.height)])
            a = rng.uniform(0, np.pi)
            half = 0.5 * rng.uniform(15.0, 60.0) * np.array([np.cos(a), np.sin(a)])
            uv = np.array([mid - half, mid + half])
        else:
            depth = rng.uniform(1.5, 7.0)
            ray = np.linalg.solve(photo.K, np.r_[rng.uniform(0, photo.width), rng.uniform(0, photo.height), 1.0])
            X = photo.C + depth * (photo.R.T @ (ray / ray[2]))
            half_m = rng.uniform(0.3, 2.5)
            uv, z = project_points(P, np.array([X - half_m * direction, X + half_m * direction]))
            if np.any(z < 0.5) or np.linalg.norm(uv[1] - uv[0]) < min_length_rel * longer:
                continue
            uv = distort(photo, uv)
        if not inside_image(uv, photo.width, photo.height, 5.0):
            continue
        # Directed as the axis' own segments run there: toward its vanishing point's side.
        m = 0.5 * (uv[0] + uv[1])
        toward = vp[:2] - m * vp[2]
        if float((uv[1] - uv[0]) @ toward) < 0:
            uv = uv[::-1]
        rows.append((uv + rng.normal(0.0, noise_px, uv.shape)).reshape(-1))
    added = list(range(first, len(rows)))
    if len({len(r) for r in rows}) <= 1:
        photo.segments[axis] = np.array(rows)
    else:
        photo.segments[axis] = rows
    photo.clutter.setdefault(axis, []).extend(added)
    return added
