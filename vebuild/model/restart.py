"""A solve's start, judged and repaired before anything is called undetermined (paper §3.1).

A least-squares solve that ends with parameters the pins do not fix, or with relations that miss,
has two possible causes: too few observations (the rank of the observations' Jacobian says so at
any start), or a start from which the iteration fell into another minimum (a node placed behind
the wall it is flush with, turned round, its pinned corners behind their camera). Only the first
is the user's to fix with more pins or entered values; the second is fixed by a better start.

- :func:`troubled_nodes`: the nodes a solve left in doubt (an undetermined parameter, a relation
  that misses, a pinned corner behind its camera);
- :func:`restart_nodes`: each such node re-started from its own pins: solved alone (the rest of
  the model held where it is, its relations holding) from its present yaw and the three quarter
  turns, the start with the least cost kept;
- :func:`start_report`: what a solve that still fails says is true of its start: which of the
  parameters it leaves undetermined the observations do determine at the start (a bad start, not
  too few observations), how far the solve carried each node from its start, and which pinned
  corners end behind their camera.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from vebuild.calibration.lsq import is_numeric_failure
from vebuild.camera import ImageCamera

from .residuals import EdgeObservation, Pin
from .scene import Model
from .solution import solution_at
from .solver import FINAL_PRIOR_SCALE, Problem, ProblemOptions

Array = NDArray[np.float64]

#: The turns (degrees) about the vertical tried for a node re-started from its pins: a node placed
#: the wrong way round (its related face away from the face it is flush with) is a half turn from
#: its minimum, one placed on its side a quarter turn; a local solve mends the rest.
RESTART_TURNS_DEG = (0.0, 90.0, 180.0, 270.0)
#: The dofs that turn a node about the vertical (rests_on, flush and free joints name it so).
TURN_DOF = "yaw"


@dataclass
class StartReport:
    """What is true of a failed solve's start (see :func:`start_report`).

    determined_at_start : of the parameters the solve's end leaves undetermined, those the
        observations determine at the start (``node.param``): a bad start, not too few pins.
    moved_m : node → how far (metres) the solve carried its farthest corner from the start.
    behind : (photo, node, handle) of each pinned corner behind its camera at the solve's end.
    """

    determined_at_start: list[str] = field(default_factory=list)
    moved_m: dict[str, float] = field(default_factory=dict)
    behind: list[tuple[str, str, str]] = field(default_factory=list)

    @property
    def bad_start(self) -> bool:
        return bool(self.determined_at_start or self.behind)


def troubled_nodes(problem: Problem, x: Array, undetermined: Sequence[str], related: Sequence[str] = ()) -> list[str]:
    """The nodes with pins that a solve ending at x left in doubt: the owners of the undetermined
    parameters, the nodes of relations that miss (``related``), and those with a pinned corner
    behind its camera; in the model's order."""
    pinned = {p.node for p in problem.pins}
    doubt = {u.rsplit(".", 1)[0] for u in undetermined} | set(related)
    doubt |= {node for _, node, _ in pins_behind(problem, x)}
    return [n.name for n in problem.model.nodes if n.name in doubt and n.name in pinned and n.solve]


def pins_behind(problem: Problem, x: Array) -> list[tuple[str, str, str]]:
    """(photo, node, handle) of every pin whose corner lies behind its camera at x."""
    xm = problem.model_vector(x)
    T = problem.model.world_transforms(xm)
    out = []
    for p in problem.pins:
        cam = problem.cameras[p.photo]
        X = problem.model.handle_world(p.node, p.handle, xm, T)
        if float(cam.R[2] @ (X - cam.C)) <= 0.0:
            out.append((p.photo, p.node, p.handle))
    return out


def restart_nodes(model: Model, cameras: Mapping[str, ImageCamera], pins: Sequence[Pin],
                  edges: Sequence[EdgeObservation], click_sigma_px: float, nodes: Sequence[str]) -> list[str]:
    """Re-start each of ``nodes`` from its own pins: solved alone (every other node held where it
    is, the relations holding), from its yaw as it is and turned by each of RESTART_TURNS_DEG; the
    end with the least cost whose pinned corners all lie in front of their cameras is kept.
    ``model`` is moved there; returns the nodes whose start changed."""
    moved = []
    for name in nodes:
        node = model.node(name)
        sq = model.slices[name][0]
        turn = [k for k, d in enumerate(node.joint.dof_names) if d == TURN_DOF]
        start = model.vector()
        best: tuple[float, Array] | None = None
        for deg in RESTART_TURNS_DEG if turn else (0.0,):
            xm = start.copy()
            if turn:
                xm[sq.start + turn[0]] += np.radians(deg)
            model.set_vector(xm)
            try:
                problem = Problem(model, cameras, pins, edges,
                                  options=ProblemOptions(click_sigma_px=click_sigma_px, prior_scale=FINAL_PRIOR_SCALE,
                                                         free_nodes=[name]))
                if not problem.n_model or not problem.n_data:
                    break
                r = problem.solve(problem.x0(), robust=True)
            except (ValueError, np.linalg.LinAlgError) as e:
                if not is_numeric_failure(e):
                    raise
                continue
            if not np.all(np.isfinite(r.x)) or pins_behind(problem, r.x):
                continue
            if best is None or r.cost < best[0]:
                xm = problem.model_vector(r.x)
                if turn:  # the turn as (−180°, 180°]: the same pose, read as the user would
                    k = sq.start + turn[0]
                    xm[k] = -((np.pi - xm[k]) % (2 * np.pi)) + np.pi
                best = (float(r.cost), xm)
        model.set_vector(start if best is None else best[1])
        if best is not None and not np.allclose(best[1], start):
            moved.append(name)
    return moved


def start_report(problem: Problem, x_start: Array, x_end: Array, undetermined: Sequence[str]) -> StartReport:
    """What is true of a solve from ``x_start`` that ended at ``x_end`` with ``undetermined``:
    which of those the observations determine at the start (the same rule as at the end,
    :func:`~vebuild.model.solution.solution_at`), how far each node's corners moved, and which
    pinned corners end behind their camera."""
    try:
        at_start = set(solution_at(problem, x_start).undetermined)
    except (ValueError, np.linalg.LinAlgError) as e:
        if not is_numeric_failure(e):
            raise
        at_start = set(undetermined)
    report = StartReport([u for u in undetermined if u not in at_start], {}, pins_behind(problem, x_end))
    H0 = problem.handle_positions(problem.model_vector(x_start),
                                  problem.model.world_transforms(problem.model_vector(x_start)))
    H1 = problem.handle_positions(problem.model_vector(x_end),
                                  problem.model.world_transforms(problem.model_vector(x_end)))
    for name in problem.prim_nodes:
        o = problem.h_offset[name]
        k = len(problem.primitive_of(name).handle_names())
        d = np.linalg.norm(H1[o:o + k] - H0[o:o + k], axis=1)
        if len(d) and np.all(np.isfinite(d)):
            report.moved_m[name] = float(np.max(d))
    return report
