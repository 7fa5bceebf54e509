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
    pytest-xdist worker. A display is taken only once the server started for it holds its lock
    (the lock file names the server's process): two workers starting servers for the same free
    number at once had both taken it when the first one's socket appeared, the second's server
    failing to start, and the second worker then drove windows on the first's display (xdotool
    found the other worker's window by its title, or one pointer moved under the other's zoom)."""
    import os
    import shutil
    import subprocess
    import time
    from pathlib import Path

    exe = shutil.which("Xvfb")
    if exe is None:
        pytest.fail("window tests need a virtual X server: `sudo apt-get install xvfb` (CI's .ci/run installs it)")
    for n in range(90, 140):
        socket, lock = Path(f"/tmp/.X11-unix/X{n}"), Path(f"/tmp/.X{n}-lock")
        if socket.exists() or lock.exists():
            continue
        proc = subprocess.Popen([exe, f":{n}", "-screen", "0", "1600x1200x24", "-nolisten", "tcp"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        mine = False
        for _ in range(200):
            if proc.poll() is not None:
                break
            try:
                mine = int(lock.read_text().strip()) == proc.pid and socket.exists()
            except (OSError, ValueError):
                mine = False
            if mine:
                break
            time.sleep(0.05)
        if not mine:
            if proc.poll() is None:
                proc.kill()
            proc.wait(10)
            continue
        old = os.environ.get("DISPLAY")
        os.environ["DISPLAY"] = f":{n}"
        try:
            yield f":{n}"
        finally:
            proc.terminate()
            proc.wait(10)
            if old is None:
                os.environ.pop("DISPLAY", None)
            else:
                os.environ["DISPLAY"] = old
        return
    pytest.fail("could not start Xvfb on any display from :90 to :139")


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


# -- markers: window, gl, slow (pyproject's [tool.pytest.ini_options] markers) ---------------------

#: Words in a test module's source that mean its tests draw with OpenGL (llvmpipe here and in CI).
GL_WORDS = ("vebuild.gl", "vebuild.render", "vebuild.texture", "vebuild.viewer", "vebuild.edit.screen",
            "headless_context", "screenshots", '["demo"', '["texture"', '["video"', '["render"')
#: Modules whose tests are slow for another cause: batches of hundreds of generated photos, whole
#: pipeline runs, subprocesses killed at random, benchmarks run through their command.
SLOW_MODULES = frozenset({
    "test_calibration_coverage", "test_robust_vanishing", "test_bending", "test_register_coverage",
    "test_house", "test_room_scenes", "test_determinism", "test_fuzz_loader", "test_kill",
    "test_example_room", "test_example_remodel", "test_single_view_kinds", "test_bench_single_view",
    "test_bench_real", "test_bench_detect", "test_bench_render", "test_bench_house", "test_bench_cli",
    "test_detect_clutter", "test_camera_groups", "test_placement_honest", "test_orientation", "test_outputs",
    "test_report", "test_report_court", "test_report_single", "test_measure", "test_relations",
    "test_person_height_coverage",
    "test_lens_second_term",
})
_gl_modules: dict[str, bool] = {}


def _draws_with_gl(item: pytest.Item) -> bool:
    path = str(item.path)
    if path not in _gl_modules:
        text = item.path.read_text(encoding="utf-8")
        _gl_modules[path] = any(w in text for w in GL_WORDS)
    return _gl_modules[path]


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark each test `window` (it drives a window on the virtual X server), `gl` (its module
    draws with OpenGL) and `slow` (either of those, or a module of SLOW_MODULES), so that
    `pytest -m "not slow"` is a developer's quick loop."""
    for item in items:
        window = "xvfb_display" in getattr(item, "fixturenames", ())
        gl = window or _draws_with_gl(item)
        if window:
            item.add_marker(pytest.mark.window)
        if gl:
            item.add_marker(pytest.mark.gl)
        if gl or item.path.stem in SLOW_MODULES:
            item.add_marker(pytest.mark.slow)
