"""vebuild detect --x-axis auto: each photo's world x chosen from the markers the photos share.

The example room (scenes/room, its cameras in ground_truth.json) with every manual segment
stripped: the automatic choice is the consistent one a user would give by hand, and `vebuild
calibrate` then places every photo within the detection tolerances; a photo that shares too few
markers is told to be given its choice; a choice given by the user is kept.
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from vebuild.actions.calibrate import calibrate_project
from vebuild.actions.detect import choice_from_segments, choice_turns, detect_project, group, photo_pixels
from vebuild.calibration.axes_choice import MIN_SHARED_MARKERS_TO_PROPOSE, choose_turns, rz, two_view
from vebuild.cli import main
from vebuild.errors import ProjectError
from vebuild.project import load_project

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"
#: The consistent choice for the room (DESIGN.md's world: x along the 5 m side, O→X5).
X_AXIS = {"p1": "toward", "p2": "toward", "p3": "left", "p4": "right", "p5": "left", "p6": "away"}
#: The issue's tolerances for a photo showing three vanishing directions, calibrated.
FOCAL_TOL_REL = 0.01
ROTATION_TOL_DEG = 0.3


def _rot_deg(R1: np.ndarray, R2: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R1 @ R2.T) - 1) / 2, -1, 1))))


def _stripped(folder: Path) -> Path:
    shutil.copytree(ROOM, folder)
    path = folder / "room.vebuild.json"
    doc = json.loads(path.read_text())
    for photo in doc["photos"]:
        photo.pop("vanishing_segments", None)
        photo.pop("vanishing_segment_sigmas", None)
    path.write_text(json.dumps(doc))
    return path


def _chosen(results: list) -> dict[str, str]:
    out = {}
    for props, _ in results:
        m = re.search(r"x axis: (right|left|away|toward)\b", props.message)
        out[props.photo] = m.group(1) if m else "?"
    return out


def test_auto_is_the_default_and_calibrates_every_photo(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = _stripped(tmp_path / "room")
    assert main(["detect", str(path)]) == 0  # no --x-axis: auto
    out = capsys.readouterr().out
    for pid, choice in X_AXIS.items():
        assert re.search(rf"^{pid}: .*x axis: {choice}\b", out, re.M), (pid, out)
    assert "O→X5 runs along +x" in out
    truth = json.loads((ROOM / "ground_truth.json").read_text())
    result = calibrate_project(load_project(path))
    assert set(result["cameras"]) == set(X_AXIS)
    for pid, cam in result["cameras"].items():
        T = truth["photos"][pid]
        assert abs(cam["focal_px"]["value"] / T["f"] - 1.0) <= FOCAL_TOL_REL, pid
        assert _rot_deg(np.array(cam["R"]), np.array(T["R"])) <= ROTATION_TOL_DEG, pid


@pytest.mark.parametrize("kept", [0, 2])
def test_a_photo_sharing_too_few_markers_is_told_to_be_given_its_choice(tmp_path: Path, kept: int) -> None:
    path = _stripped(tmp_path / "room")
    project = load_project(path)
    p4 = project.photo("p4")
    p4["marker_observations"] = {m: p4["marker_observations"][m] for m in list(p4["marker_observations"])[:kept]}
    results = detect_project(project, x_axis="auto")
    msg = next(p.message for p, _ in results if p.photo == "p4")
    assert "not chosen, kept 'right'" in msg and "give --x-axis p4=CHOICE" in msg, msg
    assert f"shares at most {kept} markers" in msg and f"{MIN_SHARED_MARKERS_TO_PROPOSE} are needed" in msg
    chosen = _chosen(results)
    assert chosen["p4"] == "?"  # not chosen: its segments are directed as 'right' (below)
    assert {p: c for p, c in chosen.items() if p != "p4"} == {p: c for p, c in X_AXIS.items() if p != "p4"}
    g = group(photo_pixels(project, "p4"), p4)
    R = g.rotation("right")
    seg = np.asarray(p4["vanishing_segments"]["x"][0]).reshape(-1, 2)
    motion = R[:2, 0] - (seg.mean(axis=0) - [g.width / 2, g.height / 2]) / g.frame.focal_px * R[2, 0]
    assert (seg[-1] - seg[0]) @ motion > 0


def test_a_given_choice_is_kept_and_the_others_follow_it(tmp_path: Path) -> None:
    path = _stripped(tmp_path / "room")
    project = load_project(path)
    # p3 given 'away' instead of the consistent 'left': p3 keeps it and the world turns with it.
    results = detect_project(project, x_axis=["p3=away"])
    chosen = _chosen(results)
    assert chosen["p3"] == "away"
    grouped = {pid: group(photo_pixels(project, pid), project.photo(pid)) for pid in X_AXIS}
    turns = {pid: choice_turns(g) for pid, g in grouped.items()}
    shift = (turns["p3"]["away"] - turns["p3"]["left"]) % 4
    for pid, choice in X_AXIS.items():
        want = (turns[pid][choice] + shift) % 4
        assert turns[pid][chosen[pid]] == want, (pid, chosen)
    # The segments written for p3 are directed by its given choice.
    R3 = grouped["p3"].rotation("away")
    seg = np.asarray(project.photo("p3")["vanishing_segments"]["x"][0]).reshape(-1, 2)
    c = np.array([grouped["p3"].width / 2, grouped["p3"].height / 2])
    f = grouped["p3"].frame.focal_px
    motion = R3[:2, 0] - (seg.mean(axis=0) - c) / f * R3[2, 0]
    assert (seg[-1] - seg[0]) @ motion > 0


#: Marker noise in the synthetic views: 1 px at f = 1200 px, in normalised image coordinates.
MARKER_NOISE = 1.0 / 1200.0
#: ... the true turn then misses by about that angle (0.05°); allow 4× it.
TRUE_MISS_MAX_DEG = 4 * np.degrees(MARKER_NOISE)


def _views(seed: int, noise: float) -> tuple[dict, dict]:
    """Three level cameras seeing six points of a room, their true rotations and marker rays."""
    rng = np.random.default_rng(seed)
    X = rng.uniform([-2, -2, 0], [2, 2, 2], (6, 3)) + [0, 6, 0]
    C = {"a": np.array([0.0, 0.0, 1.5]), "b": np.array([3.0, 1.0, 1.6]), "c": np.array([-2.5, 1.5, 1.4])}
    look = {"a": 0.3, "b": -0.4, "c": 0.6}
    R, rays = {}, {}
    for p in C:
        fwd = np.array([np.sin(look[p]), np.cos(look[p]), 0.0])
        R[p] = np.vstack([np.cross(fwd, [0, 0, 1.0]), [0, 0, -1.0], fwd])  # rows: camera axes in world
        d = (X - C[p]) @ R[p].T
        d = d / d[:, 2:]
        d[:, :2] += rng.normal(0.0, noise, (len(d), 2))
        rays[p] = {f"m{i}": d[i] for i in range(len(d))}
    return R, rays


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_choose_turns_on_synthetic_views(seed: int) -> None:
    """The true turn of each photo is found from the rays of 1 px markers; exact rays meet exactly."""
    R, rays = _views(seed, MARKER_NOISE)
    true_turn = {"b": 3, "c": 1}
    k0 = {"a": R["a"], **{p: R[p] @ rz(-k) for p, k in true_turn.items()}}  # the k = 0 candidates
    d = choose_turns(k0, rays, {"a": 0})
    for p, k in true_turn.items():
        assert d[p].turn == k, d[p]
        assert min(d[p].residual_deg) <= TRUE_MISS_MAX_DEG
        assert sorted(d[p].residual_deg)[1] >= 3 * min(d[p].residual_deg)
    R, rays = _views(seed, 0.0)
    rms, _, _ = two_view(R["a"], np.array(list(rays["a"].values())), R["b"], np.array(list(rays["b"].values())))
    assert rms < 1e-6


def test_choose_turns_refuses_what_it_cannot_decide() -> None:
    R, rays = _views(0, MARKER_NOISE)
    few = {p: dict(list(r.items())[:2]) for p, r in rays.items()}
    d = choose_turns(R, few, {"a": 0})
    assert d["b"].turn is None and "shares at most 2 markers" in d["b"].message
    # Rays that meet under no turn (b's markers shuffled): refused, not guessed.
    names = list(rays["b"])
    bad = {**rays, "b": {m: rays["b"][names[(i + 2) % len(names)]] for i, m in enumerate(names)}}
    d = choose_turns({"a": R["a"], "b": R["b"]}, {"a": rays["a"], "b": bad["b"]}, {"a": 0})
    assert d["b"].turn is None and "no choice of x makes its markers' rays meet" in d["b"].message
    with pytest.raises(ValueError):
        choose_turns(R, rays, {})


def test_photos_keeping_marked_segments_hold_the_choice_they_show(tmp_path: Path) -> None:
    """The example room as shipped (segments marked by hand): detecting p2 alone, with its own
    segments replaced, chooses the x that agrees with the other photos' marked segments."""
    folder = tmp_path / "room"
    shutil.copytree(ROOM, folder)
    project = load_project(folder / "room.vebuild.json")
    for pid in ("p1", "p4", "p6"):
        photo = project.photo(pid)
        g = group(photo_pixels(project, pid), photo)
        assert choice_from_segments(g, photo["vanishing_segments"]) == X_AXIS[pid]
        assert choice_from_segments(g, {"z": photo["vanishing_segments"]["z"]}) is None  # no x or y: none
    results = detect_project(project, ["p2", "p3"], replace=True)
    assert _chosen(results) == {"p2": X_AXIS["p2"], "p3": X_AXIS["p3"]}


def test_bad_x_axis_names_the_option(tmp_path: Path) -> None:
    project = load_project(_stripped(tmp_path / "room"))
    with pytest.raises(ProjectError, match=r"--x-axis p1=up.*auto"):
        detect_project(project, x_axis=["p1=up"])
