"""What a solve can say about the parts of a model the photos leave open (paper §3.1).

Two reports that follow from a solve's covariance:

- :func:`axis_records`: the world line of each hinge and slider whose axis the photos solve
  (``solve_axis``), with its 1σ, propagated from the parameters' covariance through the frame the
  axis is given in (FORMAT.md ``model_solution.nodes[n].axis``);
- :func:`too_few_observations`: for each undetermined parameter, what would determine it: its
  current value with the ``hold`` entry a user could add with a measured value, and the handles
  whose pins in a photo (or a second one) would fix it, found from the undetermined direction of
  the observations' normal matrix.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .joints import HingeJoint, SliderJoint
from .residuals import FD_STEP
from .solution import Solution, handle_gradients

if TYPE_CHECKING:
    from .solver import Problem

Array = NDArray[np.float64]

#: The 1σ suggested in a ``hold`` entry for a measured value, per kind (file units): a tape read
#: to 5 mm, an angle read to 1° (FORMAT.md "entered value").
SUGGESTED_SIGMA = {"position": 0.005, "size": 0.005, "angle": 1.0}
#: How many handles the message names per undetermined parameter.
HANDLES_NAMED = 3
#: A handle moves "with" the undetermined direction if it moves at least this share of the
#: farthest-moving handle's motion along it.
HANDLE_SHARE = 0.2


def _axis_frame(problem: Problem, xm: Array, name: str, T: dict[str, Array]) -> Array:
    """world_from_axis_frame of node ``name``'s hinge or slider at model vector xm: the frame its
    axis is given in (the parent's), found as world_from_node · node_from_axis_frame so that it
    holds whatever frame the joint places its axis in."""
    j = problem.model.node(name).joint
    q = xm[problem.model.slices[name][0]]
    if not isinstance(j, HingeJoint | SliderJoint):
        raise TypeError(f"node '{name}' has a {j.type} joint: no axis")
    local = j.turned(q) if isinstance(j, HingeJoint) else j.slid(q)
    return T[name] @ np.linalg.inv(local)


def _axis_values(problem: Problem, x: Array, name: str, along: float | None) -> tuple[Array, float]:
    """A hinge's world axis point at axial coordinate ``along`` (None: nearest the node's origin,
    its bottom centre), or a slider's world unit direction; and that coordinate."""
    xm = problem.model_vector(x)
    T = problem.model.world_transforms(xm)
    F = _axis_frame(problem, xm, name, T)
    j = problem.model.node(name).joint
    q = xm[problem.model.slices[name][0]]
    if isinstance(j, SliderJoint):
        return F[:3, :3] @ j.direction(q), 0.0
    assert isinstance(j, HingeJoint)
    a = F[:3, :3] @ (j.axis / np.linalg.norm(j.axis))
    p = F[:3, :3] @ j.point(q) + F[:3, 3]
    if along is None:
        along = float((T[name][:3, 3] - p) @ a)
    return p + along * a, along


def axis_records(problem: Problem, solution: Solution) -> dict[str, dict[str, Any]]:
    """node → its ``axis`` record (FORMAT.md) for every solved node on a hinge or slider with
    ``solve_axis``: a hinge's world axis point nearest the node's bottom (the axis point at that
    height along the axis: its position along the axis is no unknown), a slider's world direction
    and the 1σ of its turn (degrees); each with its 1σ per coordinate."""
    x, cov = solution.x, solution.covariance
    out: dict[str, dict[str, Any]] = {}
    names = set(problem.owner)
    for n in problem.model.nodes:
        if n.name not in names or not isinstance(n.joint, HingeJoint | SliderJoint) or not n.joint.solve_axis:
            continue
        value, along = _axis_values(problem, x, n.name, None)
        cols = [j for j in problem.layout.model.indices if n.name in problem.moves[j][0]]
        G = np.zeros((3, len(cols)))
        for k, j in enumerate(cols):
            h = FD_STEP * max(1.0, abs(x[j]))
            xp = x.copy()
            xp[j] += h
            G[:, k] = (_axis_values(problem, xp, n.name, along)[0] - value) / h
        c = G @ cov[np.ix_(cols, cols)] @ G.T
        sigma = np.sqrt(np.maximum(np.diag(c), 0.0))
        rec: dict[str, Any] = {"frame": "world"}
        if isinstance(n.joint, HingeJoint):
            rec["point"] = {"value": [float(v) for v in value], "sigma": [float(s) for s in sigma]}
        else:
            turn = float(np.degrees(np.sqrt(max(np.linalg.eigvalsh(c)[-1], 0.0))))
            rec["direction"] = {"value": [float(v) for v in value], "sigma": [float(s) for s in sigma]}
            rec["turn_sigma_deg"] = turn
        out[n.name] = rec
    return out


def _file_value(value: float, kind: str) -> float:
    return float(np.degrees(value)) if kind == "angle" else float(value)


#: A parameter as the window's Model tab and an investigator name it (the file's own name else).
PARAM_WORDS = {"s": "position across", "t": "position front to back", "yaw": "turn", "angle": "hinge angle",
               "offset": "slide", "axis_u": "hinge axis", "axis_v": "hinge axis", "axis_a": "slide direction",
               "axis_b": "slide direction"}


def param_words(full: str) -> str:
    """``door.depth`` → "door's depth"; ``door.yaw`` → "door's turn" (:data:`PARAM_WORDS`)."""
    node, param = full.rsplit(".", 1)
    return f"{node}'s {PARAM_WORDS.get(param, param)}"


def too_few_observations(problem: Problem, solution: Solution, limit: int = 12) -> tuple[str, str]:
    """What would determine each undetermined parameter (at most ``limit`` of them), in two
    parts: the user's words (the window's controls: a size typed in the Model tab and the node
    held, or a corner dragged onto a second photo and fixed with F) and the details for the
    expert (each parameter's value now, the ``hold`` entry that enters a measured value, the
    handles that move most along the direction the observations leave open and are pinned in
    fewer than two photos, so that a pin in a first or second photo would fix them)."""
    layout = problem.layout
    names, kinds = layout.model.names, layout.model.kinds
    index = {nm: j for j, nm in enumerate(names)}
    xmodel = solution.x[layout.model.slice]
    cov_obs = solution.covariance_observed
    _, G = handle_gradients(problem, solution.x) if cov_obs is not None else (None, None)
    handle_names = [f"{n}:{h}" for n in problem.prim_nodes for h in problem.primitive_of(n).handle_names()]
    photos: dict[str, set[str]] = {}
    for p in problem.pins:
        photos.setdefault(f"{p.node}:{p.handle}", set()).add(p.photo)
    details: list[str] = []
    per_node: dict[str, dict[str, list[str]]] = {}  # node → sizes typed, joint values typed, corners
    for full in solution.undetermined[:limit]:
        j = index[full]
        node, param = full.rsplit(".", 1)
        kind = kinds[j]
        unit = "°" if kind == "angle" else " m"
        value = _file_value(xmodel[j], kind)
        hold = f'{{"name": "{param}", "sigma": {SUGGESTED_SIGMA[kind]:g}, "value": <measured>}}'
        detail = f"{full} (now {value:.4g}{unit}): {hold} in the \"hold\" list of node '{node}'"
        pins = _pins_that_determine(G, cov_obs, j, layout.model.slice, handle_names, photos) \
            if G is not None and cov_obs is not None else []
        mine = per_node.setdefault(node, {"sizes": [], "joint": [], "corners": []})
        mine["sizes" if kind == "size" else "joint"].append(f"'{param} (m)'" if kind == "size" else param)
        mine["corners"] += [h.split(":", 1)[1] for h in pins if h.split(":", 1)[1] not in mine["corners"]]
        if pins:
            detail += "; or pin " + ", ".join(f"{h} (now in {len(photos.get(h, ()))} photo"
                                             f"{'' if len(photos.get(h, ())) == 1 else 's'})" for h in pins)
        details.append(detail)
    words = []
    for node, mine in per_node.items():
        typed = []
        if mine["sizes"]:
            typed.append(f"the field{'s' if len(mine['sizes']) > 1 else ''} {', '.join(mine['sizes'])}")
        if mine["joint"]:
            typed.append("the joint fields")
        text = (f"for {node}, type what was measured on the spot into {' and '.join(typed)} of the Model tab "
                "and untick 'solve' to keep it as typed")
        if mine["corners"]:
            c = mine["corners"]
            text += (f", or, in another photo, drag {node}'s corner{'s' if len(c) > 1 else ''} {', '.join(c)} "
                     "onto where that photo shows them and press F over each to fix it")
        words.append(text)
    more = f"; and {len(solution.undetermined) - limit} more" if len(solution.undetermined) > limit else ""
    return "; ".join(words), "; ".join(details) + more


def _pins_that_determine(G: Array, cov_obs: Array, j: int, model_slice: slice, handle_names: list[str],
                         photos: dict[str, set[str]]) -> list[str]:
    """The handles (at most HANDLES_NAMED) that move most along parameter j's undetermined
    direction (column j of the observations' covariance: the combination of parameters the
    photos leave open that carries j) and are pinned in fewer than two photos."""
    d = np.asarray(cov_obs[:, j], float)
    if not np.all(np.isfinite(d)) or not np.any(d):
        d = np.zeros(len(cov_obs))
        d[j] = 1.0
    d = d / np.linalg.norm(d)
    motion = np.linalg.norm(G[:, :, model_slice] @ d, axis=1)
    if not np.any(motion > 0):
        return []
    order = np.argsort(-motion, kind="stable")
    keep = [handle_names[k] for k in order if motion[k] >= HANDLE_SHARE * motion[order[0]]
            and len(photos.get(handle_names[k], ())) < 2]
    return keep[:HANDLES_NAMED]
