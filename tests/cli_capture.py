"""vebuild's command line run in-process, its exit code and what it printed captured."""

from __future__ import annotations

from dataclasses import dataclass

import pytest


@dataclass
class CliRun:
    returncode: int
    stdout: str
    stderr: str


def run_cli(capsys: pytest.CaptureFixture, *args: str) -> CliRun:
    from vebuild.cli import main

    capsys.readouterr()
    code = main(list(args))
    out = capsys.readouterr()
    return CliRun(code, out.out, out.err)
