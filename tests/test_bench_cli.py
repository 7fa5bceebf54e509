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
    assert fig["bytecode_cached"] is True  # the checkout is writable: the warm-up wrote it
    text = bench.table(fig)
    assert "vebuild check (example)" in text and "left out (--quick)" in text and "from bytecode" in text


def test_the_commands_write_their_bytecode_where_the_environment_says_not_to(
        tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A pip-installed vebuild runs from compiled modules; the bench measures that, not Python
    compiling every module of the command on each run."""
    from vebuild.bench.cli import _timed

    monkeypatch.setenv("PYTHONDONTWRITEBYTECODE", "1")
    (tmp_path / "some_module.py").write_text("X = 1\n")
    _timed([sys.executable, "-c", "import some_module"], cwd=tmp_path)
    assert list((tmp_path / "__pycache__").glob("some_module.*.pyc"))


def test_a_command_that_fails_is_named_with_what_it_said() -> None:
    from vebuild.bench.cli import _timed

    with pytest.raises(VebuildError, match=r"failed \(exit status 3\): broken$"):
        _timed([sys.executable, "-c", "import sys; print('broken', file=sys.stderr); sys.exit(3)"])
