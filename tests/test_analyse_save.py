"""`vebuild analyse … --save NAME`: a measurement made on the command line saved among the
project's analyses (as the screens' measuring tools save theirs), so that the report states it,
without the file being edited by hand; a name already taken is refused with nothing saved."""

from __future__ import annotations

import json

import numpy as np
from one_photo_scene import one_photo, write_one_photo

from vebuild.cli import main
from vebuild.project import load_project
from vebuild.report.findings import answers, run_analyses
from vebuild.report.page import Report


def test_a_saved_measurement_is_recorded_and_stated_by_the_report(tmp_path, capsys):
    ph = one_photo(np.random.default_rng(7))
    path = write_one_photo(tmp_path, ph)
    assert main(["calibrate", str(path), "--quiet"]) == 0
    (foot, top) = ph.clicks["box_foot"], ph.clicks["box_top"]
    words = ["photo-height", "--photo", "p", f"{foot[0]:.2f}", f"{foot[1]:.2f}", f"{top[0]:.2f}", f"{top[1]:.2f}"]
    out = tmp_path / "h.json"
    capsys.readouterr()
    assert main(["analyse", str(path), *words, "--json", str(out), "--save", "box height"]) == 0
    assert "saved as the analysis 'box height'" in capsys.readouterr().out
    data = json.loads(path.read_text())
    assert data["analyses"] == [{"name": "box height", "command": words}]  # neither --json nor --save kept
    assert data["audit"][-1]["command"] == "analyse"
    # The report's first page states it with the figures the command printed.
    project = load_project(path)
    (tmp_path / "rep").mkdir()
    rep = Report(tmp_path / "rep")
    run_analyses(project, rep)
    (said,) = answers(project, rep)
    m = json.loads(out.read_text())["measurements"][0]
    assert said.startswith("box height: ") and f"{m['value_m']:.3f} m, between {m['ci95_m'][0]:.3f}" in said
    # The same name again: refused, nothing saved, the file as it was.
    before = path.read_bytes()
    assert main(["analyse", str(path), *words, "--save", "box height"]) == 2
    assert "already has an analysis of that name" in capsys.readouterr().err
    assert path.read_bytes() == before
