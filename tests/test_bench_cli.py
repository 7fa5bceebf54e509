"""``vebuild bench cli``: start-up against ``python -c pass``, measured in the same run."""

from __future__ import annotations

import sys

import pytest

from vebuild.bench import BENCHES
from vebuild.errors import VebuildError


def test_quick_run_measures_the_check_against_pythons_start() -> None:
    bench = BENCHES["cli"]
    fig = bench.run(quick=True, progress=False)
    for key in ("python_start_s", "cli_check_s", "cli_check_over_python", "cli_version_s", "cli_check_cpu_s"):
        assert isinstance(fig[key], float) and fig[key] > 0, key
    # A command cannot start faster than the interpreter it runs in; the check does more than that.
    assert fig["cli_check_s"] > fig["python_start_s"] and fig["cli_check_over_python"] > 1.0
    assert fig["cli_check_median_s"] >= fig["cli_check_s"]
    assert fig["demo_s"] is None and fig["repeats"] == 3  # --quick leaves the demo out
    text = bench.table(fig)
    assert "vebuild check (example)" in text and "left out (--quick)" in text


def test_a_command_that_fails_is_named_with_what_it_said() -> None:
    from vebuild.bench.cli import _timed

    with pytest.raises(VebuildError, match=r"failed \(exit status 3\): broken$"):
        _timed([sys.executable, "-c", "import sys; print('broken', file=sys.stderr); sys.exit(3)"])
