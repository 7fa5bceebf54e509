"""What the solve's table prints for a value the solve did not estimate (held by its joint or a
relation: 1σ exactly 0): its value and "(held)", never "± 0.000" nor a negative zero; and what
`vebuild detect` calls its reference photo when no photo has markers."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from vebuild.cli import main
from vebuild.console.tables import model_table

EXAMPLE = Path(__file__).resolve().parents[1] / "scenes" / "room"


def _result(dofs: dict, params: dict) -> dict:
    return {"software": "vebuild test", "recalibrated": False, "lengths": "metres",
            "nodes": {"wall": {"joint": "rests_on", "dofs": dofs, "params": params}},
            "pins": [], "edge_observations": [], "rms_px": 0.0, "outliers": []}


def test_a_held_value_reads_held_and_a_solved_one_its_sigma() -> None:
    text = model_table(_result({"s": {"value": 2.55, "sigma": 0.0}, "yaw_deg": {"value": -0.0, "sigma": 0.0},
                                "t": {"value": 0.1234, "sigma": 0.002}},
                               {"width": {"value": 5.0, "sigma": 0.0}, "depth": {"value": 0.1, "sigma": 0.0021}}))
    line = next(x for x in text.splitlines() if x.startswith("wall"))
    assert line == "wall  [rests_on: s 2.550 (held), yaw_deg 0.000 (held), t 0.123 ± 0.002]"
    assert "width 5.0000 m (held), depth 0.1000 ± 0.0021 m" in text
    assert "± 0.000," not in text and "-0.000" not in text


def test_detect_with_no_marker_says_why_its_reference_photo_is_the_first(tmp_path: Path,
                                                                         capsys: pytest.CaptureFixture) -> None:
    shutil.copy(EXAMPLE / "photos" / "p1.jpg", tmp_path / "p1.jpg")
    project = tmp_path / "one.vebuild.json"
    assert main(["new", str(project), str(tmp_path / "p1.jpg")]) == 0
    assert main(["detect", str(project)]) == 0
    out = capsys.readouterr().out
    assert "the reference photo (the first: no photo has markers to choose another by)" in out
    assert "it sees the most markers" not in out
