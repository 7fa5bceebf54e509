"""Single-view measuring by clicking, without a window (vebuild.actions.click_single_view): what the
windows run on a calibrated photo with no solved model. One generated photo (the example room's
p3 alone, its truth in scenes/room/ground_truth.json), calibrated from its detected lines and the
door's height, or with no scale at all."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from vebuild.actions import click_single_view as sv
from vebuild.actions.click_measure import ClickError
from vebuild.analysis.single_view import SINGLE_VIEW_CLICKS
from vebuild.camera import project as project_points
from vebuild.cli import main
from vebuild.edit.session import EditSession
from vebuild.project import load_project
from vebuild.resources import example_project_dir

TRUTH = json.loads((example_project_dir() / "ground_truth.json").read_text())
PHOTO = "p3"
#: The door's hinge edge, from the floor to the door's top (2.045 m): the known length.
DOOR_FOOT, DOOR_M = np.array([4.2, 0.0, 0.0]), 2.045
#: The box's height (its vertical edge nearest p3's camera: it stands at yaw 30°).
BOX_M = 0.4


def _camera():
    t = TRUTH["photos"][PHOTO]
    return tuple(np.asarray(t[k], float) for k in ("K", "R", "C"))


def _pixel(X) -> np.ndarray:
    return project_points(*_camera(), np.asarray(X, float))


def _box_foot() -> np.ndarray:
    box = next(o for o in TRUTH["objects"] if o["name"] == "box")
    c, (sx, sy, _), a = np.asarray(box["centre"], float), box["size"], np.radians(box["yaw_deg"])
    R2 = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    feet = [np.r_[c[:2] + R2 @ [i * sx / 2, j * sy / 2], 0.0] for i in (-1, 1) for j in (-1, 1)]
    return min(feet, key=lambda X: float(np.linalg.norm(X - _camera()[2])))


def _one_photo(folder: Path, scale: bool) -> Path:
    """The photo alone, its detected lines accepted, calibrated (with the door's height, or none)."""
    (folder / "photos").mkdir(parents=True)
    shutil.copy(example_project_dir() / "photos" / f"{PHOTO}.jpg", folder / "photos")
    path = folder / "one.vebuild.json"
    assert main(["new", str(path), str(folder / "photos" / f"{PHOTO}.jpg")]) == 0
    s = EditSession.open(path, recover=False)
    s.detect_lines(PHOTO)
    s.accept_all(PHOTO)
    if scale:
        s.add_known_length(PHOTO, "z", [_pixel(DOOR_FOOT + [0, 0, z]) for z in (0.0, DOOR_M)], DOOR_M)
    s.calibrate()
    s.save()
    return path


@pytest.fixture(scope="module")
def scaled(tmp_path_factory) -> Path:
    return _one_photo(tmp_path_factory.mktemp("scaled"), scale=True)


def test_the_kinds_are_those_the_command_line_takes_in_order():
    kinds = sv.kinds()
    assert kinds[:2] == ("photo-height", "floor-distance")
    assert list(kinds[:-1]) == [k for k in SINGLE_VIEW_CLICKS if k in kinds]  # the shared order
    assert kinds[-1] == "person-height"  # its own command, clicked as a height
    for kind in kinds:
        assert sv.prompt(kind, 0).endswith(f"(point 1 of {len(sv.prompts(kind))})")
    assert sv.prompt("person-height", 1) == ("person's height: click the point between the feet on the floor "
                                             "(point 2 of 2)")
    assert sv.prompt("photo-height", 1) == "height: click its top (point 2 of 2)"


def test_a_height_clicked_is_the_saved_words_on_the_command_line(scaled, capsys):
    foot = _box_foot()
    clicks = [_pixel(foot) + [0.123, -0.456], _pixel(foot + [0, 0, BOX_M]) + [0.004, 0.006]]
    m = sv.measure_on_photo(load_project(scaled), "photo-height", PHOTO, clicks)
    # The words hold the pixels to 1/100 px, and the figure is theirs, not the unrounded clicks'.
    assert m.command[:3] == ["photo-height", "--photo", PHOTO]
    assert [float(w) for w in m.command[3:]] == pytest.approx(np.ravel(clicks), abs=0.005 + 1e-9)
    assert all(len(w.split(".")[1]) == 2 for w in m.command[3:])
    assert np.ravel(m.pixels).tolist() == [float(w) for w in m.command[3:]]
    capsys.readouterr()
    assert main(["analyse", str(scaled), *m.command]) == 0
    assert capsys.readouterr().out.strip() == m.result.table.strip()
    h = m.result.figures["measurements"][0]
    assert h["ci95_m"][0] <= BOX_M <= h["ci95_m"][1], h  # true pixels, but a σ from the calibration
    assert m.label == (f"height {h['value_m']:.4f} m ± {1000 * h['sigma_m']:.1f} mm (1σ), 95 % between "
                       f"{h['ci95_m'][0]:.4f} and {h['ci95_m'][1]:.4f} m")
    assert sv.drawn_pairs(m.kind, m.pixels)[0][0] is m.pixels[0]  # drawn foot → top


def test_without_a_scale_lengths_are_said_in_relative_units(tmp_path):
    path = _one_photo(tmp_path, scale=False)
    foot = _box_foot()
    m = sv.measure_on_photo(load_project(path), "photo-height", PHOTO, [_pixel(foot), _pixel(foot + [0, 0, BOX_M])])
    assert m.result.figures["lengths"] == "relative"
    assert sv.RELATIVE_WORDS in m.label and " m " not in m.label and not m.label.endswith(" m")
    # In units of the camera's height: the box's 0.4 m over the camera's 1.45 m (truth), within 95 %.
    h = m.result.figures["measurements"][0]
    true_rel = BOX_M / float(TRUTH["photos"][PHOTO]["C"][2])
    assert h["ci95_relative"][0] <= true_rel <= h["ci95_relative"][1], (h, true_rel)


def test_clicks_that_cannot_be_measured_are_said_in_words(scaled):
    project = load_project(scaled)
    with pytest.raises(ClickError, match="lies outside the 1600×1200 photo: click on the photo"):
        sv.check_click(1600, 1200, (1700.0, 40.0))
    sv.check_click(1600, 1200, (1600.0, 0.0))  # its edges are on it
    # A foot clicked on the ceiling, above the horizon: no floor point there.
    with pytest.raises(ClickError, match="lies on or above the horizon"):
        sv.measure_on_photo(project, "photo-height", PHOTO, [(800.0, 40.0), (800.0, 20.0)])
    with pytest.raises(ClickError, match="no single-view measurement 'volume'"):
        sv.measure_on_photo(project, "volume", PHOTO, [(1.0, 1.0)])
    with pytest.raises(ClickError, match="takes 2 clicked points, got 3"):
        sv.measure_on_photo(project, "photo-height", PHOTO, [(1.0, 1.0)] * 3)
