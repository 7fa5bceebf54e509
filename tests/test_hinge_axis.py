"""A door's hinge axis and a drawer's runner line solved from photos (FORMAT.md ``solve_axis``).

The door leaf (a box) hangs on a hinge about the vertical; its pose shut (angle 0) is known from
the frame it closes (here the world: in a real room the door's jamb), and the photos show it open
at one angle. That is the realistic case: a door is photographed at the angle it stood at, once.
One angle is enough: the turn that carries the shut door to the open one has exactly one axis,
so the hinge's axis point is solved with the angle and the door's size, from a first guess 5–15 cm
off. The drawer slides from its shut pose along a runner 3–8° off the one guessed; its direction
is solved from the drawer seen pulled out.

Cameras are known (vebuild.synthetic's generator), clicks carry its 0.7 px noise.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from corner_pins import corner_pins
from scipy.stats import chi2

from vebuild.actions.solve import _results
from vebuild.camera import ImageCamera, exp_so3
from vebuild.constants import Z95
from vebuild.model.determination import axis_records
from vebuild.model.joint_file import joint_from_dict
from vebuild.model.joints import ModelError, axis_basis
from vebuild.model.residuals import Pin
from vebuild.model.scene import model_from_dict
from vebuild.model.solution import solution_at
from vebuild.model.solver import FINAL_PRIOR_SCALE, Problem, ProblemOptions
from vebuild.synthetic import CLICK_NOISE_PX, random_camera, rotation

#: Where the true hinge is (world, metres): a door 0.9 × 0.04 × 2.0 m hangs on it, shut along +x.
HINGE = np.array([1.0, 2.0, 0.0])
DOOR = {"width": 0.9, "depth": 0.04, "height": 2.0}
#: The issue's claim for the hinge axis: within 1 cm of the truth.
AXIS_TOL_M = 0.01
#: Coverage of the axis point's 95 % intervals over the seeds, bound on both sides: with 2 × 100
#: coordinates a true 95 % lies within these with probability > 0.999 (binomial: 1.5 % 1σ); a
#: too-narrow σ (95 % intervals covering 85 %) or a too-wide one (covering 99.9 %) fails.
COVERAGE = (0.90, 0.99)
SEEDS = range(100)
#: Two first guesses must give the same figures within this share of each 1σ (the issue's 0.1 σ).
REPEAT_SIGMA = 0.1


def _cameras(rng: np.random.Generator, target: np.ndarray, n: int) -> dict[str, ImageCamera]:
    """n known cameras 3–5 m in front of the doorway (+y side), 1.3–1.8 m up, looking at ``target``."""
    cams = {}
    for i in range(n):
        photo = random_camera(rng, "3vp", photo_id=f"p{i + 1}")
        ang = np.radians(rng.uniform(35.0, 145.0))
        r = rng.uniform(3.0, 5.0)
        C = np.array([target[0] + r * np.cos(ang), target[1] + r * np.sin(ang), rng.uniform(1.3, 1.8)])
        d = target - C
        R = rotation(np.arctan2(d[1], d[0]), np.arctan2(d[2], np.hypot(d[0], d[1])), np.radians(rng.normal(0, 2)))
        cams[photo.id] = ImageCamera(photo.id, photo.K, R, C, photo.width, photo.height)
    return cams


def _door(point: np.ndarray, angle_deg: float, params: dict[str, float]) -> dict[str, Any]:
    """The door node: shut, its bottom centre half its true width along +x from the true hinge."""
    return {"name": "door", "primitive": {"type": "box", "params": params},
            "joint": {"type": "hinge", "axis": [0, 0, 1], "axis_point": [float(v) for v in point],
                      "translation": [float(HINGE[0] + DOOR["width"] / 2), float(HINGE[1]), 0.0],
                      "angle_deg": angle_deg, "limits_deg": [0.0, 120.0], "solve_axis": True}}


def _guess(rng: np.random.Generator, angle_deg: float) -> dict[str, Any]:
    """A first guess: the axis point 5–15 cm off in a random direction, sizes and angle 10–25 % off."""
    turn = rng.uniform(0, 2 * np.pi)
    off = rng.uniform(0.05, 0.15) * np.array([np.cos(turn), np.sin(turn), 0.0])
    off_by = lambda v: v * (1 + rng.choice([-1, 1]) * rng.uniform(0.10, 0.25))  # noqa: E731
    return _door(HINGE + off, off_by(angle_deg), {k: off_by(v) for k, v in DOOR.items()})


def door_scene(seed: int, n_photos: int = 3) -> tuple[Any, Problem, np.random.Generator, float]:
    """The true door (open 20–60°), its pins in ``n_photos`` known photos, and the problem posed from
    a first guess; returns (truth, problem, rng, true angle in degrees)."""
    rng = np.random.default_rng(seed)
    angle = float(rng.uniform(20.0, 60.0))
    truth = model_from_dict([_door(HINGE, angle, DOOR)])
    cams = _cameras(rng, HINGE + [0.3, 0.3, 1.0], n_photos)
    pins = corner_pins(truth, cams, "door", rng)
    return truth, _problem(_guess(rng, angle), cams, pins), rng, angle


def _problem(node: dict[str, Any], cams: dict[str, ImageCamera], pins: list[Pin]) -> Problem:
    return Problem(model_from_dict([node]), cams, pins,
                   options=ProblemOptions(click_sigma_px=CLICK_NOISE_PX, prior_scale=FINAL_PRIOR_SCALE))


def _solve(problem: Problem) -> tuple[Any, dict[str, Any]]:
    r = problem.solve()
    sol = solution_at(problem, r.x, r.iterations)
    assert not sol.undetermined
    return sol, axis_records(problem, sol)["door"]


def test_the_axis_point_is_found_from_the_door_seen_open_once() -> None:
    """Within 1 cm of the truth and inside its 95 % interval, from a guess 5–15 cm off; the
    solved point is written back into the joint's axis_point; model_solution's record has it."""
    _, problem, _, angle = door_scene(0)
    start = problem.model.node("door").joint.axis_point.copy()
    sol, rec = _solve(problem)
    assert rec["frame"] == "world"
    p, s = np.array(rec["point"]["value"]), np.array(rec["point"]["sigma"])
    assert 0.05 <= np.linalg.norm((start - HINGE)[:2]) <= 0.15
    err = p[:2] - HINGE[:2]
    assert np.linalg.norm(err) < AXIS_TOL_M, f"axis point {p} is {1000 * np.linalg.norm(err):.1f} mm off"
    assert np.all(np.abs(err) <= Z95 * s[:2]), f"error {err} m outside ±{Z95} σ = {Z95 * s[:2]}"
    assert s[2] == 0.0  # the door's parent is the world: its height along the axis is no unknown
    # Written back: the file keeps the solved axis point, and the door's bottom is its nearest point.
    problem.model.set_vector(problem.model_vector(sol.x))
    j = problem.model.node("door").joint.to_dict()
    assert j["solve_axis"] is True and j["axis_point"][:2] == pytest.approx(p[:2], abs=1e-9)
    assert abs(j["angle_deg"] - angle) < 1.0
    res = _results(problem, sol, problem.model, problem.model_vector(sol.x), False)
    assert res["nodes"]["door"]["axis"] == rec
    assert set(res["nodes"]["door"]["dofs"]) == {"angle_deg", "axis_u", "axis_v"}
    assert res["nodes"]["door"]["dofs"]["axis_u"]["determined_by"] == "observations"


def test_the_axis_points_intervals_cover_the_truth_as_claimed() -> None:
    """Over 100 seeds (angles 20–60°, three photos each), the share of the axis point's
    coordinates inside their 95 % intervals is between 90 % and 99 %; every one within 1 cm."""
    inside, worst = [], 0.0
    for seed in SEEDS:
        _, problem, _, _ = door_scene(seed)
        _, rec = _solve(problem)
        err = np.array(rec["point"]["value"][:2]) - HINGE[:2]
        inside += list(np.abs(err) <= Z95 * np.array(rec["point"]["sigma"][:2]))
        worst = max(worst, float(np.linalg.norm(err)))
    share = float(np.mean(inside))
    assert COVERAGE[0] <= share <= COVERAGE[1], f"95 % intervals cover {100 * share:.1f} % of {len(inside)}"
    assert worst < AXIS_TOL_M, f"worst axis point {1000 * worst:.1f} mm off"


def test_two_first_guesses_give_the_same_axis() -> None:
    """Two first guesses (axis 5–15 cm off, sizes and angle 10–25 % off) end within 0.1 σ of each other."""
    truth, problem_a, rng, angle = door_scene(3)
    cams, pins = problem_a.cameras, problem_a.pins
    problem_b = _problem(_guess(rng, angle), cams, pins)
    assert not np.allclose(problem_a.x0(), problem_b.x0())
    sol_a, rec_a = _solve(problem_a)
    sol_b, rec_b = _solve(problem_b)
    s = np.sqrt(np.diag(sol_a.covariance))
    assert np.all(np.abs(sol_a.x - sol_b.x) <= REPEAT_SIGMA * s), "the two solves differ by more than 0.1 σ"
    pa, pb = np.array(rec_a["point"]["value"]), np.array(rec_b["point"]["value"])
    assert np.all(np.abs(pa - pb)[:2] <= REPEAT_SIGMA * np.array(rec_a["point"]["sigma"][:2]))


def test_a_door_seen_shut_leaves_its_axis_undetermined() -> None:
    """At angle 0 every axis explains the photos: the solve says so rather than give a point."""
    rng = np.random.default_rng(5)
    truth = model_from_dict([_door(HINGE, 0.0, DOOR)])
    cams = _cameras(rng, HINGE + [0.3, 0.3, 1.0], 3)
    problem = _problem(_door(HINGE + [0.1, 0.05, 0.0], 0.0, DOOR), cams, corner_pins(truth, cams, "door", rng))
    r = problem.solve()
    sol = solution_at(problem, r.x, r.iterations)
    assert {"door.axis_u", "door.axis_v"} <= set(sol.undetermined)


#: The drawer: 0.5 × 0.4 × 0.15 m, shut with its bottom centre here, pulled out this far.
DRAWER = {"width": 0.5, "depth": 0.4, "height": 0.15}
DRAWER_AT = np.array([2.0, 1.5, 0.6])
PULLED_M = 0.35
#: The direction's error is a 2-D turn: its 95 % ellipse lies inside the circle of radius
#: √χ²₂(0.95) = 2.45 times its largest 1σ (``turn_sigma_deg``).
TURN_95 = float(np.sqrt(chi2.ppf(0.95, 2)))


def _drawer(axis: np.ndarray, offset: float, params: dict[str, float]) -> dict[str, Any]:
    return {"name": "drawer", "primitive": {"type": "box", "params": params},
            "joint": {"type": "slider", "axis": [float(v) for v in axis], "offset": offset,
                      "translation": [float(v) for v in DRAWER_AT], "solve_axis": True}}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_drawers_runner_is_found_from_the_drawer_pulled_out(seed: int) -> None:
    """The runner's direction, 3–8° off the guessed +y, is recovered within its 95 % interval
    (both its turn and each coordinate); the file keeps only the folded axis."""
    rng = np.random.default_rng(100 + seed)
    guessed = np.array([0.0, 1.0, 0.0])
    _, u, v = axis_basis(guessed)
    tilt = np.radians(rng.uniform(3.0, 8.0))
    about = rng.uniform(0, 2 * np.pi)
    true_axis = exp_so3(tilt * (np.cos(about) * u + np.sin(about) * v)) @ guessed
    truth = model_from_dict([_drawer(true_axis, PULLED_M, DRAWER)])
    cams = _cameras(rng, DRAWER_AT + [0.0, 0.3, 0.0], 3)
    problem = Problem(model_from_dict([_drawer(guessed, 0.8 * PULLED_M, {k: 1.15 * x for k, x in DRAWER.items()})]),
                      cams, corner_pins(truth, cams, "drawer", rng),
                      options=ProblemOptions(click_sigma_px=CLICK_NOISE_PX, prior_scale=FINAL_PRIOR_SCALE))
    r = problem.solve()
    sol = solution_at(problem, r.x, r.iterations)
    assert not sol.undetermined
    rec = axis_records(problem, sol)["drawer"]
    d, s = np.array(rec["direction"]["value"]), np.array(rec["direction"]["sigma"])
    turn = np.degrees(np.arccos(np.clip(d @ true_axis, -1, 1)))
    assert turn <= TURN_95 * rec["turn_sigma_deg"], f"{turn:.3f}° off, 1σ {rec['turn_sigma_deg']:.3f}°"
    assert rec["turn_sigma_deg"] < 0.2 * np.degrees(tilt)  # a real measurement of the 3–8° error
    assert np.all(np.abs(d - true_axis) <= 3.0 * s + 1e-12)  # each coordinate within 3σ (99.7 %)
    problem.model.set_vector(problem.model_vector(sol.x))
    j = problem.model.node("drawer").joint
    assert j.to_dict()["axis"] == pytest.approx(list(d), abs=1e-9) and np.all(j.values()[1:] == 0.0)
    assert j.to_dict()["offset"] == pytest.approx(PULLED_M, abs=0.01)


def test_solve_axis_is_read_written_and_checked() -> None:
    j = joint_from_dict({"type": "hinge", "axis_point": [0.3, 0.2, 0.1], "solve_axis": True}, "door")
    assert j.dof_names == ("angle", "axis_u", "axis_v") and j.dof_kinds == ("angle", "position", "position")
    assert j.values()[1:] == pytest.approx([0.3, 0.2])  # u = x̂, v = ŷ for a vertical axis
    assert joint_from_dict(j.to_dict(), "door").to_dict() == j.to_dict()
    # Without solve_axis nothing changes: one degree of freedom, nothing new written.
    old = joint_from_dict({"type": "hinge"}, "door")
    assert old.dof_names == ("angle",) and "solve_axis" not in old.to_dict()
    assert joint_from_dict({"type": "slider", "solve_axis": True}, "d").dof_names == ("offset", "axis_a", "axis_b")
    # u and v stay perpendicular to an axis near x (ŷ's part is taken then).
    a, u, v = axis_basis(np.array([1.0, 0.05, 0.0]))
    assert abs(a @ u) < 1e-12 and abs(a @ v) < 1e-12 and np.cross(a, u) @ v == pytest.approx(1.0)
    with pytest.raises(ModelError, match=r"solve_axis must be true or false .* got 'yes'") as e:
        model_from_dict([{"name": "door", "primitive": {"type": "box", "params": DOOR},
                          "joint": {"type": "hinge", "solve_axis": "yes"}}])
    assert e.value.where == "$.model.nodes[0].joint.solve_axis"


def test_vebuild_solve_writes_the_solved_axis_into_the_file_and_the_solution(tmp_path) -> None:
    """Through `vebuild solve` (solve_project) on a project file: the solved axis point goes back
    into the joint's axis_point (solve_axis kept), model_solution has the door's axis record and
    the dofs axis_u, axis_v, and the saved file loads again (the schema knows every new field)."""
    from vebuild.actions.solve import solve_project
    from vebuild.project import load_project, save_project
    from vebuild.project.records import camera_record
    from vebuild.synthetic import SyntheticPhoto, write_project

    truth, problem, rng, angle = door_scene(0)
    photos = [SyntheticPhoto(c.id, "3vp", c.width, c.height, c.K, c.R, c.C) for c in problem.cameras.values()]
    path = write_project(tmp_path, photos, {"O": np.zeros(3), "M1": np.array([1.0, 0.0, 0.0])})
    project = load_project(path)
    data = project.data
    data["reference_distances"], data["markers"] = [], [{"name": "O"}]
    guess = _guess(rng, angle)
    data["model"] = {"nodes": [guess], "pins": [{"photo": p.photo, "node": p.node, "handle": p.handle,
                                                  "uv": [float(v) for v in p.uv], "fixed": True} for p in problem.pins]}
    data["calibration"] = {
        "cameras": {c.id: {"mode": "3vp", **camera_record(c.K, c.R, c.C, np.zeros((9, 9)))}
                    for c in problem.cameras.values()},
        "lengths": "metres", "origin_marker": "O",
        "markers": {"O": {"position": [0.0, 0.0, 0.0], "sigma": [0.0, 0.0, 0.0]}}}
    result = solve_project(project)
    save_project(project)
    again = load_project(path)
    joint = again.data["model"]["nodes"][0]["joint"]
    rec = again.data["model_solution"]["nodes"]["door"]
    assert joint["solve_axis"] is True and rec["axis"] == result["nodes"]["door"]["axis"]
    point = np.array(rec["axis"]["point"]["value"])
    assert np.linalg.norm(point[:2] - HINGE[:2]) < AXIS_TOL_M
    assert joint["axis_point"][:2] == pytest.approx(list(point[:2]), abs=1e-9)
    assert rec["dofs"]["axis_u"]["value"] == pytest.approx(joint["axis_point"][0], abs=1e-9)
    assert rec["dofs"]["axis_v"]["ci95"][0] < HINGE[1] < rec["dofs"]["axis_v"]["ci95"][1]
