"""No writer goes through a link below its output folder (scenes/FORMAT.md, "What vebuild writes and
what it never touches").

The refusals of every command (a symbolic link to a subfolder or a file, a hard link, below its
output folder) are cases of tests/bad_inputs_links.py (the bad-input corpus' section 11); here: the
atomic writer's own guard against a link put in place of a folder after the checks, the demo
folder, the autosave, the walk-through's screenshots.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import shutil
from pathlib import Path

import pytest

from vebuild.cli import main
from vebuild.errors import VebuildError
from vebuild.project import atomic
from vebuild.project.outputs import temporaries

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"


def snapshot(root: Path) -> dict[str, str]:
    """Every entry under ``root``, links not followed: a file's SHA-256, a link's target, a folder."""
    out = {}
    for folder, dirs, files in os.walk(root):
        for name in dirs + files:
            p = Path(folder) / name
            rel = p.relative_to(root).as_posix()
            if p.is_symlink():
                out[rel] = "link:" + os.readlink(p)
            elif p.is_dir():
                out[rel] = "folder"
            else:
                out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def outside(tmp_path: Path) -> Path:
    """A folder of someone else's, outside every output folder."""
    folder = tmp_path / "elsewhere"
    folder.mkdir()
    (folder / "keep.txt").write_text("someone else's\n")
    return folder


def test_write_many_does_not_go_through_a_folder_made_a_link(tmp_path):
    out, elsewhere = tmp_path / "out", outside(tmp_path)
    (out / "photos").mkdir(parents=True)
    (out / "index.html").write_text("old\n")
    files = [(out / "photos" / "p1.jpg", b"jpeg"), (out / "index.html", b"new\n")]
    atomic.write_many(files, within=out)  # the folders are real: written
    assert (out / "photos" / "p1.jpg").read_bytes() == b"jpeg" and (out / "index.html").read_bytes() == b"new\n"

    shutil.rmtree(out / "photos")
    (out / "photos").symlink_to(elsewhere, target_is_directory=True)
    before, away = snapshot(out), snapshot(elsewhere)
    with pytest.raises(OSError, match="symbolic link") as e:
        atomic.write_many([(out / "index.html", b"newer\n"), (out / "photos" / "p1.jpg", b"jpeg")], within=out)
    assert e.value.filename == str(out / "photos")
    assert snapshot(out) == before and snapshot(elsewhere) == away  # nothing replaced, nothing left
    assert getattr(e.value, "replaced", None) == []


def test_write_many_keeps_the_mode_of_the_file_it_replaces(tmp_path):
    target = tmp_path / "data.js"
    target.write_text("old")
    target.chmod(0o640)
    atomic.write_many([(target, b"new")], within=tmp_path)
    assert target.read_bytes() == b"new" and target.stat().st_mode & 0o777 == 0o640 and not temporaries(tmp_path)


@pytest.fixture(scope="module")
def solved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("links") / "room"
    shutil.copytree(ROOM, folder)
    proj = folder / "room.vebuild.json"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["calibrate", str(proj), "--quiet"]) == 0
        assert main(["solve", str(proj)]) == 0
    return folder


def test_html_export_refuses_a_photos_link_made_after_its_checks(solved, tmp_path, capsys, monkeypatch):
    """The hole: `export --html` over an earlier export whose photos/ became a link to a folder
    elsewhere. Made a link after every check, just before the files are written: the writer itself
    refuses to go through it."""
    import vebuild.render.html as html

    room = tmp_path / "room"
    shutil.copytree(solved, room)
    out, elsewhere = tmp_path / "viewer", outside(tmp_path)
    assert main(["export", str(room / "room.vebuild.json"), "--html", str(out)]) == 0
    written, away = snapshot(out), snapshot(elsewhere)
    begin_stage = html.begin_stage

    def swap(project, *folders):  # someone's link in place of photos/, after the checks
        shutil.rmtree(out / "photos")
        (out / "photos").symlink_to(elsewhere, target_is_directory=True)
        written["photos"] = "link:" + str(elsewhere)
        for name in [k for k in written if k.startswith("photos/")]:
            del written[name]
        begin_stage(project, *folders)

    monkeypatch.setattr(html, "begin_stage", swap)
    capsys.readouterr()
    assert main(["export", str(room / "room.vebuild.json"), "--html", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{out / 'photos'}" in err and "symbolic link" in err and "Traceback" not in err, err
    assert snapshot(elsewhere) == away  # nothing written outside the output folder
    assert snapshot(out) == written and not temporaries(tmp_path)


def test_the_demo_folder_with_a_link_in_it_is_not_replaced(tmp_path, monkeypatch):
    from vebuild.actions.demo import copy_example

    monkeypatch.chdir(tmp_path)
    out, elsewhere = tmp_path / "vebuild-demo", outside(tmp_path)
    copy_example(out)
    (out / "evidence").symlink_to(elsewhere, target_is_directory=True)
    before, away = snapshot(out), snapshot(elsewhere)
    with pytest.raises(VebuildError, match=r"vebuild-demo/evidence: is a symbolic link .* never writes through a link"):
        copy_example(out)
    assert snapshot(out) == before and snapshot(elsewhere) == away and not temporaries(tmp_path)


def test_the_autosave_is_not_written_over_a_link(tmp_path):
    from vebuild.project import autosave_path, new_project, save_project

    project = tmp_path / "p.vebuild.json"
    save_project(project, new_project("p"))
    elsewhere = outside(tmp_path)
    auto = autosave_path(project)
    auto.symlink_to(elsewhere / "keep.txt")
    with pytest.raises(VebuildError, match=r"p.vebuild.json.autosave: is a symbolic link .* does not replace links"):
        save_project(auto, new_project("p"))
    assert auto.is_symlink() and (elsewhere / "keep.txt").read_text() == "someone else's\n"


def test_the_walk_throughs_screenshots_folder_is_not_gone_through_if_a_link(solved, tmp_path, xvfb_display):
    from vebuild.gl.window import Window
    from vebuild.project import load_project
    from vebuild.render.renderer import RenderOptions
    from vebuild.viewer.app import Viewer

    room = tmp_path / "room"
    shutil.copytree(solved, room)
    elsewhere = outside(tmp_path)
    (room / "screenshots").symlink_to(elsewhere, target_is_directory=True)
    away = snapshot(elsewhere)
    window = Window(320, 180, "vebuild links test", visible=False)
    try:
        v = Viewer(load_project(room / "room.vebuild.json"), window, RenderOptions.interactive(), view="overview")
        with pytest.raises(VebuildError, match=r"room/screenshots: is a symbolic link .* never writes through"):
            v.screenshot()  # F12: the message is shown on screen (WindowApp.guard)
        (room / "screenshots").unlink()
        (room / "screenshots").mkdir()
        assert v.screenshot().parent == room / "screenshots"  # a real folder: written
    finally:
        window.close()
    assert snapshot(elsewhere) == away  # nothing written through the link
