"""The modelling screen's relations and rooms without a window (vebuild.edit.relating, vebuild.edit.rooms):
picking a face by the ray through a pixel, making faces flush or aligned and sizes equal, removing a
relation, each undoable and decoded into the model; a room's corners, ceiling and openings, a door
leaf on a jamb, a window pane and a room joined through an opening; and the clear messages for bad
input."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from vebuild import camera as cam_math
from vebuild.cli import main
from vebuild.edit.relating import relation_residual
from vebuild.edit.session import EditError, EditSession
from vebuild.project import load_project
from vebuild.resources import example_project_dir

#: A face's centre picked through its own pixel comes back within this (metres): the ray and the
#: triangle are intersected in float64, so only the projection's round trip (~1e-12 m at 5 m) is lost.
PICK_TOL_M = 1e-6


@pytest.fixture(scope="module")
def solved_room(tmp_path_factory):
    folder = tmp_path_factory.mktemp("relate") / "room"
    shutil.copytree(example_project_dir(), folder)
    path = folder / "room.vebuild.json"
    assert main(["calibrate", str(path), "--quiet"]) == 0
    assert main(["solve", str(path)]) == 0
    return path


@pytest.fixture
def session(solved_room, tmp_path):
    shutil.copytree(solved_room.parent, tmp_path / "room")
    return EditSession.open(tmp_path / "room" / solved_room.name, recover=False)


def _face_centre(s, node, corners, along=0.5):
    """A point of a box face from its corner handles (independent of the meshes): half way up,
    ``along`` of the way from its first side (corners 0, 3) to its second (1, 2)."""
    c = [s.model.handle_world(node, h) for h in corners]
    return (1 - along) * (c[0] + c[3]) / 2 + along * (c[1] + c[2]) / 2


def _pixel(s, photo, X):
    cam = s.cameras[photo]
    return cam_math.project(cam.K, cam.R, cam.C, np.asarray(X, float), cam.lens)


def test_a_face_is_picked_by_the_ray_through_its_pixel(session):
    s = session
    # In p1 the cabinet shows its +x side (handles v1, v2, v6, v5), the west wall its front (−y)
    # face (beside the cabinet, which hides its middle), the table its top.
    for node, face, corners, along in (("cabinet", "right", ("v1", "v2", "v6", "v5"), 0.5),
                                       ("wall_west", "front", ("v0", "v1", "v5", "v4"), 0.85),
                                       ("table.top", "top", ("v4", "v5", "v6", "v7"), 0.5)):
        X = _face_centre(s, node, corners, along)
        pick = s.face_at("p1", _pixel(s, "p1", X))
        assert (pick.node, pick.name, pick.what) == (node, face, "face")
        assert np.linalg.norm(np.subtract(pick.point, X)) < PICK_TOL_M
        assert pick.ref == f"{node}:{face}"
        outline = s.pick_outline("p1", pick)  # the face's two triangles, each three pixels
        assert len(outline) == 2 and all(len(t) == 3 for t in outline)
    # Nearest along the ray: the table's top hides the floor under it.
    X = _face_centre(s, "table.top", ("v4", "v5", "v6", "v7"))
    assert s.face_at("p1", _pixel(s, "p1", X)).node == "table.top"
    # A ray over the walls of a room without a ceiling meets nothing.
    assert s.face_at("p3", (800.0, -6000.0)) is None
    # The planes offered by name (a face no photo shows), the edge of a pick.
    assert {"front", "right", "back", "left", "top", "bottom"} <= set(s.plane_names("cabinet"))
    assert s.edge_pick("cabinet", "e8").ref == "cabinet:e8"
    with pytest.raises(EditError, match="'cabinet' has no edge 'e99'"):
        s.edge_pick("cabinet", "e99")


def test_flush_and_aligned_relations_are_saved_undone_and_decoded(session):
    s = session
    i = s.add_relation("flush", "cabinet:left", "wall_west:front")
    assert s.data["model"]["relations"][i] == {"type": "flush", "a": "cabinet:left", "b": "wall_west:front"}
    assert s.undo_label == "flush cabinet:left – wall_west:front"
    assert "cabinet:left is flush against wall_west:front (relation 0); the model is" in s.messages[-1]
    assert "from it now: Solve brings the model onto it, and drags keep it" in s.messages[-1]
    assert [r.type for r in s.model.relations] == ["flush"]  # the screen's model carries it (drags keep it)
    j = s.add_relation("aligned", "table.top:top", "box:top")
    k = s.add_relation("flush", "box:back", "wall_north:front", offset=0.02)
    assert s.data["model"]["relations"][k]["offset"] == 0.02
    assert s.data["model"]["relations"][j] == {"type": "aligned", "a": "table.top:top", "b": "box:top"}
    e = s.add_relation("aligned", s.edge_pick("cabinet", "e8"), s.edge_pick("table.top", "e8"))
    assert s.data["model"]["relations"][e]["a"] == "cabinet:e8"
    # Residuals, from the model as shown: the table's top and the box's are both level (0°), the
    # box's lower by the difference of their heights.
    states = s.relation_states()
    assert len(states) == 4 and all(st.distance_m is not None for st in states)
    assert states[j].angle_deg == pytest.approx(0.0, abs=1e-6)
    table_z = s.model.handle_world("table.top", "v4")[2]
    box_z = s.model.handle_world("box", "v4")[2]
    assert states[j].distance_m == pytest.approx(abs(table_z - box_z), abs=1e-6)
    # Removed, undone, redone.
    s.remove_relation(j)
    assert len(s.data["model"]["relations"]) == 3 and "removed relations[1] (aligned" in s.messages[-1]
    s.undo()
    assert s.data["model"]["relations"][j]["type"] == "aligned"
    s.save()
    data = load_project(s.project.path).data
    assert [r["type"] for r in data["model"]["relations"]] == ["flush", "aligned", "flush", "aligned"]


def test_equal_shares_one_size_and_bad_relations_are_refused(session):
    s = session
    i = s.add_equal(["table.leg1.width", "table.leg2.width", "table.leg3.width"])
    assert s.data["model"]["relations"][i] == {"type": "equal",
                                               "params": ["table.leg1.width", "table.leg2.width", "table.leg3.width"]}
    st = s.relation_states()[i]
    assert st.spread is not None and st.distance_m is None
    rev = s.revision
    for call, message in (
            (lambda: s.add_relation("flush", "cabinet:left", "cabinet:right"), "faces of one node"),
            (lambda: s.add_relation("aligned", "cabinet:left", "box:left", offset=0.1),
             "aligned relation has no offset"),
            (lambda: s.add_relation("touching", "cabinet:left", "box:left"), "flush or aligned, not 'touching'"),
            (lambda: s.add_relation("flush", s.edge_pick("cabinet", "e8"), s.edge_pick("box", "e8")),
             "two edges are aligned"),
            (lambda: s.add_relation("flush", "cabinet:nowhere", "box:left"), "nowhere"),
            # the box rests on the floor's top: 2 cm off it as well is a conflict, named
            (lambda: s.add_relation("flush", "box:bottom", "floor:top", offset=0.02), "conflicting"),
            (lambda: s.add_equal(["table.leg1.width"]), "two or more different parameters"),
            (lambda: s.add_equal(["table.leg1.width", "table.leg1.width"]), "two or more different parameters"),
            (lambda: s.add_equal(["table.leg1.width", "table.leg2.girth"]), "'table.leg2' has no size 'girth'"),
            (lambda: s.remove_relation(7), "there is no relation 7")):
        with pytest.raises(EditError, match=message):
            call()
    assert s.revision == rev and len(s.data["model"]["relations"]) == 1


def test_relation_residuals_measure_the_model_not_the_document():
    """relation_residual on a model built in code: a box 0.3 m off a wall, turned 90° from it."""
    from vebuild.model.scene import model_from_dict

    nodes = [{"name": "floor", "primitive": {"type": "quad", "params": {"width": 4.0, "depth": 4.0}},
              "joint": {"type": "fixed", "translation": [0.0, 0.0, 0.0], "rotation_deg": [0.0, 0.0, 0.0]}},
             {"name": "wall", "parent": "floor", "primitive": {"type": "box", "params": {"width": 4.0, "depth": 0.1,
                                                                                         "height": 2.5}},
              "joint": {"type": "rests_on", "face": "top", "position": [0.0, 2.0], "yaw_deg": 0.0}},
             {"name": "crate", "parent": "floor", "primitive": {"type": "box", "params": {"width": 0.4, "depth": 0.6,
                                                                                          "height": 0.5}},
              "joint": {"type": "rests_on", "face": "top", "position": [0.0, 1.35], "yaw_deg": 0.0}}]
    m = model_from_dict(nodes)
    x = m.vector()
    # crate's back (+y, at y = 1.65) faces the wall's front (−y, at y = 1.95): 0.30 m apart, facing.
    d, a, _ = relation_residual(m, x, {"type": "flush", "a": "crate:back", "b": "wall:front"})
    assert d == pytest.approx(0.30, abs=1e-9) and a == pytest.approx(0.0, abs=1e-6)
    d, a, _ = relation_residual(m, x, {"type": "flush", "a": "crate:back", "b": "wall:front", "offset": 0.30})
    assert d == pytest.approx(0.0, abs=1e-9)
    d, a, _ = relation_residual(m, x, {"type": "aligned", "a": "crate:back", "b": "wall:front"})
    assert a == pytest.approx(180.0, abs=1e-6)  # facing each other, not the same way
    d, a, _ = relation_residual(m, x, {"type": "flush", "a": "crate:right", "b": "wall:front"})
    assert a == pytest.approx(90.0, abs=1e-6)


def test_room_corners_ceiling_and_openings_are_edited_and_renumbered(session):
    s = session
    s.add_primitive("room", name="hall")
    doc = next(n for n in s.data["model"]["nodes"] if n["name"] == "hall")
    assert doc["primitive"]["type"] == "room" and doc["primitive"]["corners"] == 4
    assert doc["joint"]["type"] == "rests_on"
    room = s.model.node("hall").primitive
    np.testing.assert_allclose(room.corners(), [[0, 0], [4, 0], [4, 3], [0, 3]])
    # A pin on corner 2 and a relation on wall 2 follow the corners' renumbering.
    s.fix("p1", "hall", "f2", (100.0, 100.0))
    s.add_relation("flush", "cabinet:left", "hall:wall2")
    s.add_primitive("room", name="den")
    s.add_equal(["hall.c2_y", "den.c2_y"])  # corner 2's y, shared with the other room's
    s.room_add_corner("hall", 1)  # a rectilinear room: a step of two corners in wall 1
    room = s.model.node("hall").primitive
    assert len(room.corners()) == 6
    assert any((p["node"], p["handle"]) == ("hall", "f4") for p in s.data["model"]["pins"])
    assert s.data["model"]["relations"][0]["b"] == "hall:wall4"
    assert s.data["model"]["relations"][1]["params"] == ["hall.c4_y", "den.c2_y"]
    s.room_remove_corner("hall", 2)
    assert len(s.model.node("hall").primitive.corners()) == 4
    assert any((p["node"], p["handle"]) == ("hall", "f2") for p in s.data["model"]["pins"])
    assert s.data["model"]["relations"][0]["b"] == "hall:wall2"
    assert s.data["model"]["relations"][1]["params"] == ["hall.c2_y", "den.c2_y"]
    s.room_add_corner("hall", 0)  # corners 1 and 2 are the step's: den shares corner 4's y now
    assert s.data["model"]["relations"][1]["params"] == ["hall.c4_y", "den.c2_y"]
    with pytest.raises(EditError, match="relation 0 names hall:wall4, which this change removes"):
        s.room_remove_corner("hall", 3)  # corners 3 and 4 go, and wall 4 with them
    s.undo()
    s.remove_node("den")
    with pytest.raises(EditError, match="corner 0 is the room's origin"):
        s.room_remove_corner("hall", 0)
    with pytest.raises(EditError, match="keeps at least 4"):
        s.room_remove_corner("hall", 1)
    # Ceiling on, off.
    s.room_set_ceiling("hall", True)
    assert s.model.node("hall").primitive.to_dict()["ceiling"] is True and "ceiling" in s.plane_names("hall")
    s.room_set_ceiling("hall", False)
    # A door on wall 0, a window on wall 1: usual sizes, centred.
    door = s.add_opening("hall", 0, "door")
    win = s.add_opening("hall", 1, "window")
    p = s.model.node("hall").primitive.to_dict()["params"]
    assert (door, win) == ("door1", "window1")
    assert (p["door1_width"], p["door1_height"], p["door1_sill"]) == (0.9, 2.05, 0.0)
    assert (p["window1_width"], p["window1_sill"]) == (1.2, 0.9)
    with pytest.raises(EditError, match="opening 'door1' is on wall 0|corner 0"):
        s.room_remove_corner("hall", 0)
    with pytest.raises(EditError, match="a door or a window, not 'hatch'"):
        s.add_opening("hall", 0, "hatch")
    with pytest.raises(EditError, match="walls 0 to 3, not 9"):
        s.add_opening("hall", 9, "door")
    with pytest.raises(EditError, match="'cabinet' is not a room"):
        s.add_opening("cabinet", 0, "door")


def test_door_leaf_window_pane_and_a_joined_room(session):
    s = session
    s.add_primitive("room", name="hall")
    s.add_opening("hall", 0, "door")
    s.add_opening("hall", 1, "window")
    leaf = s.add_door_leaf("hall", "door1")
    j = next(n for n in s.data["model"]["nodes"] if n["name"] == leaf)
    assert j["parent"] == "hall" and j["primitive"]["type"] == "box"
    assert j["joint"]["type"] == "hinge" and j["joint"]["jamb"] == {"opening": "door1", "side": "start"}
    assert j["joint"]["solve_axis"] is True
    assert j["primitive"]["params"]["width"] == 0.9 and j["primitive"]["params"]["height"] == 2.05
    # Shut at angle 0: the leaf fills the doorway, its corners on the jambs.
    m = s.model
    sb, eb = (m.handle_world("hall", h) for h in ("door1_sb", "door1_eb"))
    lo = np.array([m.handle_world(leaf, h) for h in ("v0", "v1", "v2", "v3")])
    assert min(np.linalg.norm(lo - sb, axis=1)) < 0.05 and min(np.linalg.norm(lo - eb, axis=1)) < 0.05
    # On the end jamb instead: the same doorway filled, hung from its other side.
    other_leaf = s.add_door_leaf("hall", "door1", side="end")
    lo2 = np.array([s.model.handle_world(other_leaf, h) for h in ("v0", "v1", "v2", "v3")])
    np.testing.assert_allclose(np.sort(lo2[:, :2], axis=0), np.sort(lo[:, :2], axis=0), atol=1e-9)
    with pytest.raises(EditError, match="a jamb is the opening's start or end, not 'middle'"):
        s.add_door_leaf("hall", "door1", side="middle")
    s.remove_node(other_leaf)
    pane = s.add_window_pane("hall", "window1")
    pj = next(n for n in s.data["model"]["nodes"] if n["name"] == pane)
    assert pj["joint"]["type"] == "opening" and pj["joint"]["opening"] == "window1"
    corners = np.array([m.handle_world("hall", h) for h in ("window1_sb", "window1_st", "window1_eb", "window1_et")])
    got = np.array([s.model.handle_world(pane, h) for h in ("v0", "v1", "v2", "v3")])
    # The pane's corners lie on the window's jambs, half the wall's thickness out of the room.
    t = s.model.node("hall").primitive.to_dict()["params"]["thickness"]
    d = np.min(np.linalg.norm(got[:, None, :] - corners[None, :, :], axis=2), axis=1)
    np.testing.assert_allclose(d, t / 2, atol=1e-9)
    with pytest.raises(EditError, match="has no opening 'hatch'"):
        s.add_window_pane("hall", "hatch")
    other = s.join_room("hall", "door1")
    o = next(n for n in s.data["model"]["nodes"] if n["name"] == other)
    assert o["joint"] == {"type": "through", "opening": "door1", "own_opening": "door1"}
    assert o["primitive"]["openings"][0]["wall"] == 0
    rels = s.data["model"]["relations"][-2:]
    assert rels == [{"type": "equal", "params": ["hall.door1_width", f"{other}.door1_width"]},
                    {"type": "equal", "params": ["hall.door1_height", f"{other}.door1_height"]}]
    s.undo()
    assert other not in s.model.index and "relations" not in s.data["model"]
    s.redo()
    s.save()
    data = json.loads(s.project.path.read_text())
    assert [n["name"] for n in data["model"]["nodes"]][-4:] == ["hall", leaf, pane, other]


#: A room's sizes dragged onto exact (noise-free) pixels of the true corners come out within this
#: (metres): only the drag solver's convergence is lost, a hundredth of a pixel or less (2e-5 m
#: seen at 5 m from p6's camera, whose pixel there is 4 mm), well inside a click's 0.7 px.
DRAG_TOL_M = 1e-4


@pytest.fixture
def bare(solved_room, tmp_path):
    """The example room calibrated, its model taken away."""
    shutil.copytree(solved_room.parent, tmp_path / "bare")
    path = tmp_path / "bare" / solved_room.name
    data = json.loads(path.read_text())
    for key in ("model", "model_solution", "textures"):
        data.pop(key, None)
    data["reference_distances"] = [r for r in data["reference_distances"] if ":" not in r["a"] + r["b"]]
    path.write_text(json.dumps(data))
    return EditSession.open(path, recover=False)


def test_a_room_is_sized_by_dragging_its_corners_onto_the_photos(bare):
    """The example room is 5 × 4 m, 2.6 m high: its corners dragged onto where the photos show them
    (their true pixels) give the room those sizes; a drag that would turn the room inside out is
    refused and says why."""
    s = bare
    s.add_primitive("room", name="hall")
    assert _node_doc(s, "hall")["joint"] == {"type": "marker", "marker": "O", "handle": "f0", "yaw_deg": 0.0}
    s.fix("p1", "hall", "f0")
    start = next(uv for n, h, uv, _ in s.handles("p1") if (n, h) == ("hall", "f1"))
    s.begin_drag("p1", "hall", "f1")
    fb = [s.drag_to(start + (_pixel(s, "p1", (-2.0, 0.0, 0.0)) - start) * k / 8) for k in range(1, 9)]
    s.cancel_drag()
    bad = [f for f in fb if not f.ok]
    assert bad and "would not be a valid room" in bad[-1].reason and "it stays where it was" in bad[-1].reason
    assert np.allclose(start, next(uv for n, h, uv, _ in s.handles("p1") if (n, h) == ("hall", "f1")))
    for photo, handle, X in (("p1", "f1", (5, 0, 0)), ("p6", "f2", (5, 4, 0)), ("p6", "t2", (5, 4, 2.6))):
        start = next(uv for n, h, uv, _ in s.handles(photo) if (n, h) == ("hall", handle))
        goal = _pixel(s, photo, X)
        s.begin_drag(photo, "hall", handle)
        feedback = [s.drag_to(start + (goal - start) * k / 8) for k in range(1, 9)]
        s.end_drag()
        assert all(f.ok for f in feedback), [f.reason for f in feedback if not f.ok]
        assert np.linalg.norm(s.model.handle_world("hall", handle) - X) < DRAG_TOL_M
    p = s.model.node("hall").primitive.to_dict()["params"]
    assert [p["c1_x"], p["c2_y"], p["height"]] == pytest.approx([5.0, 4.0, 2.6], abs=DRAG_TOL_M)
    # (Refused first: corner 1 dragged across corner 0 would make the walls run clockwise.)

def _node_doc(s, name):
    return next(n for n in s.data["model"]["nodes"] if n["name"] == name)


def test_a_flush_joint_puts_a_child_against_its_parents_face_where_it_is(bare):
    """A crate on a room's floor made flush against the room's wall 2 by its joint: its back on the
    wall's inner face exactly, over the point of the wall it stood before, as it was turned."""
    s = bare
    s.add_primitive("room", name="hall")
    s.add_primitive("box", name="crate", parent="hall")
    assert _node_doc(s, "crate")["joint"]["face"] == "floor"  # furniture added on a room stands on its floor
    s.set_joint("crate", {"type": "rests_on", "face": "floor", "position": [2.0, 2.5], "yaw_deg": 0.0})
    s.add_relation("flush", "crate:back", "hall:wall2")  # the relation first: the joint replaces it
    before = s.model.world_transforms()["crate"]
    s.make_flush_joint("crate:back", "hall:wall2")
    j = _node_doc(s, "crate")["joint"]
    assert (j["type"], j["face"], j["own_face"], j["offset"]) == ("flush", "wall2", "back", 0.0)
    assert "relations" not in s.data["model"]  # made by the joint now
    assert "'crate' is flush against hall:wall2 by its joint" in s.messages[-1]
    m = s.model
    d, a, _ = relation_residual(m, m.vector(), {"type": "flush", "a": "crate:back", "b": "hall:wall2"})
    assert d < 1e-9 and a < 1e-6
    after = m.world_transforms()["crate"]
    # Turned as before (its back, +y, already faced wall 2 at y = 3 m), moved only toward the wall,
    # from which it stood 0.25 m (its centre at 2.5 m, half its 0.5 m depth behind it).
    np.testing.assert_allclose(after[:3, :3], before[:3, :3], atol=1e-9)
    shift = after[:3, 3] - before[:3, 3]
    assert abs(shift[0]) < 1e-9 and abs(shift[2]) < 1e-9
    assert shift[1] == pytest.approx(3.0 - 2.5 - 0.25, abs=1e-9)
    s.add_primitive("room", name="den")
    with pytest.raises(EditError, match="'crate' hangs on 'hall', not on 'den'"):
        s.make_flush_joint("crate:back", "den:wall0")
    with pytest.raises(EditError, match="'crate' has no flat face 'rim'"):
        s.make_flush_joint("crate:rim", "hall:wall2")


def test_removing_a_node_removes_the_relations_that_name_it(session):
    s = session
    s.add_relation("flush", "cabinet:left", "wall_west:front")
    s.add_relation("aligned", "table.top:top", "box:top")
    s.add_equal(["box.height", "cabinet.height", "table.top.height"])
    s.remove_node("box")
    assert s.data["model"]["relations"] == [
        {"type": "flush", "a": "cabinet:left", "b": "wall_west:front"},
        {"type": "equal", "params": ["cabinet.height", "table.top.height"]}]
    assert "removed with it: aligned table.top:top – box:top" in s.messages[-1]
    assert s.model is not None and len(s.model.relations) == 2
    s.remove_node("cabinet")
    assert "relations" not in s.data["model"]
    s.undo()
    assert len(s.data["model"]["relations"]) == 2


#: A drag keeps a flush relation within this (metres): the solver's hard rows are whitened by a
#: micrometre (vebuild.model.constraints.HARD_SIGMA_M) and nothing pulls the crate off the wall.
KEPT_TOL_M = 1e-6


def test_a_drag_keeps_a_flush_relation(session):
    """A crate standing with its back on the north wall, flush by a relation (the two are not parent
    and child): dragged along the wall it follows the mouse and stays on the wall; dragged away from
    the wall it cannot follow and says why."""
    s = session
    s.add_primitive("box", name="crate", parent="floor")
    # wall_north rests on the floor at y = 2.05 (0.1 m thick): its front face at y = 2.0; the
    # crate (0.5 m deep) at y = 1.75 has its back there.
    s.set_joint("crate", {"type": "rests_on", "face": "top", "position": [0.5, 1.75], "yaw_deg": 0.0})
    s.add_relation("flush", "crate:back", "wall_north:front")
    assert "as the model stands already: drags keep it" in s.messages[-1]
    rel = s.data["model"]["relations"][0]
    photo = "p4"  # sees the whole crate
    W = s.model.handle_world("crate", "v0")
    along = s.model.world_transforms()["wall_north"][:3, 0]
    goal = _pixel(s, photo, W + 0.3 * along)
    start = np.array(next(uv for n, h, uv, _ in s.handles(photo) if (n, h) == ("crate", "v0")))
    s.begin_drag(photo, "crate", "v0")
    feedback = [s.drag_to(start + (goal - start) * k / 6) for k in range(1, 7)]
    live = relation_residual(s._drag.model, s._drag.x_good, rel)[0]
    s.end_drag()
    assert all(f.ok for f in feedback), [f.reason for f in feedback if not f.ok]
    assert live < KEPT_TOL_M
    m = s.model
    assert relation_residual(m, m.vector(), rel)[0] < KEPT_TOL_M
    assert np.linalg.norm(m.handle_world("crate", "v0") - (W + 0.3 * along)) < DRAG_TOL_M
    assert s.relation_states()[0].distance_m < KEPT_TOL_M
    # Away from the wall (toward the room's middle): the relation holds it; it stays.
    start = np.array(next(uv for n, h, uv, _ in s.handles(photo) if (n, h) == ("crate", "v0")))
    W = m.handle_world("crate", "v0")
    away = _pixel(s, photo, W - 0.4 * m.world_transforms()["wall_north"][:3, 1])
    s.begin_drag(photo, "crate", "v0")
    fb = [s.drag_to(start + (away - start) * k / 4) for k in range(1, 5)]
    s.cancel_drag()
    assert not fb[-1].ok and "it stays where it was" in fb[-1].reason
    assert np.allclose(m.handle_world("crate", "v0"), W)
