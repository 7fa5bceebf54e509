"""The walk-through's logic without a window: walking with collisions, moving objects only as their
joints allow, undo, reset and hypotheses (pure numpy)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from viewer_scene import DOOR_LIMITS_DEG, DRAWER_LIMITS, ROOM_X, VIEWS, nodes, write_project

from vebuild.errors import ProjectError
from vebuild.model.arrange import TOUCH_TOLERANCE_M, CannotMove, ObjectMover
from vebuild.model.collide import circle_push, convex_hull_2d, footprints, overlap_depth
from vebuild.model.scene import model_from_dict
from vebuild.project import load_project, save_project
from vebuild.project.hypotheses import find_hypothesis, model_with, save_hypothesis
from vebuild.viewer.walk import BODY_RADIUS_M, EYE_HEIGHT_M, Walker


@pytest.fixture
def model():
    return model_from_dict(nodes())


def _box_corners(model, name):
    T = model.world_transforms()[name]
    V = model.node(name).primitive.mesh(None, 4).vertices
    return V @ T[:3, :3].T + T[:3, 3]


# -- collision primitives ----------------------------------------------------------------------------


def test_circle_push_and_polygon_overlap():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    np.testing.assert_allclose(circle_push(np.array([1.1, 0.5]), 0.2, square), [0.1, 0.0], atol=1e-12)
    np.testing.assert_allclose(circle_push(np.array([0.9, 0.5]), 0.2, square), [0.3, 0.0], atol=1e-12)  # inside
    assert not circle_push(np.array([1.3, 0.5]), 0.2, square).any()
    assert overlap_depth(square, square + [0.9, 0.0]) == pytest.approx(0.1)
    assert overlap_depth(square, square + [1.5, 0.0]) < 0
    hull = convex_hull_2d(np.array([[0, 0], [1, 0], [2, 0.0]]))  # a wall quad seen from above
    assert len(hull) == 4 and overlap_depth(hull, square + [0.5, -0.5]) > 0


# -- walking -----------------------------------------------------------------------------------------


def test_the_walker_stops_at_a_wall_and_slides_along_it(model):
    obstacles = footprints(model)
    w = Walker(np.array([1.0, 1.0, EYE_HEIGHT_M]), yaw=math.pi)  # facing the west wall (x = 0)
    for _ in range(100):  # 100 × 0.05 s at a run: 20 m, far through the wall if nothing stopped it
        w.move(1.0, 0.0, 0.0, 0.05, True, obstacles)
    assert w.position[0] == pytest.approx(BODY_RADIUS_M, abs=1e-6)
    assert w.position[1] == pytest.approx(1.0) and w.position[2] == EYE_HEIGHT_M
    # Walking at 45° into it slides along it.
    w.yaw = math.pi * 0.75
    for _ in range(20):
        w.move(1.0, 0.0, 0.0, 0.05, False, obstacles)
    assert w.position[0] == pytest.approx(BODY_RADIUS_M, abs=1e-6) and w.position[1] > 1.4


def test_the_walker_walks_through_the_doorway_but_not_through_the_box(model):
    obstacles = footprints(model)
    # The door stands open 10°: open it fully first so that the doorway is free.
    mover = ObjectMover(model)
    mover.model.node("door").joint.set_values(np.array([math.radians(95)]))
    obstacles = footprints(mover.model)
    w = Walker(np.array([5.0, 2.5, EYE_HEIGHT_M]), yaw=0.0)  # facing +x, the doorway
    for _ in range(60):
        w.move(1.0, 0.0, 0.0, 0.05, False, obstacles)
    assert w.position[0] > ROOM_X + 0.5  # out through the doorway
    # The box (0.6 × 0.4 m at (2, 2)) stops a walker; it is lower than the eyes but above the knee.
    w = Walker(np.array([0.8, 2.0, EYE_HEIGHT_M]), yaw=0.0)
    for _ in range(60):
        w.move(1.0, 0.0, 0.0, 0.05, False, footprints(model))
    assert w.position[0] == pytest.approx(2.0 - 0.3 - BODY_RADIUS_M, abs=1e-6)


def test_flying_goes_anywhere_and_landing_restores_eye_height(model):
    w = Walker(np.array([1.0, 1.0, EYE_HEIGHT_M]), yaw=math.pi, pitch=0.3)
    w.set_fly(True)
    for _ in range(40):
        w.move(1.0, 0.0, 0.5, 0.05, False, footprints(model))
    assert w.position[0] < 0 and w.position[2] > EYE_HEIGHT_M
    w.set_fly(False)
    assert w.position[2] == EYE_HEIGHT_M


def test_mouse_look_turns_like_a_game():
    w = Walker()
    w.look(100, 0)
    assert w.yaw < 0  # right turns clockwise seen from above
    w.look(0, 100)
    assert w.pitch < 0  # down looks down
    w.look(0, -1e6)
    assert w.pitch == pytest.approx(math.radians(89))


# -- moving objects ----------------------------------------------------------------------------------


def _ray_to(point, from_=(3.0, 2.5, 1.6)):
    o = np.asarray(from_, float)
    d = np.asarray(point, float) - o
    return o, d / np.linalg.norm(d)


def test_a_resting_object_slides_on_the_floor_and_stays_on_it(model):
    mover = ObjectMover(model)
    before = _box_corners(model, "box")
    grab = before.mean(axis=0) + [0, 0, 0.25]  # the top's centre
    assert mover.begin("box", grab) == "box"
    target = grab + [0.7, 0.4, 0.0]
    assert mover.drag(*_ray_to(target))
    mover.end()
    after = _box_corners(mover.model, "box")
    np.testing.assert_allclose(after.mean(axis=0) - before.mean(axis=0), [0.7, 0.4, 0.0], atol=1e-9)
    assert after[:, 2].min() == pytest.approx(0.0, abs=1e-12)  # still standing on the floor
    # Turning about the vertical keeps it on the floor too.
    assert mover.turn("box", math.radians(30))
    assert _box_corners(mover.model, "box")[:, 2].min() == pytest.approx(0.0, abs=1e-12)
    # The measured model is untouched.
    np.testing.assert_array_equal(_box_corners(model, "box"), before)


def test_a_dragged_object_stops_at_a_wall(model):
    mover = ObjectMover(model)
    c = _box_corners(model, "box").mean(axis=0) + [0, 0, 0.25]
    mover.begin("box", c)
    mover.drag(*_ray_to(c - [5.0, 0.0, 0.0]))  # far through the west wall
    mover.end()
    xmin = _box_corners(mover.model, "box")[:, 0].min()
    assert -TOUCH_TOLERANCE_M <= xmin <= 0.01  # touching the wall's inner face (x = 0), not through it
    assert not mover.collides("box")


def test_a_door_swings_on_its_hinge_and_stops_at_its_limit(model):
    mover = ObjectMover(model)
    j = mover.model.node("door").joint
    free_end = _box_corners(model, "door")
    grab = free_end[np.argmax(free_end[:, 1])]  # a corner at the door's free edge
    mover.begin("door", grab)
    hinge = np.array([5.98, 2.05])
    for deg in (30, 60, 90, 150, 200):  # the mouse sweeps round the hinge, far past the limit
        a = math.radians(deg)
        target = np.r_[hinge + 0.9 * np.array([-math.sin(a), math.cos(a)]), grab[2]]
        mover.drag(*_ray_to(target, from_=(4.5, 2.2, 2.4)))
        assert DOOR_LIMITS_DEG[0] <= math.degrees(j.angle) <= DOOR_LIMITS_DEG[1] + 1e-9
    assert math.degrees(j.angle) == pytest.approx(DOOR_LIMITS_DEG[1])
    mover.end()
    # It turned about its axis: the hinge edge did not move.
    T0, T1 = model.world_transforms()["door"], mover.model.world_transforms()["door"]
    axis_pt = np.array([5.98, 2.05, 1.0, 1.0])
    np.testing.assert_allclose(T1 @ np.linalg.inv(T0) @ axis_pt, axis_pt, atol=1e-9)


def test_a_drawer_slides_out_along_its_runner_within_limits(model):
    mover = ObjectMover(model)
    d0 = _box_corners(model, "drawer")
    grab = d0.mean(axis=0) + [0, -0.225, 0]  # its front
    mover.begin("drawer", grab)
    mover.drag(*_ray_to(grab + [0.0, -2.0, 0.0], from_=(1.8, 3.0, 1.4)))
    mover.end()
    d1 = _box_corners(mover.model, "drawer")
    np.testing.assert_allclose(d1.mean(axis=0) - d0.mean(axis=0), [0, -DRAWER_LIMITS[1], 0], atol=1e-9)


def test_a_group_moves_as_a_whole_with_its_children(model):
    mover = ObjectMover(model)
    assert mover.movable("table.top") == "table"
    top0, leg0 = _box_corners(model, "table.top"), _box_corners(model, "table.leg")
    grab = top0.mean(axis=0) + [0, 0, 0.02]
    mover.begin("table.top", grab)
    mover.drag(*_ray_to(grab + [-0.5, 0.3, 0.0]))
    mover.end()
    np.testing.assert_allclose(_box_corners(mover.model, "table.top") - top0, np.tile([-0.5, 0.3, 0.0], (24, 1)),
                               atol=1e-9)
    np.testing.assert_allclose(_box_corners(mover.model, "table.leg") - leg0, np.tile([-0.5, 0.3, 0.0], (24, 1)),
                               atol=1e-9)


def test_fixed_things_say_why_they_cannot_move(model):
    mover = ObjectMover(model)
    with pytest.raises(CannotMove, match=r"'wall.west' cannot move: its joint \(through 'wall.west'\) has no "
                                         r"freedom, and 'floor' is fixed to the world"):
        mover.movable("wall.west")
    with pytest.raises(CannotMove, match="turns only on its hinge joint"):
        mover.turn("door", 0.1)


def test_undo_redo_and_reset(model):
    mover = ObjectMover(model)
    c = _box_corners(model, "box").mean(axis=0)
    mover.begin("box", c)
    mover.drag(*_ray_to(c + [0.5, 0, 0]))
    mover.end()
    moved = _box_corners(mover.model, "box")
    mover.turn("box", 0.2)
    assert mover.undo() and np.allclose(_box_corners(mover.model, "box"), moved)
    assert mover.undo() and np.allclose(_box_corners(mover.model, "box"), _box_corners(model, "box"))
    assert not mover.undo()
    assert mover.redo() and np.allclose(_box_corners(mover.model, "box"), moved)
    mover.reset()
    assert mover.arrangement() == {}
    assert mover.undo() and "box" in mover.arrangement()


def test_hypotheses_are_saved_apart_from_the_measured_model(tmp_path, model):
    path = write_project(tmp_path)
    project = load_project(path)
    measured = json.loads(json.dumps(project.data["model"]))
    mover = ObjectMover(model)
    c = _box_corners(model, "box").mean(axis=0)
    mover.begin("box", c)
    mover.drag(*_ray_to(c + [0.8, 0.2, 0]))
    mover.end()
    save_hypothesis(project, "box by the table", mover.arrangement(), "the box was moved before the photos")
    save_project(project)
    again = load_project(path)
    assert again.data["model"] == measured  # the measured scene is unchanged
    rec = find_hypothesis(again, "box by the table")
    assert set(rec["joints"]) == {"box"}
    moved = model_with(model, rec["joints"])
    np.testing.assert_allclose(_box_corners(moved, "box"), _box_corners(mover.model, "box"), atol=1e-12)
    with pytest.raises(ProjectError, match="no hypothesis is called 'nope'"):
        find_hypothesis(again, "nope")
    # A hypothesis that changes a joint's type, or names no node, is refused when the file loads.
    data = json.loads(path.read_text())
    data["hypotheses"][0]["joints"]["box"] = {"type": "fixed", "translation": [0, 0, 0], "rotation_deg": [0, 0, 0]}
    path.write_text(json.dumps(data))
    with pytest.raises(ProjectError, match=r"\$.hypotheses\[0\].joints.box.type: expected the node's own joint"):
        load_project(path)


def test_the_example_views_are_inside_the_room():
    for v in VIEWS:
        assert 0 < v["position"][0] < ROOM_X
