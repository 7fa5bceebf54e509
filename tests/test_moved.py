"""What a change of parameters moves (vebuild/model/moved.py) and the lazily computed world
transforms (Model.lazy_world_transforms): the same values as recomputing every moved node's joint,
on a generated house whose rooms hang from one another through their doorways."""

from __future__ import annotations

import numpy as np
import pytest

from vebuild.model.moved import apply_plan
from vebuild.model.solver import Problem
from vebuild.synthetic.house_layout import furnished_house

#: Handles and transforms agree within this (metres; the house is about 10 m across, so a few
#: hundred ulps of its coordinates): the rigid move is the same product in another order.
AGREE_M = 1e-12


@pytest.fixture(scope="module")
def house_problem() -> Problem:
    model = furnished_house(np.random.default_rng(11), 2, 2).model()
    return Problem(model, {})


def _recomputed(problem: Problem, columns: list[int], xm: np.ndarray, T: dict, H: np.ndarray):
    nodes = [n for j in columns for n in problem.moves[j][0]]
    Tp = problem.model.world_transforms(xm, only=nodes, cache=T)
    return Tp, problem.handle_positions(xm, Tp, nodes, H.copy())


def test_a_change_moves_transforms_and_handles_as_recomputing_every_joint(house_problem: Problem) -> None:
    """Every column group of the solver's Jacobian and every single parameter, changed by a step
    far larger than a difference's (1–10 cm or a few degrees): the plan's transforms and handles are
    the recomputed ones."""
    p = house_problem
    assert len(p.model.nodes) > 60 and max(len(p.moves[j][0]) for j in p.layout.model.indices) > 40
    rng = np.random.default_rng(3)
    x = p.x0()
    xm = p.model_vector(x)
    T = p.model.world_transforms(xm)
    H = p.handle_positions(xm, T)
    cases = [list(g) for g in p.column_groups] + [[j] for j in p.layout.model.indices]
    for columns in cases:
        xp = x.copy()
        xp[columns] += rng.uniform(0.01, 0.1, len(columns)) * rng.choice([-1, 1], len(columns))
        xmp = p.model_vector(xp)
        Tp, Hp = apply_plan(p.move_plan(columns), p.model, xmp, T, H, p.handle_positions)
        Tr, Hr = _recomputed(p, columns, xmp, T, H)
        assert np.abs(Hp - Hr).max() <= AGREE_M, columns
        moved = {n for j in columns for n in p.moves[j][0]}
        assert np.any(Hp != H), columns  # the step moves something
        for n in p.move_plan(columns).joints:
            assert np.abs(Tp[n] - Tr[n]).max() <= AGREE_M, (columns, n)
        for n in set(Tp) - moved:  # what the change does not move keeps its values bit for bit
            assert np.array_equal(Tp[n], T[n]), n


def test_a_node_whose_transform_does_not_change_keeps_its_handles_bit_for_bit(house_problem: Problem) -> None:
    """A room's height moves no node hanging from its floor or doorways: their handles stay the
    very same numbers (no product with a transform that is the identity up to rounding)."""
    p = house_problem
    j = p.layout.model.names.index("room0.height")
    x = p.x0()
    xm = p.model_vector(x)
    T = p.model.world_transforms(xm)
    H = p.handle_positions(xm, T)
    xp = x.copy()
    xp[j] += 0.05
    Tp, Hp = apply_plan(p.move_plan([j]), p.model, p.model_vector(xp), T, H, p.handle_positions)
    room = p.handle_rows("room0")
    unchanged = [n for n in p.model.children["room0"] if np.array_equal(Tp[n], T[n])]
    assert unchanged  # the floor's furniture and the next rooms do not move with the height
    rows = np.concatenate([p.handle_rows(n) for n in unchanged])
    assert np.array_equal(Hp[rows], H[rows])
    assert not np.array_equal(Hp[room], H[room])


def test_lazy_world_transforms_are_the_eager_ones_bit_for_bit(house_problem: Problem) -> None:
    model = house_problem.model
    x = model.vector() + np.random.default_rng(4).normal(0, 0.01, model.size)
    eager = model.world_transforms(x)
    lazy = model.lazy_world_transforms(x)
    def depth(name: str) -> int:
        parent = model.node(name).parent
        return 0 if parent is None else 1 + depth(parent)

    deepest = max((n.name for n in model.nodes), key=depth)
    assert np.array_equal(lazy[deepest], eager[deepest])
    assert len(lazy._done) == depth(deepest) + 1  # only the asked node and its ancestors were computed
    assert set(lazy) == set(eager) and len(lazy) == len(eager)
    for name, T in eager.items():
        assert np.array_equal(lazy[name], T), name
    with pytest.raises(KeyError):
        lazy["no such node"]
