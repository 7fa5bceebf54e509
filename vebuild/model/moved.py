"""What a change of some nodes' parameters moves, and the cheapest exact way to recompute it: the
model solver's finite-difference columns (:mod:`.residuals`) and the handles' gradients
(:mod:`.solution`).

A node's world transform is its parent's times its own joint's, and its joint depends only on its
own parameters and its parent's (:meth:`~vebuild.model.scene.Model.local_transform`). When the
parameters of the nodes P change, the joints that change are those of P and of P's children (the
set R); every other node below them keeps its joint and its own handles, so it moves rigidly with
its nearest ancestor in R: by Δ = T′ T⁻¹ of that ancestor. A room's size moves the rooms beyond
its doorways and all their furniture: R is the room and its children, and the hundreds of nodes
below them are one matrix product per child rather than one joint each.

Layer 1 (DESIGN.md): plain Python and NumPy; no GL, no file I/O.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .scene import Model

Array = NDArray[np.float64]
Index = NDArray[np.intp]


@dataclass(frozen=True)
class MovePlan:
    """How to recompute what a change of the parameters of ``changed`` moves.

    joints : the nodes whose joints change (``changed`` and their children), parents first.
    changed : the nodes whose own handles change (their parameters do).
    rigid : (node, handle rows) for each node of ``joints`` not in ``changed``: the rows of its
        handles and of its descendants', which move rigidly with it.
    followers : (node, its ancestor in ``joints``) for the nodes below whose world transforms are
        asked for (the relations' nodes).
    """

    joints: tuple[str, ...]
    changed: tuple[str, ...]
    rigid: tuple[tuple[str, Index], ...]
    followers: tuple[tuple[str, str], ...]


def move_plan(model: Model, changed: Collection[str], moved: Collection[str],
              handle_rows: Callable[[str], Index], asked: Collection[str] = ()) -> MovePlan:
    """The plan for a change of the parameters of ``changed``, which moves ``moved`` (their
    subtrees); ``handle_rows(node)`` gives a node's rows of the stacked handles (empty for a group),
    ``asked`` the nodes whose world transforms are wanted besides those recomputed."""
    order = sorted(set(moved), key=model.index.__getitem__)  # parents first
    joints = set(changed) | {c for p in changed for c in model.children[p]}
    nearest: dict[str, str] = {}
    for n in order:
        parent = model.node(n).parent
        nearest[n] = n if n in joints or parent is None else nearest[parent]
    rows: dict[str, list[Index]] = {}
    for n in order:
        if nearest[n] not in changed:
            rows.setdefault(nearest[n], []).append(handle_rows(n))
    ask = set(asked)
    return MovePlan(tuple(n for n in order if n in joints), tuple(n for n in order if n in changed),
                    tuple((c, np.concatenate(r).astype(np.intp)) for c, r in rows.items()),
                    tuple((n, nearest[n]) for n in order if n in ask and n not in joints))


def apply_plan(plan: MovePlan, model: Model, xm: Array, T: Mapping[str, Array], H: Array,
               handles: Callable[[Array, Mapping[str, Array], Sequence[str], Array], Array]
               ) -> tuple[dict[str, Array], Array]:
    """The world transforms and stacked handles at model vector ``xm``, from those at the vector
    before the change (``T``, ``H``): the plan's joints recomputed, the changed nodes' handles by
    ``handles(xm, transforms, nodes, out)``, the rest moved rigidly. A node whose transform did
    not change at all keeps its handles bit for bit."""
    Tp = dict(T)
    for n in plan.joints:
        node = model.node(n)
        local = model.local_transform(node, xm)
        Tp[n] = local if node.parent is None else Tp[node.parent] @ local
    Hp = H.copy()
    handles(xm, Tp, plan.changed, Hp)
    delta: dict[str, Array] = {}
    for c, rows in plan.rigid:
        if np.array_equal(Tp[c], T[c]):
            continue
        D = delta[c] = Tp[c] @ np.linalg.inv(T[c])
        if len(rows):
            Hp[rows] = H[rows] @ D[:3, :3].T + D[:3, 3]
    for n, c in plan.followers:
        if c in delta:
            Tp[n] = delta[c] @ T[n]
    return Tp, Hp

