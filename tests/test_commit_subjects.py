"""`.ci/commit-subjects` (what CI runs on the history) and `.ci/hooks/commit-msg` (what git runs on
each new message) hold the commit rule: a subject of at most 72 characters, a blank line before a
body. Run on a throwaway repository made here."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _git(repo: Path, *args: str) -> str:
    env = {"GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t",
           "PATH": "/usr/bin:/bin", "HOME": str(repo)}
    return subprocess.run(["git", "-C", str(repo), *args], capture_output=True, text=True, check=True, env=env).stdout


def _repo(tmp_path: Path, messages: list[str]) -> Path:
    repo = tmp_path / "r"
    (repo / ".ci").mkdir(parents=True)
    shutil.copy(ROOT / ".ci" / "commit-subjects", repo / ".ci")
    _git(repo, "init", "-q")
    _git(repo, "commit", "-q", "--allow-empty", "-m", "an old subject from before the rule, " + "long " * 20)
    (repo / ".ci" / "subjects-checked-since").write_text(_git(repo, "rev-parse", "HEAD"))
    for m in messages:
        _git(repo, "commit", "-q", "--allow-empty", "--cleanup=verbatim", "-m", m)
    return repo


def _check(repo: Path) -> subprocess.CompletedProcess:
    return subprocess.run(["python3", str(repo / ".ci" / "commit-subjects")], capture_output=True, text=True)


def test_subjects_since_the_rule_are_checked(tmp_path: Path) -> None:
    ok = _check(_repo(tmp_path / "a", ["a short subject", "another\n\nwith a body, after a blank line"]))
    assert ok.returncode == 0 and "2 commits since" in ok.stdout
    long = _check(_repo(tmp_path / "b", ["fine", "x" * 73]))
    assert long.returncode == 1 and "subject of 73 characters (at most 72)" in long.stdout
    glued = _check(_repo(tmp_path / "c", ["subject\nbody glued to it"]))
    assert glued.returncode == 1 and "no blank line between the subject and the body: subject" in glued.stdout


def test_the_hook_refuses_a_long_subject_and_a_glued_body(tmp_path: Path) -> None:
    hook = ROOT / ".ci" / "hooks" / "commit-msg"
    for text, code in (("a subject\n\nbody\n# a comment git adds\n", 0), ("y" * 73 + "\n", 1), ("s\nbody\n", 1)):
        msg = tmp_path / "msg"
        msg.write_text(text)
        assert subprocess.run([str(hook), str(msg)], capture_output=True).returncode == code, text
