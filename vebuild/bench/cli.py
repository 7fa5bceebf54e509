"""``vebuild bench cli``: how long the command line takes to start, and the demo end to end.

Each command runs in a fresh interpreter, as a user's shell runs it (``python -m vebuild``, the
interpreter of this process), in the same run as the reference: ``python -c pass``, the least a
command can cost. ``vebuild check`` on the bundled example is the light command (it decodes the
whole project but draws nothing: docs/start-up.md); ``vebuild demo`` runs every stage (calibrate,
solve with re-calibration, texture, the views under each lighting preset and each photo's camera
against its photo) into a temporary folder.

The commands run from compiled bytecode, as an installed vebuild does (pip compiles a wheel's
modules as it installs them): the children's environment drops ``PYTHONDONTWRITEBYTECODE``, so
the warm-up run writes the ``.pyc`` files of whatever the command imports, and ``bytecode_cached``
says so. A machine that sets the variable would otherwise measure Python compiling vebuild's
modules from source on every run (about 0.1 s of ``vebuild check``).

Times are wall-clock seconds, the least of ``REPEATS`` runs (other work on the machine slows a
run, never speeds it up; the median is given too), with the CPU seconds (user + system) the
commands' processes used. ``--quick`` runs each start-up three times and leaves the demo out.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from vebuild.errors import VebuildError
from vebuild.resources import example_project_dir

GOALS = {"cli_check_s": 0.4, "demo_s": 35.0}
REPEATS = 7
QUICK_REPEATS = 3
#: The longest one command may take here before the benchmark gives up on it.
TIMEOUT_S = 1800


def _child_env() -> dict[str, str]:
    """This process's environment, less what would stop a child writing its bytecode."""
    return {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def _timed(argv: list[str], cwd: Path | None = None) -> tuple[float, float]:
    """Wall and CPU seconds (user + system, of the child) of one run of ``argv``; a failure is an
    error naming the command and what it said."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    r = subprocess.run(argv, capture_output=True, text=True, timeout=TIMEOUT_S, cwd=cwd, env=_child_env())
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode not in (0, 1):  # check says 1 for a stale project: still a complete run
        raise VebuildError(f"bench cli: `{' '.join(argv[1:])}` failed (exit status {r.returncode}): "
                           f"{(r.stderr or r.stdout).strip()[-500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def _repeated(argv: list[str], n: int, cwd: Path | None = None) -> dict[str, float]:
    runs = [_timed(argv, cwd) for _ in range(n)]
    walls, cpus = [w for w, _ in runs], [c for _, c in runs]
    return {"s": min(walls), "median_s": float(np.median(walls)), "cpu_s": min(cpus)}


def _bytecode_cached() -> bool:
    """Whether the modules ``vebuild check`` imports first have their bytecode written (the
    warm-up run could not write it where vebuild's folder is read-only and was installed without)."""
    import importlib.util

    import vebuild
    source = Path(vebuild.__file__)
    return Path(importlib.util.cache_from_source(str(source))).is_file()


def run(quick: bool = False, progress: bool = True) -> dict[str, Any]:
    n = QUICK_REPEATS if quick else REPEATS
    example = example_project_dir()
    project = next(example.glob("*.vebuild.json"))
    vebuild = [sys.executable, "-m", "vebuild"]
    fig: dict[str, Any] = {"repeats": n, "python": sys.version.split()[0]}
    _timed([sys.executable, "-c", "pass"])  # warm the file cache (and write vebuild's .pyc files)
    _timed([*vebuild, "check", str(project)])
    fig["bytecode_cached"] = _bytecode_cached()
    steps = (("python_start", [sys.executable, "-c", "pass"]), ("cli_check", [*vebuild, "check", str(project)]),
             ("cli_version", [*vebuild, "--version"]))
    for name, argv in steps:
        if progress:
            print(f"bench cli: {name.replace('_', ' ')} × {n}", file=sys.stderr)
        got = _repeated(argv, n)
        fig[f"{name}_s"], fig[f"{name}_median_s"], fig[f"{name}_cpu_s"] = got["s"], got["median_s"], got["cpu_s"]
    fig["cli_check_over_python"] = fig["cli_check_s"] / max(fig["python_start_s"], 1e-9)
    fig["cli_check_above_python_s"] = fig["cli_check_s"] - fig["python_start_s"]
    if quick:
        fig["demo_s"] = None
    else:
        if progress:
            print("bench cli: vebuild demo", file=sys.stderr)
        with tempfile.TemporaryDirectory(prefix="vebuild-bench-cli-") as tmp:
            wall, cpu = _timed([*vebuild, "demo", "--out", str(Path(tmp) / "demo"), "--quiet"])
        fig["demo_s"], fig["demo_cpu_s"] = wall, cpu
    fig["goals"] = dict(GOALS)
    fig["goals_met"] = bool(fig["cli_check_s"] <= GOALS["cli_check_s"]
                            and (fig["demo_s"] is None or fig["demo_s"] <= GOALS["demo_s"]))
    return fig


def table(fig: dict[str, Any]) -> str:
    code = "from bytecode" if fig.get("bytecode_cached") else "compiling from source: no bytecode could be written"
    lines = [f"command-line start-up (python {fig['python']}, {code}; least of {fig['repeats']} runs, median, "
             "CPU seconds)", "",
             f"{'':<28}{'wall s':>9}{'median':>9}{'CPU s':>9}"]
    for name, label in (("python_start", "python -c pass"), ("cli_version", "vebuild --version"),
                        ("cli_check", "vebuild check (example)")):
        lines.append(f"{label:<28}{fig[f'{name}_s']:>9.3f}{fig[f'{name}_median_s']:>9.3f}{fig[f'{name}_cpu_s']:>9.3f}")
    lines += ["", f"vebuild check: {fig['cli_check_over_python']:.2f}× python's start, "
              f"{fig['cli_check_above_python_s']:.3f} s above it (goal: ≤ {GOALS['cli_check_s']} s)"]
    if fig.get("demo_s") is None:
        lines.append("vebuild demo: left out (--quick)")
    else:
        lines.append(f"vebuild demo: {fig['demo_s']:.1f} s wall, {fig['demo_cpu_s']:.1f} s CPU "
                     f"(goal: ≤ {GOALS['demo_s']:g} s)")
    lines.append(f"goals: {'met' if fig['goals_met'] else 'NOT met'}")
    return "\n".join(lines)
