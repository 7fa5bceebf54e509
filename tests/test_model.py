"""The scene graph, its joints and the solver (paper §3.1): seeded synthetic scenes and the
example room, whose truth comes from the independent generator."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from claims import dimension_tolerance

from vebuild.actions.calibrate import calibrate_project
from vebuild.actions.solve import solve_project
from vebuild.errors import ProjectError, VebuildError
from vebuild.model.edit import DragSession
from vebuild.model.scene import ModelError, model_from_dict
from vebuild.camera import ImageCamera
from vebuild.model.solver import Pin, Problem
from vebuild.project import load_project
from vebuild.synthetic import model_scene

EXAMPLE = Path(__file__).resolve().parents[1] / "scenes" / "room"
#: The paper's vertex fixing: a fixed vertex stays within this of its pin while others are dragged.
#: The drags are noise-free; a fixed pin moves only by its trade-off with the solve's priors and the
#: dragged pin: measured at most 0.124 px over 7 scenes (0.016 px and 0.10 px on this file's two),
#: 0.072 px in bench solver. 0.2 px is well under a click's 0.7 px and 1.6× the worst measured.
FIXED_VERTEX_TOL_PX = 0.2


BOX = {"name": "b", "parent": "floor", "primitive": {"type": "box", "params": {"width": 1, "depth": 1, "height": 1}},
       "joint": {"type": "rests_on", "face": "top"}}
FLOOR = {"name": "floor", "primitive": {"type": "quad", "params": {"width": 4, "depth": 3}},
         "joint": {"type": "marker", "marker": "O", "handle": "v0"}}
MARKERS = {"O": np.zeros(3)}


def test_cycle_in_the_scene_graph() -> None:
    a = dict(BOX, name="a", parent="c")
    c = dict(BOX, name="c", parent="a")
    with pytest.raises(ModelError, match=r"the scene graph has a cycle: .*a.*c"):
        model_from_dict([FLOOR, a, c], MARKERS)


def test_joint_to_a_missing_parent() -> None:
    with pytest.raises(ModelError, match=r"node 'b': its joint attaches it to parent 'ghost', which is not a node"):
        model_from_dict([FLOOR, dict(BOX, parent="ghost")], MARKERS)


def test_negative_size() -> None:
    bad = dict(BOX, primitive={"type": "box", "params": {"width": -1, "depth": 1, "height": 1}})
    with pytest.raises(ModelError, match=r"\$.model.nodes\[1\] \(node 'b'\).primitive: box: width must be > 0"):
        model_from_dict([FLOOR, bad], MARKERS)


def test_rests_on_a_face_the_parent_lacks_and_a_marker_joint_with_a_parent() -> None:
    with pytest.raises(ModelError, match=r"rests on face 'side' of 'floor', which has faces: top"):
        model_from_dict([FLOOR, dict(BOX, joint={"type": "rests_on", "face": "side"})], MARKERS)
    with pytest.raises(ModelError, match=r"a marker joint ties a node to the world"):
        model_from_dict([FLOOR, dict(BOX, joint=FLOOR["joint"])], MARKERS)
    with pytest.raises(ModelError, match=r"hinge angle 120.0° lies outside its limits"):
        model_from_dict([FLOOR, dict(BOX, joint={"type": "hinge", "angle_deg": 120, "limits_deg": [0, 90]})], MARKERS)


def _scene(seed: int, n_boxes: int = 1, n_photos: int = 2):
    rng = np.random.default_rng(seed)
    truth, start, pins, photos = model_scene(rng, n_boxes=n_boxes, n_photos=n_photos)
    cams = {p.id: ImageCamera(p.id, p.K, p.R, p.C, p.width, p.height) for p in photos.values()}
    return (model_from_dict(truth["nodes"], MARKERS), model_from_dict(start["nodes"], MARKERS), pins, cams)


def _project(cam: ImageCamera, X: np.ndarray) -> np.ndarray:
    h = cam.K @ (cam.R @ (X - cam.C))
    return h[:2] / h[2]


def _drag(model, cams, fixed, photo, handle, target, steps=15):
    """Drag a handle of box0 in a straight line to target, checking every fixed pin on each move."""
    s = DragSession(model, cams, fixed, [], photo, "box0", handle, click_sigma_px=0.7)
    start = s.pin.uv.copy()
    worst = 0.0
    for k in range(1, steps + 1):
        r = s.move(start + (target - start) * k / steps)
        worst = max(worst, r.fixed_error_px)
    return s, r, worst


def test_figure_7_drag_sequence() -> None:
    """Paper Figure 7: with nothing fixed a drag moves the whole box; once vertices are fixed,
    dragging another changes size and pose while the fixed ones stay put."""
    truth, model, _, cams = _scene(11)
    cam = cams["p1"]
    true_px = {h: _project(cam, truth.handle_world("box0", h)) for h in ("v0", "v1", "v6")}
    size0 = model.node("box0").primitive.params.copy()

    # (a) Nothing fixed: drag v0 onto its corner. The box moves as a whole; its size stays.
    s, r, _ = _drag(model, cams, [], "p1", "v0", true_px["v0"])
    # Noise-free, the handle reaches the mouse to the solve's tolerance (measured ≤ 1.0e-3 px over 7 scenes).
    assert np.linalg.norm(r.handle_px - true_px["v0"]) < 2e-3
    fixed = [s.release()]
    assert model.node("box0").primitive.params == pytest.approx(size0, rel=1e-6)

    # (b) v0 fixed: drag the far top corner v6. Size and turn change; v0 stays within 0.5 px.
    s, r, worst = _drag(model, cams, fixed, "p1", "v6", true_px["v6"])
    assert worst < FIXED_VERTEX_TOL_PX
    # Here it trades against the fixed v0 too (measured ≤ 0.020 px over 7 scenes).
    assert np.linalg.norm(r.handle_px - true_px["v6"]) < 0.03
    fixed.append(s.release())
    assert not np.allclose(model.node("box0").primitive.params, size0)

    # (c) v0 and v6 fixed: drag v1. All three corners now sit on the box's true corners, and the
    # box (on the floor: 6 pin coordinates for 6 unknowns) takes its true size.
    s, r, worst = _drag(model, cams, fixed, "p1", "v1", true_px["v1"])
    assert worst < FIXED_VERTEX_TOL_PX
    s.release()
    true_size = truth.node("box0").primitive.params
    assert model.node("box0").primitive.params == pytest.approx(true_size, abs=2e-3)


def test_undetermined_directions_stay_put() -> None:
    """With a bottom corner fixed, dragging another bottom corner says nothing about the height:
    the height stays where it was instead of jumping."""
    _, model, _, cams = _scene(12)
    h0 = model.node("box0").primitive.params[2]
    s = DragSession(model, cams, [], [], "p1", "box0", "v0", click_sigma_px=0.7)
    s.move(s.pin.uv + [5.0, 3.0])
    fixed = [s.release()]
    s = DragSession(model, cams, fixed, [], "p1", "box0", "v1", click_sigma_px=0.7)
    r = s.move(s.pin.uv + [40.0, -25.0])
    s.release()
    assert r.fixed_error_px < FIXED_VERTEX_TOL_PX
    assert model.node("box0").primitive.params[2] == pytest.approx(h0, abs=1e-6)


def test_nan_pixels_are_refused() -> None:
    _, model, _, cams = _scene(13)
    s = DragSession(model, cams, [], [], "p1", "box0", "v1")
    with pytest.raises(ValueError, match=r"expected a finite pixel"):
        s.move([np.nan, 3.0])
    with pytest.raises(ValueError, match=r"pin box0:v2 in photo 'p1': expected a finite pixel"):
        Problem(model, cams, [Pin("p1", "box0", "v2", np.array([1.0, np.inf]))])


def test_joints_hold_exactly_and_limits_are_kept() -> None:
    truth, model, pins, cams = _scene(14, n_boxes=3, n_photos=6)
    prob = Problem(model, cams, [Pin(p["photo"], p["node"], p["handle"], np.array(p["uv"])) for p in pins],
                   click_sigma_px=0.7, prior_scale=1e5)
    model.set_vector(prob.model_vector(prob.solve().x))
    for k in range(3):
        for h in ("v0", "v1", "v2", "v3"):  # the bottom rests on the floor exactly
            assert model.handle_world(f"box{k}", h)[2] == pytest.approx(0.0, abs=1e-12)


@pytest.fixture(scope="module")
def origin_only(tmp_path_factory: pytest.TempPathFactory):
    """The issue's scenario: the example with no marker but the origin and one reference distance."""
    folder = tmp_path_factory.mktemp("origin_only")
    shutil.copytree(EXAMPLE, folder, dirs_exist_ok=True)
    path = folder / "room.vebuild.json"
    data = json.loads(path.read_text())
    data["markers"] = [m for m in data["markers"] if m["name"] == "O"]
    for ph in data["photos"]:
        ph["marker_observations"] = {k: v for k, v in ph["marker_observations"].items() if k == "O"}
    data["reference_distances"] = [{"a": "O", "b": "floor:v1", "distance": 5.0, "sigma": 0.002, "role": "scale"}]
    path.write_text(json.dumps(data, indent=1))
    project = load_project(path)
    calibrate_project(project)
    result = solve_project(project, recalibrate=True)
    truth = json.loads((folder / "ground_truth.json").read_text())
    return project, result, truth


def test_example_dimensions_joints_and_intervals(origin_only) -> None:
    project, result, truth = origin_only
    true_nodes = {n["name"]: n for n in truth["model"]["nodes"]}
    inside = total = 0
    for name, node in result["nodes"].items():
        t = true_nodes[name]
        for k, v in node["params"].items():
            tv = t["primitive"]["params"][k]
            assert abs(v["value"] - tv) < dimension_tolerance(tv), f"{name}.{k}"
            if v["sigma"]:
                total += 1
                inside += v["ci95"][0] <= tv <= v["ci95"][1]
        for k, v in node["dofs"].items():
            tv = t["joint"]["position"]["st".index(k)] if k in ("s", "t") else t["joint"][k]
            if v["sigma"]:  # held (the walls, placed from measurements): no interval to test
                total += 1
                inside += v["ci95"][0] <= tv <= v["ci95"][1]
    assert inside >= 0.9 * total, f"{inside}/{total} true values inside the reported 95 % intervals"
    # Joints hold exactly: everything resting on the floor stands on z = 0; the door turns within its limits.
    for name in ("cabinet", "box", "table.leg1", "table.leg3", "wall_north", "wall_south.west"):
        for h in ("v0", "v1", "v2", "v3"):
            assert result["nodes"][name]["handles"][h]["value"][2] == pytest.approx(0.0, abs=1e-9)
    lo, hi = true_nodes["door"]["joint"]["limits_deg"]
    assert lo <= result["nodes"]["door"]["dofs"]["angle_deg"]["value"] <= hi
    assert not result["outliers"]


def test_too_few_observations_names_the_undetermined_parameters(tmp_path: Path) -> None:
    shutil.copytree(EXAMPLE, tmp_path, dirs_exist_ok=True)
    path = tmp_path / "room.vebuild.json"
    data = json.loads(path.read_text())
    data["model"]["pins"] = [p for p in data["model"]["pins"] if p["node"] != "box" or p["photo"] == "p1"]
    data["model"]["edge_observations"] = [e for e in data["model"]["edge_observations"] if e["node"] != "box"]
    path.write_text(json.dumps(data))
    project = load_project(path)
    calibrate_project(project)
    with pytest.raises(VebuildError, match=r"too few observations: .*box\.(s|t|yaw|width|depth|height)"):
        solve_project(project)


def test_pin_on_a_vertex_the_camera_cannot_see(tmp_path: Path) -> None:
    shutil.copytree(EXAMPLE, tmp_path, dirs_exist_ok=True)
    path = tmp_path / "room.vebuild.json"
    data = json.loads(path.read_text())
    # p4 faces the north wall; the cabinet's corner by the west wall lies far outside its view.
    data["model"]["pins"].append({"photo": "p4", "node": "cabinet", "handle": "v0", "uv": [120.0, 900.0],
                                  "fixed": True})
    path.write_text(json.dumps(data))
    project = load_project(path)
    calibrate_project(project)
    with pytest.raises(ProjectError, match=r"pins cabinet:v0 in photo 'p4'.*cannot see"):
        solve_project(project)


def test_recalibrated_camera_records_agree_with_their_matrices(origin_only) -> None:
    """Re-calibration refines f and the principal point: every field written must say so."""
    project, _, _ = origin_only
    for pid, cam in project.data["calibration"]["cameras"].items():
        assert cam["recalibrated"] is True, pid
        assert cam["focal_px"]["value"] == pytest.approx(cam["K"][0][0])
        assert cam["principal_point"]["value"] == pytest.approx([cam["K"][0][2], cam["K"][1][2]])
        assert all(s is not None and s > 0 for s in cam["principal_point"]["sigma"])
