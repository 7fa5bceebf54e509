"""Bad, degenerate and hostile inputs through every command they apply to (the corpus is
tests/bad_inputs_corpus.py).

For every case × command: exit status 2; no traceback; the message names the file and the field
(or the option) and says what was expected; and every file under the test's folder (the project
folder with its photos and textures, the output folder, the working folder) is byte for byte as it
was before the command, with no file added (temporary files included) and none removed.

One decoder, one answer: beside each refusal by a command that reads the project, ``vebuild check``
(run once per case) must refuse the same project with the very same message, unless the case's fault
is not the project's (bad_inputs_corpus.NOT_THE_PROJECTS says why for each); and every case ``check``
refuses, two cheap readers (render --list, analyse dimensions) refuse with its message too,
whether or not the case lists them.

Cases that still fail are listed, with what happens, in bad_inputs_corpus.KNOWN_FAILURES and marked
strict xfail: a fix turns one into an XPASS, which fails the suite until its entry is removed.
Runs in-process through vebuild.cli.main (an exception escaping it counts as a traceback); cases
that may crash in native code or allocate without bound run as ``python -m vebuild.cli`` under a
memory limit.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import traceback
from pathlib import Path
from typing import Any

import pytest
from bad_inputs_corpus import (
    CASES,
    CMDS,
    KNOWN_FAILURES,
    NOT_THE_PROJECTS,
    PROJECT,
    READ_NO_PROJECT,
    Case,
    Ctx,
)

REPO = Path(__file__).resolve().parents[1]
ROOM = REPO / "scenes" / "room"
IN_PROCESS_TIMEOUT_S = 60
SUBPROCESS_TIMEOUT_S = 120
SUBPROCESS_MEMORY = 6 << 30  # a command that tries to allocate a 40000² image must not take the machine down


@pytest.fixture(scope="session")
def states(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The example room as given (raw), calibrated and solved (solved), and textured (textured)."""
    from vebuild.cli import main

    base = tmp_path_factory.mktemp("bad_inputs_states")
    raw = base / "raw"
    shutil.copytree(ROOM, raw)
    solved = base / "solved"
    shutil.copytree(raw, solved)
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["calibrate", str(solved / PROJECT), "--quiet"]) == 0
        assert main(["solve", str(solved / PROJECT)]) == 0
    textured = base / "textured"
    shutil.copytree(solved, textured)
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["texture", str(textured / PROJECT), "--quiet", "--density", "20"]) == 0
    return {"raw": raw, "solved": solved, "textured": textured}


def snapshot(root: Path) -> dict[str, Any]:
    """Every entry under ``root``: a file's SHA-256, a link's target, a folder as such."""
    out: dict[str, Any] = {}
    for folder, dirs, files in os.walk(root, followlinks=False):
        for name in dirs + files:
            p = Path(folder) / name
            rel = p.relative_to(root).as_posix()
            if p.is_symlink():
                out[rel] = ("link", os.readlink(p))
            elif p.is_dir():
                out[rel] = ("dir",)
            else:
                out[rel] = ("file", hashlib.sha256(p.read_bytes()).hexdigest())
    return out


def differences(before: dict[str, Any], after: dict[str, Any]) -> list[str]:
    diff = [f"added {k}" for k in sorted(after.keys() - before.keys())]
    diff += [f"removed {k}" for k in sorted(before.keys() - after.keys())]
    diff += [f"changed {k}" for k in sorted(before.keys() & after.keys()) if before[k] != after[k]]
    return diff


class _Timeout(BaseException):
    pass


def _alarm(signum: int, frame: Any) -> None:
    raise _Timeout(f"still running after {IN_PROCESS_TIMEOUT_S} s")


def run_in_process(words: list[str], cwd: Path) -> tuple[Any, str, str]:
    """vebuild.cli.main(words): (exit status, stdout, stderr); a raised exception is its traceback."""
    from vebuild.cli import main

    out, err = io.StringIO(), io.StringIO()
    old_cwd = os.getcwd()
    old_handler = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, IN_PROCESS_TIMEOUT_S)
    try:
        os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code: Any = main(words)
    except SystemExit as e:
        code = 0 if e.code is None else e.code if isinstance(e.code, int) else 1
    except BaseException:  # noqa: BLE001 -- any exception escaping main is a finding: report it as such
        code = "an exception"
        err.write(traceback.format_exc())
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old_handler)
        os.chdir(old_cwd)
    return code, out.getvalue(), err.getvalue()


def _limit_memory() -> None:
    import resource
    resource.setrlimit(resource.RLIMIT_AS, (SUBPROCESS_MEMORY, SUBPROCESS_MEMORY))


def run_subprocess(words: list[str], cwd: Path) -> tuple[Any, str, str]:
    """``python -m vebuild.cli`` (for crashes in native code, and memory-hungry failures)."""
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    try:
        r = subprocess.run([sys.executable, "-m", "vebuild.cli", *words], cwd=cwd, env=env, capture_output=True,
                           text=True, timeout=SUBPROCESS_TIMEOUT_S, preexec_fn=_limit_memory)
    except subprocess.TimeoutExpired as e:
        return f"killed after {SUBPROCESS_TIMEOUT_S} s", str(e.stdout or ""), str(e.stderr or "")
    code: Any = r.returncode if r.returncode >= 0 else f"killed by signal {-r.returncode}"
    return code, r.stdout, r.stderr


def _words(cmd: Any) -> list[str]:
    return list(CMDS[cmd]) if isinstance(cmd, str) else list(cmd)


def _label(k: int, cmd: Any) -> str:
    if isinstance(cmd, str):
        return cmd
    opts = [w for w in cmd[2:] if not w.startswith("{")]
    return f"{k}:{cmd[0]}" + (" " + " ".join(opts[:4]) if opts else "")


def _param(c: Case, k: int, cmd: Any) -> Any:
    tid = f"{c.name}|{_label(k, cmd)}"
    marks = [pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[tid])] if tid in KNOWN_FAILURES else []
    return pytest.param(c, k, id=tid, marks=marks)


PARAMS = [_param(c, k, cmd) for c in CASES for k, cmd in enumerate(c.commands)]


def prepare(case: Case, tmp_path: Path, states: dict[str, Path]) -> tuple[Path, Path, Path, str]:
    """The case's state copied to tmp_path/room and mutated: (folder, project file, output folder, and
    the path of the first atlas page as the unmutated project records it (its name carries a hash))."""
    folder = tmp_path / "room"
    shutil.copytree(states[case.state], folder, symlinks=True)
    out = tmp_path / "out"
    out.mkdir()
    (tmp_path / "work").mkdir()
    project = folder / PROJECT
    ctx = Ctx(folder, project, out, json.loads(project.read_text("utf-8")))
    pages = (ctx.doc.get("textures") or {}).get("pages") or [{}]
    atlas = str(pages[0].get("atlas", "textures/atlas_0.png"))
    case.mutate(ctx)
    if ctx.write:
        text = ctx.text if ctx.text is not None else json.dumps(ctx.doc, indent=2, ensure_ascii=False) + "\n"
        project.write_bytes(text.encode("utf-8", "surrogateescape"))
    return folder, project, out, atlas


def fill(word: str, subs: dict[str, str]) -> str:
    for k, v in subs.items():
        word = word.replace(k, v)
    return word


def refusal(command: str, stderr: str, folder: Path) -> str:
    """The error message a command printed (after ``vebuild COMMAND: error:``), the project folder
    written {D}."""
    head = f"vebuild {command}: error: "
    at = stderr.rfind(head)
    return "" if at < 0 else stderr[at + len(head):].strip().replace(str(folder), "{D}")


_CHECKED: dict[str, str | None] = {}


def check_answer(case: Case, states: dict[str, Path], factory: pytest.TempPathFactory) -> str | None:
    """``vebuild check``'s refusal of the case's project (None where it accepts it), run once per
    case in a folder of its own."""
    if case.name not in _CHECKED:
        tmp = factory.mktemp("check_answer")
        folder, project, _, _ = prepare(case, tmp, states)
        words = [fill(w, {"{P}": str(project), "{D}": str(folder)}) for w in CMDS["check"]]
        code, _, stderr = (run_subprocess if case.sub else run_in_process)(words, folder if case.cwd == "project"
                                                                            else tmp / "work")
        _CHECKED[case.name] = refusal("check", stderr, folder) if code == 2 else None
    return _CHECKED[case.name]


@pytest.mark.parametrize(("case", "k"), PARAMS)
def test_bad_input(case: Case, k: int, tmp_path: Path, states: dict[str, Path],
                   tmp_path_factory: pytest.TempPathFactory) -> None:
    folder, project, out, atlas = prepare(case, tmp_path, states)
    subs = {"{P}": str(project), "{D}": str(folder), "{OUT}": str(out), "{ATLAS}": atlas}
    words = [fill(w, subs) for w in _words(case.commands[k])]
    cwd = folder if case.cwd == "project" else tmp_path / "work"
    before = snapshot(tmp_path)
    code, stdout, stderr = (run_subprocess if case.sub else run_in_process)(words, cwd)
    after = snapshot(tmp_path)

    shown = f"vebuild {' '.join(words)}"[:400] + f"\n--- exit {code}\n--- stderr:\n{stderr[-3000:]}" \
            f"\n--- stdout:\n{stdout[-1500:]}"
    problems = []
    if "Traceback" in stdout + stderr:
        problems.append("a traceback")
    if code != 2:
        problems.append(f"exit status {code}, expected 2")
    groups = [w if isinstance(w, tuple) else (w,) for w in case.expect] + ([tuple(case.any_of)] if case.any_of else [])
    for group in groups:
        wants = [fill(w, subs) for w in group]
        if not any(w in stderr for w in wants):
            problems.append(f"the message does not name {' or '.join(map(repr, wants))}")
    if code == 2 and not re.search(case.word, stderr, re.IGNORECASE):
        problems.append("the message does not say what was expected")
    changed = differences(before, after)
    if changed:
        problems.append("the folder changed: " + ", ".join(changed[:12]))
    if code == 2 and words[0] not in ("check", *READ_NO_PROJECT) and case.name not in NOT_THE_PROJECTS:
        checked = check_answer(case, states, tmp_path_factory)
        said = refusal(words[0], stderr, folder)
        if checked is None:
            problems.append(f"`vebuild check` accepts the project that {words[0]} refuses")
        elif said != checked:
            problems.append(f"the message is not check's:\n  {words[0]}: {said}\n  check: {checked}")
    assert not problems, "; ".join(problems) + "\n" + shown


#: Commands that read the project and do little more (cheap, in-process), run on every case that
#: ``check`` refuses: each must refuse it with check's message, whether or not the case lists it.
READERS = {"render-list": ["render", "{P}", "--list"], "analyse-dims": CMDS["analyse-dims"]}
REFUSED = [c for c in CASES if "check" in c.commands and not c.sub]


@pytest.mark.parametrize("case", REFUSED, ids=[c.name for c in REFUSED])
def test_every_command_refuses_what_check_refuses(case: Case, tmp_path: Path, states: dict[str, Path],
                                                  tmp_path_factory: pytest.TempPathFactory) -> None:
    checked = check_answer(case, states, tmp_path_factory)
    assert checked is not None, f"`vebuild check` accepts the case {case.name}"
    folder, project, out, _ = prepare(case, tmp_path, states)
    cwd = folder if case.cwd == "project" else tmp_path / "work"
    before = snapshot(tmp_path)
    problems = []
    for name, command in READERS.items():
        words = [fill(w, {"{P}": str(project), "{D}": str(folder), "{OUT}": str(out)}) for w in command]
        code, _, stderr = run_in_process(words, cwd)
        said = refusal(words[0], stderr, folder)
        if code != 2 or said != checked:
            problems.append(f"{name}: exit {code}, {said or stderr[-800:]!r}")
    changed = differences(before, snapshot(tmp_path))
    assert not problems and not changed, "\n".join([f"check: {checked}", *problems, *changed])


def test_corpus_size() -> None:
    names = [c.name for c in CASES]
    assert len(names) == len(set(names))
    assert len(CASES) >= 120, len(CASES)
    ids = {p.id for p in PARAMS}
    assert not set(KNOWN_FAILURES) - ids, "known failures of cases that no longer exist"
    assert not set(NOT_THE_PROJECTS) - set(names), "exemptions of cases that no longer exist"
