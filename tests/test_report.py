"""`vebuild report`: everything in it re-computed from the project file, reproducible byte for byte."""

from __future__ import annotations

import json
import shutil

import pytest

from vebuild.cli import main
from vebuild.errors import ProjectError, VebuildError
from vebuild.project import load_project
from vebuild.report.write import digest, write_report


@pytest.fixture(scope="module")
def analysed_room(textured_room, tmp_path_factory):
    folder = tmp_path_factory.mktemp("report") / "room"
    shutil.copytree(textured_room.parent, folder)
    proj = folder / textured_room.name
    data = json.loads(proj.read_text())
    data["analyses"] = [
        {"name": "cabinet to table", "command": ["distance", "cabinet:v4", "table.top:v6"]},
        {"name": "check distances", "command": ["checks"]},
        {"name": "could a witness in the doorway see the box?", "command": ["sightline", "--standing", "3.7,0.4",
                                                                           "--object", "box"]},
        {"name": "a shot across the table", "command": ["trajectory", "--from", "1.0,3.0,1.2", "--to",
                                                        "2.0,2.8,1.0", "--view", "overview"]},
        {"name": "the table from the doorway", "command": ["lighting", "--view", "doorway", "--preset",
                                                           "ceiling lamp", "--preset", "night, torch",
                                                           "--target", "table.top", "--size", "480x270"]},
    ]
    data["evidence_markers"] = [{"label": "A", "position": [2.2, 2.7, 0.76], "node": "table.top",
                                 "description": "a glass"}]
    data["hypotheses"] = [{"name": "box by the door", "joints": {"box": {"type": "rests_on", "face": "top",
                                                                          "position": [1.0, -1.5], "yaw_deg": 0.0}}}]
    proj.write_text(json.dumps(data, indent=1))
    return proj


def test_the_report_holds_every_section_and_is_reproducible(analysed_room, tmp_path, capsys):
    out1, out2 = tmp_path / "r1", tmp_path / "r2"
    assert main(["report", str(analysed_room), "--out", str(out1), "--quiet"]) == 0
    assert "report written to" in capsys.readouterr().out
    page = (out1 / "report.html").read_text()
    project = load_project(analysed_room)
    for p in project.data["photos"]:
        assert p["sha256"] in page  # every photo with its hash
    for title in ("Photographs", "Calibration (vanishing points)", "Final cameras (re-calibrated with the model)",
                  "Reference and check distances", "Model", "Limitations", "Plan", "Evidence views",
                  "The photos as marked", "How well the model explains each photo", "Analyses", "Hypotheses"):
        assert f">{title}<" in page, title
    for k, rec in enumerate(json.loads(analysed_room.read_text())["analyses"], start=1):
        assert rec["name"] in page
        assert json.loads((out1 / "figures" / f"analysis-{k}.json").read_text())["command"] == rec["command"]
    assert all((out1 / "images" / f"analysis-{k}.png").is_file() for k in (3, 4, 5))
    assert "T2 – C1" in page and "check" in page  # the check distance, measured vs known
    # Each camera's lens: p6's barrel distortion with its 1σ and corner displacement, p1 a pinhole.
    cams = project.data["calibration"]["cameras"]
    d6 = cams["p6"]["distortion"]
    pm = "\u00a0±\u00a0"  # a value and its σ kept on one line
    assert (f"k1 {d6['k1']['value']:+.4f}{pm}{d6['k1']['sigma']:.4f}, corners "
            f"{d6['corner_displacement_px']['value']:.1f}") in page
    assert d6["k1"]["value"] < -0.02 and "distortion" not in cams["p1"]
    assert "<td>pinhole</td>" in page
    assert "HYPOTHESIS: box by the door (not the measured scene)" in page
    assert "a glass" in page and "vebuild 0." in page
    assert (out1 / "report.pdf").read_bytes().startswith(b"%PDF")
    # views, photos, analyses, hypothesis, the photos as marked; and the plan view
    assert len(list((out1 / "images").glob("*.png"))) >= 3 + 5 + 3 + 1 + 6
    assert (out1 / "images" / "plan.svg").is_file()
    # The same project gives the same report: numbers and images byte for byte.
    write_report(load_project(analysed_room), out2, pdf=False)
    assert digest(out1) == digest(out2)


def test_report_errors(analysed_room, tmp_path, textured_room):
    project = load_project(analysed_room)
    (tmp_path / "file").write_text("x")
    with pytest.raises(VebuildError, match="is a file; expected a folder"):
        write_report(project, tmp_path / "file", pdf=False)
    with pytest.raises(VebuildError, match="does not exist"):
        write_report(project, tmp_path / "no" / "where", pdf=False)
    project.data["analyses"][4]["command"][-3] = "box"  # not seen from the doorway
    with pytest.raises(ProjectError, match=r"\$.analyses\[4\].command: the target 'box' is not seen"):
        write_report(project, tmp_path / "r", pdf=False)
    project.data["analyses"][4]["command"] = ["lighting", "--vieww", "doorway"]
    with pytest.raises(ProjectError, match=r"\$.analyses\[4\].command: the following arguments are required"):
        write_report(project, tmp_path / "r", pdf=False)
    assert not (tmp_path / "r").exists() and not list(tmp_path.glob(".r.*"))  # nothing half-written
    bare = load_project(textured_room)
    bare.data.pop("calibration")
    with pytest.raises(VebuildError, match=r"no report yet: the photos are not calibrated yet; run `vebuild calibrate"):
        write_report(bare, tmp_path / "r", pdf=False)
