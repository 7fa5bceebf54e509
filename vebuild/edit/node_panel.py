"""The modelling screen's properties of the selected node (the Model tab, below the scene graph):
its sizes, with what is entered of each (FORMAT.md ``hold``), its joint and the joint's values, a
hinge's or slider's limits, and whether it is solved. Functions of
:class:`~vebuild.edit.panels.Panels` (``p``: its fields,
:class:`~vebuild.edit.panel_fields.PanelFields`), which holds what is typed into them."""

from __future__ import annotations

from typing import Any

import numpy as np
from imgui_bundle import imgui

from .model_panels import equal_section, room_section
from .panel_fields import PanelFields

#: The joint types the properties offer (a node's own other type is added to the list).
JOINT_TYPES = ["rests_on", "flush", "fixed", "hinge", "slider", "free"]


def properties_section(p: PanelFields, model: Any, name: str) -> None:
    """The selected node's properties: its sizes (typed, with what is entered of each), its joint
    and the joint's values, a hinge's or slider's limits, and whether it is solved."""
    s = p.ed.session
    doc = p.node_doc(name)
    if doc is None:
        return
    imgui.separator()
    imgui.text(f"{name}" + (f" on {doc['parent']}" if doc.get("parent") else ""))
    imgui.same_line()
    if p.ed.button("Remove##node", tip=f"remove {name} (and what rests on it) from the model"):
        p.ed.guard(s.remove_node, name)
        if s.model is None or name not in s.model.index:
            p.ed.select(None)
            return
    prim = doc.get("primitive")
    if prim is not None and prim.get("type") == "room":
        room_section(p, name, prim)
    if prim is not None:
        equal_section(p, name, prim)
        for k, v in prim["params"].items():
            imgui.set_next_item_width(110)
            new = p.float_field(f"{k} (m)##param:{k}", v)
            if new is not None and new != v:
                p.ed.guard(s.set_params, name, {k: new})
            note = entered_text(doc, k, p.ed.session.data.get("model_solution"))
            if note:
                imgui.same_line()
                imgui.text(note)
    joint = doc.get("joint", {})
    jtype = joint.get("type", "fixed")
    types = JOINT_TYPES + ([jtype] if jtype not in JOINT_TYPES else [])
    imgui.set_next_item_width(110)
    changed, idx = imgui.combo("joint##type", types.index(jtype), types)
    p.ed.rect("joint type")
    imgui.set_item_tooltip("how it is attached: resting on, flush with, fixed to its parent, on a hinge or a "
                           "slider, or free")
    if changed and types[idx] != jtype:
        p.ed.guard(lambda: s.set_joint(name, default_joint(model, name, types[idx], joint)))
    for key, value in joint.items():
        if key in ("type", "limits", "limits_deg", "solve_axis") or isinstance(value, str | bool | dict):
            if isinstance(value, str) and key != "type":
                imgui.text(f"{key}: {value}")
            elif isinstance(value, dict):  # a hinge's jamb: the opening and its side
                imgui.text(f"{key}: " + ", ".join(f"{k} {v}" for k, v in value.items()))
            continue
        if isinstance(value, (int, float)):
            imgui.set_next_item_width(110)
            new = p.float_field(f"{key}##joint:{key}", float(value), "%.3f")
            if new is not None and new != value:
                p.ed.guard(s.set_joint, name, {**joint, key: new})
        elif isinstance(value, list) and len(value) in (2, 3):
            imgui.set_next_item_width(200)
            fn = imgui.input_float2 if len(value) == 2 else imgui.input_float3
            label = f"{key}##joint:{key}"
            shown = p.param_edits.get(label, [float(c) for c in value])
            changed, vec = fn(label, list(shown), "%.3f")
            p.ed.rect(label)
            if changed:
                p.param_edits[label] = list(vec)
            if imgui.is_item_deactivated_after_edit():
                vec = p.param_edits.pop(label, list(vec))
                p.ed.guard(s.set_joint, name, {**joint, key: [float(c) for c in vec]})
    if jtype in ("hinge", "slider"):
        key = "limits_deg" if jtype == "hinge" else "limits"
        lo, hi = joint.get(key, [-180.0, 180.0] if jtype == "hinge" else [-1.0, 1.0])
        label = f"limits ({'°' if jtype == 'hinge' else 'm'})##limits"
        shown = p.param_edits.get(label, [float(lo), float(hi)])
        imgui.set_next_item_width(200)
        changed, vec = imgui.input_float2(label, list(shown), "%.3f")
        p.ed.rect("limits")
        if changed:
            p.param_edits[label] = list(vec)
        if imgui.is_item_deactivated_after_edit():
            vec = p.param_edits.pop(label, list(vec))
            p.ed.guard(s.set_limits, name, float(vec[0]), float(vec[1]))
        # Whether the photos solve the axis too (a door seen open, a drawer pulled out: FORMAT.md).
        changed, on = imgui.checkbox("solve axis (from the photos)##solve_axis", bool(joint.get("solve_axis")))
        p.ed.rect("solve axis")
        if changed:
            p.ed.guard(s.set_joint, name, {**joint, "solve_axis": bool(on)})
    solve = doc.get("solve", True)
    changed, on = imgui.checkbox("solve (untick: hold as it is)", bool(solve))
    p.ed.rect("solve")
    if changed:
        p.ed.guard(s.set_solve, name, bool(on))


def default_joint(model: Any, name: str, jtype: str, old: dict[str, Any]) -> dict[str, Any]:
    """A joint of another type that keeps the node where it is now, as far as the type allows."""
    from vebuild.model.scene import pose_to_dict

    node = model.node(name)
    T = model.world_transforms()
    rel = T[name] if node.parent is None else np.linalg.inv(T[node.parent]) @ T[name]
    pose = pose_to_dict(rel)
    if jtype == "rests_on":
        j = {"type": "rests_on", "position": [float(rel[0, 3]), float(rel[1, 3])],
             "yaw_deg": float(pose["rotation_deg"][2])}
        if node.parent is not None:
            j["face"] = "top"
            j["position"] = old.get("position", [0.0, 0.0])
        return j
    if jtype == "flush":  # its bottom on its parent's top (a room's floor), or on the floor
        from .relating import flush_joint_here

        parent = model.node(node.parent).primitive if node.parent is not None else None
        if parent is None:
            return {"type": "flush", "own_face": "bottom", "offset": 0.0,
                    "position": [float(rel[0, 3]), float(rel[1, 3])], "yaw_deg": float(pose["rotation_deg"][2])}
        return flush_joint_here(model, name, "bottom", "top" if "top" in parent.planes() else "floor")
    if jtype == "hinge":
        return {"type": "hinge", "axis_point": [0.0, 0.0, 0.0], "axis": [0.0, 0.0, 1.0], **pose,
                "angle_deg": 0.0, "limits_deg": [-180.0, 180.0]}
    if jtype == "slider":
        return {"type": "slider", "axis": [1.0, 0.0, 0.0], **pose, "offset": 0.0, "limits": [-1.0, 1.0]}
    return {"type": jtype, **pose}


def entered_text(doc: dict[str, Any], param: str, solution: dict[str, Any] | None = None) -> str:
    """What the properties panel says beside a size that is held or entered (FORMAT.md ``hold``):
    "entered (exact)", or "entered 0.4000 m ± 2.0 mm" with, once solved, the solved 1σ; "" for a
    size that is solved from the photos alone."""
    for e in doc.get("hold", []):
        if e == param or (isinstance(e, dict) and e.get("name") == param):
            sigma = 0.0 if isinstance(e, str) else float(e.get("sigma", 0.0))
            if sigma == 0:
                return "entered (exact)"
            value = e.get("value")
            text = f"entered {value:.4f} m ± {1000 * sigma:.1f} mm" if value is not None \
                else f"entered ± {1000 * sigma:.1f} mm"
            solved = ((solution or {}).get("nodes", {}).get(doc["name"], {}).get("params", {}).get(param) or {})
            if solved.get("sigma") is not None:
                text += f"; solved ± {1000 * solved['sigma']:.1f} mm"
            return text
    return ""
