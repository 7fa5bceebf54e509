"""The scene graph, its joints and the solver (paper §3.1): seeded synthetic scenes and the
example room, whose truth comes from the independent generator."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from claims import dimension_tolerance
from jacobian_check import assert_jacobian_matches_differences
from scipy.stats import chi2

from vebuild.actions.calibrate import calibrate_project
from vebuild.actions.solve import solve_project
from vebuild.calibration.positions import ReferenceDistance
from vebuild.camera import ImageCamera
from vebuild.errors import VebuildError
from vebuild.model.drag import DragSession
from vebuild.model.layout import ParameterLayout
from vebuild.model.residuals import EdgeObservation, MarkerObservation, Pin
from vebuild.model.scene import ModelError, model_from_dict
from vebuild.model.solution import solution_at
from vebuild.model.solver import MarkerData, Problem, ProblemOptions
from vebuild.project import load_project
from vebuild.synthetic import CLICK_NOISE_PX, model_scene

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


def rms_band(n: int) -> tuple[float, float]:
    """Two-sided band on the RMS of n values of error / reported 1σ: for honest uncertainties
    n·RMS² follows χ² with n degrees of freedom; the band holds 99.9 % of it (0.05 % each side),
    so an inflated σ (RMS far below 1) fails as surely as an overconfident one (far above)."""
    return tuple(float(np.sqrt(chi2.ppf(q, n) / n)) for q in (0.0005, 0.9995))  # type: ignore[return-value]


#: A lid hinged on the top back edge of box0: opened this far in the truth (degrees).
LID_ANGLE_DEG = 40.0


def _with_lid(seed: int, limits_deg: tuple[float, float]):
    """The synthetic scene of ``_scene`` with a lid on a hinge along box0's top back edge, its
    true angle LID_ANGLE_DEG, its limits ``limits_deg`` in the model to solve; every visible lid
    corner pinned with the generator's click noise."""
    rng = np.random.default_rng(seed)
    truth, start, pins, photos = model_scene(rng, n_boxes=3, n_photos=6)
    w, d, h = (truth["nodes"][1]["primitive"]["params"][k] for k in ("width", "depth", "height"))
    lid = {"name": "lid", "parent": "box0",
           "primitive": {"type": "box", "params": {"width": 0.8 * w, "depth": 0.8 * d, "height": 0.05}},
           "joint": {"type": "hinge", "axis": [1.0, 0.0, 0.0], "axis_point": [0.0, 0.4 * d, h],
                     "translation": [0.0, 0.0, h], "angle_deg": LID_ANGLE_DEG, "limits_deg": [0.0, 90.0]}}
    true_model = model_from_dict(truth["nodes"] + [lid], MARKERS)
    T = true_model.world_transforms()
    for photo in photos.values():
        for k, X in enumerate(true_model.node("lid").primitive.handles() @ T["lid"][:3, :3].T + T["lid"][:3, 3]):
            x_cam = photo.R @ (X - photo.C)
            uv = photo.K[:2] @ x_cam / x_cam[2]
            if x_cam[2] > 0.3 and 0 <= uv[0] <= photo.width and 0 <= uv[1] <= photo.height:
                pins.append({"photo": photo.id, "node": "lid", "handle": f"v{k}",
                             "uv": list(uv + rng.normal(0.0, CLICK_NOISE_PX, 2))})
    lid_start = {**lid, "primitive": {"type": "box", "params": {"width": 0.9 * w, "depth": 0.7 * d, "height": 0.06}},
                 "joint": {**lid["joint"], "angle_deg": 0.5 * limits_deg[1], "limits_deg": list(limits_deg)}}
    cams = {p.id: ImageCamera(p.id, p.K, p.R, p.C, p.width, p.height) for p in photos.values()}
    model = model_from_dict(start["nodes"] + [lid_start], MARKERS)
    problem = Problem(model, cams, [Pin(p["photo"], p["node"], p["handle"], np.array(p["uv"])) for p in pins],
                      options=ProblemOptions(click_sigma_px=CLICK_NOISE_PX, prior_scale=1e5))
    return true_model, problem


def test_joints_hold_exactly_and_limits_are_kept() -> None:
    """Every joint's solved values (each box's position and turn on the floor, the lid's hinge
    angle) and every size agree with the truth within the reported uncertainty, two-sided; a
    hinge whose truth lies beyond its stop ends exactly on it, and not short of it."""
    z, scenes = [], 0
    for seed in range(12, 30):
        truth, problem = _with_lid(seed, (0.0, 60.0))
        r = problem.solve()
        sol = solution_at(problem, r.x, r.iterations)
        if sol.undetermined:  # a box too few photos see: `vebuild solve` refuses such a scene
            continue
        scenes += 1
        true_x = truth.vector()[problem.free_idx]
        sigma = np.sqrt(np.diag(sol.covariance))[problem.layout.model.slice]
        kept = [j for j, name in enumerate(problem.names) if not name.startswith("floor.")]  # on the marker
        z += list(((r.x[problem.layout.model.slice] - true_x) / sigma)[kept])
        lid = problem.names.index("lid.angle")
        assert abs(r.x[lid] - np.radians(LID_ANGLE_DEG)) < 4 * sigma[lid], f"seed {seed}: lid angle"
    assert scenes >= 10
    lo, hi = rms_band(len(z))
    assert lo < np.sqrt(np.mean(np.square(z))) < hi, f"RMS of error/σ over {len(z)} joint values and sizes"

    # The stop at 25° holds the lid short of its true 40°: the solve ends on the stop exactly,
    # while the pins still pull past it (a solve that ignored the stop would end near 40°, one
    # that stopped early below 25°).
    _, problem = _with_lid(14, (0.0, 25.0))
    r = problem.solve()
    assert np.degrees(problem.model_vector(r.x)[problem.model.slices["lid"][0]][0]) == pytest.approx(25.0, abs=1e-9)
    assert problem.model.node("lid").joint.clip(np.radians([30.0])) == pytest.approx(np.radians([25.0]))


def test_the_parameter_layout_names_every_block_in_file_units() -> None:
    """Model, camera and marker blocks tile the vector in order; angles (by the joints' declared
    kinds, not by their names) are written in degrees under a ``_deg`` name."""
    layout = ParameterLayout(["box.s", "box.t", "box.yaw", "box.width"], ["position", "position", "angle", "size"],
                             ["p1", "p2"], intrinsics=True, markers=["M"])
    assert [(b.what, b.key, b.start, b.stop) for b in layout.blocks] == [
        ("model", "", 0, 4), ("camera", "p1", 4, 13), ("camera", "p2", 13, 22), ("marker", "M", 22, 25)]
    assert layout.n == 25 and layout.block_of(13).key == "p2"
    assert layout.cameras["p1"].pose_start == 7 and layout.cameras["p1"].calibration_index == tuple(range(9))
    assert layout.model.file_names() == ["box.s", "box.t", "box.yaw_deg", "box.width"]
    assert layout.model.units == ("m", "m", "rad", "m")
    assert layout.file_scale([layout.model, layout.markers["M"]]) == pytest.approx([1, 1, np.degrees(1)] + [1] * 4)
    assert list(layout.model_and_markers()) == [0, 1, 2, 3, 22, 23, 24]
    without = ParameterLayout(["box.width"], ["size"], ["p1"])  # re-calibration without intrinsics
    assert without.cameras["p1"].calibration_index == (3, 4, 5, 6, 7, 8) and not without.cameras["p1"].intrinsics
    model = model_from_dict([FLOOR, dict(BOX, joint={"type": "hinge", "angle_deg": 10, "limits_deg": [0, 90]})],
                            MARKERS)
    assert model.parameter_kinds() == ["angle", "size", "size", "angle", "size", "size", "size"]



def test_the_whole_jacobian_agrees_with_central_differences() -> None:
    """The solver's Jacobian (analytic for cameras, intrinsics and markers, differenced and chained
    for the model's parameters) against an independent central difference of the residual vector,
    over every block: joints of every kind that moves (rests_on, marker, hinge, free), sizes,
    cameras with intrinsics, markers; pins, edges, marker sightings, distances and priors."""
    rng = np.random.default_rng(21)
    truth, start, pins, photos = model_scene(rng, n_boxes=2, n_photos=3)
    markers = {"O": np.zeros(3), "A": np.array([1.0, 2.0, 0.0]), "B": np.array([3.0, 0.5, 0.0])}
    extra = [{"name": "lid", "parent": "box0", "primitive": {"type": "box", "params": {"width": 0.3, "depth": 0.3,
                                                                                      "height": 0.05}},
              "joint": {"type": "hinge", "axis": [1.0, 0.0, 0.0], "axis_point": [0.0, 0.1, 0.4],
                        "translation": [0.0, 0.0, 0.4], "angle_deg": 30.0}},
             {"name": "ball", "primitive": {"type": "sphere", "params": {"radius": 0.2}},
              "joint": {"type": "free", "translation": [0.5, 0.5, 1.0], "rotation_deg": [10.0, 20.0, 30.0]}}]
    model = model_from_dict(truth["nodes"] + extra, markers)
    cov = np.diag([25.0] * 3 + [np.radians(0.2) ** 2] * 3 + [0.02**2] * 3)
    cams, sightings, edges = {}, [], []
    for p in photos.values():
        cams[p.id] = ImageCamera(p.id, p.K, p.R, p.C, p.width, p.height, covariance=cov)
        sightings += [MarkerObservation(p.id, m, _project(cams[p.id], X)) for m, X in markers.items()]
        a, b = model.handle_world("box0", "v4"), model.handle_world("box0", "v5")
        edges.append(EdgeObservation(p.id, "box0", "e4", np.array([_project(cams[p.id], a + 0.3 * (b - a)),
                                                                   _project(cams[p.id], a + 0.7 * (b - a))])))
        pins += [{"photo": p.id, "node": n, "handle": h, "uv": _project(cams[p.id], model.handle_world(n, h))}
                 for n, h in (("lid", "v6"), ("lid", "v7"), ("ball", "top"), ("ball", "px"))]
    distances = [ReferenceDistance("A", "B", 2.5, 0.002), ReferenceDistance("O", "box0:v1", 2.0, 0.01),
                 ReferenceDistance("box1:v6", "lid:v2", 1.0, 0.01)]
    problem = Problem(model, cams, [Pin(p["photo"], p["node"], p["handle"], np.array(p["uv"])) for p in pins],
                      edges, options=ProblemOptions(click_sigma_px=0.7, recalibrate=True, refine_intrinsics=True),
                      markers=MarkerData(markers, ["O"], sightings, distances))
    layout = problem.layout
    assert {b.what for b in layout.blocks} == {"model", "camera", "marker"}
    assert all(b.intrinsics for b in layout.cameras.values())
    # Away from the start (turns and changes of K are zero there, where errors could hide).
    x = problem.x0()
    x[layout.model.slice] += rng.normal(0.0, 0.02, len(layout.model))
    for b in layout.cameras.values():
        x[b.start : b.pose_start] += rng.normal(0.0, 2.0, 3)
        x[b.pose_start : b.pose_start + 3] += rng.normal(0.0, 2e-3, 3)
    for b in layout.markers.values():
        x[b.slice] += rng.normal(0.0, 0.01, 3)
    J, F = assert_jacobian_matches_differences(problem, layout, x)
    assert np.count_nonzero(F) > 0.9 * np.count_nonzero(J)  # not a comparison of two empty matrices


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
    z = []
    for name, node in result["nodes"].items():
        t = true_nodes[name]
        for k, v in node["params"].items():
            tv = t["primitive"]["params"][k]
            assert abs(v["value"] - tv) < dimension_tolerance(tv), f"{name}.{k}"
            if v["sigma"]:
                z.append((v["value"] - tv) / v["sigma"])
        for k, v in node["dofs"].items():
            tv = t["joint"]["position"]["st".index(k)] if k in ("s", "t") else t["joint"][k]
            if v["sigma"]:  # held (the walls, placed from measurements): no uncertainty to test
                z.append((v["value"] - tv) / v["sigma"])
    lo, hi = rms_band(len(z))
    assert lo < np.sqrt(np.mean(np.square(z))) < hi, f"RMS of error/σ over {len(z)} parameters"
    # Joints hold exactly: everything resting on the floor stands on z = 0.
    for name in ("cabinet", "box", "table.leg1", "table.leg3", "wall_north", "wall_south.west"):
        for h in ("v0", "v1", "v2", "v3"):
            assert result["nodes"][name]["handles"][h]["value"][2] == pytest.approx(0.0, abs=1e-9)
    # The door's hinge angle is the truth's within 3σ (its limits, 0–150°, are far from it: the
    # synthetic test above checks a stop that binds).
    door = result["nodes"]["door"]["dofs"]["angle_deg"]
    assert abs(door["value"] - true_nodes["door"]["joint"]["angle_deg"]) < 3 * door["sigma"]
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
    with pytest.raises(VebuildError, match=r"too few observations: .*box's (position|turn|width|depth|height)"):
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
    with pytest.raises(VebuildError, match=r"a pin on cabinet's corner v0 in photo 'p4'.*cannot see"):
        solve_project(project)


def test_recalibrated_camera_records_agree_with_their_matrices(origin_only) -> None:
    """Re-calibration refines f and the principal point: every field written must say so."""
    project, _, _ = origin_only
    assert not any(c.get("recalibrated") for c in project.data["calibration"]["cameras"].values())
    assert set(project.data["model_solution"]["cameras"]) == set(project.data["calibration"]["cameras"])
    for pid, cam in project.data["model_solution"]["cameras"].items():
        assert cam["recalibrated"] is True, pid
        assert cam["focal_px"]["value"] == pytest.approx(cam["K"][0][0])
        assert cam["principal_point"]["value"] == pytest.approx([cam["K"][0][2], cam["K"][1][2]])
        assert all(s is not None and s > 0 for s in cam["principal_point"]["sigma"])


def test_the_variance_factor_counts_the_observations_redundancy_not_the_pulls() -> None:
    """Clicks twice as noisy as stated (stated σ half the generator's): σ0² = χ² / redundancy
    comes out near 4 on average, with the redundancy that of the pins (rows − unknowns where every
    unknown is determined), not rows + pulled unknowns − unknowns (the weak pull toward the start,
    counted as rows, added one per unknown: σ0² would be low by the share of the unknowns)."""
    s2, spread = [], []
    for seed in range(12, 24):
        _, problem = _with_lid(seed, (0.0, 60.0))
        problem = Problem(problem.model, problem.cameras, problem.pins,
                          options=ProblemOptions(click_sigma_px=CLICK_NOISE_PX / 2, prior_scale=1e5))
        r = problem.solve()
        sol = solution_at(problem, r.x, r.iterations)
        if sol.undetermined:
            continue
        res = problem.evaluate(r.x)[: problem.n_data]
        redundancy = problem.n_data - problem.layout.n
        assert sol.variance_factor == pytest.approx(max(1.0, res @ res / redundancy), rel=1e-6)
        s2.append(sol.variance_factor)
        spread.append(4.0 * np.sqrt(2.0 / redundancy))  # the sampling 1σ of χ²/dof at σ0² = 4
    # The mean of the draws within 3 of its sampling σ of 4.
    print(f"mean σ0² {np.mean(s2):.3f} over {len(s2)} scenes (expected 4)")
    assert abs(np.mean(s2) - 4.0) < 3.0 * np.sqrt(np.sum(np.square(spread))) / len(s2)
