"""Relations in the solve (scenes/FORMAT.md "Relations"): ``equal`` as one shared unknown,
``flush`` and ``aligned`` as hard rows of the least-squares problem, and the check after a final
solve that every relation holds.

``equal`` is exact: the group's parameters take one unknown (the first free one; the others copy
it into the model vector), or, where one member is held, all are held at its value. ``flush`` and
``aligned`` relate nodes the tree does not join, so no parameterisation makes them exact; each is
a few rows (:func:`~vebuild.model.relations.rows_of`, metres) whitened by ``HARD_SIGMA_M``, so
stiff that the observations cannot bend them measurably, yet not so stiff that the normal
equations lose their precision. They are constraints, not observations: they stay out of the
robust loss, and in the variance factor each independent row takes away one unknown rather than
adding one observation (:func:`constraint_rank`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .graph import Relation
from .relations import equal_groups, relation_residual, rows_of
from .scene import Model

Array = NDArray[np.float64]

#: The 1σ (metres) that whitens a hard row: a micrometre. The pull of the observations on a row
#: moves it by about (their force)·σ², some 1e-8 m for a room's pins (a pixel's footprint is
#: millimetres), far below anything reported, while the normal matrix's entries (≤ 1e12 against
#: the observations' ~1e6) stay well within double precision's 1e16.
HARD_SIGMA_M = 1e-6
#: After a final solve, a relation that misses by more than this (metres; radians for an
#: ``equal`` of angles) could not hold together with the others: a tenth of a millimetre, 10⁴
#: times what the observations' pull leaves in a hard row and still far below a pixel's
#: footprint, so only relations that contradict each other (or the tree) cross it.
CONFLICT_TOL_M = 1e-4


@dataclass
class Ties:
    """How ``equal`` groups change a problem's unknowns.

    free_idx, owner : the problem's free model parameters and their nodes, with tied members
        dropped (held ones too).
    x_model0 : the model vector with every group at one value (the held member's, or the mean of
        its members' first guesses).
    src, dst : model-vector indices: ``xm[dst] = xm[src]`` after the free values are put in.
    also : column (place in free_idx) → the other nodes its shared unknown moves.
    alias : member name → the name of the unknown it shares (its group's representative).
    """

    free_idx: NDArray[np.intp]
    owner: list[str]
    x_model0: Array
    src: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, np.intp))
    dst: NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, np.intp))
    also: dict[int, tuple[str, ...]] = field(default_factory=dict)
    alias: dict[str, str] = field(default_factory=dict)


def tie_equal(model: Model, x_model0: Array, free_idx: NDArray[np.intp], owner: list[str]) -> Ties:
    """The unknowns of a problem once its ``equal`` relations are exact (see :class:`Ties`)."""
    x0 = np.array(x_model0, float)
    names = model.parameter_names()
    where = {nm: i for i, nm in enumerate(names)}
    free = [int(i) for i in free_idx]
    own = list(owner)
    src: list[int] = []
    dst: list[int] = []
    rep_of: dict[int, list[int]] = {}
    alias: dict[str, str] = {}
    for group, _ in equal_groups(model.relations):
        members = sorted(where[p] for p in group)
        loose = [i for i in free if i in members]
        held = [i for i in members if i not in loose]
        value = x0[held[0]] if held else float(np.mean(x0[members]))
        x0[members] = value
        keep = [] if held else loose[:1]
        for i in loose:
            if i not in keep:
                k = free.index(i)
                del free[k], own[k]
        if keep:
            rep_of[keep[0]] = [i for i in members if i != keep[0]]
            src += [keep[0]] * (len(members) - 1)
            dst += rep_of[keep[0]]
            alias.update({names[i]: names[keep[0]] for i in members})
    node_of = {i: nm.rpartition(".")[0] for i, nm in enumerate(names)}
    also = {free.index(r): tuple(dict.fromkeys(node_of[i] for i in m if node_of[i] != node_of[r]))
            for r, m in rep_of.items()}
    return Ties(np.array(free, dtype=np.intp), own, x0, np.array(src, np.intp), np.array(dst, np.intp),
                {k: v for k, v in also.items() if v}, alias)


def hard_relations(model: Model, moving: set[str] | None) -> list[Relation]:
    """The flush and aligned relations a problem keeps as hard rows: those with a node it moves
    (``moving``; None: all). A relation between nodes the problem holds still is constant."""
    return [r for r in model.relations if r.type != "equal" and (moving is None or set(r.nodes()) & moving)]


#: The return onto the relations after a step ends when they miss by less than this (metres):
#: a thousandth of what a relation is reported to hold to, far below the stiff rows' own slack.
RESTORE_TOL_M = 1e-9
#: At most this many Gauss–Newton returns per step (each costs one evaluation of the hard rows).
RESTORE_STEPS = 3


def restore(problem: Any, x: Array, J_hard: Array) -> Array:
    """x moved back onto its problem's flush and aligned relations: the least change (minimum
    norm, through the hard rows' linearisation ``J_hard`` at the step's start) that zeroes them.

    A step along curved constraints (a cabinet turning with its wall) leaves a second-order miss;
    through rows whitened by a micrometre it would cost more than the step gains, and the solve
    would creep along the relations in tiny steps. Returned onto them first (the second-order
    correction of constrained optimisation), the step is judged on what it gains in the fit."""
    m = problem.layout.model.slice
    x = np.array(x, float)
    for _ in range(RESTORE_STEPS):
        xm = problem.model_vector(x)
        T = problem.transforms(xm)
        r = np.concatenate([rows_of(rel, problem.model, T, xm) for rel in problem.hard]) / HARD_SIGMA_M
        if not np.all(np.isfinite(r)) or np.max(np.abs(r), initial=0.0) * HARD_SIGMA_M < RESTORE_TOL_M:
            break
        dx = np.linalg.lstsq(J_hard, -r, rcond=None)[0]
        x[m] += dx[m]
    return x


def constraint_rank(J_hard: Any) -> int:
    """The number of independent hard rows (rows of J that constrain the unknowns): what they
    take from the unknowns in the redundancy. A relation whose rows the unknowns cannot move (both
    nodes held) takes nothing."""
    A = J_hard.toarray() if hasattr(J_hard, "toarray") else np.asarray(J_hard)
    if A.size == 0:
        return 0
    return int(np.linalg.matrix_rank(A))


def relation_records(model: Model, x: Array | None = None) -> list[dict[str, Any]]:
    """``model_solution.relations``: each relation as in the file with how far it misses at model
    vector x: ``residual_m`` (metres), or ``residual_deg`` for an ``equal`` of angles."""
    xm = model.vector() if x is None else x
    T = model.world_transforms(xm)
    kinds = dict(zip(model.parameter_names(), model.parameter_kinds(), strict=True))
    out = []
    for r in model.relations:
        miss = relation_residual(r, model, xm, T)
        if r.type == "equal" and kinds[r.params[0]] == "angle":
            out.append({**r.to_dict(), "residual_deg": float(np.degrees(miss))})
        else:
            out.append({**r.to_dict(), "residual_m": float(miss)})
    return out


def conflicts(model: Model, x: Array | None = None, tol: float = CONFLICT_TOL_M) -> list[tuple[int, Relation, float]]:
    """The relations that miss by more than ``tol`` at model vector x: (index, relation, miss)."""
    xm = model.vector() if x is None else x
    T = model.world_transforms(xm)
    out = []
    for i, r in enumerate(model.relations):
        miss = relation_residual(r, model, xm, T)
        if miss > tol:
            out.append((i, r, miss))
    return out


def conflict_message(found: list[tuple[int, Relation, float]]) -> str:
    """What :func:`conflicts` found, for the user: the relations named as the Model tab lists them,
    each with its miss, what to do in the window; then, on a ``details:`` line, where they are in
    the project file."""
    parts = [f"{r.label()} misses by " + (f"{miss * 1000:.3g} mm" if miss < 1.0 else f"{miss:.3g} m")
             for _, r, miss in found]
    return ("the relations cannot all hold together with the joints: " + "; ".join(parts) + "; correct or remove "
            "one of them in the Model tab's list of relations (an offset, a face turned the wrong way, or a joint "
            "that keeps a node from reaching it)\ndetails: "
            + ", ".join(f"$.model.relations[{i}]" for i, _, _ in found))
