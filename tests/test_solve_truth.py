"""A solve that tells the truth (vebuild/model/restart.py, vebuild/actions/solve_words.py): a bad
start is repaired before anything is called undetermined or contradictory; a refusal says whether
the observations are too few (their rank at a good start) or the start was bad; and its first line
is in the investigator's words, the project file's fields on a ``details:`` line."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from vebuild.actions.solve import REPRODUCED_SIGMA, solve_project
from vebuild.errors import UndeterminedError, VebuildError
from vebuild.model.restart import start_report
from vebuild.model.solution import solution_at
from vebuild.model.solver import FINAL_PRIOR_SCALE, Problem, ProblemOptions
from vebuild.project.decode import cameras_from_calibration, load_model
from vebuild.synthetic import CLICK_NOISE_PX

sys.path.insert(0, str(Path(__file__).parent))
from flush_door_scene import DOOR, DOOR_T, door_project  # noqa: E402

#: The issue's start: the door 0.63 m behind the wall it is flush with.
BEHIND_M = 0.63
SEEDS = (1, 2, 3)
#: A figure is claimed to lie within its 95 % interval; over the three seeds' three sizes the
#: chance that one of nine misses is 1 − 0.95⁹ ≈ 37 %, so the bound is the 99.9 % interval's
#: (3.29σ): all nine within it by chance 99.1 %.
Z999 = 3.29


def _door(result: dict) -> dict:
    return result["nodes"]["door"]


def _same(a: dict, b: dict) -> None:
    """Two solves' door figures agree as two honest runs of one solve do (REPRODUCED_SIGMA)."""
    for part in ("params", "dofs"):
        for k, v in a[part].items():
            w = b[part][k]
            assert abs(v["value"] - w["value"]) <= REPRODUCED_SIGMA * max(v["sigma"], 1e-3) + 1e-6, (k, v, w)


@pytest.mark.parametrize("seed", SEEDS)
def test_a_door_turned_round_behind_its_wall_is_restarted_from_its_pins(tmp_path: Path, seed: int) -> None:
    """Started 0.63 m behind the back wall and turned round (its back away from the wall it is
    flush with), with its eight corners pinned in one photo: the relation cannot hold from there,
    which the solve once reported as relations that contradict each other. Re-started from its own
    pins it solves to the figures of a solve from the truth, the truth within them."""
    good = solve_project(door_project(tmp_path / "good", seed))
    bad = solve_project(door_project(tmp_path / "bad", seed, DOOR_T + BEHIND_M, 180.0))
    _same(_door(good), _door(bad))
    for k, true in DOOR.items():
        v = _door(bad)["params"][k]
        assert abs(v["value"] - true) <= Z999 * v["sigma"], (k, v)
    # The depth the one photo measures, and the turn the relation holds.
    assert 0 < _door(bad)["params"]["depth"]["sigma"] < DOOR["depth"] / 4


@pytest.mark.parametrize("seed", SEEDS)
def test_a_door_behind_its_wall_solves(tmp_path: Path, seed: int) -> None:
    """The issue's start (0.63 m behind the wall, facing it): the solve finds the door, as from
    the truth."""
    good = solve_project(door_project(tmp_path / "good", seed))
    bad = solve_project(door_project(tmp_path / "bad", seed, DOOR_T + BEHIND_M))
    _same(_door(good), _door(bad))


def test_a_door_with_too_few_pins_is_still_undetermined_and_said_in_words(tmp_path: Path) -> None:
    """The door not related and only its front four corners pinned in one photo: its depth is
    truly undetermined (at the start as at the end), so the refusal says too few observations,
    in words on its first line, the file's fields on the details line."""
    project = door_project(tmp_path, 1, related=False, door_corners=("v0", "v1", "v4", "v5"))
    with pytest.raises(UndeterminedError) as e:
        solve_project(project)
    first, details = str(e.value).split("\n")
    assert "door.depth" in e.value.names
    assert "too few observations" in first and "door's depth" in first and "'depth (m)'" in first
    for bad in ('"', "{", "}", "$.", "hold", "sigma", "door.depth"):
        assert bad not in first, (bad, first)
    assert details.startswith("details: $.model: undetermined ") and "door.depth" in details
    assert "model_solution" not in project.data


def test_a_refusal_at_a_far_minimum_says_the_start_was_bad(tmp_path: Path) -> None:
    """Where the solve ends with the door carried 30 m off (its eight pins then shrink to a few
    pixels, leaving its depth open) while at the start the same pins determine it, the refusal
    says the start was bad, how far the door went and what to do in the window, not too few
    observations."""
    from vebuild.actions.solve_words import refusal

    project = door_project(tmp_path, 2)
    model, pins, edges = load_model(project)
    problem = Problem(model, cameras_from_calibration(project), [p for p in pins if p.fixed], edges,
                      options=ProblemOptions(click_sigma_px=CLICK_NOISE_PX, prior_scale=FINAL_PRIOR_SCALE))
    x0 = problem.clip(problem.x0())
    far = x0.copy()
    far[problem.names.index("door.t")] += 30.0
    solution = solution_at(problem, far)
    assert any(u.startswith("door.") for u in solution.undetermined)
    report = start_report(problem, x0, far, solution.undetermined)
    assert report.determined_at_start == solution.undetermined
    assert report.moved_m["door"] == pytest.approx(30.0, abs=1e-6)
    error = refusal(project, problem, SimpleNamespace(x=far), solution)
    assert not isinstance(error, UndeterminedError) and isinstance(error, VebuildError)
    first, details = str(error).split("\n")
    assert "could not find door from where the model starts" in first and "door 30.00 m" in first
    assert "press Solve again" in first and "too few" not in first
    assert details.startswith("details: $.model.nodes")


def test_a_turn_a_relation_holds_says_so(tmp_path: Path) -> None:
    """The wall held as it stands (not solved), the door flush with it: the door's turn is held
    by the relation, not measured; its record says which relation, and the console table and the
    report print that, never '-0.000 ± 0.000'. Its sizes stay from the photos."""
    from vebuild.console.tables import model_table
    from vebuild.report.page import Report
    from vebuild.report.sections import model as report_model

    project = door_project(tmp_path, 1)
    wall = next(n for n in project.data["model"]["nodes"] if n["name"] == "wall")
    wall["solve"] = False
    result = solve_project(project)
    yaw = _door(result)["dofs"]["yaw_deg"]
    assert yaw["determined_by"] == "relation" and yaw["held_by"] == "flush door:back – wall:front"
    assert all(v["determined_by"] == "observations" for v in _door(result)["params"].values())
    table = model_table(result)
    assert "yaw_deg 0.000 (held by relation flush door:back – wall:front)" in table, table
    assert "-0.000" not in table and "0.000 ± 0.000" not in table
    rep = Report(tmp_path)
    report_model(project, rep)
    assert "held by relation flush door:back – wall:front" in rep.sections[0]
