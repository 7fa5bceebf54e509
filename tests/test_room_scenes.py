"""Generated rooms (vebuild.synthetic_rooms), calibrated and solved as a user would: `vebuild
calibrate`, then `vebuild solve --recalibrate`, on a written project.

Each room is L-shaped (six corners) with a doorway and a window, a door leaf open 20–70° on a hinge
at a jamb (its axis solved: ``solve_axis``), a cabinet and a row of equal units with their backs
flush against walls; 4–10 photos from inside, none of which sees a
corner of the floor (the room's corners are solved from its walls' lines and top corners). The
first guess is 10–25 % off in every size and position. What the issue asks to be shown:

- dimensions (the walls' lengths, the height, the openings' and the furniture's sizes) within 1 cm
  per metre of the truth, the hinge's axis within 1 cm;
- over several rooms, the share of true values inside their 95 % intervals at least 90 % and not
  more than an upper bound (too-wide intervals are as wrong);
- from two different first guesses, the same figures within 0.1 σ.

Measured at this commit (seed 1; coverage over seeds 1, 3, 4, 6, 10 and 18, 138 values, the
rooms that generate and solve in about 10 s each): worst dimension 0.82 cm per metre, coverage
95.7 %. The cameras are held by their vanishing-point priors (FORMAT.md ``vanishing_point_prior``),
not by their calibration, which already counts the marker sightings the re-calibration uses again.
The solve starts from staged_start (the room alone first, then everything): from the raw guess
seeds 6 and 8 ended with pinned vertices behind a camera. Over 15 rooms (seeds 1–20 that draw)
the share is 92.8 %; see the README.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vebuild.actions.calibrate import calibrate_project
from vebuild.actions.solve import solve_project
from vebuild.constants import Z95
from vebuild.model.scene import model_from_dict
from vebuild.model.solver import staged_start
from vebuild.project import load_project, save_project
from vebuild.project.decode import cameras_from_calibration, load_model
from vebuild.synthetic_room_model import guessed_nodes, room_params, write_room_project
from vebuild.synthetic_room_photos import shortfall
from vebuild.synthetic_rooms import GeneratedRoom, RoomScene, room_scene

#: The room whose figures are checked one by one (and whose solve is repeated from another guess).
SEED = 1
#: Rooms for the coverage figure.
COVERAGE_SEEDS = (1, 3, 4, 6, 10, 18)
#: The issue's accuracy: a dimension within 1 cm per metre of it (1 %), the hinge's axis within 1 cm.
DIMENSION_TOL_REL = 0.01
AXIS_TOL_M = 0.01
#: The least share of true values inside their 95 % intervals (the issue's figure).
COVERAGE_MIN = 0.90
#: Too-wide intervals: above the nominal 95 % by 2.5 binomial standard deviations sqrt(0.95·0.05/n)
#: at n intervals (a correct solver passes this about 99 % of the time).
Z_BINOMIAL = 2.5
#: Repeatability: two first guesses give the same solved values within this share of their σ.
REPEAT_SIGMA = 0.1


def _solved(g: GeneratedRoom, folder: Path, nodes: list | None = None) -> dict:
    """Calibrate and solve (re-calibrating) the generated room's project; the model's solution."""
    path = write_room_project(folder, g.scene, g.guess if nodes is None else nodes, g.pins, g.edges)
    project = load_project(path)
    calibrate_project(project)
    save_project(path, project.data)
    project = load_project(path)
    solve_project(project, recalibrate=True)
    return project.data["model_solution"]


def _wall_lengths(corners: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.roll(corners, -1, axis=0) - corners, axis=1)


def _solved_corners(sol: dict) -> np.ndarray:
    p = {k: v["value"] for k, v in sol["nodes"]["room"]["params"].items()}
    return np.array([[0, 0], [p["c1_x"], 0], [p["c1_x"], p["c2_y"]], [p["c3_x"], p["c2_y"]], [p["c3_x"], p["c4_y"]],
                     [0, p["c4_y"]]], float)


def _true_axis(scene: RoomScene) -> np.ndarray:
    """The hinge's true axis in the world: its point nearest the leaf's bottom centre (the axis is
    vertical: the axis point at the leaf's bottom's height)."""
    J = scene.jamb_frame("door", scene.hinge.side)
    p = J[:3, :3] @ scene.hinge.axis_point + J[:3, 3]
    return np.r_[p[:2], scene.leaf.centre[2]]


def _dimensions(scene: RoomScene, sol: dict) -> list[tuple[str, float, float]]:
    """(name, solved, true) of every dimension the issue names."""
    out = []
    for i, (a, b) in enumerate(zip(_wall_lengths(_solved_corners(sol)), _wall_lengths(scene.corners), strict=True)):
        out.append((f"wall{i} length", float(a), float(b)))
    rp, tp = sol["nodes"]["room"]["params"], room_params(scene)
    for k in ("height", "door_width", "door_height", "win_width", "win_height", "win_sill"):
        out.append((k, rp[k]["value"], tp[k]))
    for b in scene.boxes():
        for i, k in enumerate(("width", "depth", "height")):
            if b.name == "door" and k == "depth":
                continue  # entered from a tape: no photo measures it
            out.append((f"{b.name}.{k}", sol["nodes"][b.name]["params"][k]["value"], float(b.size[i])))
    return out


def _z_scores(g: GeneratedRoom, sol: dict) -> list[float]:
    """(solved − true) / σ of every solved parameter and degree of freedom the photos determine."""
    truth = model_from_dict(g.truth["nodes"], {"O": np.zeros(3)}, g.truth["relations"])
    out = []
    # The members of an equal group share one unknown: counted once (by the first member).
    shared = {p for r in g.truth["relations"] if r["type"] == "equal" for p in r["params"][1:]}
    for n in truth.nodes:
        rec = sol["nodes"][n.name]
        if n.primitive is not None:
            for k, v in zip(n.primitive.PARAMS, n.primitive.params, strict=True):
                r = rec["params"][k]
                if r["sigma"] > 0 and r.get("determined_by") == "observations" and f"{n.name}.{k}" not in shared:
                    out.append((r["value"] - float(v)) / r["sigma"])
        axis = rec.get("axis")
        if axis is not None:
            err = np.asarray(axis["point"]["value"]) - _true_axis(g.scene)
            s = np.asarray(axis["point"]["sigma"])
            out += [float(e / q) for e, q in zip(err, s, strict=True) if q > 0]
    return out


@pytest.fixture(scope="module")
def generated() -> GeneratedRoom:
    return room_scene(np.random.default_rng(SEED))


@pytest.fixture(scope="module")
def solved(generated: GeneratedRoom, tmp_path_factory: pytest.TempPathFactory) -> dict:
    return _solved(generated, tmp_path_factory.mktemp("room"))


def test_the_generated_geometry_is_vebuilds_room(generated: GeneratedRoom) -> None:
    """The true model written as nodes puts every handle where the generator's own geometry has it
    (a convention slip in the room primitive or its joints would show here), no photo sees a floor
    corner, and the photos show what the model needs."""
    g = generated
    model = model_from_dict(g.truth["nodes"], {"O": np.zeros(3)}, g.truth["relations"])
    pts = {**{("room", h): X for h, X in g.scene.handles().items()}, **g.scene.seen_points()}
    for (node, handle), X in pts.items():
        assert np.linalg.norm(model.handle_world(node, handle) - X) < 1e-9, (node, handle)
    assert 4 <= len(g.scene.photos) <= 10
    for p in g.scene.photos:
        assert g.scene.seen_floor_corners(p) == [], p.id
    assert not any(pin["handle"].startswith("f") and pin["node"] == "room" for pin in g.pins)
    from vebuild.synthetic_room_photos import _coverage

    assert shortfall(g.scene, [_coverage(g.scene, p, g.scene.markers) for p in g.scene.photos]) == {}


def test_dimensions_within_a_centimetre_per_metre(generated: GeneratedRoom, solved: dict) -> None:
    worst = []
    for name, got, true in _dimensions(generated.scene, solved):
        worst.append((abs(got - true) / max(true, 1.0), name, got, true))
        assert abs(got - true) <= DIMENSION_TOL_REL * max(true, 1.0), (name, got, true)
    print("worst dimension error (per metre, name, solved, true):", max(worst))


def test_hinge_axis_within_a_centimetre(generated: GeneratedRoom, solved: dict) -> None:
    axis = solved["nodes"]["door"]["axis"]
    err = np.asarray(axis["point"]["value"]) - _true_axis(generated.scene)
    print("hinge axis error (m):", err, "1σ", axis["point"]["sigma"])
    assert np.linalg.norm(err[:2]) < AXIS_TOL_M


def test_true_values_inside_their_95_percent_intervals(generated: GeneratedRoom, solved: dict,
                                                       tmp_path_factory: pytest.TempPathFactory) -> None:
    z = _z_scores(generated, solved)
    for seed in COVERAGE_SEEDS:
        if seed == SEED:
            continue
        g = room_scene(np.random.default_rng(seed))
        z += _z_scores(g, _solved(g, tmp_path_factory.mktemp(f"room{seed}")))
    inside = float(np.mean(np.abs(z) < Z95))
    print("z of the values outside:", sorted(round(float(v), 2) for v in z if abs(v) >= Z95))
    hi = 0.95 + Z_BINOMIAL * np.sqrt(0.95 * 0.05 / len(z))
    print(f"coverage {inside:.3f} of {len(z)} values over {len(COVERAGE_SEEDS)} rooms "
          f"(bounds {COVERAGE_MIN}, {hi:.3f})")
    assert COVERAGE_MIN <= inside <= hi


def test_two_first_guesses_give_the_same_figures(generated: GeneratedRoom, solved: dict, tmp_path: Path) -> None:
    other = guessed_nodes(np.random.default_rng(SEED + 1000), generated.scene, (0.10, 0.25))
    assert other != generated.guess
    again = _solved(generated, tmp_path, other)
    worst = 0.0
    for node, rec in solved["nodes"].items():
        for k, v in rec["params"].items():
            if v["sigma"] > 0:
                d = abs(v["value"] - again["nodes"][node]["params"][k]["value"]) / v["sigma"]
                worst = max(worst, d)
                assert d < REPEAT_SIGMA, (node, k, v["value"], again["nodes"][node]["params"][k]["value"])
    print("largest difference between the two guesses' solutions (σ):", worst)


def test_the_staged_start_places_the_room_before_its_furniture(generated: GeneratedRoom, tmp_path: Path) -> None:
    """staged_start solves the room alone first (one stage: the room, then its children in the
    final solve), from its own pins and edges with the calibrated cameras held: the room's sizes
    come much nearer the truth than the 10–25 % guess, the furniture is left where it was, and the
    model's relations are as they were. (Seed 1: the room's mean error goes from 16 % to 5.0 %;
    what remains is the calibration's cameras, which the re-calibrating solve then corrects.)"""
    path = write_room_project(tmp_path, generated.scene, generated.guess, generated.pins, generated.edges)
    project = load_project(path)
    calibrate_project(project)
    save_project(path, project.data)
    project = load_project(path)
    model, pins, edges = load_model(project)
    relations = list(model.relations)
    children = {n.name: list(n.primitive.params) for n in model.nodes if n.parent is not None and n.primitive}
    truth = room_params(generated.scene)

    def room_error() -> float:
        r = model.node("room").primitive
        got = dict(zip(r.PARAMS, r.params, strict=True))
        return float(np.mean([abs(got[k] / v - 1) for k, v in truth.items() if v != 0 and k != "thickness"]))

    before = room_error()
    stages = staged_start(model, cameras_from_calibration(project), [p for p in pins if p.fixed], edges,
                          project.settings["click_sigma_px"])
    print(f"room's mean error: guess {before:.3f}, after the staged start {room_error():.3f}")
    assert stages == 1
    assert room_error() < 0.5 * before
    assert model.relations == relations
    assert {n: list(model.node(n).primitive.params) for n in children} == children
