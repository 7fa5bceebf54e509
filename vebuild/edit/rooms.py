"""Room shells in the modelling screen (FORMAT.md, the ``room`` primitive): its corners (a corner or a
step added after a corner, one removed), its ceiling, its openings (a doorway or a window on a
chosen wall), a door leaf on an opening's jamb (a box on a ``hinge`` joint at the jamb whose axis
is solved), a window pane (a quad set in the opening) and another room joined ``through`` an
opening (with an ``equal`` relation on the two openings' widths and heights, a shared hole).

A room's handles, edges and planes are numbered by corner (``f3``, ``wall3``): a change of its
corners renumbers what the project's pins, edges, relations and joints name of it, so that each
still names the same corner or wall.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Callable
from typing import Any

import numpy as np

from vebuild.model.primitives import primitive_from_dict

from .history import EditError
from .relating import Relating

#: A new opening's size (metres) by kind: a standard interior doorway, a common window (its sill at
#: table height). The user types the measured sizes, or the solve finds them.
OPENING_DEFAULTS: dict[str, dict[str, float]] = {
    "door": {"width": 0.9, "height": 2.05, "sill": 0.0},
    "window": {"width": 1.2, "height": 1.1, "sill": 0.9},
}
#: A door leaf's thickness (metres) when first added: a common interior door; solved or typed after.
LEAF_DEPTH_M = 0.04
#: A window pane's thickness is none (a quad); it is set this far into the wall from its inner face,
#: as a fraction of the wall's thickness (the middle of the reveal).
PANE_DEPTH_FRACTION = 0.5
#: Names a room's corner numbering reaches: its handles, edges and planes with a corner index.
_CORNER_PARAM = re.compile(r"^c(\d+)_([xy])$")
_INDEXED = re.compile(r"^(f|t|fo|to|floor|top|corner|ofloor|otop|ocorner|wall|outer|wtop)(\d+)$")


class Rooms(Relating):
    """Rooms, their openings, door leaves, panes and joined rooms (mixed into the session)."""

    def _room(self, node: str) -> Any:
        """The node's room primitive (EditError if it is not a room)."""
        doc = self._node_doc(node)
        prim = doc.get("primitive") or {}
        if prim.get("type") != "room":
            raise EditError(f"'{node}' is not a room (it is a {prim.get('type', 'group')})")
        try:
            return primitive_from_dict(prim)
        except ValueError as e:
            raise EditError(f"'{node}': {e}") from None

    def _set_room(self, node: str, room: Any, label: str,
                  renumber: Callable[[int], int | None] | None = None) -> None:
        """Replace the node's room (one undoable edit); ``renumber`` maps an old corner index to its
        new one (None: it is gone) for what the project names of the room."""
        with self._edit(label):
            doc = self._node_doc(node)
            doc["primitive"] = room.to_dict()
            if renumber is not None:
                self._renumber_room(node, renumber)
            self._rebuild_check()

    def _renumber_room(self, node: str, renumber: Callable[[int], int | None]) -> None:
        """Pins, edge observations, relations and reference distances naming the room's corners,
        walls and edges, renumbered; those naming a corner that is gone are removed (a relation:
        refused, it must be removed by the user)."""
        def new_name(name: str) -> str | None:
            m = _INDEXED.match(name)
            if m is None:
                return name
            j = renumber(int(m.group(2)))
            return None if j is None else f"{m.group(1)}{j}"

        def new_param(name: str) -> str | None:
            m = _CORNER_PARAM.match(name)
            if m is None:
                return name
            j = renumber(int(m.group(1)))
            return None if j is None else f"c{j}_{m.group(2)}"

        doc = self._model_doc()
        for key, field in (("pins", "handle"), ("edge_observations", "edge")):
            kept = []
            for item in doc.get(key, []):
                if item["node"] == node:
                    name = new_name(item[field])
                    if name is None:
                        continue
                    item[field] = name
                kept.append(item)
            doc[key] = kept
        for i, r in enumerate(doc.get("relations", [])):
            for side in ("a", "b"):
                ref = r.get(side)
                if isinstance(ref, str) and ref.rpartition(":")[0] == node:
                    name = new_name(ref.rpartition(":")[2])
                    if name is None:
                        raise EditError(f"relation {i} names {ref}, which this change removes: remove the "
                                        "relation first")
                    r[side] = f"{node}:{name}"
            if r.get("type") == "equal":  # a corner's coordinate shared with another's
                params = []
                for ref in r.get("params", []):
                    owner, _, param = ref.rpartition(".")
                    moved = new_param(param) if owner == node else param
                    if moved is None:
                        raise EditError(f"relation {i} names {ref}, which this change removes: remove the "
                                        "relation first")
                    params.append(f"{owner}.{moved}")
                r["params"] = params
        for n in self._nodes():  # the room's held or entered corner coordinates
            if n["name"] == node and n.get("hold"):
                kept = []
                for e in n["hold"]:
                    param = e if isinstance(e, str) else e.get("name", "")
                    moved = new_param(param)
                    if moved is not None:
                        kept.append(moved if isinstance(e, str) else {**e, "name": moved})
                n["hold"] = kept
        for d in self.data.get("reference_distances", []):
            for side in ("a", "b"):
                ref = d.get(side, "")
                if ref.partition(":")[0] == node and ":" in ref:
                    name = new_name(ref.partition(":")[2])
                    if name is None:
                        raise EditError(f"a reference distance names {ref}, which this change removes: remove it "
                                        "first")
                    d[side] = f"{node}:{name}"
        for n in self._nodes():  # a marker joint's handle on the room
            j = n.get("joint", {})
            if n["name"] == node and j.get("type") == "marker":
                name = new_name(j["handle"])
                if name is None:
                    raise EditError(f"'{node}' is tied to its marker by {j['handle']}, which this change removes")
                j["handle"] = name

    # -- corners, height, ceiling ---------------------------------------------------------------

    def room_add_corner(self, node: str, after: int) -> None:
        """Split the wall after corner ``after``: a corner (a general room) or a step of two
        (a rectilinear room) in its middle."""
        room = self._room(node)
        n = len(room.corners())
        if not 0 <= after < n:
            raise EditError(f"'{node}' has corners 0 to {n - 1}, not {after}")
        try:
            new = room.with_corner(after)
        except ValueError as e:
            raise EditError(f"'{node}': {e}") from None
        k = len(new.corners()) - n
        self._set_room(node, new, f"corner after {after} of {node}", lambda j: j if j <= after else j + k)
        self.say(f"'{node}' has {n + k} corners now: {k} added after corner {after}; drag them onto the photo")

    def room_remove_corner(self, node: str, corner: int) -> None:
        """Remove a corner (a general room) or the step it begins (corners ``corner`` and the next of
        a rectilinear room); the walls either side become one. Openings on a removed wall must go
        first; corner 0 (the room's origin) stays."""
        room = self._room(node)
        d = room.to_dict()
        corners = np.asarray(room.corners(), float)
        n = len(corners)
        rect = bool(d.get("rectilinear", True))
        k = 2 if rect else 1
        if not 1 <= corner <= n - (3 if rect else 1):
            raise EditError(f"'{node}': corner {corner} cannot be removed (corner 0 is the room's origin; "
                            f"a {'rectilinear ' if rect else ''}room has corners 0 to {n - 1})")
        if n - k < (4 if rect else 3):
            raise EditError(f"'{node}' has {n} corners: a {'rectilinear ' if rect else ''}room keeps at least "
                            f"{4 if rect else 3}")
        gone = set(range(corner, corner + k))
        walls_gone = gone  # wall j runs from corner j: those starting at a removed corner merge away
        for o in d.get("openings", []):
            if o["wall"] in walls_gone:
                raise EditError(f"opening '{o['name']}' is on wall {o['wall']}, which goes with corner {corner}: "
                                "remove the opening first")
        if rect:
            seq = _rect_sequence(corners)
            del seq[corner - 1:corner + 1]
            kept = _rect_corners(seq)
        else:
            kept = np.delete(corners, sorted(gone), axis=0)
        openings = [{**o, "wall": o["wall"] - (k if o["wall"] > corner else 0)} for o in d.get("openings", [])]
        params = d["params"]
        try:
            walls = [w for j, w in enumerate(room.walls_present) if j not in gone]
            new = type(room).from_corners(kept, params["height"], params["thickness"], rectilinear=rect,
                                          ceiling=bool(d.get("ceiling", False)), openings=(),
                                          walls=walls if any(walls) else None)
            for o in openings:
                nm = o["name"]
                new = new.with_opening(nm, o["wall"], o["kind"], params[f"{nm}_offset"], params[f"{nm}_width"],
                                       params[f"{nm}_height"], params[f"{nm}_sill"])
        except ValueError as e:
            raise EditError(f"'{node}' without corner {corner}: {e}") from None
        self._set_room(node, new, f"remove corner {corner} of {node}",
                       lambda j: None if j in gone else (j - k if j > corner else j))
        self.say(f"'{node}' has {n - k} corners now: corner{'s' if k > 1 else ''} "
                 f"{', '.join(map(str, sorted(gone)))} removed")

    def room_set_ceiling(self, node: str, ceiling: bool) -> None:
        room = self._room(node)
        d = room.to_dict()
        d["ceiling"] = bool(ceiling)
        with self._edit(f"{'ceiling on' if ceiling else 'no ceiling on'} {node}"):
            doc = self._node_doc(node)
            if not ceiling:
                self._refuse_named(node, "ceiling")
            doc["primitive"] = primitive_from_dict(d).to_dict()
            self._rebuild_check()

    def _refuse_named(self, node: str, plane: str) -> None:
        for i, r in enumerate(self._relation_docs()):
            if f"{node}:{plane}" in (r.get("a"), r.get("b")):
                raise EditError(f"relation {i} relates {node}:{plane}: remove it first")

    # -- openings ---------------------------------------------------------------------------------

    def add_opening(self, node: str, wall: int, kind: str, name: str | None = None) -> str:
        """A doorway or a window in wall ``wall`` (from corner ``wall`` to the next), of the usual
        size (:data:`OPENING_DEFAULTS`), centred on the wall's inner face."""
        if kind not in OPENING_DEFAULTS:
            raise EditError(f"an opening is a door or a window, not {kind!r}")
        room = self._room(node)
        c = np.asarray(room.corners(), float)
        n = len(c)
        if not 0 <= wall < n:
            raise EditError(f"'{node}' has walls 0 to {n - 1}, not {wall}")
        from .modelling import fresh_name

        taken = set(room.opening_names())
        name = fresh_name(name, kind, taken)
        if name in taken:
            raise EditError(f"'{node}' already has an opening called '{name}'")
        size = OPENING_DEFAULTS[kind]
        inner = float(np.linalg.norm(c[(wall + 1) % n] - c[wall]))  # the inner face, corner to corner
        width = min(size["width"], 0.8 * inner)
        offset = 0.5 * (inner - width)
        try:
            new = room.with_opening(name, wall, kind, offset, width, size["height"], size["sill"])
        except ValueError as e:
            raise EditError(f"'{node}': a {kind} on wall {wall}: {e}") from None
        self._set_room(node, new, f"add {kind} {name} to {node}")
        self.say(f"{kind} '{name}' in wall {wall} of '{node}', {width:.2f} × {size['height']:.2f} m: drag its "
                 "corners onto the photo, or type its sizes")
        return name

    def _opening_kind(self, node: str, opening: str) -> str:
        room = self._room(node)
        for o in room.to_dict().get("openings", []):
            if o["name"] == opening:
                return str(o["kind"])
        raise EditError(f"'{node}' has no opening '{opening}' (its openings: "
                        f"{', '.join(room.opening_names()) or 'none'})")

    def _new_node_name(self, base: str) -> str:
        existing = {n["name"] for n in self._nodes()}
        k = 1
        while f"{base}{k}" in existing:
            k += 1
        return f"{base}{k}"

    def add_door_leaf(self, node: str, opening: str, side: str = "start", name: str | None = None) -> str:
        """A door leaf (a box as wide and high as the opening) on a hinge at the opening's ``side``
        jamb, shut in the opening at angle 0, its axis solved from the photos (``solve_axis``)."""
        if side not in ("start", "end"):
            raise EditError(f"a jamb is the opening's start or end, not {side!r}")
        self._opening_kind(node, opening)
        params = self._room(node).to_dict()["params"]
        width, height = float(params[f"{opening}_width"]), float(params[f"{opening}_height"])
        name = (name or "").strip() or self._new_node_name(f"{opening}_leaf")
        sign = 1.0 if side == "start" else -1.0  # the jamb frame's x runs along the wall, into the opening at start
        leaf = {"name": name, "parent": node,
                "primitive": {"type": "box", "params": {"width": width, "depth": LEAF_DEPTH_M, "height": height}},
                "joint": {"type": "hinge", "jamb": {"opening": opening, "side": side},
                          "axis_point": [0.0, 0.0, 0.0], "axis": [0.0, 0.0, 1.0],
                          "translation": [sign * width / 2, -LEAF_DEPTH_M / 2, 0.0], "rotation_deg": [0.0, 0.0, 0.0],
                          "angle_deg": 0.0, "limits_deg": [-180.0, 180.0], "solve_axis": True}}
        self._add_node(leaf, f"add door leaf {name}")
        self.say(f"door leaf '{name}' on the {side} jamb of '{opening}': drag its free edge to where the photo "
                 "shows the door; its hinge's axis is solved with the model")
        return name

    def add_window_pane(self, node: str, opening: str, name: str | None = None) -> str:
        """A window pane (a quad filling the opening, upright, half way through the wall) set in the
        opening: no freedom of its own, it follows the opening."""
        self._opening_kind(node, opening)
        params = self._room(node).to_dict()["params"]
        width, height = float(params[f"{opening}_width"]), float(params[f"{opening}_height"])
        depth = PANE_DEPTH_FRACTION * float(params["thickness"])
        name = (name or "").strip() or self._new_node_name(f"{opening}_pane")
        # The quad lies in z = 0 with its depth along y: turned +90° about x, its depth runs up (z)
        # and its face looks out of the room (−y, the opening frame's y pointing into the room).
        pane = {"name": name, "parent": node,
                "primitive": {"type": "quad", "params": {"width": width, "depth": height}},
                "joint": {"type": "opening", "opening": opening, "translation": [0.0, -depth, height / 2],
                          "rotation_deg": [90.0, 0.0, 0.0]}}
        self._add_node(pane, f"add window pane {name}")
        self.say(f"window pane '{name}' in '{opening}' of '{node}'")
        return name

    def join_room(self, node: str, opening: str, name: str | None = None) -> str:
        """Another room beyond the opening: a new room (the default rectangle) with an opening of the
        same kind in its wall 0, tied ``through`` the two openings (walls back to back), and an
        ``equal`` relation making the two holes one size."""
        kind = self._opening_kind(node, opening)
        name = (name or "").strip() or self._new_node_name("room")
        from .modelling import DEFAULT_PARAMS

        base: Any = primitive_from_dict({"type": "room", "params": dict(DEFAULT_PARAMS["room"])})
        params = self._room(node).to_dict()["params"]
        own = opening
        c = np.asarray(base.corners(), dtype=float)
        length = float(np.linalg.norm(c[1] - c[0]))
        width = float(params[f"{opening}_width"])
        try:
            room = base.with_opening(own, 0, kind, max(0.5 * (length - width), 0.0), width,
                                     float(params[f"{opening}_height"]), float(params[f"{opening}_sill"]))
        except ValueError as e:
            raise EditError(f"a room joined through '{opening}': {e}") from None
        new = {"name": name, "parent": node, "primitive": room.to_dict(),
               "joint": {"type": "through", "opening": opening, "own_opening": own}}
        eq = {"type": "equal", "params": [f"{node}.{opening}_width", f"{name}.{own}_width"]}
        eq_h = {"type": "equal", "params": [f"{node}.{opening}_height", f"{name}.{own}_height"]}
        with self._edit(f"join room {name} through {opening}"):
            self._nodes().append(new)
            self._model_doc().setdefault("relations", []).extend([eq, eq_h])
            self._rebuild_check()
        self.say(f"room '{name}' joined to '{node}' through '{opening}' (its own '{own}' in its wall 0; the two "
                 "share their width and height): drag its corners onto the photos")
        return name

    def _add_node(self, node_doc: dict[str, Any], label: str) -> None:
        if node_doc["name"] in {n["name"] for n in self._nodes()}:
            raise EditError(f"the model already has a node called '{node_doc['name']}'")
        with self._edit(label):
            self._nodes().append(copy.deepcopy(node_doc))
            self._rebuild_check()


def _rect_sequence(corners: np.ndarray) -> list[float]:
    """A rectilinear room's parameters c1_x, c2_y, c3_x, … (FORMAT.md) from its corners."""
    return [float(corners[i][0] if i % 2 == 1 else corners[i][1]) for i in range(1, len(corners) - 1)]


def _rect_corners(seq: list[float]) -> np.ndarray:
    """The corners of a rectilinear room from its parameter sequence (the inverse of
    :func:`_rect_sequence`): corner i = (c_i, c_{i-1}) for odd i, (c_{i-1}, c_i) for even i."""
    p = [0.0, *seq]
    out = [(0.0, 0.0)]
    for i in range(1, len(seq) + 1):
        out.append((p[i], p[i - 1]) if i % 2 == 1 else (p[i - 1], p[i]))
    out.append((0.0, p[-1]))
    return np.asarray(out, float)
