"""Honest determination (vebuild/model/solution.py): a parameter is undetermined by its 1σ from
the observations relative to the scene's size and to its value (angles by their own rule), not by
a fixed metre; one only an entered value determines is reported as such; and the "too few
observations" message says what would determine each undetermined parameter."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from vebuild.actions.calibrate import calibrate_project
from vebuild.actions.solve import solve_project
from vebuild.camera import ImageCamera
from vebuild.console.tables import model_table
from vebuild.errors import VebuildError
from vebuild.model.scene import model_from_dict
from vebuild.model.solution import (
    UNDETERMINED_ANGLE_RAD,
    UNDETERMINED_SHARE_OF_SCENE,
    UNDETERMINED_SHARE_OF_VALUE,
    determined,
    solution_at,
)
from vebuild.model.solver import FINAL_PRIOR_SCALE, Problem, ProblemOptions
from vebuild.project import load_project
from vebuild.report.page import Report
from vebuild.report.sections import model as report_model
from vebuild.synthetic import CLICK_NOISE_PX, rotation

sys.path.insert(0, str(Path(__file__).parent))
from corner_pins import corner_pins  # noqa: E402
from entered_scene import entered_project  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[1] / "scenes" / "room"
#: The issue's wall: 6.04 m long, its far end seen by one photo only, at one top corner, from a
#: camera near the wall's plane and height looking along it.
WALL = {"width": 6.04, "depth": 0.12, "height": 2.5}
#: How far (m) that photo stands out of the wall's front plane: 23 cm gives the issue's figure
#: (6.10 ± 0.85 m for this seed); a metre out it sees the far end squarely.
GRAZING_M = 0.23
K = np.array([[1200.0, 0.0, 800.0], [0.0, 1200.0, 600.0], [0.0, 0.0, 1.0]])


def _wall(params: dict[str, float], pos: tuple[float, float] = (3.0, 0.0), yaw: float = 0.0) -> dict[str, Any]:
    return {"name": "wall", "primitive": {"type": "box", "params": params},
            "joint": {"type": "rests_on", "position": list(pos), "yaw_deg": yaw}}


def _camera(cid: str, C: list[float], target: list[float]) -> ImageCamera:
    d = np.asarray(target) - C
    R = rotation(np.arctan2(d[1], d[0]), np.arctan2(d[2], np.hypot(d[0], d[1])), 0.0)
    return ImageCamera(cid, K, R, np.asarray(C, float), 1600, 1200)


def wall_solve(out_m: float, far: tuple[str, ...]) -> tuple[Problem, Any]:
    """The wall's near end (x = 0) pinned in two photos; its far end's corners ``far`` in a third,
    standing ``out_m`` out of the wall's front plane; solved from a first guess 9 % short."""
    rng = np.random.default_rng(6)
    truth = model_from_dict([_wall(WALL)])
    near = {c.id: c for c in (_camera("p1", [-1.5, -3.0, 1.6], [0.3, 0, 1.2]),
                              _camera("p2", [1.5, -3.5, 1.5], [0.2, 0, 1.2]))}
    side = {"p3": _camera("p3", [-2.0, -0.06 - out_m, 2.5 - 0.2 * out_m], [6.04, 0, 2.4])}
    pins = [p for p in corner_pins(truth, near, "wall", rng) if p.handle in ("v0", "v3", "v4", "v7")]
    pins += [p for p in corner_pins(truth, side, "wall", rng) if p.handle in far]
    start = model_from_dict([_wall({"width": 5.5, "depth": 0.1, "height": 2.4}, (2.8, 0.05), 1.0)])
    problem = Problem(start, {**near, **side}, pins,
                      options=ProblemOptions(click_sigma_px=CLICK_NOISE_PX, prior_scale=FINAL_PRIOR_SCALE))
    r = problem.solve()
    return problem, solution_at(problem, r.x, r.iterations)


def test_the_issues_wall_is_undetermined() -> None:
    """6.1 ± 0.85 m: under the old fixed 1 m, so it was reported as a measurement; at 13 % of a
    6.6 m scene it is undetermined now. Seen squarely by the same photo it is measured (± 1.5 cm)."""
    problem, sol = wall_solve(GRAZING_M, ("v5",))
    j = problem.names.index("wall.width")
    value, sigma = sol.x[j], np.sqrt(sol.covariance[j, j])
    assert 5.5 < value < 6.6 and 0.6 < sigma < 1.0, f"{value:.2f} ± {sigma:.2f} m: not the issue's case"
    assert np.sqrt(sol.covariance_observed[j, j]) < 1.0  # the old rule called it determined
    assert "wall.width" in sol.undetermined
    problem, sol = wall_solve(1.0, ("v1", "v2", "v5", "v6"))
    j = problem.names.index("wall.width")
    assert not sol.undetermined and abs(sol.x[j] - WALL["width"]) < 3 * np.sqrt(sol.covariance[j, j]) < 0.05


def test_the_rule_is_relative_to_the_scene_the_value_and_for_angles_its_own() -> None:
    scene = 8.0
    edge = UNDETERMINED_SHARE_OF_SCENE * scene
    assert determined((0.99 * edge) ** 2, 6.0, "size", scene) and not determined((1.01 * edge) ** 2, 6.0, "size", scene)
    assert not determined(0.87**2, 6.04, "size", scene)  # the issue's figure
    # The same figures scaled by 100 (a project in other units, or a model of a cupboard) agree.
    assert determined((0.99 * edge / 100) ** 2, 0.06, "size", scene / 100)
    # A size known to no better than half itself has not been measured, however small the σ.
    half = UNDETERMINED_SHARE_OF_VALUE * 0.02
    assert not determined((1.02 * half) ** 2, 0.02, "size", scene)
    assert determined((0.98 * half) ** 2, 0.02, "size", scene)
    assert determined((1.02 * half) ** 2, 0.02, "position", scene)  # a position has no value rule
    assert determined((0.99 * UNDETERMINED_ANGLE_RAD) ** 2, 0.0, "angle", scene)
    assert not determined((1.01 * UNDETERMINED_ANGLE_RAD) ** 2, 0.0, "angle", scene)
    assert not determined(np.inf, 1.0, "size", scene)


@pytest.fixture(scope="module")
def example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("room")
    shutil.copytree(EXAMPLE, folder, dirs_exist_ok=True)
    return folder / "room.vebuild.json"


def test_every_parameter_of_the_example_room_stays_determined(example: Path) -> None:
    """The example solves, every solved parameter from the observations, its least determined
    length well inside the rule (measured: 1.0 cm, 0.14 % of its 7.2 m extent, against 5 %)."""
    project = load_project(example)
    calibrate_project(project)
    result = solve_project(project)
    handles = np.array([h["value"] for n in result["nodes"].values() for h in n["handles"].values()])
    extent = float(np.linalg.norm(np.ptp(handles, axis=0)))
    worst = 0.0
    for node in result["nodes"].values():
        for group in ("params", "dofs"):
            for name, v in node[group].items():
                if "determined_by" in v:
                    assert v["determined_by"] == "observations"
                    if not name.endswith("_deg"):
                        worst = max(worst, v["sigma"])
    assert 0 < worst < 0.2 * UNDETERMINED_SHARE_OF_SCENE * extent, f"worst 1σ {worst:.4f} m of {extent:.2f} m"


def test_a_dimension_only_an_entered_value_determines_is_reported_as_such(tmp_path: Path) -> None:
    """The floor's pins removed, its size entered with a 1σ: its record says "determined_by":
    "entered value", the console table and the report say so; the boxes' positions on it are
    measured in the photos from its centre, which only its entered size places: "observations and
    entered values", printed as from the photos, measured from entered values (not as entered
    values only); the boxes' sizes and turns come from the photos."""
    project, _ = entered_project(tmp_path / "a", 3, [])
    data = project.data
    data["model"]["pins"] = [p for p in data["model"]["pins"] if p["node"] != "floor"]
    data["model"]["nodes"][0]["hold"] = ["yaw", {"name": "width", "sigma": 0.01}, {"name": "depth", "sigma": 0.01}]
    result = solve_project(project)
    floor = result["nodes"]["floor"]["params"]
    assert floor["width"]["determined_by"] == floor["depth"]["determined_by"] == "entered value"

    def by(source: str) -> set[str]:
        return {f"{n}.{k}" for n, rec in result["nodes"].items() for g in ("params", "dofs")
                for k, v in rec[g].items() if v.get("determined_by") == source}

    boxes = [n for n in result["nodes"] if n.startswith("box")]
    assert by("entered value") == {"floor.width", "floor.depth"}
    assert by("observations and entered values") == {f"{b}.{k}" for b in boxes for k in ("s", "t")}
    assert all(result["nodes"][b][g][k]["determined_by"] == "observations" for b in boxes
               for g, k in (("params", "width"), ("params", "height"), ("dofs", "yaw_deg")))
    assert "determined_by" not in result["nodes"]["floor"]["dofs"]["yaw_deg"]  # held exactly: not solved
    table = model_table({**result, "lengths": "metres"})
    assert table.count("(entered value only: no photo shows it)") == 2, table
    assert table.count("(from the photos, measured from entered values)") == 2 * len(boxes), table
    rep = Report(tmp_path)
    report_model(project, rep)
    assert rep.sections[0].count("entered value only (no photo shows it)") == 2
    assert rep.sections[0].count("from the photos, measured from entered values") == 2 * len(boxes)


def test_too_few_observations_says_what_would_determine_each_parameter(example: Path, tmp_path: Path) -> None:
    """The box pinned in one photo only: the message names each undetermined parameter with its
    value now, the hold entry that enters a measured one, and box corners to pin in another photo."""
    shutil.copytree(example.parent, tmp_path / "r", dirs_exist_ok=True)
    path = tmp_path / "r" / example.name
    data = json.loads(path.read_text())
    data["model"]["pins"] = [p for p in data["model"]["pins"] if p["node"] != "box" or p["photo"] == "p1"]
    data["model"]["edge_observations"] = [e for e in data["model"]["edge_observations"] if e["node"] != "box"]
    path.write_text(json.dumps(data))
    project = load_project(path)
    calibrate_project(project)
    box = next(n for n in project.data["model"]["nodes"] if n["name"] == "box")
    with pytest.raises(VebuildError) as e:
        solve_project(project)
    first, details = str(e.value).split("\n")
    # The first line in the window's words: the parameters by name, the Model tab's fields, F.
    assert "too few observations: the pins and edges do not fix box's " in first
    assert "$." not in first and '"' not in first and "hold" not in first and "sigma" not in first
    assert "untick 'solve'" in first and "press F" in first
    for param in ("width", "depth", "height"):
        assert (f"box.{param}" in details) == (f"'{param} (m)'" in first)
    # The details line, for the expert: the file's fields.
    assert details.startswith("details: $.model: undetermined box.")
    undetermined = details.split("undetermined ")[1].split("; ")[0].split(", ")
    assert undetermined and all(u.startswith("box.") for u in undetermined), details
    assert e.value.names == undetermined  # the same names for a caller (UndeterminedError)
    for u in undetermined:
        param = u.split(".", 1)[1]
        unit, sigma = ("°", 1) if param == "yaw" else (" m", 0.005)
        clause = details.split(f"{u} (now ")[1].split("; box.")[0]
        assert f'{{"name": "{param}", "sigma": {sigma:g}, "value": <measured>}}' in clause
        assert "in the \"hold\" list of node 'box'" in clause
        now = float(clause.split(unit)[0])
        if param in box["primitive"]["params"]:
            # (the value the solve left it at: its start, for a direction no photo fixes)
            assert now == pytest.approx(box["primitive"]["params"][param], rel=0.2)
        pins = clause.split("; or pin ")[1].split(" (now in")
        assert pins[0].startswith("box:v") and "photo" in clause
    assert '"solve": false' in details


def _normal_matrix(rng: np.random.Generator, n_rest: int, cameras: int, join: bool = False) -> tuple[Any, list[slice]]:
    """A solve's normal matrix JᵀJ + a ridge: the model's unknowns first, then 9 per camera, then
    a marker's 3; each row in one photo (its camera's unknowns and a few others), or, with
    ``join``, one row in two photos."""
    n = n_rest - 3 + 9 * cameras + 3
    slices = [slice(n_rest - 3 + 9 * c, n_rest - 3 + 9 * (c + 1)) for c in range(cameras)]
    rest = np.r_[np.arange(n_rest - 3), np.arange(n - 3, n)]
    rows = []
    for c in range(cameras):
        for _ in range(40):
            row = np.zeros(n)
            row[slices[c]] = rng.normal(size=9)
            row[rng.choice(rest, 4, replace=False)] = rng.normal(size=4)
            rows.append(row)
    if join:
        row = np.zeros(n)
        row[slices[0]] = row[slices[1]] = 1.0
        rows.append(row)
    rows += [np.eye(n)[j] * 0.1 for j in rest]  # every unknown outside the cameras observed
    J = np.array(rows)
    return J.T @ J + 1e-12 * np.eye(n), slices


def test_the_inverse_by_the_cameras_schur_complement_is_the_whole_inverse() -> None:
    """A⁻¹ from the Schur complement of the cameras' block, and its block outside the cameras
    alone, are the whole inverse (to 1e-9 of its largest entry, exactly symmetric), and so are the
    fallbacks where two cameras are joined or a camera's block is singular (the whole matrix then
    too: ∞ where the whole inverse has it)."""
    from vebuild.model.inverse import inverse, inverse_by_cameras, outside_cameras_inverse

    rng = np.random.default_rng(7)
    for join, singular in ((False, False), (True, False), (False, True)):
        A, slices = _normal_matrix(rng, 40, 6, join)
        if singular:
            A[slices[2], :] = 0.0
            A[:, slices[2]] = 0.0
            A[slices[2], slices[2]] = 1e-12 * np.ones((9, 9))  # rank one: not positive definite
        rest = np.ones(len(A), bool)
        for sl in slices:
            rest[sl] = False
        whole = inverse(A)
        for got, expected in ((outside_cameras_inverse(A, slices), whole[np.ix_(rest, rest)]),
                              (inverse_by_cameras(A, slices), whole)):
            assert got.shape == expected.shape
            finite = np.isfinite(expected)
            assert np.array_equal(np.isfinite(got), finite) and finite.sum() > 0.9 * finite.size
            assert np.max(np.abs(got[finite] - expected[finite])) <= 1e-9 * np.max(np.abs(expected[finite])), \
                (join, singular)
            assert singular or np.array_equal(got, got.T)  # (the pseudo-inverse's need not be)


def test_a_recalibration_determines_as_with_the_whole_inverse(example: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The re-calibrating solve of the example (its cameras among the unknowns) reports every
    parameter's determination, the observations' covariance and the solution's as the whole
    inverse gives them."""
    from vebuild.model import solution
    from vebuild.model.inverse import inverse

    project = load_project(example)
    calibrate_project(project)
    got = solve_project(project, recalibrate=True)
    seen: list[Any] = []
    real = solution._outside_cameras_inverse

    def whole(A: Any, cameras: Any) -> Any:
        rest = np.ones(len(A), bool)
        for sl in cameras:
            rest[sl] = False
        seen.append((len(cameras), real(A, cameras), inverse(A)[np.ix_(rest, rest)]))
        return seen[-1][2]

    project = load_project(example)
    calibrate_project(project)
    monkeypatch.setattr(solution, "_outside_cameras_inverse", whole)
    monkeypatch.setattr(solution, "_inverse_by_cameras", lambda A, cameras: inverse(A))
    expected = solve_project(project, recalibrate=True)
    assert seen and all(k == len(project.data["photos"]) for k, _, _ in seen)  # every camera solved for
    for _, schur, full in seen:
        assert np.max(np.abs(schur - full)) <= 1e-9 * np.max(np.abs(full))

    def determination(result: dict[str, Any]) -> dict[str, Any]:
        return {(n, g, k): v.get("determined_by") for n, rec in result["nodes"].items() for g in ("params", "dofs")
                for k, v in rec[g].items()}

    assert determination(got) == determination(expected)
    cov = np.array(got["covariance"]["matrix"], float)
    cov_whole = np.array(expected["covariance"]["matrix"], float)
    assert got["covariance"]["parameters"] == expected["covariance"]["parameters"]
    assert np.max(np.abs(cov - cov_whole)) <= 1e-9 * np.max(np.abs(cov_whole))
    assert got["rms_px"] == pytest.approx(expected["rms_px"], rel=1e-9)
