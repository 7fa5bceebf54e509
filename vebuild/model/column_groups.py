"""Which of the model solver's finite-difference Jacobian columns one difference gives at once
(:class:`vebuild.model.residuals.Residuals`).

Layer 1 (DESIGN.md): plain Python; no GL, no file I/O.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any


def column_groups(indices: Iterable[int], moves: Sequence[tuple[Sequence[str], Any]],
                  column_rows: Sequence[tuple[Any, Any, Any]], column_hard: Sequence[Sequence[int]]) -> list[list[int]]:
    """The model parameters ``indices`` in groups whose Jacobian columns one finite difference
    gives at once (Curtis, Powell and Reid's grouping): within a group no two parameters move a
    common node (``moves[j][0]``, so no common handle, pin or edge) or a common distance
    (``column_rows[j][2]``) or hard relation (``column_hard[j]``). Each handle moved is then moved
    by one parameter of the group alone, by exactly what that parameter alone would move it by: the
    columns are bit for bit those of one difference per parameter. Greedy, in the parameters'
    order; a house's thousand parameters fall into a few dozen groups."""
    groups: list[tuple[list[int], set[str], set[int], set[int]]] = []
    for j in indices:
        nodes = set(moves[j][0])
        dists = {int(i) for i in column_rows[j][2]}
        hard = set(column_hard[j])
        for cols, g_nodes, g_dists, g_hard in groups:
            if nodes.isdisjoint(g_nodes) and dists.isdisjoint(g_dists) and hard.isdisjoint(g_hard):
                cols.append(j)
                g_nodes |= nodes
                g_dists |= dists
                g_hard |= hard
                break
        else:
            groups.append(([j], nodes, dists, hard))
    return [cols for cols, *_ in groups]
