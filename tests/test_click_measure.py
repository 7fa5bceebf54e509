"""What a click means, without a window (vebuild.actions.click_measure): the reference of a clicked
surface point is the command line's, its measurement the command line's request, its record one
`vebuild report` runs again; bad clicks are clear errors."""

from __future__ import annotations

import dataclasses
import math
import shutil

import numpy as np
import pytest

from vebuild.actions import click_measure as cm
from vebuild.analysis.points import face_point
from vebuild.analysis.recorded import run_recorded
from vebuild.cli import main
from vebuild.project import load_project
from vebuild.resources import example_project_dir

#: A face coordinate is written to 10^-ST_DECIMALS m: the point it names is within half of that
#: per axis of the point clicked.
ROUND_M = 0.5 * 10.0 ** -cm.ST_DECIMALS * math.sqrt(2)


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    folder = tmp_path_factory.mktemp("click") / "room"
    shutil.copytree(example_project_dir(), folder)
    path = folder / "room.vebuild.json"
    assert main(["calibrate", str(path), "--quiet"]) == 0
    assert main(["solve", str(path)]) == 0
    project = load_project(path)
    return project, cm.solved_model(project)


def test_a_clicked_point_becomes_the_reference_the_command_line_reads(solved):
    project, s = solved
    p = face_point(s, "table.top", "top", 0.1234, -0.2)
    X = s.world(p)
    c = cm.surface_reference(s, "table.top", X + [0, 0, 0.003])  # the ID buffer's depth error: 3 mm
    assert c.reference == "table.top@top:0.1234,-0.2000" and c.face == "top"
    assert np.linalg.norm(c.world - X) < ROUND_M
    # Another face, found as the nearest to the point; the point off it by the rounding at most.
    front, fx, fy = (s.world(face_point(s, "cabinet", "front", *st)) for st in ((0.05, 0.1), (0.15, 0.1), (0.05, 0.2)))
    normal = np.cross(fx - front, fy - front)
    side = cm.surface_reference(s, "cabinet", front + 0.003 * normal / np.linalg.norm(normal))
    assert side.reference == "cabinet@front:0.0500,0.1000"  # the face nearest the point
    again = cm.surface_reference(s, "cabinet", side.world)
    assert again.reference == side.reference  # a reference's point gives the same reference


def test_a_photo_pixel_is_the_command_lines_pick(solved):
    project, s = solved
    c = cm.photo_reference(project, s, "p1", (800, 600))
    assert c.node == "table.top" and c.face == "top"
    from vebuild.analysis.points import parse_point
    from vebuild.project.decode import photo_camera

    picked = parse_point("photo:p1@800.00,600.00", s, resolve_camera=lambda k, n: photo_camera(project, n))
    assert np.linalg.norm(s.world(picked) - c.world) < ROUND_M


def test_measurements_run_the_requests_and_their_records_run_again(solved):
    project, s = solved
    a, b = cm.photo_reference(project, s, "p1", (800, 600)), cm.photo_reference(project, s, "p1", (400, 900))
    data = {"analyses": [{"name": "clicked distance 1", "command": ["checks"]}]}
    for kind, clicks in (("distance", [a, b]), ("height", [a]), ("dimension", [a])):
        m = cm.measure(project, kind, clicks)
        rec = cm.save_analysis(data, m)
        _, again = run_recorded(project, 0, rec)
        assert again.table == m.result.table
        row = m.result.figures["measurements"][0]
        assert f"{row['value_m']:.4f} m (1σ {1000 * row['sigma_m']:.2f} mm, 95 % [{row['ci95_m'][0]:.4f}, " \
               f"{row['ci95_m'][1]:.4f}] m)" in m.label
        lo, hi = row["ci95_m"]
        assert hi - lo == pytest.approx(2 * 1.959964 * row["sigma_m"], rel=1e-5)
    assert [r["name"] for r in data["analyses"]] == ["clicked distance 1", "clicked distance 2", "clicked height 1",
                                                      "clicked dimension 1"]
    with pytest.raises(cm.ClickError, match="a distance needs 2 clicked points"):
        cm.measure(project, "distance", [a])
    with pytest.raises(cm.ClickError, match="no measurement 'area'"):
        cm.measure(project, "area", [a])


def test_trajectories_from_two_holes_and_from_a_hole_and_a_direction(solved):
    project, s = solved
    a, b = cm.photo_reference(project, s, "p1", (800, 600)), cm.photo_reference(project, s, "p1", (400, 900))
    m = cm.trajectory(project, a, b)
    words = m.command
    sa, sb = (float(v) for v in words[words.index("--sigma") + 1].split(","))
    assert 0 < sa < 0.005 and 0 < sb < 0.005
    assert sa == pytest.approx(cm.hole_sigma(s, a), abs=1e-5)
    _, again = run_recorded(project, 0, {"name": "t", "command": words})
    assert again.table == m.result.table
    d = cm.trajectory(project, a, direction=[1.0, 1.0, -math.sqrt(2)])
    assert d.command[-4:] == ["--azimuth", "45", "--elevation", "-45"]
    assert cm.direction_angles([0, -1, 0]) == (-90.0, 0.0)
    with pytest.raises(cm.ClickError, match="an exit hole or a direction"):
        cm.trajectory(project, a)


def test_markers_are_placed_and_removed(solved):
    _, s = solved
    data: dict = {"evidence_markers": [{"label": "E1", "position": [1, 1, 0], "node": "floor"}]}
    rec = cm.place_marker(data, "floor", [2.0, 1.0, 0.0])
    assert rec == {"label": "E2", "position": [2.0, 1.0, 0.0], "node": "floor"}
    assert cm.marker_near(data, [("E1", 100, 100), ("E2", 130, 100)], (126, 103)) == "E2"
    assert cm.marker_near(data, [("E1", 100, 100)], (120, 100)) is None
    cm.remove_marker(data, "E1")
    assert [m["label"] for m in data["evidence_markers"]] == ["E2"]
    with pytest.raises(cm.ClickError, match="no evidence marker is labelled 'E9'"):
        cm.remove_marker(data, "E9")
    with pytest.raises(cm.ClickError, match="not a place for a marker"):
        cm.place_marker(data, "floor", [float("nan"), 0, 0])


def test_bad_clicks_are_clear_errors(solved, tmp_path):
    project, s = solved
    with pytest.raises(cm.ClickError, match="from every face of 'table.top'"):
        cm.surface_reference(s, "table.top", [0.0, 0.0, 2.0])
    with pytest.raises(cm.ClickError, match="'table' is a group with no surface"):
        cm.surface_reference(s, "table", [0.0, 0.0, 0.0])
    with pytest.raises(cm.ClickError, match="'sofa' is not a node"):
        cm.surface_reference(s, "sofa", [0.0, 0.0, 0.0])
    with pytest.raises(cm.ClickError, match="meets no surface|lies outside"):
        cm.photo_reference(project, s, "p1", (5000, 5))
    shutil.copytree(example_project_dir(), tmp_path / "room")
    with pytest.raises(cm.ClickError, match="measuring needs a solved model"):
        cm.solved_model(load_project(tmp_path / "room" / "room.vebuild.json"))


def test_a_clicked_measurement_appears_in_the_report(solved, tmp_path):
    """The report's section of recorded analyses runs the clicked record again and shows its figure."""
    from vebuild.report.page import Report
    from vebuild.report.sections import analyses

    project, s = solved
    a, b = cm.photo_reference(project, s, "p1", (800, 600)), cm.photo_reference(project, s, "p1", (400, 900))
    m = cm.measure(project, "distance", [a, b])
    data = dict(project.data)
    cm.save_analysis(data, m)
    shown = dataclasses.replace(project, data=data)  # the module's project stays as it is
    rep = Report(tmp_path)
    (tmp_path / "images").mkdir()
    analyses(shown, rep)
    (html,) = rep.sections
    value = m.result.figures["measurements"][0]["value_m"]
    assert "clicked distance 1" in html and f"{value:.4f}" in html and a.reference in html
