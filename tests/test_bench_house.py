"""The house benchmark's stand-in for a user who reads the solve's refusal: the sizes it names are
measured (the true size with a tape's error) and entered as hold entries."""

from __future__ import annotations

import copy

import numpy as np

from vebuild.bench.house import TAPE_SIGMA_M, taped_values

TRUTH = [{"name": "room6", "primitive": {"type": "room", "params": {"c1_x": 4.96, "c2_y": 4.99, "thickness": 0.1}}},
         {"name": "step1", "primitive": {"type": "box", "params": {"width": 0.27, "depth": 0.95, "height": 0.18}}}]
DATA = {"model": {"nodes": [
    {"name": "room6", "primitive": {"type": "room", "params": {"c1_x": 5.1, "c2_y": 5.04, "thickness": 0.099}},
     "hold": ["south_sill", {"name": "thickness", "sigma": 0.003, "value": 0.099}]},
    {"name": "step1", "primitive": {"type": "box", "params": {"width": 0.28, "depth": 0.9, "height": 0.17}},
     "hold": [{"name": "depth", "sigma": 0.05, "value": 0.9}]}]}}


def test_the_sizes_named_are_entered_as_measured_with_a_tapes_error():
    data = copy.deepcopy(DATA)
    entered = taped_values(data, TRUTH, ["room6.c2_y", "step1.depth"], np.random.default_rng(3))
    assert entered == ["room6.c2_y", "step1.depth"]
    room, step = data["model"]["nodes"]
    assert room["hold"][:2] == DATA["model"]["nodes"][0]["hold"]  # what was entered before stays
    (c2,) = [h for h in room["hold"] if isinstance(h, dict) and h["name"] == "c2_y"]
    (depth,) = [h for h in step["hold"] if h["name"] == "depth"]  # the old entry replaced
    for h, true in ((c2, 4.99), (depth, 0.95)):
        assert h["sigma"] == TAPE_SIGMA_M
        assert 0.0 < abs(h["value"] - true) < 4 * TAPE_SIGMA_M  # a tape's error, not the truth itself
    assert data["model"]["nodes"][0]["primitive"] == DATA["model"]["nodes"][0]["primitive"]


def test_nothing_is_entered_where_a_name_is_not_a_size():
    data = copy.deepcopy(DATA)
    assert taped_values(data, TRUTH, ["room6.c2_y", "step1.yaw"], np.random.default_rng(3)) is None
    assert taped_values(data, TRUTH, ["gone.width"], np.random.default_rng(3)) is None
    assert data == DATA


def test_the_drag_figures_on_a_solved_room(tmp_path):
    """The house bench's modelling-screen figures, measured on the example room (the house's own
    run needs its cached photos): the drags, a frame as the cursor crosses the photo, and an undo
    step's size: less than the solved document's, whose covariance matrix it leaves out (shared,
    not packed: tests/test_edit_session.py), though it holds the box the bench added."""
    import json
    import pickle
    import shutil

    from vebuild.bench.house import drag
    from vebuild.cli import main
    from vebuild.resources import example_project_dir

    shutil.copytree(example_project_dir(), tmp_path / "room")
    path = tmp_path / "room" / "room.vebuild.json"
    assert main(["calibrate", str(path), "--quiet"]) == 0
    assert main(["solve", str(path)]) == 0
    data = json.loads(path.read_text())
    fig = drag(path, moves=4)
    for key in ("update", "start", "release"):
        assert 0 < fig[f"house_drag_{key}_ms_median"] <= fig[f"house_drag_{key}_ms_p95"]
    assert fig["house_hover_frame_ms_median"] > 0
    whole = len(pickle.dumps(data, protocol=pickle.HIGHEST_PROTOCOL)) / 2**20
    assert 0 < fig["house_undo_step_mb"] < whole
