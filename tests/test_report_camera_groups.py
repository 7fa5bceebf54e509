"""The report's "Final cameras" shows each re-calibrated camera group's shared intrinsics
(``model_solution.camera_groups``) with 1σ beside the calibration's (``calibration.camera_groups``):
a generated set of one camera (tests/camera_group_scene.py), calibrated as one group, a box pinned,
then `vebuild solve --recalibrate`."""

from __future__ import annotations

import html
import json
import re
import shutil
from pathlib import Path

import pytest
from camera_group_scene import camera_set, run_vebuild, with_box

from vebuild.project import load_project
from vebuild.report.cameras import final_cameras
from vebuild.report.page import Report
from vebuild.synthetic.shared import write_one_camera_project


def _tables(section: str) -> list[list[list[str]]]:
    """Each table of an HTML section as rows of cell texts (tags removed)."""
    out = []
    for t in re.findall(r"<table[^>]*>(.*?)</table>", section, re.S):
        rows = [[html.unescape(re.sub(r"<[^>]+>", "", c)).strip()
                 for c in re.findall(r"<t[dh][^>]*>(.*?)</t[dh]>", r, re.S)]
                for r in re.findall(r"<tr>(.*?)</tr>", t, re.S)]
        out.append(rows)
    return out


@pytest.fixture(scope="module")
def recalibrated(tmp_path_factory) -> Path:
    photos, markers = camera_set()
    path = write_one_camera_project(tmp_path_factory.mktemp("groups"), photos, markers)
    assert run_vebuild("calibrate", path, "--quiet").returncode == 0
    with_box(path)
    r = run_vebuild("solve", path, "--recalibrate")
    assert r.returncode == 0, r.stderr
    return path


def test_final_cameras_show_each_groups_recalibrated_intrinsics_beside_the_calibrations(recalibrated, tmp_path):
    doc = json.loads(recalibrated.read_text(encoding="utf-8"))
    [cal] = doc["calibration"]["camera_groups"]
    [final] = doc["model_solution"]["camera_groups"]
    rep = Report(tmp_path)
    final_cameras(load_project(recalibrated), rep)
    [section] = rep.sections
    assert "<h3>Camera groups re-calibrated</h3>" in section
    [table] = [t for t in _tables(section) if t[0][0] == "camera group"]
    header, *rows = table
    assert header == ["camera group", "photos", "focal px (calibration)", "focal px (final)",
                      "principal point px (calibration)", "principal point px (final)", "lens k1 (calibration)",
                      "lens k1 (final)"]
    [row] = rows
    cells = dict(zip(header, row, strict=True))
    assert cells["camera group"] == final["id"] == cal["id"]
    assert cells["photos"] == ", ".join(final["photos"])

    def pm(v: dict, digits: int) -> str:
        vals, sigs = (v["value"], v["sigma"]) if isinstance(v["value"], list) else ([v["value"]], [v["sigma"]])
        return " / ".join(f"{a:.{digits}f} ± {s:.{digits}f}" for a, s in zip(vals, sigs, strict=True))

    assert cells["focal px (calibration)"] == pm(cal["focal_px"], 1)
    assert cells["focal px (final)"] == pm(final["focal_px"], 1)
    assert cells["principal point px (calibration)"] == pm(cal["principal_point"], 1)
    assert cells["principal point px (final)"] == pm(final["principal_point"], 1)
    # k1: ± 1σ where solved for; held (σ 0 in the calibration's record, refined false in the solve's).
    c = cal["distortion"]
    assert cells["lens k1 (calibration)"] == (f"{c['k1']:+.4f} ± {c['sigma']:.4f}" if c["sigma"] else
                                              f"{c['k1']:+.4f} (held)")
    d = final["distortion"]
    assert cells["lens k1 (final)"] == (f"{d['k1']:+.4f} ± {d['sigma']:.4f}" if d["refined"] else
                                        f"{d['k1']:+.4f} (held)")
    # Two stages, two estimates: the re-calibration moved the values and did not widen their 1σ.
    assert cells["focal px (final)"] != cells["focal px (calibration)"]
    assert final["focal_px"]["sigma"] <= cal["focal_px"]["sigma"]


def test_without_a_recalibrated_group_no_group_table(recalibrated, tmp_path):
    path = tmp_path / "copy" / recalibrated.name
    shutil.copytree(recalibrated.parent, path.parent)
    assert run_vebuild("solve", path, "--recalibrate", "--fixed-intrinsics").returncode == 0
    assert "camera_groups" not in json.loads(path.read_text(encoding="utf-8"))["model_solution"]
    rep = Report(tmp_path)
    final_cameras(load_project(path), rep)
    assert "Camera groups re-calibrated" not in rep.sections[0]
    assert any(t[0][0] == "photo" for t in _tables(rep.sections[0]))  # the cameras are still shown
