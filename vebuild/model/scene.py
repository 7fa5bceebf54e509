"""The scene graph: primitives and groups attached to their parents by joints (paper §3, Figure 6).

A joint is an exact parameterisation of how a node may sit on its parent: a box that rests on the
floor has three degrees of freedom (a position in the floor's plane and a turn about its normal),
a door on its hinge has one. The solver moves only these degrees of freedom and the primitives'
own parameters, so every joint holds exactly, whatever the observations say.

This module reads the graph from the project file (:func:`model_from_dict`). The nodes and the
:class:`Model` that holds them are in :mod:`vebuild.model.graph`, the joints in
:mod:`vebuild.model.joints` (both re-exported here). Transforms are 4×4 matrices mapping a
node's local frame into its parent's (``parent_from_node``); a node attached to the world has the
world as parent. Lengths in metres, angles in radians here (degrees in the project file).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .entered import Entered, HoldError, hold_list
from .graph import Model, Node, check_cycles  # noqa: F401  (Model re-exported: the model and its file form)
from .joint_file import joint_from_dict
from .joints import (  # noqa: F401  (re-exported: the scene graph and its joints, one import)
    DOF_KINDS,
    JOINT_TYPES,
    FlushJoint,
    FreeJoint,
    HingeJoint,
    Joint,
    MarkerJoint,
    ModelError,
    RestsOnJoint,
    SliderJoint,
    error_at,
    pose_matrix,
    pose_to_dict,
    rotation4,
    rz,
    translation,
)
from .primitives import MIN_SIZE_M, PRIMITIVE_TYPES, Primitive, primitive_from_dict
from .relations import relations_from_dict
from .room import RoomError
from .room_joints import check_room_joints

Array = NDArray[np.float64]

def _primitive(d: Any, human: str, path: str) -> Primitive:
    """A node's primitive, its sizes checked with the JSON path of the one at fault."""
    if not isinstance(d, Mapping) or not isinstance(d.get("params", {}), Mapping):
        raise error_at(human, path, "expected an object {\"type\": T, \"params\": {...}}")
    params = d.get("params", {})
    kind = d.get("type")
    cls = PRIMITIVE_TYPES.get(kind) if isinstance(kind, str) else None
    for name, value in params.items():
        if cls is None or name not in cls.PARAMS or not isinstance(value, int | float):
            continue
        least = cls.minimum_size(name)  # (a room's PARAMS depend on its structure: it checks its own)
        if value >= least:
            continue
        if least > 0 and value <= 0:
            raise error_at(human, f"{path}.params.{name}", f"{cls.TYPE}: {name} must be > 0, got {value!r}")
        raise error_at(human, f"{path}.params.{name}", f"{cls.TYPE}: {name} must be at least {least:g} m (sizes "
                     f"stay above {MIN_SIZE_M:g} m, the solver's least), got {value!r}")
    try:
        prim = primitive_from_dict(d)
    except RoomError as e:  # a room names its field: params.c2_y, openings[1].wall, corners
        raise error_at(human, f"{path}.{e.at}", str(e)) from None
    except (ValueError, TypeError) as e:
        raise error_at(human, f"{path}.params" if isinstance(d.get("type"), str) else f"{path}.type", str(e)) from None
    for name, value, least in zip(prim.PARAMS, prim.params, prim.minimum_sizes(), strict=True):
        if not value >= least:
            raise error_at(human, f"{path}.params.{name}", f"{prim.TYPE}: {name} must be at least {least:g} m (sizes "
                         f"stay above {MIN_SIZE_M:g} m, the solver's least), got {params.get(name, value)!r}")
    return prim


def model_from_dict(nodes: list[Mapping[str, Any]], markers: Mapping[str, Array] | None = None,
                    relations: Any = None) -> Model:
    """The model from the project file's ``model.nodes`` and ``model.relations`` (None: none);
    ModelError names the node (or the relation) and the field."""
    out = []
    index: dict[str, int] = {}
    for i, d in enumerate(nodes):
        where = f"$.model.nodes[{i}] (node '{d.get('name')}')"
        path = f"$.model.nodes[{i}]"
        prim = None
        if "primitive" in d:
            prim = _primitive(d["primitive"], f"{where}.primitive", f"{path}.primitive")
        joint = joint_from_dict(d.get("joint", {"type": "fixed"}), f"{where}.joint", markers, f"{path}.joint")
        if isinstance(joint, MarkerJoint):
            if d.get("parent") is not None:
                raise error_at(f"{where}.joint", f"{path}.parent",
                             "a marker joint ties a node to the world; this node has a parent")
            if prim is None or joint.handle not in prim.handle_names():
                have = ", ".join(prim.handle_names()) if prim is not None else "none (a group has no handles)"
                raise error_at(f"{where}.joint", f"{path}.joint.handle", f"handle '{joint.handle}' is not a handle of "
                             f"this node's primitive (its handles are: {have})")
        try:
            hold, entered = hold_list(d.get("hold", ()), (prim.PARAMS if prim is not None else ()) + joint.dof_names)
        except HoldError as e:
            raise error_at(f"{where}.hold", f"{path}.hold{e.at}", e.detail) from None
        index.setdefault(d["name"], i)
        out.append(Node(d["name"], d.get("parent"), prim, joint, bool(d.get("solve", True)), hold, entered))
    for i, n in enumerate(out):
        if n.parent is not None and n.parent not in index:
            raise ModelError(f"node '{n.name}': its joint attaches it to parent '{n.parent}', which is not a node",
                             f"$.model.nodes[{i}].parent",
                             f"node '{n.name}' is attached to parent '{n.parent}', which is not a node")
    check_cycles(out)
    model = Model(out)
    fill_entered_values(model)
    check_room_joints(model, index)
    for n in model.nodes:
        if isinstance(n.joint, RestsOnJoint) and n.parent is not None:
            parent = model.node(n.parent).primitive
            if parent is None or n.joint.face not in parent.faces():
                faces = ", ".join(parent.faces()) if parent is not None else "none (a group)"
                detail = f"rests on face '{n.joint.face}' of '{n.parent}', which has faces: {faces}"
                raise ModelError(f"node '{n.name}': {detail}", f"$.model.nodes[{index[n.name]}].joint.face",
                                 f"node '{n.name}' {detail}")
        if isinstance(n.joint, FlushJoint):
            _check_flush_joint(model, n, f"$.model.nodes[{index[n.name]}]")
    model.relations = relations_from_dict([] if relations is None else relations, model)
    return model


def _check_flush_joint(model: Model, n: Node, path: str) -> None:
    """A flush joint's faces must be flat faces of the parent and of the node."""
    joint = n.joint
    assert isinstance(joint, FlushJoint)
    sides: list[tuple[str, str | None, str, Primitive | None]] = [("own_face", joint.own_face, n.name, n.primitive)]
    if n.parent is not None:
        sides.insert(0, ("face", joint.face, n.parent, model.node(n.parent).primitive))
    elif joint.face is not None:
        detail = (f"node '{n.name}' is flush against face '{joint.face}' of the world, which has none; with no "
                  "parent, leave out \"face\" (the floor z = 0)")
        raise ModelError(f"node '{n.name}': {detail}", f"{path}.joint.face", detail)
    for key, face, owner, prim in sides:
        if face is None:
            detail = f"node '{n.name}' is flush against its parent '{owner}' but names no face; expected \"face\": " \
                     f"one of the parent's flat faces: {', '.join(prim.planes()) if prim else 'none (a group)'}"
            raise ModelError(f"node '{n.name}': {detail}", f"{path}.joint.face", detail)
        if prim is None or face not in prim.planes():
            have = ", ".join(prim.planes()) or "none" if prim is not None else "none (a group)"
            detail = f"node '{n.name}' is flush with face '{face}' of '{owner}', which has flat faces: {have}"
            raise ModelError(f"node '{n.name}': {detail}", f"{path}.joint.{key}", detail)


def fill_entered_values(model: Model) -> None:
    """Each entered value given without ``value`` takes the parameter's value (file units)."""
    x = model.vector()
    names, kinds = model.parameter_names(), model.parameter_kinds()
    index = {nm: j for j, nm in enumerate(names)}
    for n in model.nodes:
        if not any(e.value is None for e in n.entered):
            continue  # (every entry has its value)
        filled = []
        for e in n.entered:
            if e.value is None:
                j = index[f"{n.name}.{e.name}"]
                v = float(np.degrees(x[j])) if kinds[j] == "angle" else float(x[j])
                e = Entered(e.name, e.sigma, v)
            filled.append(e)
        n.entered = tuple(filled)
    # An exact entry (σ 0) given with a value holds the parameter at it.
    changed = False
    for n in model.nodes:
        for e in n.entered:
            j = index[f"{n.name}.{e.name}"]
            if e.sigma == 0 and e.value is not None:
                v = np.radians(e.value) if kinds[j] == "angle" else e.value
                changed = changed or x[j] != v
                x[j] = v
    if changed:
        model.set_vector(x)
