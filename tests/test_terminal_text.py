"""Text from a project printed on the terminal: its control characters are shown as escapes, never
sent (vebuild.console.terminal). A project whose case details, names, descriptions, labels and
paths hold terminal escape sequences (ESC]0;…BEL retitles a terminal, ESC[2J clears it), a carriage
return, a right-to-left override and C1 and DEL characters is run through the commands that print
them (case, render --list, scan add and scan check, analyse, and the errors of check and analyse
that quote them): stdout and stderr carry none of those characters raw, and show each as its
escape."""

from __future__ import annotations

import contextlib
import io
import json
import shutil
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from vebuild.cli import main  # noqa: E402
from vebuild.console.terminal import CONTROLS, EscapingStream, escaped_output, shown  # noqa: E402

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"
PROJECT = "room.vebuild.json"
#: Hostile text: retitle the terminal, clear it, return to the line's start, reverse what follows.
TITLE, CLEAR, BIDI = "\x1b]0;owned\x07", "\x1b[2J\x1b[H", "\u202e"
HOSTILE = f"A{TITLE}B{CLEAR}C\rD{BIDI}E\x9bF\x7fG"


def run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def raw_controls(text: str) -> list[str]:
    return sorted({repr(c) for c in CONTROLS.findall(text)})


def test_shown_escapes_controls_and_keeps_text():
    assert shown(HOSTILE) == "A\\x1b]0;owned\\x07B\\x1b[2J\\x1b[HC\\x0dD\\u202eE\\x9bF\\x7fG"
    keep = "line one\n\tsecond: é 中文 ±σ ✓ \u200d (a joiner) C:\\photos\\p1.jpg"
    assert shown(keep) == keep
    assert shown("\ud800") == "\\ud800"  # a lone surrogate, which no terminal encoding writes
    buf = io.StringIO()
    stream = EscapingStream(buf)
    assert stream.write(HOSTILE) == len(HOSTILE)
    assert not raw_controls(buf.getvalue())
    saved = sys.stdout, sys.stderr
    with escaped_output():
        assert isinstance(sys.stdout, EscapingStream) and isinstance(sys.stderr, EscapingStream)
        with escaped_output():  # nested: not wrapped twice
            assert not isinstance(sys.stdout.raw, EscapingStream)
    assert (sys.stdout, sys.stderr) == saved


@pytest.fixture(scope="module")
def hostile_room(tmp_path_factory) -> Path:
    """The example room, solved, with hostile text in its case details, name, a view's description
    and name, a marker's description, an evidence marker's label and description."""
    folder = tmp_path_factory.mktemp("terminal") / "room"
    shutil.copytree(ROOM, folder)
    proj = folder / PROJECT
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["calibrate", str(proj), "--quiet"]) == 0
        assert main(["solve", str(proj)]) == 0
    doc = json.loads(proj.read_text("utf-8"))
    doc["name"] = f"room {HOSTILE}"
    doc["case"] = {"number": f"2026/{HOSTILE}", "examiner": TITLE + "examiner", "declaration": CLEAR + "declared"}
    doc["views"][0]["description"] = f"doorway {HOSTILE}"
    doc["views"].append({**doc["views"][0], "name": f"v{TITLE}", "description": "second"})
    doc["markers"][0]["description"] = f"origin {HOSTILE}"
    doc["evidence_markers"] = [{"label": f"E{TITLE}1", "description": f"casing {HOSTILE}",
                                "position": [1.0, 1.0, 0.0], "node": "floor"}]
    proj.write_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n", "utf-8")
    return proj


def _copy(proj: Path, tmp_path: Path) -> Path:
    shutil.copytree(proj.parent, tmp_path / "room")
    return tmp_path / "room" / PROJECT


@pytest.mark.parametrize("words", [
    ["case", "{P}"],
    ["case", "{P}", "--organisation", f"lab{TITLE}"],
    ["render", "{P}", "--list"],
    ["analyse", "{P}", "distance", "cabinet:v4", f"nosuch{TITLE}:v1"],  # the command line's words quoted back
], ids=["case", "case-set", "render-list", "analyse-error"])
def test_no_raw_control_character_reaches_the_terminal(hostile_room, tmp_path, words):
    proj = _copy(hostile_room, tmp_path)
    code, out, err = run([w.replace("{P}", str(proj)) for w in words])
    assert "Traceback" not in out + err
    assert not raw_controls(out + err), (raw_controls(out + err), out[-2000:], err[-2000:])
    if words[0] in ("case", "render"):
        assert code == 0
        assert "\\x1b]0;owned\\x07" in out or "\\x1b[2J" in out, out  # shown, not dropped


def test_an_error_quoting_a_files_text_shows_its_controls(hostile_room, tmp_path):
    """A photo whose file name holds an escape sequence is missing: the error names it, escaped,
    and exits 2 with the project unchanged."""
    proj = _copy(hostile_room, tmp_path)
    doc = json.loads(proj.read_text("utf-8"))
    doc["photos"][0]["file"] = f"photos/p{TITLE}{CLEAR}.jpg"
    proj.write_text(json.dumps(doc, indent=2, ensure_ascii=False) + "\n", "utf-8")
    before = proj.read_bytes()
    code, out, err = run(["check", str(proj)])
    assert code == 2 and "Traceback" not in err
    assert not raw_controls(out + err), err
    assert "photos/p\\x1b]0;owned\\x07\\x1b[2J\\x1b[H.jpg" in err and "$.photos[0]" in err, err
    assert proj.read_bytes() == before


def test_scan_add_and_check_show_a_scan_files_name_escaped(hostile_room, tmp_path):
    """A scan whose file name holds ESC[2J: `scan add` and `scan check` print the name as the project
    records it, escaped."""
    from scan_scene import write_ply

    from vebuild.analysis.scans import resolve_points
    from vebuild.project import load_project

    proj = _copy(hostile_room, tmp_path)
    names = ("floor:v0", "floor:v1", "floor:v2", "cabinet:v6")
    W = resolve_points(load_project(proj), list(names), list(names))
    path = proj.parent / f"scan{CLEAR}.ply"
    write_ply(path, W.repeat(10, axis=0))
    targets = [f"--target=T{k}{TITLE}={float(w[0])!r},{float(w[1])!r},{float(w[2])!r}:{n}"
               for k, (w, n) in enumerate(zip(W, names, strict=True))]
    for words in (["scan", "add", str(proj), str(path), *targets], ["scan", "check", str(proj)]):
        code, out, err = run(words)
        assert code == 0, err
        assert not raw_controls(out + err), (raw_controls(out + err), out)
        assert "scan\\x1b[2J\\x1b[H.ply" in out, out
