"""The same bytes for two examiners: the pipeline's outputs do not depend on the machine's threads,
the project's folder, the working directory or the time.

A second examiner re-running a project on another machine must get the same files. A threaded
BLAS adds its partial sums in an order that depends on its thread count, so each run here is a
fresh process with its own ``OPENBLAS_NUM_THREADS`` / ``OMP_NUM_THREADS`` (and llvmpipe's
``LP_NUM_THREADS``), set before numpy loads, as on a machine with that many cores. The pipeline
is the example room with a coarse texture and small renders: calibrate, solve --recalibrate,
texture, render, export (.glb, .obj and the HTML viewer), an analysis's figures and the report
(HTML and its images).

The two copies lie in folders of other names and depths; each run works from a folder outside its
copy and names the project and the outputs by absolute and by relative paths, the two runs mixing
them the other way round; one run sets ``SOURCE_DATE_EPOCH`` (to another value at each step), the
other does not, so it records the clock. Every file is the same, byte for byte, but the project
file's audit times (``audit[].time``), which say when each examiner ran each command and so must
differ; with them set aside the project file is the same bytes too.
"""

from __future__ import annotations

import datetime
import json
import os
import re
import shutil
import subprocess
import sys
import threading
from pathlib import Path

from vebuild.determinism import THREADS, fixed_threads

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "scenes" / "room"

PIPELINE = """
import json
import os
import sys
from pathlib import Path
from vebuild.cli import main

folder, cwd, absolute_first = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3] == "1"
epochs = json.loads(sys.argv[4])  # per step: SOURCE_DATE_EPOCH, or none for the clock
os.chdir(cwd)
k = 0

def name(rel):  # absolute and relative paths in turn, starting with the one asked for
    global k
    k += 1
    return str(folder / rel) if (k % 2 == 1) == absolute_first else os.path.relpath(folder / rel, cwd)

(folder / "renders").mkdir()
(folder / "export").mkdir()
(folder / "figures").mkdir()
steps = [
    ["calibrate", name("room.vebuild.json"), "--quiet"],
    ["solve", name("room.vebuild.json"), "--recalibrate"],
    ["texture", name("room.vebuild.json"), "--density", "50", "--quiet"],
    ["render", name("room.vebuild.json"), "--view", "doorway", "--size", "320x180", "--out",
     name("renders/doorway.png")],
    ["render", name("room.vebuild.json"), "--view", "overview", "--lighting", "daylight", "--size", "320x180",
     "--out=" + name("renders/overview-daylight.png")],
    ["render", name("room.vebuild.json"), "--photo", "p1", "--validate", "--size", "320x240", "--out",
     name("renders/p1.png")],
    ["export", name("room.vebuild.json"), "--out", name("export/room.glb")],
    ["export", name("room.vebuild.json"), "--out", name("export/room.obj")],
    ["export", name("room.vebuild.json"), "--html", name("viewer")],
    ["analyse", name("room.vebuild.json"), "distance", "cabinet:v4", "table.top:v6", "--json",
     name("figures/distance.json")],
    ["video", name("room.vebuild.json"), "--views", "doorway,overview", "--size", "96x64", "--fps", "4",
     "--speed", "4", "--out", name("renders/walk.mp4"), "--quiet"],
    ["report", name("room.vebuild.json"), "--out", name("report"), "--quiet"],
]
for argv, epoch in zip(steps, epochs, strict=True):
    os.environ.pop("SOURCE_DATE_EPOCH", None)
    if epoch is not None:
        os.environ["SOURCE_DATE_EPOCH"] = str(epoch)
    if main(argv) != 0:
        sys.exit(f"vebuild {' '.join(argv)} failed")
"""
STEPS = 12
#: The first run's SOURCE_DATE_EPOCH at each step: the times its audit trail must record.
EPOCHS = [1_700_000_000 + 86_400 * i for i in range(STEPS)]
#: The audit times, set aside where the project files are compared (they are the examiners').
AUDIT_TIME = re.compile(rb'("time": )"[^"]*"')


def _run(folder: Path, cwd: Path, threads: int, absolute_first: bool, epochs: list[int | None]) -> None:
    shutil.copytree(EXAMPLE, folder)
    project = folder / "room.vebuild.json"
    data = json.loads(project.read_text())
    data["analyses"] = [  # measurements propagate the solve's covariance into the report
        {"name": "cabinet to table", "command": ["distance", "cabinet:v4", "table.top:v6"]},
        {"name": "check distances", "command": ["checks"]},
    ]
    project.write_text(json.dumps(data, indent=1))
    cwd.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, OPENBLAS_NUM_THREADS=str(threads), OMP_NUM_THREADS=str(threads),
               LP_NUM_THREADS=str(threads), PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    env.pop("SOURCE_DATE_EPOCH", None)
    proc = subprocess.run([sys.executable, "-c", PIPELINE, str(folder), str(cwd), "1" if absolute_first else "0",
                           json.dumps(epochs)], env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _utc(epoch: float) -> str:
    return datetime.datetime.fromtimestamp(epoch, datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def test_two_examiners_get_the_same_bytes(tmp_path: Path) -> None:
    one = tmp_path / "examiner one" / "cases" / "2024-117" / "room"
    two = tmp_path / "b" / "copy"
    _run(one, tmp_path, 1, True, list(EPOCHS))  # from above the copy, absolute paths first
    start = _utc(datetime.datetime.now(datetime.UTC).timestamp())
    _run(two, tmp_path / "elsewhere" / "work", 2, False, [None] * STEPS)  # beside it, relative first; the clock
    end = _utc(datetime.datetime.now(datetime.UTC).timestamp())
    a, b = _files(one), _files(two)
    assert a.keys() == b.keys()
    made = [k for k in a if not (EXAMPLE / k).is_file()] + ["room.vebuild.json"]
    for kind in ("textures/", "renders/", "renders/walk.mp4", "export/room.glb", "export/room.obj",
                 "viewer/index.html", "figures/distance.json", "report/report.html", "report/report.pdf",
                 "report/images/"):
        assert any(k.startswith(kind) for k in made), f"the pipeline wrote no {kind}"
    differ = sorted(k for k in a if a[k] != b[k] and k != "room.vebuild.json")
    assert not differ, f"{len(differ)} of {len(a)} files differ between the two examiners: {differ}"

    # The project file: the same bytes but the audit's times, which are each examiner's own.
    assert AUDIT_TIME.sub(rb"\1", a["room.vebuild.json"]) == AUDIT_TIME.sub(rb"\1", b["room.vebuild.json"])
    trail_a, trail_b = json.loads(a["room.vebuild.json"])["audit"], json.loads(b["room.vebuild.json"])["audit"]
    assert [e["command"] for e in trail_a] == ["calibrate", "solve", "texture"]
    assert [e["arguments"] for e in trail_a] == [["room.vebuild.json", "--quiet"],
                                                 ["room.vebuild.json", "--recalibrate"],
                                                 ["room.vebuild.json", "--density", "50", "--quiet"]]
    # SOURCE_DATE_EPOCH is the time recorded, step by step; without it, the clock.
    assert [e["time"] for e in trail_a] == [_utc(t) for t in EPOCHS[:3]]
    assert all(start <= e["time"] <= end for e in trail_b), [e["time"] for e in trail_b]

    # Every output names the state it was made from by the same digest: the last audit entry's after_sha256.
    digest = trail_a[-1]["after_sha256"]
    assert trail_b[-1]["after_sha256"] == digest
    assert json.loads(a["figures/distance.json"])["inputs_sha256"] == digest
    assert json.loads(a["viewer/vebuild-html.json"])["inputs_sha256"] == digest
    assert digest.encode() in a["renders/doorway.png"] and digest.encode() in a["export/room.glb"]
    assert digest.encode() in a["export/room.obj"] and digest.encode() in a["report/report.html"]


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
