"""The output policy (vebuild/project/outputs.py) and the atomic writer (vebuild/project/atomic.py).

Every refusal exits with status 2, names the path, and leaves the project's folder byte for byte as
it was; outputs vebuild wrote are replaced; no temporary file is left behind.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from vebuild.cli import main
from vebuild.project import atomic
from vebuild.project.outputs import temporaries

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"


def snapshot(folder: Path) -> dict[str, str]:
    """Every file (and link) under ``folder``, by relative path: its SHA-256 (a link: its target)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder).as_posix()
        if p.is_symlink():
            out[rel] = "link:" + os.readlink(p)
        elif p.is_file():
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    capsys.readouterr()
    rc = main(argv)
    cap = capsys.readouterr()
    return rc, cap.out + cap.err


@pytest.fixture(scope="module")
def base(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example calibrated, solved and textured (30 texels per metre: quick), once."""
    folder = tmp_path_factory.mktemp("outputs") / "room"
    shutil.copytree(ROOM, folder)
    proj = folder / "room.vebuild.json"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["calibrate", str(proj), "--quiet"]) == 0
        assert main(["solve", str(proj)]) == 0
        assert main(["texture", str(proj), "--density", "30", "--quiet"]) == 0
    return folder


@pytest.fixture
def room(base: Path, tmp_path: Path) -> Path:
    """A fresh copy of the textured example; returns its project file."""
    folder = tmp_path / "room"
    shutil.copytree(base, folder, symlinks=True)
    return folder / "room.vebuild.json"


def refused(argv: list[str], capsys: pytest.CaptureFixture[str], folder: Path, names: str,
            *more: Path) -> str:
    before = snapshot(folder)
    extra = {p: snapshot(p) if p.is_dir() else p.read_bytes() for p in more}
    rc, text = run(argv, capsys)
    assert rc == 2, text
    assert names in text and "Traceback" not in text, text
    assert snapshot(folder) == before
    for p, was in extra.items():
        assert (snapshot(p) if p.is_dir() else p.read_bytes()) == was
    return text


# -- the report's folder -----------------------------------------------------------------------------


def test_report_refuses_the_projects_folder(room, capsys):
    text = refused(["report", str(room), "--out", str(room.parent), "--no-pdf", "--quiet"], capsys, room.parent,
                   str(room.parent))
    assert "the project's folder" in text and "report/" in text


def test_report_refuses_the_photos_folder(room, capsys):
    photos = room.parent / "photos"
    text = refused(["report", str(room), "--out", str(photos), "--no-pdf", "--quiet"], capsys, room.parent,
                   str(photos))
    assert "photo photos/p1.jpg" in text


def test_report_refuses_a_folder_holding_someone_elses_file(room, tmp_path, capsys):
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "statement.odt").write_bytes(b"a witness statement")
    text = refused(["report", str(room), "--out", str(docs), "--no-pdf", "--quiet"], capsys, room.parent,
                   str(docs), docs)
    assert "statement.odt" in text


def test_report_refuses_the_current_folder(room, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(room.parent)  # `--out .` beside the project
    refused(["report", room.name, "--out", ".", "--no-pdf", "--quiet"], capsys, room.parent, ".:")
    work = tmp_path / "work"
    work.mkdir()
    (work / "notes.txt").write_text("mine")
    monkeypatch.chdir(work)  # `--out .` elsewhere
    refused(["report", str(room), "--out", ".", "--no-pdf", "--quiet"], capsys, room.parent, ".:", work)


def test_report_refuses_a_file_added_to_its_own_folder_and_replaces_its_own(room, tmp_path, capsys):
    out = tmp_path / "report"
    rc, text = run(["report", str(room), "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert rc == 0, text
    manifest = json.loads((out / ".vebuild-output.json").read_text())
    assert manifest["software"].startswith("vebuild") and "report.html" in manifest["files"]
    first = snapshot(out)
    rc, text = run(["report", str(room), "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert rc == 0, text
    assert snapshot(out) == first  # replaced by the same report
    assert temporaries(tmp_path) == [] and temporaries(room.parent) == []
    (out / "images" / "my-annotation.png").write_bytes(b"not vebuild's")
    refused(["report", str(room), "--out", str(out), "--no-pdf", "--quiet"], capsys, room.parent,
            "images/my-annotation.png", out)
    (out / "images" / "my-annotation.png").unlink()
    (out / "report.html").write_text("edited by hand")
    refused(["report", str(room), "--out", str(out), "--no-pdf", "--quiet"], capsys, room.parent, "report.html", out)


# -- output files ----------------------------------------------------------------------------------


def test_render_refuses_to_overwrite_a_photo(room, capsys):
    photo = room.parent / "photos" / "p1.jpg"
    text = refused(["render", str(room), "--photo", "p1", "--size", "64x48", "--out", str(photo)], capsys,
                   room.parent, str(photo))
    assert "the project's photo photos/p1.jpg" in text


def test_render_refuses_a_link_and_a_hard_link_to_a_photo_and_a_texture_page(room, tmp_path, capsys):
    photo = room.parent / "photos" / "p2.jpg"
    link = tmp_path / "view.png"
    link.symlink_to(photo)
    refused(["render", str(room), "--photo", "p1", "--size", "64x48", "--out", str(link)], capsys, room.parent,
            str(link))
    hard = tmp_path / "hard.png"
    os.link(photo, hard)
    text = refused(["render", str(room), "--photo", "p1", "--size", "64x48", "--out", str(hard)], capsys,
                   room.parent, str(hard))
    assert "photos/p2.jpg" in text
    page = room.parent / json.loads(room.read_text())["textures"]["pages"][0]["atlas"]
    refused(["render", str(room), "--photo", "p1", "--size", "64x48", "--out", str(page)], capsys, room.parent,
            str(page))


def test_render_refuses_someone_elses_png_and_replaces_its_own(room, tmp_path, capsys):
    from PIL import Image

    theirs = tmp_path / "scene.png"
    Image.new("RGB", (4, 4)).save(theirs)
    refused(["render", str(room), "--photo", "p1", "--size", "64x48", "--out", str(theirs)], capsys, room.parent,
            str(theirs), theirs)
    ours = tmp_path / "p1.png"
    for _ in range(2):
        rc, text = run(["render", str(room), "--photo", "p1", "--size", "64x48", "--out", str(ours)], capsys)
        assert rc == 0, text
    assert temporaries(tmp_path) == []


def test_export_refuses_the_project_and_someone_elses_file(room, tmp_path, capsys):
    refused(["export", str(room), "--out", str(room)], capsys, room.parent, f"{room}: is the project file")
    theirs = tmp_path / "model.glb"
    theirs.write_bytes(b"glTF but not ours")
    refused(["export", str(room), "--out", str(theirs)], capsys, room.parent, str(theirs), theirs)
    mtl = tmp_path / "room.mtl"
    mtl.write_text("newmtl mine\n")
    refused(["export", str(room), "--out", str(tmp_path / "room.obj")], capsys, room.parent, str(mtl), mtl)
    assert not (tmp_path / "room.obj").exists()
    mtl.unlink()
    for out in (tmp_path / "room.obj", theirs.with_name("ours.glb")):
        for _ in range(2):  # a second export replaces the first
            rc, text = run(["export", str(room), "--out", str(out)], capsys)
            assert rc == 0, text
    assert temporaries(tmp_path) == []


def test_video_refuses_the_project_autosave_and_someone_elses_file(room, tmp_path, capsys):
    refused(["video", str(room), "--views", "doorway,overview", "--out", str(room)], capsys, room.parent,
            f"{room}: is the project file")
    auto = room.with_name(room.name + ".autosave")
    refused(["video", str(room), "--views", "doorway,overview", "--out", str(auto)], capsys, room.parent,
            "autosave")
    theirs = tmp_path / "walk.mp4"
    theirs.write_bytes(b"\0\0\0\x18ftypisom a video of someone else's")
    refused(["video", str(room), "--views", "doorway,overview", "--out", str(theirs)], capsys, room.parent,
            str(theirs), theirs)


def test_figures_json_refuses_someone_elses_file(room, tmp_path, capsys):
    theirs = tmp_path / "figures.json"
    theirs.write_text('{"mine": 1}\n')
    refused(["analyse", str(room), "checks", "--json", str(theirs)], capsys, room.parent, str(theirs), theirs)
    ours = tmp_path / "ours.json"
    for _ in range(2):
        rc, text = run(["analyse", str(room), "checks", "--json", str(ours)], capsys)
        assert rc == 0, text
    assert json.loads(ours.read_text())["software"].startswith("vebuild")


# -- textures/ ---------------------------------------------------------------------------------------


def test_texture_refuses_a_textures_link(room, tmp_path, capsys):
    elsewhere = tmp_path / "elsewhere"
    shutil.move(room.parent / "textures", elsewhere)
    (room.parent / "textures").symlink_to(elsewhere)
    text = refused(["texture", str(room), "--density", "30", "--quiet"], capsys, room.parent,
                   str(room.parent / "textures"), elsewhere)
    assert "symbolic link" in text


def test_a_users_file_listed_as_an_old_page_survives_a_new_texture(room, capsys):
    data = json.loads(room.read_text())
    page = room.parent / data["textures"]["pages"][0]["atlas"]
    page.write_bytes(b"the user's own file, under the old page's name")
    stray = room.parent / "textures" / "atlas_0_000000000000.png"  # vebuild's pattern, but not its bytes
    stray.write_bytes(b"also the user's")
    rc, text = run(["texture", str(room), "--density", "25", "--quiet"], capsys)
    assert rc == 0, text
    assert page.read_bytes() == b"the user's own file, under the old page's name"
    assert stray.read_bytes() == b"also the user's"
    new = json.loads(room.read_text())["textures"]["pages"]
    for p in new:
        for key in ("atlas", "coverage"):
            assert hashlib.sha256((room.parent / p[key]).read_bytes()).hexdigest() == p[f"{key}_sha256"]


def test_texture_replaces_its_pages_and_removes_the_old_ones(room, capsys):
    old = snapshot(room.parent / "textures")
    rc, text = run(["texture", str(room), "--density", "25", "--quiet"], capsys)
    assert rc == 0, text
    pages = json.loads(room.read_text())["textures"]["pages"]
    names = {Path(p[k]).name for p in pages for k in ("atlas", "coverage")}
    assert set(snapshot(room.parent / "textures")) == names and not names & set(old)
    assert temporaries(room.parent) == []


def test_a_failed_texture_leaves_the_last_good_textures(room, capsys, monkeypatch):
    import vebuild.actions.texture as tx
    from vebuild.errors import ProjectError

    before = snapshot(room.parent)

    def refuse(*a, **k):
        raise ProjectError(room, "", "cannot write the project file (No space left on device)")

    monkeypatch.setattr(tx, "save_project", refuse)  # after the new pages are written
    rc, text = run(["texture", str(room), "--density", "25", "--quiet"], capsys)
    assert rc == 2 and "No space left" in text
    assert snapshot(room.parent) == before
    calls = []

    def fail_second(path, data):
        calls.append(path)
        if len(calls) == 2:
            raise OSError(28, "No space left on device")
        return atomic.write_bytes(path, data)

    monkeypatch.setattr(tx, "write_bytes", fail_second)  # while writing the pages
    rc, text = run(["texture", str(room), "--density", "25", "--quiet"], capsys)
    assert rc == 2 and "cannot write the textures" in text
    assert snapshot(room.parent) == before


# -- the atomic writer -------------------------------------------------------------------------------


def test_atomic_write_keeps_the_mode_and_leaves_nothing_on_failure(tmp_path):
    f = tmp_path / "a.json"
    f.write_text("old")
    os.chmod(f, 0o640)
    atomic.write_text(f, "new")
    assert f.read_text() == "new" and stat.S_IMODE(f.stat().st_mode) == 0o640

    def boom(fh):
        fh.write(b"half")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError):
        atomic.write_with(f, boom)
    with pytest.raises(OSError):
        atomic.write_via_path(f, lambda p: None)  # wrote nothing
    assert f.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["a.json"]


def test_clean_stale_removes_only_vebuilds_temporaries_of_dead_processes(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()
    stale = tmp_path / f".room.vebuild.json.{dead}.0123abcd.vebuild-tmp"
    live = tmp_path / f".room.vebuild.json.{os.getpid()}.0123abcd.vebuild-tmp"
    users = [tmp_path / n for n in (f".notes.{dead}.0123abcd.tmp", "x.vebuild-tmp", f".a.{dead}.xyz.vebuild-tmp")]
    for p in (stale, live, *users):
        p.write_text("x")
    folder = tmp_path / f".report.{dead}.89abcdef.vebuild-tmp"  # a report's build, killed
    folder.mkdir()
    (folder / atomic.MANIFEST).write_text("{}")
    plain = tmp_path / f".other.{dead}.89abcdef.vebuild-tmp"  # a folder without vebuild's manifest
    plain.mkdir()
    (plain / "letter.txt").write_text("someone's")
    begun = tmp_path / f".report.{dead}.76543210.vebuild-tmp"  # killed as it began: empty but for a temporary
    begun.mkdir()
    (begun / f".vebuild-output.json.{dead}.01234567.vebuild-tmp").write_text("{")
    aside = tmp_path / f".report.{dead}.00112233.vebuild-old"  # set aside; the new one never came
    aside.mkdir()
    (aside / atomic.MANIFEST).write_text("{}")
    removed = atomic.clean_stale(tmp_path)
    assert sorted(removed) == sorted([stale, folder, begun])
    assert live.exists() and plain.exists() and all(p.exists() for p in users)
    assert (tmp_path / "report" / atomic.MANIFEST).exists() and not aside.exists()  # put back


def test_the_demo_folder_is_replaced_only_when_vebuild_wrote_it_and_nobody_changed_it(tmp_path, monkeypatch):
    from vebuild.actions.demo import PROJECT_NAME, copy_example
    from vebuild.errors import VebuildError

    monkeypatch.chdir(tmp_path)
    out = tmp_path / "vebuild-demo"
    assert copy_example(out) == out / PROJECT_NAME
    first = snapshot(out)
    assert copy_example(out) == out / PROJECT_NAME  # an untouched demo folder is made afresh
    assert snapshot(out) == first and not temporaries(tmp_path)

    (out / PROJECT_NAME).write_text((out / PROJECT_NAME).read_text().replace('Example room', 'My room', 1))
    edited = snapshot(out)
    with pytest.raises(VebuildError, match=r"vebuild-demo: holds room.vebuild.json, which vebuild did not write "
                                           r"there \(or which changed since\)"):
        copy_example(out)
    assert snapshot(out) == edited

    other = tmp_path / "notes"
    other.mkdir()
    (other / "case.txt").write_text("an examiner's notes")
    with pytest.raises(VebuildError, match=r"notes: is not empty \(it holds case.txt\)"):
        copy_example(other)
    assert snapshot(other) == {"case.txt": hashlib.sha256(b"an examiner's notes").hexdigest()}
    with pytest.raises(VebuildError, match="is the folder you are working in"):
        copy_example(Path("."))
    assert not temporaries(tmp_path)
