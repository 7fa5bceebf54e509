"""A one-photo project calibrated with no scale has lengths in relative units (the camera's height
above the floor is 1): no output shows or writes them as metres, and what needs metres says why it
cannot be done. Each output is checked on such a project and, where it differs, against the same
project given a scale (metres), so that a test passing on both would fail."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from cli_capture import run_cli
from one_photo_scene import BOX_M, box_on_the_floor, one_photo, write_one_photo

from vebuild.project import load_project, save_project
from vebuild.project.units import METRES, RELATIVE, RELATIVE_UNITS, length_unit, record_unit

#: What every table of a relative project says of its lengths.
NOTE = "lengths are RELATIVE (relative units: the camera height is 1: no scale was given"


@dataclass
class Built:
    path: Path
    camera_height: float  # the truth, metres: relative lengths are metres / this


def _build(folder: Path, *, scale: bool) -> Built:
    """A one-photo project (the door's height as its scale, or none) with a box resting on the floor
    pinned at its visible corners, calibrated and solved from the command line; a check distance
    between two floor markers and a named view."""
    rng = np.random.default_rng(81)
    ph = one_photo(rng)
    path = write_one_photo(folder, ph, known_length=scale)
    project = load_project(path)
    node, pins = box_on_the_floor(ph, rng)
    foot = ph.truth("box_foot")
    start = json.loads(json.dumps(node))
    start["primitive"]["params"] = {"width": 0.5, "depth": 0.5, "height": 0.8}
    project.data["model"] = {"nodes": [start], "pins": pins}
    dist = float(np.linalg.norm(ph.points["F1"] - ph.points["F2"]))
    project.data["reference_distances"] = [{"a": "F1", "b": "F2", "distance": round(dist, 4), "sigma": 0.002,
                                            "role": "check"}]
    C = ph.C / (1.0 if scale else ph.C[2])
    project.data["views"] = [{"name": "front", "position": [float(v) for v in C],
                              "look_at": [float(foot[0]), float(foot[1]), 0.0], "width": 320, "height": 240}]
    save_project(project)
    from vebuild.cli import main

    assert main(["calibrate", str(path), "--quiet"]) == 0
    assert main(["solve", str(path)]) == 0
    return Built(path, float(ph.C[2]))


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Built]:
    return {"relative": _build(tmp_path_factory.mktemp("relative"), scale=False),
            "metres": _build(tmp_path_factory.mktemp("metres"), scale=True)}


# -- the helper ------------------------------------------------------------------------------------


def test_length_unit_follows_the_calibration() -> None:
    assert length_unit({}) is METRES  # before calibration lengths are the user's: metres
    assert length_unit({"calibration": {"lengths": "metres", "cameras": {}}}) is METRES
    assert length_unit({"calibration": {"lengths": "relative", "cameras": {}}}) is RELATIVE
    assert length_unit({"calibration": {"cameras": {"p": {"placement": {"lengths": "relative"}}}}}) is RELATIVE
    assert record_unit({"lengths": "relative"}) is RELATIVE and record_unit({}) is METRES
    assert RELATIVE.length(1.23456) == "1.235 (relative units: the camera height is 1)"
    assert METRES.length(1.23456) == "1.235 m"
    assert RELATIVE.keyed({"a_m": [{"b_m2": 1}], "c_m3": 2, "d": 3, "sum": 4}) == \
        {"a_relative": [{"b_relative2": 1}], "c_relative3": 2, "d": 3, "sum": 4}
    assert METRES.keyed({"a_m": 1}) == {"a_m": 1}
    assert METRES.note == "" and RELATIVE.note.startswith(NOTE)
    METRES.refuse("anything")  # metres: nothing refused
    with pytest.raises(Exception, match=r"^an eye height is in metres, but this project's lengths are relative "
                       r"\(relative units: the camera height is 1: no scale was given\), so it has no meaning here; "
                       r"give the photo a scale \(its camera_height, a known length in it, or a scale distance "
                       r"between two floor markers\) and run `vebuild calibrate` again for metres$"):
        RELATIVE.refuse("an eye height")


# -- calibrate and solve ---------------------------------------------------------------------------


def test_calibration_table_and_record_say_relative(built: dict[str, Built]) -> None:
    from vebuild.console.tables import calibration_table

    for kind, b in built.items():
        cal = load_project(b.path).data["calibration"]
        placement = cal["cameras"]["p"]["placement"]
        text = calibration_table(cal)
        if kind == "relative":
            assert placement["camera_height_relative"] == {"value": 1.0, "sigma": None}
            assert "camera_height_m" not in placement
            assert "markers (relative units: the camera height is 1):" in text and "markers (m):" not in text
            assert "reference distances (known in m; measured in relative units: the camera height is 1, so not " \
                   "compared):" in text
            assert "(relative units)" in text.split("F1–F2")[1].splitlines()[0] and " mm" not in text
        else:
            assert placement["camera_height_m"]["value"] == pytest.approx(b.camera_height, rel=0.02)
            assert "markers (m):" in text and "difference" in text and "relative" not in text


def test_solve_output_and_its_solution_record_say_relative(built: dict[str, Built],
                                                           capsys: pytest.CaptureFixture) -> None:
    for kind, b in built.items():
        r = run_cli(capsys, "solve", str(b.path))
        assert r.returncode == 0, r.stderr
        sol = load_project(b.path).data["model_solution"]
        assert sol["lengths"] == kind
        height = sol["nodes"]["box"]["params"]["height"]
        if kind == "relative":
            assert "; lengths are RELATIVE (no scale given: the camera's height is 1)" in r.stdout
            assert "height " in r.stdout and " (relative units)" in r.stdout
            assert not re.search(r"\d m\b", r.stdout)  # no figure in metres
            # In units of the camera's height: the box's true height divided by it.
            assert height["value"] == pytest.approx(BOX_M / b.camera_height, rel=0.03)
        else:
            assert "RELATIVE" not in r.stdout and f"height {height['value']:.4f} ± " in r.stdout
            assert height["value"] == pytest.approx(BOX_M, rel=0.03)


# -- analyse ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("words", [["distance", "box:v0", "box:v6"], ["height", "box:v6"],
                                   ["dimensions", "box"]], ids=["distance", "height", "dimensions"])
def test_measurements_are_in_relative_units(built: dict[str, Built], capsys: pytest.CaptureFixture,
                                            tmp_path: Path, words: list[str]) -> None:
    for kind, b in built.items():
        out = tmp_path / f"{kind}.json"
        r = run_cli(capsys, "analyse", str(b.path), *words, "--json", str(out))
        assert r.returncode == 0, r.stderr
        doc = json.loads(out.read_text())
        assert doc["lengths"] == kind
        m = doc["measurements"][0]
        if kind == "relative":
            assert {"value_relative", "sigma_relative", "ci95_relative"} <= set(m) and "value_m" not in m
            assert all("position_m" not in p for p in m["points"])
            assert "value rel." in r.stdout and "value m" not in r.stdout and NOTE in r.stdout
            assert f"{m['value_relative']:.4f}" in r.stdout
        else:
            assert "value_m" in m and "value m" in r.stdout and "RELATIVE" not in r.stdout


def test_check_distances_are_not_compared_in_relative_units(built: dict[str, Built], capsys: pytest.CaptureFixture,
                                                            tmp_path: Path) -> None:
    out = tmp_path / "c.json"
    r = run_cli(capsys, "analyse", str(built["relative"].path), "checks", "--json", str(out))
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("the 1 check distance is not compared: " + NOTE)
    doc = json.loads(out.read_text())
    assert doc["checks"] == [] and doc["not_compared"][0]["a"] == "F1" and doc["lengths"] == "relative"
    r = run_cli(capsys, "analyse", str(built["metres"].path), "checks")
    assert r.returncode == 0, r.stderr and "known m" in r.stdout


def test_single_view_heights_are_in_relative_units(built: dict[str, Built], capsys: pytest.CaptureFixture,
                                                   tmp_path: Path) -> None:
    out = tmp_path / "h.json"
    r = run_cli(capsys, "analyse", str(built["relative"].path), "photo-height", "--photo", "p", "700", "700", "700",
             "600", "--json", str(out))
    assert r.returncode == 0, r.stderr
    doc = json.loads(out.read_text())
    assert doc["lengths"] == "relative" and "value_relative" in doc["measurements"][0]
    assert NOTE in r.stdout and "value m" not in r.stdout


def _eye(b: Built) -> str:
    """An eye a little beside the solved box (the whole scene), at its top's height, as --eye."""
    handles = load_project(b.path).data["model_solution"]["nodes"]["box"]["handles"].values()
    X = np.array([h["value"] for h in handles])
    lo, hi = X.min(axis=0), X.max(axis=0)
    eye = [hi[0] + 0.5 * (hi[0] - lo[0]), 0.5 * (lo[1] + hi[1]), 0.9 * hi[2]]
    return ",".join(f"{v:.4f}" for v in eye)


def test_sightline_and_trajectory_in_relative_units_and_what_needs_metres_is_refused(
        built: dict[str, Built], capsys: pytest.CaptureFixture, tmp_path: Path) -> None:
    path = str(built["relative"].path)
    out = tmp_path / "s.json"
    r = run_cli(capsys, "analyse", path, "sightline", "--eye=" + _eye(built["relative"]), "--object", "box", "--json",
             str(out))
    assert r.returncode == 0, r.stderr
    doc = json.loads(out.read_text())
    assert doc["lengths"] == "relative" and "distance_relative" in doc["sightline"]
    assert not [k for k in json.dumps(doc).split('"') if k.endswith("_m")]
    assert " rel. (to the centre of its surface)" in r.stdout and NOTE in r.stdout
    for words, what in ((["sightline", "--standing", "0,0", "--object", "box"],
                         "sightline --standing: a person's eye height"),
                        (["sightline", "--sitting", "0,0", "--object", "box"], "sightline --sitting: a person's eye "
                         "height"),
                        (["viewshed", "--object", "box", "--out", str(tmp_path / "v.png")],
                         "viewshed: the eye height (1.6) and the grid's cell (0.1)"),
                        (["trajectory", "--from", "box:v6", "--to", "box:v0", "--sigma", "0.005"],
                         "trajectory --sigma 0.005: the holes' position error (give the cone's half-angle, --cone "
                         "DEG, instead)")):
        r = run_cli(capsys, "analyse", path, *words)
        assert r.returncode == 2, words
        assert r.stderr.strip().endswith(f"{what} is in metres, but this project's lengths are relative "
                                         f"({RELATIVE_UNITS}: no scale was given), so it has no meaning here; give "
                                         "the photo a scale (its camera_height, a known length in it, or a scale "
                                         "distance between two floor markers) and run `vebuild calibrate` again for "
                                         "metres"), r.stderr
    out = tmp_path / "t.json"
    r = run_cli(capsys, "analyse", path, "trajectory", "--from", "box:v6", "--to", "box:v0", "--cone", "1",
             "--json", str(out))
    assert r.returncode == 0, r.stderr
    doc = json.loads(out.read_text())
    assert doc["lengths"] == "relative" and not [k for k in json.dumps(doc).split('"') if k.endswith("_m")]
    assert " rel. apart" in r.stdout and "distance rel." in r.stdout and NOTE in r.stdout
    # The same sight line in metres keeps its metres.
    r = run_cli(capsys, "analyse", str(built["metres"].path), "sightline", "--eye=" + _eye(built["metres"]), "--object",
             "box")
    assert r.returncode == 0, r.stderr
    assert " m (to the centre of its surface)" in r.stdout and "RELATIVE" not in r.stdout


# -- the report, render provenance, exports --------------------------------------------------------


def test_report_sections_say_relative(built: dict[str, Built], tmp_path: Path) -> None:
    from vebuild.report import sections
    from vebuild.report.analyses import analyses_html
    from vebuild.report.page import Report

    for kind, b in built.items():
        project = load_project(b.path)
        rep = Report(tmp_path / kind)
        (rep.folder / "images").mkdir(parents=True)
        sections.calibration(project, rep)
        sections.model(project, rep)
        sections.checks(project, rep)
        sections.views(project, rep)  # the named view rendered (headless GL), its caption
        html = "".join(rep.sections) + analyses_html(project, rep, [{"name": "h", "command": ["height", "box:v6"]}])
        if kind == "relative":
            assert "position x / y / z rel." in html and "position x / y / z m" not in html
            assert "Lengths in relative units: the camera height is 1 (no scale was given)" in html
            assert "Lengths in metres" not in html and "known m</th><th>measured rel." in html
            assert "difference m" not in html and "value rel." in html
            assert f"eye at ({RELATIVE_UNITS})" not in html and f") ({RELATIVE_UNITS})</figcaption>" in html
        else:
            assert "position x / y / z m" in html and "Lengths in metres" in html and "relative" not in html


def test_render_provenance_and_stereo_in_relative_units(built: dict[str, Built], tmp_path: Path) -> None:
    from vebuild.actions.render import RenderRequest, render_evidence
    from vebuild.errors import VebuildError
    from vebuild.project.decode import find_view
    from vebuild.render.png import provenance

    for kind, b in built.items():
        project = load_project(b.path)
        text = provenance(project, find_view(project, "front"), "view", "as-photographed", None, [], {})
        assert text["vebuild:lengths"] == (RELATIVE_UNITS if kind == "relative" else "metres")
    project = load_project(built["relative"].path)
    with pytest.raises(VebuildError, match=r"^render --stereo: the eyes' separation \(0\.063\) is in metres, but "
                       r"this project's lengths are relative"):
        render_evidence(project, RenderRequest(out=tmp_path / "s.png", view="front", stereo="sbs"))


def test_exports_state_relative_units(built: dict[str, Built], tmp_path: Path) -> None:
    from vebuild.render.export import export_model

    for kind, b in built.items():
        project = load_project(b.path)
        glb = tmp_path / f"{kind}.glb"
        export_model(project, glb)
        data = glb.read_bytes()
        n = int.from_bytes(data[12:16], "little")
        doc = json.loads(data[20:20 + n])
        units = doc["asset"]["extras"]["units"]
        obj = tmp_path / f"{kind}.obj"
        export_model(project, obj)
        head = obj.read_text().splitlines()[1]
        if kind == "relative":
            assert units == RELATIVE_UNITS
            assert f"right-handed, {RELATIVE_UNITS}, +Z up" in doc["nodes"][0]["extras"]["note"]
            assert head.startswith(f"# Units: {RELATIVE_UNITS}.")
        else:
            assert units == "metre" and head.startswith("# Units: metres.")


def test_a_walk_through_at_a_walking_speed_is_refused_in_relative_units(built: dict[str, Built],
                                                                       capsys: pytest.CaptureFixture) -> None:
    project = load_project(built["relative"].path)
    project.data["views"].append({**project.data["views"][0], "name": "back"})
    save_project(project)
    r = run_cli(capsys, "video", str(built["relative"].path), "--views", "front,back")
    assert r.returncode == 2
    assert r.stderr.strip().endswith("video: the walking speed (1 m/s; give --seconds per segment instead) is in "
                                     "metres, but this project's lengths are relative (relative units: the camera "
                                     "height is 1: no scale was given), so it has no meaning here; give the photo a "
                                     "scale (its camera_height, a known length in it, or a scale distance between two "
                                     "floor markers) and run `vebuild calibrate` again for metres"), r.stderr


def test_an_evidence_marker_is_placed_in_relative_units(built: dict[str, Built], capsys: pytest.CaptureFixture,
                                                        tmp_path: Path) -> None:
    for kind, b in built.items():
        top = load_project(b.path).data["model_solution"]["nodes"]["box"]["handles"]
        handles = np.array([h["value"] for h in top.values()])
        X = handles.mean(axis=0)
        X[2] = handles[:, 2].max()  # the centre of its top face
        r = run_cli(capsys, "mark", str(b.path), "A", "--at=" + ",".join(f"{v:.6f}" for v in X))
        assert r.returncode == 0, r.stderr
        at = f"({X[0]:.3f}, {X[1]:.3f}, {X[2]:.3f})"
        assert f"on 'box' at {at} {'(' + RELATIVE_UNITS + ')' if kind == 'relative' else 'm'}, written to" in r.stdout


def test_refusals_of_points_off_the_scene_or_off_a_face_speak_the_project_s_unit(
        built: dict[str, Built], capsys: pytest.CaptureFixture) -> None:
    for kind, b in built.items():
        u = "rel." if kind == "relative" else "m"
        r = run_cli(capsys, "analyse", str(b.path), "sightline", "--eye=50,50,1", "--object", "box")
        assert r.returncode == 2
        assert "the eye point (50, 50, 1) is off the scene: the model spans x " in r.stderr
        assert f" {u} (points up to " in r.stderr and f" {u} outside it are accepted" in r.stderr
        assert (NOTE in r.stderr) == (kind == "relative")
        r = run_cli(capsys, "analyse", str(b.path), "distance", "box:v0", "box@top:5,5")
        assert r.returncode == 2
        assert f"point 'box@top:5,5': (5, 5) {u} from the centre of face 'top' of 'box' lies off that face (" \
            in r.stderr
        assert r.stderr.strip().endswith(f" {u})")


def test_the_texture_table_counts_texels_per_relative_unit() -> None:
    from vebuild.console.tables import texture_table

    record = {"faces": [{"node": "box", "face": "top", "rect": [0, 0, 64, 32], "texels_per_metre": [212.0, 210.0],
                         "seen_fraction": 0.5, "photos": ["p"]}],
              "photos": [{"id": "p", "order": 0, "gain": [1.0, 1.0, 1.0], "overlap_texels": 0}],
              "pages": [{"width": 64, "height": 64, "atlas": "a.png", "coverage": "c.png"}]}
    rel, met = texture_table(record, RELATIVE), texture_table(record)
    assert rel.splitlines()[0].split()[2] == "t/rel." and met.splitlines()[0].split()[2] == "t/m"
    assert rel.splitlines()[-1] == "texels per relative unit (t/rel.): " + RELATIVE.note and "RELATIVE" not in met
