"""The command line speaks to users: a mistyped word gets "did you mean", a place in the project
file is named in words (photo 'door', field "width") besides its JSON path."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from PIL import Image

from vebuild.cli import main
from vebuild.console.arguments import suggestion
from vebuild.console.messages import error_in_words as _in_words
from vebuild.errors import ProjectError, VebuildError
from vebuild.project import new_photo_entry, new_project, save_project
from vebuild.project.json_paths import field_words, parse_json_path


def error_of(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    with pytest.raises(SystemExit) as e:
        main(list(argv))
    assert e.value.code == 2
    return capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.parametrize(("argv", "want"), [
    (["calbrate", "p.json"], "did you mean 'calibrate'?"),
    (["soleve", "p.json"], "did you mean 'solve'?"),
    (["calib", "p.json"], "did you mean 'calibrate'?"),
    (["bench", "rendr"], "did you mean 'render'?"),
    (["analyse", "p.json", "distanse"], "did you mean 'distance' or 'floor-distance'?"),
])
def test_mistyped_name_suggests(capsys: pytest.CaptureFixture[str], argv: list[str], want: str) -> None:
    line = error_of(capsys, *argv)
    assert "invalid choice" in line and line.endswith(want), line


def test_mistyped_option_is_looked_up_in_its_command(capsys: pytest.CaptureFixture[str]) -> None:
    # --size is an option of render, not of the top-level parser that first sees the extra words.
    line = error_of(capsys, "render", "p.json", "--sise=640x480", "--outt", "a.png")
    assert line.startswith("vebuild render: error: unrecognized arguments: --sise=640x480 --outt a.png"), line
    assert "--sise: did you mean '--size'?" in line and "--outt: did you mean '--out'?" in line, line


def test_nothing_close_gets_no_suggestion(capsys: pytest.CaptureFixture[str]) -> None:
    assert "did you mean" not in error_of(capsys, "frobnicate")
    assert "did you mean" not in error_of(capsys, "render", "p.json", "--zzz")
    assert suggestion("xy", ["export", "edit"]) == ""


def test_json_path_round_trip() -> None:
    assert parse_json_path('$.photos[2].vanishing_segments.x[0]') == ["photos", 2, "vanishing_segments", "x", 0]
    assert parse_json_path('$.model.nodes["a b"].joint') == ["model", "nodes", "a b", "joint"]
    assert parse_json_path("$.photos[0] photo 'p1'") is None
    assert parse_json_path("photo p1") is None


DOC = {"photos": [{"id": "door", "vanishing_segments": {"x": [[1, 2, 3, 4], [5, 6, 7]]}}, {"file": "b.jpg"}],
       "model": {"nodes": [{"name": "table", "joint": {"face": "up"}}], "relations": [{"params": [1]}]},
       "known_lengths": [{"ends": ["A", "B"]}], "textures": {"pages": [{"file": "t.png"}]}}


@pytest.mark.parametrize(("where", "words"), [
    ("$", ""), ("$.model", ""), ("$.version", ""),
    ("$.photos[0].width", "photo 'door', field \"width\""),
    ("$.photos[1].width", "the 2nd photo, field \"width\""),
    ("$.photos[0].vanishing_segments.x[1]", "photo 'door', field \"vanishing_segments.x\", its 2nd item"),
    ("$.model.nodes[0].joint.face", "node 'table', field \"joint.face\""),
    ("$.model.relations[0].params", "the 1st relation, field \"params\""),
    ("$.known_lengths[0].ends[1]", "the 1st known length, field \"ends\", its 2nd item"),
    ("$.textures.pages[0].file", "the 1st texture page, field \"file\""),
    ("$.photos[7].id", "the 8th photo, field \"id\""),
    ("$.photos[0] photo 'p1'", ""),
])
def test_field_words(where: str, words: str) -> None:
    assert field_words(where, DOC) == words


@pytest.fixture
def proj(tmp_path: Path) -> Path:
    doc = new_project("words")
    for name in ("door", "window"):
        image = tmp_path / f"{name}.jpg"
        Image.new("RGB", (64, 48), (90, 90, 90)).save(image)
        doc["photos"].append(new_photo_entry(tmp_path, image))
    path = tmp_path / "room.vebuild.json"
    save_project(path, doc)
    return path


def test_check_names_the_photo_and_field(capsys: pytest.CaptureFixture[str], proj: Path) -> None:
    data = json.loads(proj.read_text())
    data["photos"][1]["width"] = "64"
    proj.write_text(json.dumps(data))
    assert main(["check", str(proj)]) == 2
    err = capsys.readouterr().err
    assert f"{proj}: photo 'window', field \"width\", at $.photos[1].width: expected a whole number" in err, err


def test_errors_raised_after_loading_are_named_too(proj: Path) -> None:
    # An error a later stage raises with a JSON path only is named from the file when printed.
    e = ProjectError(proj, "$.photos[0].vanishing_segments", "needs two segments on an axis")
    assert _in_words(e) == (f"{proj}: photo 'door', field \"vanishing_segments\", at "
                            "$.photos[0].vanishing_segments: needs two segments on an axis")
    assert e.where == "$.photos[0].vanishing_segments"
    # Not a JSON file, a missing file, other errors: the message as it was.
    assert _in_words(ProjectError(proj.parent / "door.jpg", "$.photos[0]", "m")) == f"{proj.parent / 'door.jpg'}: " \
        "$.photos[0]: m"
    assert _in_words(ProjectError(proj.parent / "gone.json", "$.photos[0]", "m")).endswith("$.photos[0]: m")
    assert _in_words(VebuildError("plain")) == "plain"
