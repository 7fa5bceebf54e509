"""The same bytes on any machine: the pipeline's outputs do not depend on the number of threads.

A second examiner re-running a project on another machine must get the same files. A threaded
BLAS adds its partial sums in an order that depends on its thread count, so each run here is a
fresh process with its own ``OPENBLAS_NUM_THREADS`` / ``OMP_NUM_THREADS`` (and llvmpipe's
``LP_NUM_THREADS``), set before numpy loads, as on a machine with that many cores. The pipeline
is the example room with a coarse texture and small renders: calibrate, solve --recalibrate,
texture, render, export (.glb and .obj), analyses and the report (HTML and its images). Both
runs give the same words from inside their folders and the same ``SOURCE_DATE_EPOCH``, so that
the project's audit trail, which records the commands and their time, is the same too.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import threading
from pathlib import Path

from vebuild.determinism import THREADS, fixed_threads

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "scenes" / "room"

PIPELINE = """
import os
import sys
from pathlib import Path
from vebuild.cli import main

out = Path(sys.argv[1])
os.chdir(out)  # the same words in both runs: the audit trail records them
p = "room.vebuild.json"
(out / "renders").mkdir()
(out / "export").mkdir()
steps = [
    ["calibrate", p, "--quiet"],
    ["solve", p, "--recalibrate"],
    ["texture", p, "--density", "50", "--quiet"],
    ["render", p, "--view", "doorway", "--size", "320x180", "--out", "renders/doorway.png"],
    ["render", p, "--view", "overview", "--lighting", "daylight", "--size", "320x180",
     "--out", "renders/overview-daylight.png"],
    ["render", p, "--photo", "p1", "--validate", "--size", "320x240", "--out", "renders/p1.png"],
    ["export", p, "--out", "export/room.glb"],
    ["export", p, "--out", "export/room.obj"],
    ["report", p, "--out", "report", "--no-pdf", "--quiet"],
]
for argv in steps:
    if main(argv) != 0:
        sys.exit(f"vebuild {' '.join(argv)} failed")
"""


def _run(folder: Path, threads: int) -> None:
    shutil.copytree(EXAMPLE, folder)
    project = folder / "room.vebuild.json"
    data = json.loads(project.read_text())
    data["analyses"] = [  # measurements propagate the solve's covariance into the report
        {"name": "cabinet to table", "command": ["distance", "cabinet:v4", "table.top:v6"]},
        {"name": "check distances", "command": ["checks"]},
    ]
    project.write_text(json.dumps(data, indent=1))
    env = dict(os.environ, OPENBLAS_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads),
               LP_NUM_THREADS=str(threads), SOURCE_DATE_EPOCH="1700000000",  # the audit trail's time
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.run([sys.executable, "-c", PIPELINE, str(folder)], env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_the_pipeline_gives_the_same_bytes_with_one_or_two_threads(tmp_path: Path) -> None:
    _run(tmp_path / "one", 1)
    _run(tmp_path / "two", 2)
    one, two = _files(tmp_path / "one"), _files(tmp_path / "two")
    assert one.keys() == two.keys()
    made = [k for k in one if not (EXAMPLE / k).is_file()] + ["room.vebuild.json"]
    for kind in ("textures/", "renders/", "export/room.glb", "export/room.obj", "report/report.html",
                 "report/images/"):
        assert any(k.startswith(kind) for k in made), f"the pipeline wrote no {kind}"
    differ = sorted(k for k in one if one[k] != two[k])
    assert not differ, f"{len(differ)} of {len(one)} files differ between 1 and 2 threads: {differ}"


def _blas_threads() -> list[int]:
    import scipy.linalg  # noqa: F401  (its wheel brings a BLAS of its own besides numpy's)
    from threadpoolctl import threadpool_info

    return [d["num_threads"] for d in threadpool_info() if d["user_api"] in ("blas", "openmp")]


def test_fixed_threads_nests_and_restores() -> None:
    before = _blas_threads()
    with fixed_threads():
        assert set(_blas_threads()) == {THREADS}
        with fixed_threads():
            assert set(_blas_threads()) == {THREADS}
        assert set(_blas_threads()) == {THREADS}  # the inner exit does not restore while the outer runs
    assert _blas_threads() == before


def test_fixed_threads_holds_while_any_thread_is_inside() -> None:
    with fixed_threads():  # the main thread sets and restores first, as in a session before a worker's
        pass
    before = _blas_threads()
    inside, leave, seen = threading.Event(), threading.Event(), []

    def worker() -> None:
        with fixed_threads():
            inside.set()
            leave.wait(10)
            seen.append(set(_blas_threads()))

    t = threading.Thread(target=worker)
    t.start()
    inside.wait(10)
    with fixed_threads():
        pass  # this thread leaves first: the worker's solve must still run on one thread
    leave.set()
    t.join(10)
    assert seen == [{THREADS}]
    assert _blas_threads() == before


def test_fixed_threads_holds_a_blas_loaded_after_its_first_use() -> None:
    """OpenCV's wheel bundles an OpenBLAS of its own; imported after the first solve, it is held
    to one thread too (the controller is made again when modules were imported since)."""
    import subprocess
    import sys

    code = ("from vebuild.determinism import fixed_threads\n"
            "from threadpoolctl import threadpool_info\n"
            "with fixed_threads(): pass\n"
            "import cv2\n"
            "with fixed_threads():\n"
            "    print(sorted({d['num_threads'] for d in threadpool_info() if d['user_api'] in ('blas', 'openmp')}))\n"
            "print(len([d for d in threadpool_info() if 'opencv' in d['filepath']]))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       env={**__import__("os").environ, "OPENBLAS_NUM_THREADS": "2", "OMP_NUM_THREADS": "2"})
    assert r.returncode == 0, r.stderr
    inside, opencv_pools = r.stdout.split()
    assert inside == f"[{THREADS}]" and int(opencv_pools) >= 1, r.stdout
