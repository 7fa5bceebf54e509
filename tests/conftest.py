"""Shared fixtures: seeded synthetic scenes with known answers (no GL needed here)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


@pytest.fixture(scope="session")
def xvfb_display():
    """A virtual X server for window tests (Debian's xvfb; CI's .ci/run installs it), one per
    pytest-xdist worker. Xvfb picks a free display itself and writes its number to a pipe
    (``-displayfd``): two workers choosing a number by looking for free ones could both take the
    same display, one's server failing to start after the other's socket was there, and then one
    worker's pointer and keys moved the other's window (a zoom about the wrong cursor)."""
    import os
    import select
    import shutil
    import subprocess

    exe = shutil.which("Xvfb")
    if exe is None:
        pytest.fail("window tests need a virtual X server: `sudo apt-get install xvfb` (CI's .ci/run installs it)")
    read, write = os.pipe()
    proc = subprocess.Popen([exe, "-displayfd", str(write), "-screen", "0", "1600x1200x24", "-nolisten", "tcp"],
                            pass_fds=(write,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    number = b""
    while not number.endswith(b"\n") and select.select([read], [], [], 30.0)[0]:
        chunk = os.read(read, 16)
        if not chunk:
            break
        number += chunk
    os.close(read)
    if not number.strip().isdigit() or proc.poll() is not None:
        proc.kill()
        pytest.fail(f"Xvfb did not start (it said {number!r}, exit status {proc.poll()})")
    old = os.environ.get("DISPLAY")
    os.environ["DISPLAY"] = f":{int(number)}"
    try:
        yield os.environ["DISPLAY"]
    finally:
        proc.terminate()
        proc.wait(10)
        if old is None:
            os.environ.pop("DISPLAY", None)
        else:
            os.environ["DISPLAY"] = old


@pytest.fixture(scope="session")
def xdotool():
    """The program the window tests send input events with, as a user's keyboard and mouse would."""
    import shutil

    exe = shutil.which("xdotool")
    if exe is None:
        pytest.fail("the window tests send input events with xdotool: `sudo apt-get install xdotool` "
                    "(CI's .ci/run installs it)")
    return exe


@pytest.fixture(scope="session")
def solved_room(tmp_path_factory):
    """The example room calibrated and solved, once per session. Tests that change it work on a copy."""
    import shutil

    from vebuild.cli import main
    from vebuild.resources import example_project_dir

    folder = tmp_path_factory.mktemp("solved") / "room"
    shutil.copytree(example_project_dir(), folder)
    path = folder / "room.vebuild.json"
    assert main(["calibrate", str(path), "--quiet"]) == 0
    assert main(["solve", str(path)]) == 0
    return path


@pytest.fixture(scope="session")
def textured_room(tmp_path_factory):
    """The example room calibrated, solved and textured (100 texels per metre), once per session.
    Tests that change it work on a copy."""
    import shutil
    from pathlib import Path

    from vebuild.cli import main

    room = Path(__file__).resolve().parents[1] / "scenes" / "room"
    folder = tmp_path_factory.mktemp("render") / "room"
    shutil.copytree(room, folder)
    proj = folder / "room.vebuild.json"
    assert main(["calibrate", str(proj), "--quiet"]) == 0
    assert main(["solve", str(proj)]) == 0
    # Through the command line, as the stages before it, so that the audit trail records it too.
    assert main(["texture", str(proj), "--density", "100", "--quiet"]) == 0
    return proj
