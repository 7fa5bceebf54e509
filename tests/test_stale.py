"""Stale results (vebuild.project.provenance): each stage records what it was computed from, and a
result whose inputs changed is named as stale, with why and the command that updates it, by the
commands, the screens' status lines and the report; a re-run on unchanged inputs, or a change to
something that is no stage's input, leaves every result current."""

from __future__ import annotations

import contextlib
import io
import json
import shutil
from pathlib import Path

import pytest
from PIL import Image

from vebuild.cli import main
from vebuild.project import load_project
from vebuild.project.provenance import stale, stale_line, stamp

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"
PROJECT = "room.vebuild.json"
#: How far the mark is moved after calibrating (the issue's example): far more than any click's
#: noise, so that no one would call the old calibration current.
MOVED_PX = 150.0


def run(*words: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(words))
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example room calibrated, solved and textured (coarsely: provenance, not pixels, is tested)."""
    folder = tmp_path_factory.mktemp("stale") / "room"
    shutil.copytree(ROOM, folder)
    p = str(folder / PROJECT)
    for words in (["calibrate", p, "--quiet"], ["solve", p], ["texture", p, "--quiet", "--density", "20"]):
        code, _, err = run(*words)
        assert code == 0, err
    return folder


@pytest.fixture
def room(made: Path, tmp_path: Path) -> Path:
    """A copy of the made room to change: its project file."""
    folder = tmp_path / "room"
    shutil.copytree(made, folder)
    return folder / PROJECT


def edit(path: Path, change) -> dict:
    """Change the project file by hand (outside vebuild); the changed document."""
    data = json.loads(path.read_text(encoding="utf-8"))
    change(data)
    path.write_text(json.dumps(data, indent=2), encoding="utf-8")
    return data


def stages(data: dict) -> list[str]:
    return [s.stage for s in stale(data)]


def test_the_made_room_is_current(room: Path) -> None:
    data = json.loads(room.read_text(encoding="utf-8"))
    for stage in ("calibration", "model_solution", "textures"):
        assert data[stage]["computed_from"], stage
    assert stale(data) == []
    code, out, err = run("check", str(room))
    assert code == 0, out + err
    assert ": valid vebuild project" in out
    assert "current: calibration, model_solution, textures" in out


def test_marks_moved_after_calibrating_make_every_stage_stale(room: Path) -> None:
    def move(d: dict) -> None:
        d["photos"][1]["marker_observations"]["T1"][0] += MOVED_PX
    data = edit(room, move)
    found = stale(data, str(room))
    assert [s.stage for s in found] == ["calibration", "model_solution", "textures"]
    assert found[0].reason == "the marks of photo p2 changed after calibrating"
    assert found[0].command == f"vebuild calibrate {room}"
    assert "computed from the calibration, which is stale (the marks of photo p2 changed" in found[1].reason
    assert found[1].command == f"vebuild calibrate {room} && vebuild solve {room}"
    assert found[2].command.endswith(f"vebuild solve {room} && vebuild texture {room}")

    code, _, err = run("solve", str(room))  # it still runs: the user may want the old calibration's model
    assert code == 0, err
    assert "warning: the calibration is stale: the marks of photo p2 changed after calibrating; run " \
           f"`vebuild calibrate {room}`" in err
    after = json.loads(room.read_text(encoding="utf-8"))
    assert stages(after) == ["calibration", "model_solution", "textures"]  # solved on a stale calibration

    code, out, _ = run("check", str(room))
    assert code == 1
    assert ": stale vebuild project" in out
    assert "stale: the calibration is stale: the marks of photo p2" in out

    for words in (["calibrate", str(room), "--quiet"], ["solve", str(room)]):
        assert run(*words)[0] == 0
    assert stages(json.loads(room.read_text(encoding="utf-8"))) == ["textures"]


def test_geometry_changed_after_texturing_makes_the_textures_stale(room: Path) -> None:
    def widen(d: dict) -> None:
        cabinet = next(n for n in d["model"]["nodes"] if n["name"] == "cabinet")
        cabinet["primitive"]["params"]["width"] *= 2
    data = edit(room, widen)
    found = {s.stage: s for s in stale(data, str(room))}
    assert set(found) == {"model_solution", "textures"}  # the calibration read no model
    assert found["textures"].reason.startswith("node cabinet of the model changed after texturing")
    assert found["model_solution"].reason == "node cabinet of the model changed after solving"

    out = room.parent / "doorway.png"
    code, _, err = run("render", str(room), "--view", "doorway", "--out", str(out), "--size", "64x36")
    assert code == 0, err
    assert "warning: the textures are stale: node cabinet of the model changed after texturing" in err
    with Image.open(out) as im:
        text = dict(im.text)
    assert set(json.loads(text["vebuild:stale"])) == {"model_solution", "textures"}
    assert set(json.loads(text["vebuild:stages"])) == {"calibration", "model_solution", "textures"}

    report = room.parent / "report"
    code, _, err = run("report", str(room), "--out", str(report), "--no-pdf", "--quiet")
    assert code == 0, err
    page = (report / "report.html").read_text(encoding="utf-8")
    body = page[page.index("<body>"):]
    assert body.index("class='stale-banner'") < body.index("<h1>")  # at the top
    assert "the textures are stale: node cabinet of the model changed after texturing" in page
    assert "@top-center" in page and "STALE RESULTS (model&#x27;s solution, textures)" not in page
    assert "content: \"STALE RESULTS (model's solution, textures)" in page  # the PDF's every page
    record = page[page.index("<h2>Processing record</h2>"):]
    assert "<td>stale</td>" in record and "<td>current</td>" in record


def test_a_current_report_has_no_banner(room: Path) -> None:
    from vebuild.report.stale import banner_css, banner_html

    project = load_project(room)
    assert banner_html(project) == "" and banner_css(project) == ""


def test_a_camera_removed_after_solving_makes_the_solution_stale(room: Path) -> None:
    data = edit(room, lambda d: d["calibration"]["cameras"].pop("p3"))
    found = {s.stage: s for s in stale(data)}
    assert set(found) == {"model_solution", "textures"}  # the calibration's inputs are as they were
    assert found["model_solution"].reason == "the calibrated camera of photo p3 was removed after solving"
    assert "the camera of photo p3 was removed after texturing" in found["textures"].reason


def test_a_rerun_on_unchanged_inputs_leaves_each_stage_current(room: Path) -> None:
    before = json.loads(room.read_text(encoding="utf-8"))
    code, _, err = run("calibrate", str(room), "--quiet")
    assert code == 0 and err == "", err
    data = json.loads(room.read_text(encoding="utf-8"))
    assert data["calibration"]["cameras"] == before["calibration"]["cameras"]  # the same figures
    assert data["calibration"]["computed_from"] == before["calibration"]["computed_from"]
    assert stale(data) == []
    code, _, err = run("solve", str(room))
    assert code == 0 and err == "", err  # no stale warning
    # The re-run gives the recorded figures within the solver's tolerance, so the recorded solution
    # stands (vebuild.actions.solve.reproduces) and the textures made from it stay current.
    data = json.loads(room.read_text(encoding="utf-8"))
    assert data["model"] == before["model"] and data["model_solution"] == before["model_solution"]
    assert stale(data) == []
    code, _, err = run("texture", str(room), "--quiet", "--density", "20")
    assert code == 0 and err == "", err
    assert stale(json.loads(room.read_text(encoding="utf-8"))) == []


def test_a_later_stage_never_makes_an_earlier_one_stale(room: Path) -> None:
    assert run("texture", str(room), "--quiet", "--density", "10")[0] == 0  # other options: new textures
    assert stale(json.loads(room.read_text(encoding="utf-8"))) == []
    assert run("solve", str(room), "--recalibrate")[0] == 0  # re-calibrated cameras: a new solution
    assert stages(json.loads(room.read_text(encoding="utf-8"))) == ["textures"]


def test_views_analyses_and_other_non_inputs_leave_everything_current(room: Path) -> None:
    def add(d: dict) -> None:
        d["name"] = "renamed"
        d["views"].append({**d["views"][0], "name": "another"})
        d["analyses"] = [{"name": "cabinet to table", "command": ["distance", "cabinet:v4", "table.top:v4"]}]
        d["lighting"]["presets"].append({**d["lighting"]["presets"][0], "name": "dusk"})
        d["evidence_markers"] = [{"label": "A", "position": [2.0, 2.0, 0.0], "node": "floor"}]
        d["hypotheses"] = [{"name": "moved", "joints": {}}]
    data = edit(room, add)
    assert stale(data) == []
    code, out, _ = run("check", str(room))
    assert "stale" not in out
    # The hand edit changed no input; the audit trail sees it all the same.
    assert code == 1 and ": valid vebuild project" in out and "changed outside vebuild" in out


def test_a_record_from_before_provenance_is_not_known_to_be_current(room: Path) -> None:
    data = edit(room, lambda d: d["textures"].pop("computed_from"))
    (s,) = stale(data, "P")
    assert s.stage == "textures"
    assert "not known to be current" in s.reason
    assert s.command == "vebuild texture P"


def test_registering_a_photo_keeps_the_other_photos_stale(room: Path) -> None:
    def move(d: dict) -> None:
        d["photos"][1]["marker_observations"]["T1"][0] += MOVED_PX
    data = edit(room, move)
    stamp(data, "calibration", photos=["p3"])  # what vebuild register does for the photo it places
    assert stale(data)[0].reason == "the marks of photo p2 changed after calibrating"
    next(iter(data["photos"][2]["marker_observations"].values()))[0] += MOVED_PX
    assert stale(data)[0].reason == "the marks of photo p2 changed after calibrating; the marks of photo p3 " \
                                    "changed after calibrating"
    stamp(data, "calibration", photos=["p3"])
    assert stale(data)[0].reason == "the marks of photo p2 changed after calibrating"


def test_the_modelling_screen_shows_a_stale_line(room: Path) -> None:
    from vebuild.edit.session import EditSession

    s = EditSession(load_project(room, verify_photos=False), autosave=False)
    assert s.stale == [] and stale_line(s.stale) is None
    u, v = s.data["photos"][1]["marker_observations"]["T1"]
    s.place_marker("p2", "T1", (u + MOVED_PX, v))
    assert [x.stage for x in s.stale] == ["calibration", "model_solution", "textures"]
    assert stale_line(s.stale) == ("STALE: calibration, model's solution, textures: calibrate then solve then "
                                   "texture again")
    s.calibrate()  # the screen's Calibrate runs the same action, which records what it read
    found = {x.stage: x for x in s.stale}
    assert set(found) == {"model_solution", "textures"}
    assert "changed after solving" in found["model_solution"].reason


def test_the_walk_through_panel_lists_stale_results(room: Path) -> None:
    from vebuild.viewer.panel import stale_lines

    assert stale_lines(load_project(room)) == []
    edit(room, lambda d: d["model"]["pins"].pop())
    lines = stale_lines(load_project(room))
    assert lines[0] == "STALE: model's solution, textures: solve then texture again"
    assert lines[1].startswith("the model's solution is stale: the model's pins changed after solving; "
                               "run `vebuild solve")


def test_a_registered_photo_is_stamped_with_its_pins(tmp_path: Path) -> None:
    folder = tmp_path / "room"
    shutil.copytree(ROOM, folder)
    path = folder / PROJECT
    edit(path, lambda d: d["photos"][4].update(vanishing_segments={}))  # p5 is left to `vebuild register`
    for words in (["calibrate", str(path), "--quiet"], ["solve", str(path)], ["register", str(path), "p5"]):
        code, _, err = run(*words)
        assert code == 0, err
    data = json.loads(path.read_text(encoding="utf-8"))
    assert "photos/p5/pins" in data["calibration"]["computed_from"]
    assert "photos/p1/pins" not in data["calibration"]["computed_from"]  # p1 was not placed from the model
    (s,) = stale(data)  # the new camera is one the solution did not have
    assert (s.stage, s.reason) == ("model_solution", "the calibrated camera of photo p5 was added after solving")

    def move_pin(d: dict) -> None:
        next(p for p in d["model"]["pins"] if p["photo"] == "p5")["uv"][0] += MOVED_PX
    found = stale(edit(path, move_pin))
    assert found[0].stage == "calibration" and found[0].reason == "the pins of photo p5 changed after calibrating"


def test_the_glb_and_the_video_of_a_stale_project_say_so(room: Path) -> None:
    """Every output made from a stale result records it: the glTF's ``asset.extras`` and the MP4's
    comment carry the stage hashes they used and the stale stages with their reasons."""
    import av

    from vebuild.project.provenance import stage_hashes

    current = json.loads(room.read_text(encoding="utf-8"))
    glb = room.parent / "room.glb"
    assert run("export", str(room), "--out", str(glb))[0] == 0
    extras = _glb_json(glb)["asset"]["extras"]
    assert extras["stale"] == {} and extras["stages"] == stage_hashes(current)

    edit(room, lambda d: next(n for n in d["model"]["nodes"] if n["name"] == "cabinet")["primitive"]["params"]
         .update(width=1.0))
    code, _, err = run("export", str(room), "--out", str(glb))
    assert code == 0 and "warning: the textures are stale" in err
    assert set(_glb_json(glb)["asset"]["extras"]["stale"]) == {"model_solution", "textures"}

    mp4 = room.parent / "walk.mp4"
    code, _, err = run("video", str(room), "--views", "doorway,overview", "--out", str(mp4), "--size", "64x48",
                       "--fps", "4", "--seconds", "0.5", "--quiet")
    assert code == 0, err
    with av.open(str(mp4)) as f:
        comment = json.loads(f.metadata["comment"])
    assert set(comment["stale"]) == {"model_solution", "textures"}
    assert set(comment["stages"]) == {"calibration", "model_solution", "textures"}


def _glb_json(path: Path) -> dict:
    import struct

    data = path.read_bytes()
    length, kind = struct.unpack_from("<II", data, 12)
    assert kind == 0x4E4F534A  # "JSON"
    return json.loads(data[20:20 + length])
