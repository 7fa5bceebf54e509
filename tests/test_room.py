"""The room primitive (vebuild/model/room.py): its corners, handles, edges, planes and opening
frames against geometry worked out by hand for an L-shaped room and a pentagon with a 45° bay;
its file form and every refusal with its JSON path; its mesh."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

from vebuild.model import PRIMITIVE_TYPES, Room, primitive_from_dict
from vebuild.model.primitives import MIN_SIZE_M, primitive_kinds
from vebuild.model.room_mesh import ear_clip
from vebuild.model.scene import ModelError, model_from_dict

#: Geometry here is exact arithmetic on a few metres: agreement to rounding.
EXACT = 1e-12
MARKERS = {"O": np.zeros(3)}

#: The L-shaped room: 5 × 2.5 m, with a 2.5 × 1.5 m wing; door in wall 0, window in wall 4.
L_ROOM = {"type": "room", "corners": 6, "rectilinear": True, "ceiling": False,
          "params": {"c1_x": 5.0, "c2_y": 2.5, "c3_x": 2.5, "c4_y": 4.0, "height": 2.6, "thickness": 0.1,
                     "door_offset": 1.2, "door_width": 0.9, "door_height": 2.05, "door_sill": 0.0,
                     "win_offset": 0.8, "win_width": 1.2, "win_height": 1.1, "win_sill": 0.9},
          "openings": [{"name": "door", "wall": 0, "kind": "door"}, {"name": "win", "wall": 4, "kind": "window"}]}
#: A 4 × 3 m room whose corner (4, 3) is cut by a 45° bay wall from (4, 2) to (3, 3), with a window in it.
R2 = np.sqrt(2.0)
BAY = {"type": "room", "corners": 5, "rectilinear": False, "ceiling": True,
       "params": {"c1_x": 4.0, "c2_x": 4.0, "c2_y": 2.0, "c3_x": 3.0, "c3_y": 3.0, "c4_x": 0.0, "c4_y": 3.0,
                  "height": 2.4, "thickness": 0.1, "bay_offset": 0.2, "bay_width": 0.8, "bay_height": 1.0,
                  "bay_sill": 1.0},
       "openings": [{"name": "bay", "wall": 2, "kind": "window"}]}


def handle(room: Room, name: str) -> np.ndarray:
    return room.handles()[room.handle_names().index(name)]


def test_the_l_shaped_room_against_hand_geometry() -> None:
    room = primitive_from_dict(L_ROOM)
    assert isinstance(room, Room) and "room" in PRIMITIVE_TYPES
    assert room.PARAMS[:6] == ("c1_x", "c2_y", "c3_x", "c4_y", "height", "thickness")
    assert room.c3_x == 2.5 and room.param("win_sill") == 0.9
    corners = [(0, 0), (5, 0), (5, 2.5), (2.5, 2.5), (2.5, 4), (0, 4)]
    np.testing.assert_allclose(room.corners(), corners, atol=EXACT)
    # Outer corners mitred 0.1 m out: convex corners diagonally out, the reflex corner 3 at (2.6, 2.6).
    outer = [(-0.1, -0.1), (5.1, -0.1), (5.1, 2.6), (2.6, 2.6), (2.6, 4.1), (-0.1, 4.1)]
    for i in range(6):
        np.testing.assert_allclose(handle(room, f"f{i}"), [*corners[i], 0], atol=EXACT)
        np.testing.assert_allclose(handle(room, f"t{i}"), [*corners[i], 2.6], atol=EXACT)
        np.testing.assert_allclose(handle(room, f"fo{i}"), [*outer[i], 0], atol=EXACT)
        np.testing.assert_allclose(handle(room, f"to{i}"), [*outer[i], 2.6], atol=EXACT)
    # The door: 1.2 to 2.1 m along wall 0 (y = 0), 2.05 m high; outside at y = −0.1.
    np.testing.assert_allclose(handle(room, "door_sb"), [1.2, 0, 0], atol=EXACT)
    np.testing.assert_allclose(handle(room, "door_et"), [2.1, 0, 2.05], atol=EXACT)
    np.testing.assert_allclose(handle(room, "door_oet"), [2.1, -0.1, 2.05], atol=EXACT)
    # The window on wall 4, which runs from (2.5, 4) toward (0, 4): 0.8 m along is x = 1.7.
    np.testing.assert_allclose(handle(room, "win_sb"), [1.7, 4, 0.9], atol=EXACT)
    np.testing.assert_allclose(handle(room, "win_et"), [0.5, 4, 2.0], atol=EXACT)
    np.testing.assert_allclose(handle(room, "win_ost"), [1.7, 4.1, 2.0], atol=EXACT)
    edges = {e: (a, b) for e, a, b in room.edges()}
    assert edges["floor5"] == ("f5", "f0") and edges["corner3"] == ("f3", "t3") and edges["otop2"] == ("to2", "to3")
    assert edges["door_start"] == ("door_sb", "door_st") and edges["win_sill"] == ("win_sb", "win_eb")
    assert len(edges) == 6 * 6 + 2 * 4 and len(room.handle_names()) == 4 * 6 + 2 * 8

    planes = room.planes()
    assert list(planes) == ["floor"] + [f"wall{i}" for i in range(6)] + [f"outer{i}" for i in range(6)]
    for _, x, y, n in planes.values():  # unit, right-handed
        np.testing.assert_allclose([x @ x, y @ y, n @ n], 1, atol=EXACT)
        np.testing.assert_allclose(np.cross(x, y), n, atol=EXACT)
    # Wall 3's inner face (x = 2.5, y 2.5 → 4) faces the room (−x); its outer face is at x = 2.6.
    o, x, y, n = planes["wall3"]
    np.testing.assert_allclose([o, x, y, n], [[2.5, 3.25, 1.3], [0, -1, 0], [0, 0, 1], [-1, 0, 0]], atol=EXACT)
    o, x, y, n = planes["outer3"]
    np.testing.assert_allclose([o, x, y, n], [[2.6, 3.35, 1.3], [0, 1, 0], [0, 0, 1], [1, 0, 0]], atol=EXACT)
    o, x, y, n = planes["floor"]
    np.testing.assert_allclose([o, n], [[0, 0, 0], [0, 0, 1]], atol=EXACT)
    assert room.faces().keys() == {"floor"}

    # The window's frame: sill centre 1.4 m along wall 4 (x = 1.1), x along the wall (−x),
    # y into the room (−y), z up; its end jamb 2.0 m along (x = 0.5).
    F = room.opening_frame("win")
    np.testing.assert_allclose(F, [[-1, 0, 0, 1.1], [0, -1, 0, 4], [0, 0, 1, 0.9], [0, 0, 0, 1]], atol=EXACT)
    np.testing.assert_allclose(room.jamb_frame("win", "end")[:3, 3], [0.5, 4, 0.9], atol=EXACT)
    np.testing.assert_allclose(room.jamb_frame("door", "start"), [[1, 0, 0, 1.2], [0, 1, 0, 0], [0, 0, 1, 0],
                                                                  [0, 0, 0, 1]], atol=EXACT)


def test_the_pentagon_with_a_45_degree_bay_against_hand_geometry() -> None:
    room = primitive_from_dict(BAY)
    assert room.PARAMS[:7] == ("c1_x", "c2_x", "c2_y", "c3_x", "c3_y", "c4_x", "c4_y")
    np.testing.assert_allclose(room.corners(), [(0, 0), (4, 0), (4, 2), (3, 3), (0, 3)], atol=EXACT)
    # Corner 2 joins wall 1 (outer face x = 4.1) and the bay (outer face x + y = 6 + 0.1·√2):
    # they meet at (4.1, 2 + 0.1 (√2 − 1)); corner 3 joins the bay and wall 3 (y = 3.1).
    np.testing.assert_allclose(handle(room, "fo2"), [4.1, 2 + 0.1 * (R2 - 1), 0], atol=EXACT)
    np.testing.assert_allclose(handle(room, "to3"), [3 + 0.1 * (R2 - 1), 3.1, 2.4], atol=EXACT)
    d = np.array([-1, 1]) / R2  # along the bay; its outward normal (1, 1)/√2
    np.testing.assert_allclose(handle(room, "bay_sb"), [*(np.array([4, 2]) + 0.2 * d), 1.0], atol=EXACT)
    np.testing.assert_allclose(handle(room, "bay_oet"), [*(np.array([4, 2]) + 1.0 * d + 0.1 / R2), 2.0], atol=EXACT)
    assert "ceiling" in room.planes()
    o, x, y, n = room.plane_frame("ceiling")
    np.testing.assert_allclose([o, n], [[0, 0, 2.4], [0, 0, -1]], atol=EXACT)
    o, x, y, n = room.plane_frame("wall2")
    np.testing.assert_allclose([o, x, y, n], [[3.5, 2.5, 1.2], [1 / R2, -1 / R2, 0], [0, 0, 1], [-1 / R2, -1 / R2, 0]],
                               atol=EXACT)
    F = room.opening_frame("bay")
    np.testing.assert_allclose(F[:3, :3], np.column_stack([[*d, 0], [-1 / R2, -1 / R2, 0], [0, 0, 1]]), atol=EXACT)
    np.testing.assert_allclose(F[:3, 3], [*(np.array([4, 2]) + 0.6 * d), 1.0], atol=EXACT)
    # Outer faces of a convex room are the inner ones moved out by the thickness.
    for i in range(5):
        (oi, _, _, ni), (oo, _, _, no) = room.plane_frame(f"wall{i}"), room.plane_frame(f"outer{i}")
        np.testing.assert_allclose(no, -ni, atol=EXACT)
        assert (oo - oi) @ no == pytest.approx(0.1, abs=EXACT)


def test_file_form_round_trip_and_value_semantics() -> None:
    for d in (L_ROOM, BAY):
        room = primitive_from_dict(d)
        assert room.to_dict() == d and Room.from_dict(room.to_dict()) == room
        assert copy.deepcopy(room) == room and pickle.loads(pickle.dumps(room)) == room
        assert hash(primitive_from_dict(d)) == hash(room)
        moved = room.with_params({"height": 3.0})
        assert moved.height == 3.0 and room.height != 3.0 and moved != room
        assert room.with_params(room.params) == room
        with pytest.raises(AttributeError):
            room.height = 1.0  # type: ignore[misc]
    kinds = primitive_kinds()
    cls, defaults = kinds["room"]
    default = cls(**defaults)
    np.testing.assert_allclose(default.corners(), [(0, 0), (4, 0), (4, 3), (0, 3)])
    assert (default.height, default.thickness) == (2.5, 0.1)
    room = primitive_from_dict(L_ROOM)
    assert room.param_kinds()[:6] == ("position",) * 4 + ("size",) * 2
    least = dict(zip(room.PARAMS, room.minimum_sizes(), strict=True))
    assert least["c1_x"] == -np.inf and least["door_sill"] == 0 and least["door_offset"] == 0
    assert least["thickness"] == MIN_SIZE_M and not Room.LINEAR


def test_building_rooms_in_code() -> None:
    room = Room.from_corners([(0, 0), (5, 0), (5, 2.5), (2.5, 2.5), (2.5, 4), (0, 4)], 2.6, 0.1)
    assert room == primitive_from_dict({**L_ROOM, "params": {k: v for k, v in L_ROOM["params"].items()
                                                            if not k.startswith(("door", "win"))}, "openings": []})
    room = room.with_opening("door", 0, "door", 1.2, 0.9, 2.05, 0.0).with_opening("win", 4, "window", 0.8, 1.2,
                                                                                    1.1, 0.9)
    assert room == primitive_from_dict(L_ROOM) and room.opening_names() == ["door", "win"]
    # A general room: a corner in the middle of wall 1; the window on wall 4 is now on wall 5.
    bay = primitive_from_dict(BAY)
    split = bay.with_corner(0)
    np.testing.assert_allclose(split.corners(), [(0, 0), (2, 0), (4, 0), (4, 2), (3, 3), (0, 3)], atol=EXACT)
    assert split.opening("bay").wall == 3 and split.param("bay_offset") == 0.2
    # A rectilinear room gets a step: wall 1 (x = 5, y 0 → 2.5) now steps 0.5 m in at y = 1.25.
    step = primitive_from_dict(L_ROOM).with_corner(1)
    np.testing.assert_allclose(step.corners(), [(0, 0), (5, 0), (5, 1.25), (4.5, 1.25), (4.5, 2.5), (2.5, 2.5),
                                                (2.5, 4), (0, 4)], atol=EXACT)
    assert step.opening("win").wall == 6 and step.opening("door").wall == 0
    # An opening past the middle of the split wall moves to the new wall, its offset from its start.
    moved = primitive_from_dict(L_ROOM).with_corner(0)
    assert moved.opening("door").wall == 0  # 1.2–2.1 m: before the middle (2.5 m)
    far = primitive_from_dict({**L_ROOM, "params": {**L_ROOM["params"], "door_offset": 3.0}}).with_corner(0)
    assert far.opening("door").wall == 2 and far.param("door_offset") == pytest.approx(0.5, abs=EXACT)
    with pytest.raises(ValueError, match="spans the middle of wall 0"):
        primitive_from_dict({**L_ROOM, "params": {**L_ROOM["params"], "door_offset": 2.0}}).with_corner(0)


def test_the_handle_jacobian_matches_the_handles() -> None:
    """Central differences of smooth handles: each column against an independent forward
    difference 100 times coarser (agreement to its truncation, ~1e-4 × curvature)."""
    room = primitive_from_dict(BAY)
    J = room.handle_jacobian()
    p = room.params
    for j in range(len(p)):
        q = p.copy()
        q[j] += 1e-4
        np.testing.assert_allclose(J[:, :, j], (room.handles(q) - room.handles()) / 1e-4, atol=1e-3)
    # Exact entries: corner 1 follows c1_x one for one; every top corner follows the height.
    assert J[room.handle_names().index("f1"), 0, 0] == pytest.approx(1.0, abs=1e-8)
    assert J[room.handle_names().index("t3"), 2, room.PARAMS.index("height")] == pytest.approx(1.0, abs=1e-8)


def room_node(prim: dict) -> dict:
    return {"name": "room", "primitive": prim, "joint": {"type": "marker", "marker": "O", "handle": "f0"}}


def with_params(base: dict, **changes: float) -> dict:
    return {**base, "params": {**base["params"], **changes}}


PATH = "$.model.nodes[0].primitive"


@pytest.mark.parametrize(("prim", "where", "message"), [
    ({**L_ROOM, "corners": 5}, f"{PATH}.corners", "a rectilinear room has an even number of corners"),
    ({**L_ROOM, "corners": "six"}, f"{PATH}.corners", "corners must be a whole number"),
    ({**BAY, "corners": 2}, f"{PATH}.corners", "at least 3 corners"),
    ({**L_ROOM, "rectilinear": "yes"}, f"{PATH}.rectilinear", "rectilinear must be true or false"),
    (with_params(L_ROOM, thickness=0.0), f"{PATH}.params.thickness", "thickness must be > 0"),
    (with_params(L_ROOM, thickness=-0.1), f"{PATH}.params.thickness", "thickness must be > 0"),
    (with_params(L_ROOM, height=0.0), f"{PATH}.params.height", "height must be > 0"),
    (with_params(L_ROOM, c2_y=float("nan")), f"{PATH}.params.c2_y", "c2_y must be a finite number"),
    (with_params(L_ROOM, c2_y="2"), f"{PATH}.params.c2_y", "c2_y must be a number"),
    ({**L_ROOM, "params": {k: v for k, v in L_ROOM["params"].items() if k != "c4_y"}}, f"{PATH}.params",
     "missing c4_y"),
    (with_params(L_ROOM, c5_x=1.0), f"{PATH}.params.c5_x", "unknown param 'c5_x'"),
    # The wing pulled below the floor's first wall: wall 3 crosses wall 0.
    (with_params(L_ROOM, c4_y=-1.0), f"{PATH}.params", "the floor polygon intersects itself"),
    (with_params(BAY, c3_x=5.0, c3_y=-1.0), f"{PATH}.params", "the floor polygon intersects itself"),
    (with_params(L_ROOM, c1_x=-5.0, c3_x=-2.5), f"{PATH}.params", "counter-clockwise"),
    (with_params(L_ROOM, c2_y=0.0), f"{PATH}.params", "walls are at least"),
    # A notch 0.2 m wide into the room: 0.15 m walls on its sides would pass through each other.
    ({**L_ROOM, "corners": 8, "openings": [], "params": {"c1_x": 4.0, "c2_y": 3.0, "c3_x": 2.1, "c4_y": 1.0,
                                                         "c5_x": 1.9, "c6_y": 3.0, "height": 2.6, "thickness": 0.15}},
     f"{PATH}.params.thickness", "too large for its walls"),
    (with_params(L_ROOM, door_offset=4.5), f"{PATH}.params.door_offset", "lies outside the wall"),
    (with_params(L_ROOM, win_width=3.0), f"{PATH}.params.win_width", "wall 4 has room for 2.5 m"),
    (with_params(L_ROOM, door_height=2.7), f"{PATH}.params.door_height", "the walls are 2.6 m high"),
    (with_params(L_ROOM, door_offset=-0.2), f"{PATH}.params.door_offset", "door_offset must be at least 0"),
    (with_params(L_ROOM, door_sill=-0.1), f"{PATH}.params.door_sill", "door_sill must be at least 0"),
    ({**L_ROOM, "openings": [L_ROOM["openings"][0], {"name": "door2", "wall": 0, "kind": "door"}],
      "params": {**{k: v for k, v in L_ROOM["params"].items() if not k.startswith("win")}, "door2_offset": 1.8,
                 "door2_width": 0.9, "door2_height": 2.0, "door2_sill": 0.0}},
     f"{PATH}.params.door2_offset", "openings 'door' and 'door2' overlap on wall 0"),
    ({**L_ROOM, "corners": 4, "params": {"c1_x": 2.0, "c2_y": 3.0, "height": 2.6, "thickness": 0.1,
                                         **{f"{n}_{s}": v for n in ("a", "b") for s, v in
                                            (("offset", 0.0), ("width", 1.05), ("height", 1.0), ("sill", 0.0))}},
      "openings": [{"name": "a", "wall": 0, "kind": "door"}, {"name": "b", "wall": 0, "kind": "door"}]},
     f"{PATH}.params.a_width", "shorter than its openings together"),
    ({**L_ROOM, "openings": [L_ROOM["openings"][0], {"name": "door", "wall": 4, "kind": "window"}]},
     f"{PATH}.openings[1].name", "opening name 'door' is used twice"),
    ({**L_ROOM, "openings": [L_ROOM["openings"][0], {"name": "f3", "wall": 4, "kind": "window"}]},
     f"{PATH}.openings[1].name", "reads as one of the room's own names"),
    ({**L_ROOM, "openings": [L_ROOM["openings"][0], {"name": "my win", "wall": 4, "kind": "window"}]},
     f"{PATH}.openings[1].name", "must start with a letter"),
    ({**L_ROOM, "openings": [L_ROOM["openings"][0], {"name": "win", "wall": 6, "kind": "window"}]},
     f"{PATH}.openings[1].wall", "expected a wall 0…5"),
    ({**L_ROOM, "openings": [L_ROOM["openings"][0], {"name": "win", "wall": 4, "kind": "hatch"}]},
     f"{PATH}.openings[1].kind", "expected one of door, window"),
    ({**L_ROOM, "openings": [L_ROOM["openings"][0], {"name": "win", "wall": 4, "kind": "window", "w": 1}]},
     f"{PATH}.openings[1].w", "unknown field 'w'"),
    ({**L_ROOM, "doors": []}, f"{PATH}.doors", "unknown field 'doors'"),
])
def test_every_refusal_names_its_field(prim: dict, where: str, message: str) -> None:
    with pytest.raises(ModelError) as e:
        model_from_dict([room_node(prim)], MARKERS)
    assert e.value.where == where, str(e.value)
    assert message in str(e.value) and "node 'room'" in str(e.value)


def test_a_room_in_a_project_file_loads_and_bad_fields_are_refused_with_the_file(tmp_path) -> None:
    import json

    from vebuild.errors import ProjectError
    from vebuild.project import load_project
    from vebuild.project.decode import model as decode_model

    path = tmp_path / "r.vebuild.json"
    doc = {"format": "vebuild-project", "version": 1, "name": "r", "settings": {"click_sigma_px": 0.7},
           "reference_distances": [], "photos": [], "markers": [{"name": "O"}], "origin_marker": "O",
           "model": {"nodes": [room_node(L_ROOM)]}}
    path.write_text(json.dumps(doc))
    m = decode_model(load_project(path), MARKERS)
    assert m.node("room").primitive == primitive_from_dict(L_ROOM)
    doc["model"]["nodes"][0]["primitive"] = {**L_ROOM, "corners": 7}
    path.write_text(json.dumps(doc))
    with pytest.raises(ProjectError, match=r"\$\.model\.nodes\[0\]\.primitive\.corners: .*even number"):
        decode_model(load_project(path), MARKERS)
    # The schema: a room's keys on another primitive, a corner beyond 10 km, an unknown kind.
    box = {"type": "box", "params": {"width": 1, "depth": 1, "height": 1}}
    for prim, where, what in (({**box, "openings": []}, "primitive", "belong to a room"),
                              (with_params(L_ROOM, c1_x=2e4), "primitive.params.c1_x", "at least -10000"),
                              ({**L_ROOM, "openings": [{"name": "d", "wall": 0, "kind": "arch"}]},
                               r"primitive.openings\[0\].kind", '"door" or "window"')):
        doc["model"]["nodes"][0]["primitive"] = prim
        path.write_text(json.dumps(doc))
        with pytest.raises(ProjectError, match=rf"\$\.model\.nodes\[0\]\.{where}: .*{what}"):
            load_project(path)


def polygon_area(c: np.ndarray) -> float:
    return 0.5 * float(np.sum(c[:, 0] * np.roll(c[:, 1], -1) - np.roll(c[:, 0], -1) * c[:, 1]))


def face_areas(mesh) -> dict[str, float]:
    v = mesh.vertices[mesh.faces]
    a = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    return {name: float(a[mesh.face_ids == i + 1].sum()) for i, name in enumerate(mesh.face_names)}


@pytest.mark.parametrize("prim", [L_ROOM, BAY])
def test_the_mesh_covers_each_face_once_with_its_holes(prim: dict) -> None:
    room = primitive_from_dict(prim)
    mesh = room.mesh(texels_per_metre=100)
    n = room.n_corners
    names = (["floor"] + (["ceiling"] if room.ceiling else []) + [f"wall{i}" for i in range(n)]
             + [f"outer{i}" for i in range(n)] + ([] if room.ceiling else [f"wtop{i}" for i in range(n)])
             + [f"{o.name}_reveal" for o in room.openings])
    assert mesh.face_names == names
    # Each triangle's winding agrees with its vertices' normals (counter-clockwise seen from outside).
    v = mesh.vertices[mesh.faces]
    geo = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    assert np.all(np.einsum("ij,ij->i", geo, mesh.normals[mesh.faces[:, 0]]) > 0)
    areas = face_areas(mesh)
    c, h, t = room.corners(), room.height, room.thickness
    assert areas["floor"] == pytest.approx(polygon_area(c), abs=1e-9)
    w = room.walls()
    holes = {i: 0.0 for i in range(n)}
    for o in room.openings:
        holes[o.wall] += room.param(f"{o.name}_width") * room.param(f"{o.name}_height")
        width, oh = room.param(f"{o.name}_width"), room.param(f"{o.name}_height")
        assert areas[f"{o.name}_reveal"] == pytest.approx(2 * (width + oh) * t, abs=1e-9)
    for i in range(n):
        assert areas[f"wall{i}"] == pytest.approx(w["length"][i] * h - holes[i], abs=1e-9)
        u0, u1 = w["outer_u"][i]
        assert areas[f"outer{i}"] == pytest.approx((u1 - u0) * h - holes[i], abs=1e-9)
    if not room.ceiling:  # the wall tops fill the ring between the inner and the outer polygon
        ring = polygon_area(w["outer"]) - polygon_area(c)
        assert sum(areas[f"wtop{i}"] for i in range(n)) == pytest.approx(ring, abs=1e-9)
    else:
        assert areas["ceiling"] == pytest.approx(polygon_area(c), abs=1e-9)
    # Every chart is its face's size in metres; they do not overlap in the atlas.
    np.testing.assert_allclose(mesh.chart_size_m[names.index("floor")], np.ptp(c, axis=0), atol=1e-9)


def test_ear_clipping_covers_non_convex_floors_exactly_once() -> None:
    rng = np.random.default_rng(3)
    # A comb (many reflex corners) and a star: the triangles' areas sum to the polygon's, none inverted.
    comb = [(0, 0), (6, 0), (6, 3)] + [(x, y) for k in range(5, 0, -1) for x, y in ((k + 0.5, 3), (k + 0.5, 1),
                                                                                      (k, 1), (k, 3))] + [(0, 3)]
    angles = np.sort(rng.uniform(0, 2 * np.pi, 17))
    star = np.column_stack([np.cos(angles), np.sin(angles)]) * rng.uniform(0.3, 1.0, (17, 1))
    for poly in (np.array(comb, float), star):
        tris = ear_clip(poly)
        assert len(tris) == len(poly) - 2
        a = poly[tris]
        e1, e2 = a[:, 1] - a[:, 0], a[:, 2] - a[:, 0]
        signed = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        assert np.all(signed > 0) and signed.sum() == pytest.approx(polygon_area(poly), rel=1e-12)
