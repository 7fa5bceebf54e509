"""Bad sizes, layouts and numbers get a VebuildError naming where they came from, never a crash in
native code, a traceback or a half-written file."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from vebuild.cli import main
from vebuild.errors import VebuildError
from vebuild.render.sizes import MAX_PIXELS, MAX_SIDE, check_gl_render_size, check_render_size

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"


@pytest.fixture
def room(tmp_path):
    """A copy of the example room (not calibrated: the size checks come before any of that)."""
    folder = tmp_path / "room"
    shutil.copytree(ROOM, folder)
    return folder / "room.vebuild.json"


def _set_view(proj: Path, index: int, width: int, height: int) -> None:
    data = json.loads(proj.read_text())
    data["views"][index].update(width=width, height=height)
    proj.write_text(json.dumps(data))


# -- render sizes ----------------------------------------------------------------------------------

def test_check_render_size_names_the_source_and_the_limits():
    assert check_render_size(1280, 720, "--size") == (1280, 720)
    assert check_render_size(MAX_SIDE, MAX_PIXELS // MAX_SIDE, "x") == (MAX_SIDE, 4096)
    for (w, h), what in [((0, 10), "each side 1 to 16384"), ((20000, 1), "each side 1 to 16384"),
                         ((960, 96_000_000), "each side 1 to 16384"), ((10000, 10000), "at most 67,108,864 pixels"),
                         ((1.5, 10), "a whole number of pixels"), ((True, 10), "a whole number of pixels")]:
        with pytest.raises(VebuildError, match=r"^\$\.views\[2\] \(width × height\): .*" + what):
            check_render_size(w, h, "$.views[2] (width × height)")

    class _Ctx:
        info = {"GL_MAX_TEXTURE_SIZE": 8192, "GL_MAX_RENDERBUFFER_SIZE": 16384, "GL_MAX_VIEWPORT_DIMS": (16384, 16384)}
    with pytest.raises(VebuildError, match=r"--size: .*each side 1 to 8192 pixels \(the most this machine's OpenGL"):
        check_gl_render_size(_Ctx(), 9000, 100, "--size")


@pytest.mark.parametrize(("size", "message"), [
    ((1, 100000), r"\$\.views\[0\] \(width × height\): a 1×100000 image cannot be rendered"),
    ((20000, 1), r"\$\.views\[0\] \(width × height\): a 20000×1 image cannot be rendered: expected each side 1 to "
                 r"16384 pixels"),
    ((40000, 40000), r"\$\.views\[0\] \(width × height\): a 40000×40000 image"),
])
def test_a_view_too_large_to_render_is_refused_naming_the_view(room, tmp_path, capsys, size, message):
    _set_view(room, 0, *size)
    out = tmp_path / "x.png"
    assert main(["render", str(room), "--view", "doorway", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "--size" not in err, err
    assert re.search(message, err), err
    assert not out.exists()


def test_the_report_refuses_a_view_whose_image_would_be_too_tall(room, tmp_path, monkeypatch):
    from vebuild.actions.report import write_report
    from vebuild.project import load_project

    project = load_project(room)
    project.data["calibration"] = {"cameras": {"p1": {}}}  # the size check comes before any use of it
    project.data["views"][2].update(width=1, height=100000)
    for section in ("_photos", "_calibration", "_model"):  # only the views' section matters here
        monkeypatch.setattr(f"vebuild.actions.report.{section}", lambda project, rep: None)
    with pytest.raises(VebuildError) as e:
        write_report(project, tmp_path / "r", pdf=False)
    assert "the report's image of view 'overview' (960 pixels wide, its height from the aspect of $.views[2], " \
           "1×100000): a 960×96000000 image cannot be rendered" in str(e.value)
    assert "--size" not in str(e.value)
    assert not (tmp_path / "r").exists() and not (tmp_path / ".r.tmp").exists()


def test_a_video_frame_too_large_names_the_view_or_the_option(room, tmp_path, capsys):
    _set_view(room, 0, 20000, 2)
    out = tmp_path / "v.mp4"
    assert main(["video", str(room), "--views", "doorway,overview", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "$.views[0] (width × height of view 'doorway', which sets the video's size; no --size given)" in err, err
    assert "Traceback" not in err and not out.exists()
    assert main(["video", str(room), "--views", "overview,doorway", "--size", "8000x6000", "--stereo", "sbs",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--size, in stereo side by side (twice the width): a 16000×6000 image cannot be rendered" in err, err
    assert not out.exists()


# -- recorded analyses -----------------------------------------------------------------------------

class _Rep:
    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.images: list[Path] = []


@pytest.mark.parametrize(("command", "message"), [
    (["distance", "--help"], r"\$\.analyses\[0\]\.command: the command asks for help \('--help'\), which is not an "
                             r"analysis; expected the words of a `vebuild analyse` command"),
    (["-h"], r"asks for help \('-h'\)"),
    (["sightline", "--standing", "1,1", "--object", "box", "-h"], r"asks for help"),
    (["distance"], r"\$\.analyses\[0\]\.command: the following arguments are required: a, b"),
    (["sightline", "--standing", "1,1", "--object", "box", "--samples", "many"], r"invalid .*'many'"),
    (["sightline", "--standing", "1,1", "--object", "box", "--size", "40000x40000"],
     r"\$\.analyses\[0\]\.command: --size: a 40000×40000 image cannot be rendered"),
])
def test_recorded_analyses_never_print_help_or_exit(room, tmp_path, capsys, command, message):
    from vebuild.analysis.report_sections import analyses
    from vebuild.project import load_project

    project = load_project(room)
    (tmp_path / "images").mkdir()
    with pytest.raises(VebuildError, match=message):
        analyses(project, _Rep(tmp_path), [{"name": "n", "command": command}])
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""
    assert not (tmp_path / "figures" / "analysis-1.json").exists()


def test_a_report_with_a_recorded_help_fails_with_status_2(room, tmp_path, capsys, monkeypatch):
    from vebuild.actions import report

    data = json.loads(room.read_text())
    data["analyses"] = [{"name": "help", "command": ["distance", "--help"]}]
    room.write_text(json.dumps(data))
    monkeypatch.setattr(report, "write_report", _report_without_renders(report.write_report, monkeypatch))
    assert main(["report", str(room), "--out", str(tmp_path / "r"), "--no-pdf", "--quiet"]) == 2
    err = capsys.readouterr()
    assert "$.analyses[0].command: the command asks for help ('--help')" in err.err and "usage" not in err.out
    assert "Traceback" not in err.err and not (tmp_path / "r").exists()


def _report_without_renders(write_report, monkeypatch):
    """The report with only its analyses section (the others need a solved, textured project)."""
    from vebuild.actions import report

    def run(project, out, pdf=True, progress=None):
        project.data.setdefault("calibration", {"cameras": {"p1": {}}})
        for section in ("_photos", "_calibration", "_model", "_views", "_validation", "_hypotheses"):
            monkeypatch.setattr(report, section, lambda project, rep: None)
        return write_report(project, out, pdf, progress)
    return run
