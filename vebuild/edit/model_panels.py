"""Parts of the modelling screen's Model tab for relations and rooms: the scene graph's Relations
section (each relation with its residual now, and a button that removes it), "make equal" over a
size of the selected primitives, and a room's corners, ceiling, openings, door leaves, window panes
and joined rooms. Functions of :class:`~vebuild.edit.panels.Panels` (``p``: its fields,
:class:`~vebuild.edit.panel_fields.PanelFields`), which holds what is typed into them."""

from __future__ import annotations

from typing import Any

from imgui_bundle import imgui

from .panel_fields import PanelFields
from .rooms import OPENING_DEFAULTS

#: The Relations section's height (window pixels): four relations shown, the rest scrolled.
RELATIONS_H = 96
OPENING_KINDS = list(OPENING_DEFAULTS)


def relations_section(p: PanelFields) -> None:
    """The relations of the model, each with its residual in the model as shown (after the last
    solve, or live during a drag) and a remove button."""
    s = p.ed.session
    states = s.relation_states()
    imgui.text(f"Relations ({len(states)})")
    p.ed.rect("relations")
    imgui.set_item_tooltip("flush and aligned are made with the Relate tool (R) in the photo; equal with "
                           "Make equal in a primitive's properties")
    if not states:
        return
    imgui.begin_child("relations list", (0, RELATIONS_H), imgui.ChildFlags_.borders)
    for r in states:
        if r.spread is not None:
            res = f"spread {r.spread:.4g}"
        elif r.distance_m is not None:
            res = f"{1000 * r.distance_m:.1f} mm, {r.angle_deg:.2f}°"
        else:
            res = "residual unknown"
        if p.ed.button(f"x##relation{r.index}", tip=f"remove {r.label}"):
            p.ed.guard(s.remove_relation, r.index)
            imgui.end_child()
            return
        imgui.same_line()
        imgui.text(f"{r.label}: {res}")
        p.ed.rect(f"relation:{r.index}")
    imgui.end_child()


def equal_section(p: PanelFields, name: str, prim: dict[str, Any]) -> None:
    """Make equal: the chosen size of this node and of every other selected node that has it share
    one value (six identical chairs)."""
    params = list(prim.get("params", {}))
    if not params:
        return
    others = [n for n in p.ed.selected_nodes if n != name]
    p.equal_param = min(p.equal_param, len(params) - 1)
    imgui.set_next_item_width(110)
    p.equal_param = p.ed.combo("equal param", p.equal_param, params)
    imgui.set_item_tooltip("the size that Make equal shares")
    imgui.same_line()
    param = params[p.equal_param]
    if p.ed.button("Make equal", tip=f"{name}.{param} and the same size of the other selected nodes "
                                      "(Ctrl+click them in the tree) take one value"):
        if not others:
            p.ed.say(f"select the other nodes whose {param} equals {name}'s (Ctrl+click them in the tree), then "
                     "Make equal")
            return
        p.ed.guard(p.ed.session.add_equal, [f"{n}.{param}" for n in [name, *others]])


def room_section(p: PanelFields, name: str, prim: dict[str, Any]) -> None:
    """A room's corners (a corner, or a step in a rectilinear room, after the chosen corner; one
    removed), its ceiling, and its openings with what each can hold."""
    s = p.ed.session
    corners = p.ed.guard(lambda: s._room(name).corners())
    n = 0 if corners is None else len(corners)
    rect = prim.get("rectilinear", True)
    imgui.text(f"room: {n} corners{' (rectilinear)' if rect else ''}, {len(prim.get('openings', []))} openings")
    changed, on = imgui.checkbox("ceiling##room", bool(prim.get("ceiling", False)))
    p.ed.rect("ceiling")
    imgui.set_item_tooltip("the room has a ceiling at its walls' height (its faces are textured too)")
    if changed:
        p.ed.guard(s.room_set_ceiling, name, bool(on))
    walls = list(prim.get("walls") or [True] * n)
    imgui.text("walls:")
    for i in range(n):
        imgui.same_line()
        changed, on = imgui.checkbox(f"{i}##wall there", bool(walls[i]) if i < len(walls) else True)
        p.ed.rect(f"wall there {i}")
        imgui.set_item_tooltip(f"wall {i} (from corner {i} to corner {(i + 1) % n}) is there; untick a wall the photos "
                               "do not show: it then has no faces, is not textured and hides nothing")
        if changed:
            walls[i] = bool(on)
            p.ed.guard(s.set_room_walls, name, walls)
    imgui.set_next_item_width(80)
    _, p.room_corner = imgui.input_int("corner##room", p.room_corner)
    p.ed.rect("room corner")
    imgui.set_item_tooltip("the number of the corner that Add corner after and Remove corner act on")
    p.room_corner = max(0, min(p.room_corner, max(n - 1, 0)))
    imgui.same_line()
    if p.ed.button("Add corner after", tip="split the wall after this corner: a corner in its middle (a step of "
                                           "two in a rectilinear room)"):
        p.ed.guard(s.room_add_corner, name, p.room_corner)
    imgui.same_line()
    if p.ed.button("Remove corner", tip="this corner (and the next, a step, in a rectilinear room) goes; the walls "
                                        "either side become one"):
        p.ed.guard(s.room_remove_corner, name, p.room_corner)
    imgui.set_next_item_width(70)
    p.room_wall = p.ed.combo("wall", min(p.room_wall, max(n - 1, 0)), [f"wall{i}" for i in range(max(n, 1))])
    imgui.set_item_tooltip("the wall that Add opening cuts")
    imgui.same_line()
    imgui.set_next_item_width(80)
    p.room_kind = p.ed.combo("opening kind", p.room_kind, OPENING_KINDS)
    imgui.set_item_tooltip("a doorway or a window")
    imgui.same_line()
    if p.ed.button("Add opening", tip="a doorway or window of the usual size, centred on the wall"):
        p.ed.guard(s.add_opening, name, p.room_wall, OPENING_KINDS[p.room_kind])
    for o in prim.get("openings", []):
        op = o["name"]
        imgui.text(f"{op} ({o['kind']}, wall {o['wall']})")
        imgui.same_line()
        if o["kind"] == "door":
            if p.ed.button(f"Door leaf##{op}", tip="a door on a hinge at the start jamb, its axis solved from the "
                                                   "photos (Shift+click: at the end jamb)"):
                made = p.ed.guard(s.add_door_leaf, name, op, "end" if p.ed.shift_held() else "start")
                if made is not None:
                    p.ed.select(made)
        else:
            if p.ed.button(f"Window pane##{op}", tip="a pane filling the window, set in the opening"):
                made = p.ed.guard(s.add_window_pane, name, op)
                if made is not None:
                    p.ed.select(made)
        imgui.same_line()
        if p.ed.button(f"Join room##{op}", tip="another room beyond this opening, its own opening back to back "
                                               "with it (the two share their width and height)"):
            made = p.ed.guard(s.join_room, name, op)
            if made is not None:
                p.ed.select(made)
