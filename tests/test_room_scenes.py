"""Generated rooms (vebuild.synthetic.rooms), calibrated and solved as a user would: `vebuild
calibrate`, then `vebuild solve --recalibrate`, on a written project.

Each room is L-shaped (six corners) with a doorway and a window, a door leaf open 20–70° on a hinge
at a jamb (its axis solved: ``solve_axis``), a cabinet and a row of equal units with their backs
flush against walls; 4–10 photos from inside, none of which sees a
corner of the floor (the room's corners are solved from its walls' lines and top corners). The
first guess is 10–25 % off in every size and position. What the issue asks to be shown:

- dimensions (the walls' lengths, the height, the openings' and the furniture's sizes) within 1 cm
  per metre of the truth, the hinge's axis within 1 cm, in each of the COVERAGE_SEEDS rooms;
- over those rooms, the share of true values inside their 95 % intervals at least 90 % and not
  more than an upper bound (too-wide intervals are as wrong);
- from two different first guesses, the same figures within 0.1 σ.

Measured at this commit (seed 1; coverage over seeds 1, 3, 4, 6, 10 and 18, 138 values, the
rooms that generate and solve in about 10 s each): worst dimension 0.44–0.82 cm per metre per room,
hinge axis 1.4–6.8 mm off, coverage 95.7 %. The cameras are held by their vanishing-point priors
(FORMAT.md ``vanishing_point_prior``), not by their calibration, which already counts the marker
sightings the re-calibration uses again. The solve starts from the raw guess and, where that does
not plainly find the minimum (seeds 6 and 8 ended with pinned vertices behind a camera), from
staged_start (the room alone first, then everything).
The helpers that solve a room and compare it with its truth are `vebuild bench rooms`'s, which
runs all rooms of seeds 1–20 (15 draw; 92.8 % inside) and redraws the least covered one's clicks;
see docs/accuracy.md.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vebuild.actions.calibrate import calibrate_project
from vebuild.bench import rooms as rooms_bench
from vebuild.bench.rooms import dimensions, solve_room, true_axis, z_scores
from vebuild.constants import Z95
from vebuild.model.scene import model_from_dict
from vebuild.model.solver import staged_start
from vebuild.project import load_project, save_project
from vebuild.project.decode import cameras_from_calibration, load_model
from vebuild.synthetic import CLICK_NOISE_PX
from vebuild.synthetic.room_model import GeneratedRoom, guessed_nodes, room_params, room_scene, write_room_project
from vebuild.synthetic.room_photos import coverage, shortfall
from vebuild.synthetic.rooms import THICKNESS_TAPE_SIGMA_M

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


@pytest.fixture(scope="module")
def generated() -> GeneratedRoom:
    return room_scene(np.random.default_rng(SEED))


@pytest.fixture(scope="module")
def solved(generated: GeneratedRoom, tmp_path_factory: pytest.TempPathFactory) -> dict:
    return solve_room(generated, tmp_path_factory.mktemp("room"))


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

    assert shortfall(g.scene, [coverage(g.scene, p, g.scene.markers) for p in g.scene.photos]) == {}


def test_dimensions_within_a_centimetre_per_metre(generated: GeneratedRoom, solved: dict) -> None:
    worst = []
    for name, got, true in dimensions(generated.scene, solved):
        worst.append((abs(got - true) / max(true, 1.0), name, got, true))
        assert abs(got - true) <= DIMENSION_TOL_REL * max(true, 1.0), (name, got, true)
    print("worst dimension error (per metre, name, solved, true):", max(worst))


def test_hinge_axis_within_a_centimetre(generated: GeneratedRoom, solved: dict) -> None:
    axis = solved["nodes"]["door"]["axis"]
    err = np.asarray(axis["point"]["value"]) - true_axis(generated.scene)
    print("hinge axis error (m):", err, "1σ", axis["point"]["sigma"])
    assert np.linalg.norm(err[:2]) < AXIS_TOL_M


def test_true_values_inside_their_95_percent_intervals(generated: GeneratedRoom, solved: dict,
                                                       tmp_path_factory: pytest.TempPathFactory) -> None:
    """Over the COVERAGE_SEEDS rooms: the pooled share inside, between its bounds; and in each room
    (not only SEED's) every dimension within 1 cm per metre and the hinge axis within 1 cm."""
    z = []
    for seed in COVERAGE_SEEDS:
        if seed == SEED:
            g, sol = generated, solved
        else:
            g = room_scene(np.random.default_rng(seed))
            sol = solve_room(g, tmp_path_factory.mktemp(f"room{seed}"))
        z += z_scores(g, sol)
        fig = rooms_bench.room_figures(g, sol)
        print(f"room {seed}: worst dimension {fig['dimension_error_worst_cm_per_m']:.2f} cm/m "
              f"({fig['dimension_worst']}), hinge axis {fig['axis_error_mm']:.1f} mm off")
        assert fig["dimension_error_worst_cm_per_m"] <= 100 * DIMENSION_TOL_REL, (seed, fig)
        assert fig["axis_error_mm"] < 1000 * AXIS_TOL_M, (seed, fig)
    inside = float(np.mean(np.abs(z) < Z95))
    print("z of the values outside:", sorted(round(float(v), 2) for v in z if abs(v) >= Z95))
    hi = 0.95 + Z_BINOMIAL * np.sqrt(0.95 * 0.05 / len(z))
    print(f"coverage {inside:.3f} of {len(z)} values over {len(COVERAGE_SEEDS)} rooms "
          f"(bounds {COVERAGE_MIN}, {hi:.3f})")
    assert COVERAGE_MIN <= inside <= hi


def test_two_first_guesses_give_the_same_figures(generated: GeneratedRoom, solved: dict, tmp_path: Path) -> None:
    other = guessed_nodes(np.random.default_rng(SEED + 1000), generated.scene, (0.10, 0.25))
    assert other != generated.guess
    again = solve_room(generated, tmp_path, other)
    worst = 0.0
    for node, rec in solved["nodes"].items():
        for k, v in rec["params"].items():
            if v["sigma"] > 0:
                d = abs(v["value"] - again["nodes"][node]["params"][k]["value"]) / v["sigma"]
                worst = max(worst, d)
                assert d < REPEAT_SIGMA, (node, k, v["value"], again["nodes"][node]["params"][k]["value"])
    print("largest difference between the two guesses' solutions (σ):", worst)


@pytest.mark.parametrize("seed,direct", [(3, True), (8, False)])
def test_the_solve_from_the_first_guess_is_kept_only_where_it_found_the_minimum(
        seed: int, direct: bool, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`vebuild solve` tries the whole problem from the first guess first (Problem.plausible) and
    takes the staged start only where that did not plainly find the minimum. Seed 3's room: found
    (the staged start is not run); seed 8's: not (which seed's room is which depends on its
    calibrated cameras: seed 6 was the second until vanishing points were fitted robustly), so the
    staged start runs and the room is solved within the issue's centimetre per metre."""
    from vebuild.actions import solve as solve_action
    from vebuild.model.solver import Problem

    verdicts: list[bool] = []
    stages: list[int] = []
    plausible, staged = Problem.plausible, solve_action.staged_start
    monkeypatch.setattr(Problem, "plausible", lambda self, r: verdicts.append(plausible(self, r)) or verdicts[-1])
    monkeypatch.setattr(solve_action, "staged_start", lambda *a, **k: stages.append(staged(*a, **k)) or stages[-1])
    g = room_scene(np.random.default_rng(seed))
    sol = solve_room(g, tmp_path)
    assert verdicts == [direct]
    assert stages == ([] if direct else [1])
    for name, got, true in dimensions(g.scene, sol):
        assert abs(got - true) <= DIMENSION_TOL_REL * max(true, 1.0), (name, got, true)


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


def test_a_room_drawn_with_exact_clicks_is_the_same_room_and_fresh_noise_is_as_stated(generated: GeneratedRoom) -> None:
    """``noise_px=0`` draws the same room, photos and first guess with the clicks exactly on the
    truth (the generator's stream does not depend on the noise), and with_fresh_noise then adds
    noise of the stated σ to every click and draws both tapes again into the guess. The clicks'
    spread is checked on both sides: within 4 sampling σ (σ/√(2n)) of CLICK_NOISE_PX."""
    exact = room_scene(np.random.default_rng(SEED), noise_px=0.0)
    assert [p.id for p in exact.scene.photos] == [p.id for p in generated.scene.photos]
    for a, b in zip(exact.scene.photos, generated.scene.photos, strict=True):
        assert np.allclose(a.K, b.K) and np.allclose(a.R, b.R) and np.allclose(a.C, b.C) and a.k1 == b.k1
        assert a.markers.keys() == b.markers.keys()
    assert np.allclose(exact.scene.corners, generated.scene.corners)
    assert [(p["photo"], p["node"], p["handle"]) for p in exact.pins] == \
        [(p["photo"], p["node"], p["handle"]) for p in generated.pins]

    def clicks(g: GeneratedRoom) -> np.ndarray:
        out = [np.asarray(p["uv"]) for p in g.pins] + [np.asarray(q) for e in g.edges for q in e["points"]]
        for cam in g.scene.photos:
            out += [np.asarray(uv) for uv in cam.markers.values()]
            for segs in cam.segments.values():
                out += [np.asarray(s).reshape(-1, 2) for s in segs]
        return np.vstack([np.reshape(c, (-1, 2)) for c in out])

    def spread_ok(d: np.ndarray) -> bool:
        return abs(float(d.std()) - CLICK_NOISE_PX) < 4 * CLICK_NOISE_PX / np.sqrt(2 * d.size)

    base = clicks(exact)
    assert spread_ok(clicks(generated) - base)
    fresh = exact.with_fresh_noise(np.random.default_rng(99), CLICK_NOISE_PX)
    assert spread_ok(clicks(fresh) - base)
    assert np.array_equal(clicks(exact), base)  # the exact room is left as it was
    room = next(n for n in fresh.guess if n["name"] == "room")
    assert room["primitive"]["params"]["thickness"] == fresh.scene.tapes["thickness"] != exact.scene.tapes["thickness"]
    tape = fresh.scene.tapes["thickness"]
    assert {"name": "thickness", "sigma": THICKNESS_TAPE_SIGMA_M, "value": tape} in room["hold"]


def test_vebuild_bench_rooms_reports_the_rooms_figures(generated: GeneratedRoom, solved: dict) -> None:
    """``vebuild bench rooms`` on one room and two redraws: the room's figures are the ones this
    module checks, the redraws' are finite, and the table names them."""
    fig = rooms_bench.run(seeds=(SEED,), n_redraws=2, progress=False)
    assert fig["rooms_drawn"] == 1 and fig["seeds_not_drawn"] == [] and fig["solve_failures"] == []
    ours = rooms_bench.room_figures(generated, solved)
    got = fig["rooms"][str(SEED)]
    assert {k: got[k] for k in ours} == pytest.approx(ours, rel=1e-6)
    assert fig["coverage_values"] == got["values"] and fig["coverage_share"] == got["inside"] / got["values"]
    assert fig["redraw_seed"] == SEED and fig["redraw_count"] == 2 and fig["redraw_failures"] == []
    assert 0.0 < fig["redraw_z_rms"] < np.inf and 0.0 <= fig["redraw_coverage_share"] <= 1.0
    text = rooms_bench.table(fig)
    assert f"{got['inside']}/{got['values']}" in text and "redrawn 2 times" in text
