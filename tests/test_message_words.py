"""Messages in the investigator's words: every message the solve, calibrate and edit paths raise,
warn or say has a first line with no JSON syntax (braces, ``["``, a ``$.`` path, a quoted key)
and no field name or internal identifier (a snake_case name, ``sigma``, ``hold`` as the file's
list, ``solve: false``); the project file's field may follow on a ``details:`` line. Found by
reading those modules' sources: the literal parts of each message (an f-string's values are
left out, except a ``json_path(...)`` call, which is a JSON path).

The project file's own bad-input errors (:class:`~vebuild.errors.ProjectError`: a file and the
field in it that is malformed) keep their file and field first, as every command's bad-input
message does (tests/bad_inputs_corpus.py); they are not walked here."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "vebuild"
MODULES = sorted([ROOT / "actions" / "solve.py", ROOT / "actions" / "solve_words.py",
                  ROOT / "actions" / "calibrate.py", ROOT / "model" / "determination.py",
                  ROOT / "model" / "constraints.py", ROOT / "model" / "restart.py",
                  *(ROOT / "edit").glob("*.py")])
#: The calls whose string arguments are messages: an error raised (other than ProjectError), a
#: warning appended, a message said on screen.
SAYS = ("say", "append", "warn")
JSON = re.compile(r'\$\.|[{}]|\["|"\w+"\s*:')
#: A field name or internal identifier: snake_case, the file's 1σ and hold list, a node held in
#: the file's words. "hold" as a verb before a key (hold Alt) is the user's own word.
FIELD = re.compile(r"\b[a-z]+_[a-z0-9_]+\b|\bsigma\b|solve: false|\"hold\"|\bhold list\b|\bhold\b(?! (Alt|Shift|Ctrl))")
#: Stands for an f-string's value in the text walked.
VALUE = "\x00"


def _text(node: ast.AST) -> str | None:
    """The literal text of a message argument (a string, an f-string, a sum of them), each
    value as VALUE, a json_path(...) call as "$."; None for anything else."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        out = []
        for v in node.values:
            if isinstance(v, ast.Constant):
                out.append(str(v.value))
            elif isinstance(v, ast.FormattedValue) and isinstance(v.value, ast.Call) \
                    and getattr(v.value.func, "id", "") == "json_path":
                out.append("$.")
            else:
                out.append(VALUE)
        return "".join(out)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        a, b = _text(node.left), _text(node.right)
        return None if a is None and b is None else (a or VALUE) + (b or VALUE)
    return None


def messages(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every message in the module: the string arguments of its error calls and
    of its say/append/warn calls."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.Call):
            continue
        f = node.func
        name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
        if not ((name.endswith("Error") and name != "ProjectError") or name in SAYS):
            continue
        out += [(node.lineno, t) for a in node.args if (t := _text(a)) is not None]
    return out


def first_line_faults(text: str) -> list[str]:
    first = text.split("\n", 1)[0]
    return [m.group(0) for m in JSON.finditer(first)] + [m.group(0) for m in FIELD.finditer(first)]


def test_the_walk_finds_the_messages() -> None:
    """The walk reads what it should: the solve's refusal, the calibration's warnings, the edit
    window's errors (so that a test that finds nothing wrong has looked)."""
    found = {p.name: [t for _, t in messages(p)] for p in MODULES}
    assert any("too few observations" in t for t in found["solve_words.py"])
    assert any("is not placed: one photo places only markers" in t for t in found["calibrate.py"])
    assert any("cannot be dragged" in t for t in found["modelling.py"])
    assert sum(len(v) for v in found.values()) > 100


def test_the_check_catches_json_and_field_names() -> None:
    for bad in ('add {"name": "yaw"} to the list', "see $.model.pins[3]", "mark it on_floor",
                'the "hold" list of node', "a sigma of 1", "node box (solve: false)"):
        assert first_line_faults(bad), bad
    for good in ("tick its 'on the floor' box in the Calibration tab\ndetails: $.markers[0].on_floor",
                 "hold Alt to place it exactly", "type it in the Model tab's 'depth (m)' field"):
        assert not first_line_faults(good), good


@pytest.mark.parametrize("path", MODULES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_message_first_line_is_in_the_users_words(path: Path) -> None:
    faults = [f"{path.name}:{line}: {first_line_faults(t)} in {t.splitlines()[0][:100]!r}"
              for line, t in messages(path) if first_line_faults(t)]
    assert not faults, "\n".join(faults)
