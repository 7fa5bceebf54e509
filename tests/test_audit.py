"""The audit trail (top-level ``audit``, vebuild.project.provenance): one entry per command that
changed the project, whose hashes a second examiner can verify with nothing but the documented
recipe; ``vebuild check`` verifies the chain and names an edit made outside vebuild."""

from __future__ import annotations

import contextlib
import copy
import datetime
import hashlib
import io
import json
import re
import shutil
from pathlib import Path

import pytest

from vebuild import __version__
from vebuild.cli import main
from vebuild.errors import ProjectError
from vebuild.project import load_project, save_project
from vebuild.project.provenance import command_context, verify_audit

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"
PROJECT = "room.vebuild.json"
TIME = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ$")


def run(*words: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(words))
    return code, out.getvalue(), err.getvalue()


def examiner_sha256(doc: dict) -> str:
    """The documented recipe (FORMAT.md, "Audit trail"), written out here rather than taken from vebuild."""
    rest = {k: v for k, v in doc.items() if k != "audit"}
    return hashlib.sha256(json.dumps(rest, sort_keys=True, separators=(",", ":"),
                                     ensure_ascii=False).encode("utf-8")).hexdigest()


def read(path: Path) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, list[list[str]], tuple[str, str]]:
    """The example room taken through calibrate, solve and texture: its folder, the document
    before, the commands' words and the UTC times around the run."""
    folder = tmp_path_factory.mktemp("audit") / "room"
    shutil.copytree(ROOM, folder)
    p = str(folder / PROJECT)
    original = read(folder / PROJECT)
    commands = [["calibrate", p, "--quiet"], ["solve", p], ["texture", p, "--quiet", "--density", "20"]]
    start = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    for words in commands:
        code, _, err = run(*words)
        assert code == 0, err
    end = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    return folder, original, commands, (start, end)


@pytest.fixture
def room(made, tmp_path: Path) -> Path:
    folder = tmp_path / "room"
    shutil.copytree(made[0], folder)
    return folder / PROJECT


def test_the_trail_after_calibrate_solve_texture_verifies(made) -> None:
    folder, original, commands, (start, end) = made
    doc = read(folder / PROJECT)
    trail = doc["audit"]
    assert [e["command"] for e in trail] == ["calibrate", "solve", "texture"]
    # The project, given by its absolute path, is recorded relative to its folder (FORMAT.md, "Audit trail").
    assert [e["arguments"] for e in trail] == [[PROJECT, *c[2:]] for c in commands]
    assert {e["vebuild"] for e in trail} == {__version__}
    assert all(TIME.match(e["time"]) and start <= e["time"] <= end for e in trail)
    assert trail[0]["before_sha256"] == examiner_sha256(original)
    for prev, e in zip(trail, trail[1:], strict=False):
        assert e["before_sha256"] == prev["after_sha256"]
    assert trail[-1]["after_sha256"] == examiner_sha256(doc)
    assert len({e["after_sha256"] for e in trail}) == 3  # each command changed the document
    assert verify_audit(doc) == []
    code, out, _ = run("check", str(folder / PROJECT))
    assert code == 0
    assert "audit trail: 3 command(s), the chain verified; the file is as `vebuild texture` wrote it" in out
    assert f"inputs SHA-256: {trail[-1]['after_sha256']} (what outputs made from it now record)" in out


def test_a_command_that_changes_nothing_adds_no_entry(room: Path) -> None:
    before = read(room)
    assert run("texture", str(room), "--quiet", "--density", "20")[0] == 0  # the same textures again
    assert read(room)["audit"] == before["audit"]


def test_an_outside_edit_is_detected(room: Path) -> None:
    doc = read(room)
    doc["name"] = "another title"  # no stage's input: only the audit trail can tell
    room.write_text(json.dumps(doc, indent=2), encoding="utf-8")
    code, out, _ = run("check", str(room))
    assert code == 1
    assert out.splitlines()[0].endswith("hashes verified; changed outside vebuild (see the audit trail below)")
    assert "audit trail: the project was changed outside vebuild after its last recorded command, `texture`" in out

    assert run("mark", str(room), "Z", "--at", "2,2,0")[0] == 0  # a later command: the break stays in the trail
    doc = read(room)
    assert doc["audit"][-1]["command"] == "mark"
    assert doc["audit"][-1]["before_sha256"] != doc["audit"][-2]["after_sha256"]
    (problem,) = verify_audit(doc)
    assert problem.index == 2
    assert problem.message.startswith("the project was changed outside vebuild between `texture`")
    code, out, _ = run("check", str(room))
    assert code == 1 and "between `texture`" in out


def test_a_failed_save_adds_no_entry_and_writes_nothing(room: Path) -> None:
    project = load_project(room)
    on_disk = room.read_bytes()
    trail = copy.deepcopy(project.data["audit"])
    project.data["settings"]["click_sigma_px"] = "one"
    with command_context("solve", [str(room)]), pytest.raises(ProjectError, match=r"\$\.settings\.click_sigma_px"):
        save_project(project)
    assert project.data["audit"] == trail
    assert room.read_bytes() == on_disk


def test_library_saves_outside_a_command_are_not_entries(room: Path) -> None:
    project = load_project(room)
    project.data["name"] = "renamed by a script"
    save_project(project)
    doc = read(room)
    assert len(doc["audit"]) == 3
    assert verify_audit(doc)  # the script's change is outside vebuild's commands, and seen as such


def test_the_modelling_screens_save_is_recorded(room: Path) -> None:
    from vebuild.edit.session import EditSession

    s = EditSession(load_project(room, verify_photos=False), autosave=False)
    u, v = s.data["photos"][1]["marker_observations"]["T1"]
    s.place_marker("p2", "T1", (u + 1.0, v))
    with command_context("edit", [str(room)]):
        s.save()
    doc = read(room)
    assert doc["audit"][-1]["command"] == "edit" and doc["audit"][-1]["arguments"] == [PROJECT]
    assert verify_audit(doc) == []


def test_bad_audit_content_names_the_field(room: Path) -> None:
    doc = read(room)
    doc["audit"][1]["time"] = "last Tuesday"
    room.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(ProjectError, match=r"\$\.audit\[1\]\.time"):
        load_project(room)


def test_the_report_shows_the_processing_record(room: Path) -> None:
    from vebuild.report.page import Report
    from vebuild.report.processing import processing

    project = load_project(room)
    rep = Report(room.parent)
    processing(project, rep)
    (section,) = rep.sections
    assert section.startswith("<h2>Processing record</h2>")
    assert section.count("<td>current</td>") == 3
    trail = project.data["audit"]
    for e in trail:
        assert e["after_sha256"][:12] in section
    assert "The chain verifies" in section


def test_source_date_epoch_sets_the_time(monkeypatch: pytest.MonkeyPatch) -> None:
    from vebuild.project.provenance import audit_entry

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    assert audit_entry("solve", ["P"], None, "0" * 64)["time"] == "2023-11-14T22:13:20Z"


def test_a_word_that_is_not_utf8_is_kept_as_its_bytes() -> None:
    from vebuild.project.provenance import audit_entry

    assert audit_entry("calibrate", ["caf\udce9.json"], None, "0" * 64)["arguments"] == ["caf\\xe9.json"]


def test_paths_are_recorded_relative_to_the_project_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Whatever the working directory and however a path is given, the audit records it relative to
    the project's folder (POSIX separators); a path outside that folder, as absolute; other words as
    given, even where one happens to name a file."""
    from vebuild.project.provenance import audit_entry

    folder = tmp_path / "cases" / "117"
    (folder / "renders").mkdir(parents=True)
    (tmp_path / "work").mkdir()
    (tmp_path / "work" / "doorway").write_text("")  # a word that is also a file's name here
    project = folder / PROJECT
    project.write_text("{}")
    monkeypatch.chdir(tmp_path / "work")
    words = ["../cases/117/room.vebuild.json", "--view", "doorway", "--out", str(folder / "renders" / "a.png"),
             "--json=../cases/117/renders/../f.json", "--html", "../site"]
    paths = {str(folder / "renders" / "a.png"), "../cases/117/renders/../f.json", "../site"}
    with command_context("render", words, paths):
        entry = audit_entry("render", words, None, "0" * 64, Path("../cases/117") / PROJECT)
    assert entry["arguments"] == [PROJECT, "--view", "doorway", "--out", "renders/a.png", "--json=f.json",
                                  "--html", str((tmp_path / "site").resolve())]
    monkeypatch.chdir(folder)  # from inside the folder: the words as given are already relative to it
    with command_context("render", [PROJECT, "--out", "renders/a.png"], {PROJECT, "renders/a.png"}):
        assert audit_entry("render", [PROJECT, "--out", "renders/a.png"], None, "0" * 64, project)[
            "arguments"] == [PROJECT, "--out", "renders/a.png"]
    assert audit_entry("render", words, None, "0" * 64, project)["arguments"] == words  # outside a command


def test_the_command_line_records_its_paths_relative(room: Path, tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """`vebuild mark` run from another folder, the project named by a relative path: the trail has
    the words that the same command gives from inside the folder."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert run("mark", "../room/" + PROJECT, "Z", "--at", "2,2,0")[0] == 0
    assert read(room)["audit"][-1]["arguments"] == [PROJECT, "Z", "--at", "2,2,0"]


def test_the_inputs_digest_moves_with_the_inputs_not_with_the_trail(room: Path) -> None:
    """The digest every output embeds (FORMAT.md, "Inputs digest") is the documented recipe over
    the document without its audit trail: the last entry's after_sha256. Another examiner's times
    and words leave it as it is; a changed photo, mark, result or case detail moves it."""
    from vebuild.project.provenance import inputs_sha256

    doc = read(room)
    digest = inputs_sha256(doc)
    assert digest == examiner_sha256(doc) == doc["audit"][-1]["after_sha256"]
    other = copy.deepcopy(doc)
    for e in other["audit"]:
        e["time"], e["arguments"] = "2001-01-01T00:00:00Z", ["/somewhere/else/" + PROJECT]
    assert inputs_sha256(other) == digest

    def changed(edit) -> str:
        d = copy.deepcopy(doc)
        edit(d)
        return inputs_sha256(d)

    def moved(d: dict) -> None:
        d["photos"][1]["marker_observations"]["T1"][0] += 0.5

    assert changed(lambda d: d["photos"][0].update(sha256="0" * 64)) != digest  # another photo's bytes
    assert changed(moved) != digest
    assert changed(lambda d: d["textures"]["pages"][0].update(atlas_sha256="0" * 64)) != digest
    assert changed(lambda d: d.update(case={"examiner": "B. Other"})) != digest


def test_the_parsers_path_arguments_are_recorded_relative(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`vebuild new` from above the folder: the project and the photos (paths to the parser) are
    recorded relative to the project's folder."""
    case = tmp_path / "case 7"
    case.mkdir()
    photo = sorted((ROOM / "photos").iterdir())[0]
    shutil.copy(photo, case / photo.name)
    monkeypatch.chdir(tmp_path)
    code, _, err = run("new", f"case 7/{PROJECT}", str(case / photo.name))
    assert code == 0, err
    (entry,) = read(case / PROJECT)["audit"]
    assert entry["command"] == "new" and entry["arguments"] == [PROJECT, photo.name]
