"""Start-up: a command imports only what it uses (docs/start-up.md).

The parser names every command but adds the arguments of the one being run only, and the
modules that ``vebuild check`` goes through import scipy (and the GL, window and PDF libraries)
at their first use. Each case runs the command in a fresh interpreter, as the ``vebuild`` script
does, and reads what it imported from ``sys.modules``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vebuild.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "scenes" / "room"

#: No command of these three draws, opens a window or writes a PDF.
NEVER = ("moderngl", "glfw", "imgui_bundle", "weasyprint")

RUNNER = ("import sys\n"
          "from vebuild.cli import main\n"
          "rc = main(sys.argv[1:])\n"
          "print('MODULES ' + ' '.join(sorted({m.split('.')[0] for m in sys.modules})))\n"
          "sys.exit(rc)\n")


def _imported(folder: Path, *words: str) -> set[str]:
    r = subprocess.run([sys.executable, "-c", RUNNER, *words], capture_output=True, text=True, timeout=600,
                       cwd=folder)
    assert r.returncode == 0, r.stderr
    line = next(w for w in r.stdout.splitlines() if w.startswith("MODULES "))
    return set(line.split()[1:])


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example, calibrated: `solve` needs calibrated cameras, and with pytest-xdist the
    calibrate case need not run first, or in the same worker."""
    folder = tmp_path_factory.mktemp("start") / "room"
    shutil.copytree(EXAMPLE, folder)
    r = subprocess.run([sys.executable, "-m", "vebuild", "calibrate", "room.vebuild.json", "--quiet"],
                       capture_output=True, text=True, timeout=600, cwd=folder)
    assert r.returncode == 0, r.stderr
    return folder


def test_check_imports_no_gl_no_pdf_and_no_scipy(room: Path) -> None:
    mods = _imported(room, "check", "room.vebuild.json")
    assert "vebuild" in mods and "numpy" in mods  # the runner's list is real
    assert not mods & {*NEVER, "scipy", "cv2", "trimesh", "av"}, sorted(mods & {*NEVER, "scipy", "cv2"})


@pytest.mark.parametrize("words", [("calibrate", "room.vebuild.json", "--quiet"),
                                   ("solve", "room.vebuild.json"),
                                   ("solve", "room.vebuild.json", "--recalibrate")])
def test_calibrate_and_solve_import_no_gl_and_no_pdf(room: Path, words: tuple[str, ...]) -> None:
    mods = _imported(room, *words)
    assert "scipy" in mods  # they do solve
    assert not mods & set(NEVER), sorted(mods & set(NEVER))


def test_check_of_a_project_with_analyses_still_parses_them_lightly(tmp_path: Path) -> None:
    """The recorded analyses are parsed (their words checked) without the renderer's GL."""
    folder = tmp_path / "room"
    shutil.copytree(EXAMPLE, folder)
    path = folder / "room.vebuild.json"
    data = json.loads(path.read_text())
    data["analyses"] = [{"name": "door", "command": ["distance", "0,0,0", "1,0,0"]}]
    path.write_text(json.dumps(data))
    mods = _imported(folder, "check", "room.vebuild.json")
    assert not mods & set(NEVER)


def _helps(parser) -> dict[str, str]:
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return {a.dest: a.help for a in sub._choices_actions}


def test_every_command_is_named_with_the_help_its_own_parser_gives() -> None:
    """The names-only parser (what `vebuild --help` and "did you mean" see) lists every command
    in the same order, with the very help each command's full parser gives (some are written
    beside their actions: cli.py repeats their help, and this keeps the two the same)."""
    full, names = _helps(build_parser()), _helps(build_parser(""))
    assert list(full) == list(names) and len(full) >= 20
    assert full == names
    for name in full:  # a command built alone has its arguments; the others only their names
        alone = build_parser(name)
        chosen = next(a for a in alone._actions if a.__class__.__name__ == "_SubParsersAction").choices
        assert chosen[name]._actions[1:], name  # more than -h
        others = [n for n in chosen if n != name]
        assert all(len(chosen[n]._actions) == 1 for n in others), name


def test_version_and_help_need_no_command(capsys: pytest.CaptureFixture[str]) -> None:
    from vebuild import __version__
    from vebuild.cli import main

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and __version__ in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "calibrate" in out and "analyse" in out and "case" in out


def test_euler_matrix_has_the_bits_of_scipys() -> None:
    """A model's joints are decoded without scipy's spatial package: the same bits, or every
    solved figure downstream would differ in its last digits."""
    from scipy.spatial.transform import Rotation

    from vebuild.model.joints import euler_xyz_matrix

    rng = np.random.default_rng(20)
    angles = [*rng.uniform(-400, 400, (3000, 3)), *rng.choice([0.0, 45.0, 90.0, 180.0, -90.0, 270.0], (300, 3)),
              np.array([0.0, 0.0, 180.0]), np.zeros(3)]
    for a in angles:
        assert np.array_equal(euler_xyz_matrix(a), Rotation.from_euler("xyz", a, degrees=True).as_matrix()), a
    assert not np.array_equal(euler_xyz_matrix([0, 0, 1e-3]), np.eye(3))  # it does turn


def test_a_blas_loaded_inside_fixed_threads_starts_on_one_thread() -> None:
    """scipy is now imported at a solver's first use, inside the command's fixed_threads: its
    BLAS must still start on one thread (from the environment), and the environment is given
    back as it was when the last one leaves."""
    code = ("import os\n"
            "from vebuild.determinism import fixed_threads\n"
            "from threadpoolctl import threadpool_info\n"
            "with fixed_threads():\n"
            "    import numpy, scipy.linalg\n"
            "    print(sorted({d['num_threads'] for d in threadpool_info() if d['user_api'] == 'blas'}), "
            "len(threadpool_info()))\n"
            "print(os.environ['OPENBLAS_NUM_THREADS'], os.environ.get('MKL_NUM_THREADS'))\n")
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "2", "OMP_NUM_THREADS": "2"}
    env.pop("MKL_NUM_THREADS", None)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert r.returncode == 0, r.stderr
    inside, after = r.stdout.splitlines()
    assert inside.startswith("[1] ") and int(inside.split()[1]) >= 2, inside  # numpy's and scipy's
    assert after == "2 None"
