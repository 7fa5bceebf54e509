"""Benchmarks run by ``vebuild bench NAME``: each module has ``run(quick, progress) -> figures``
(a flat dict whose keys name the quantity and its unit) and ``table(figures) -> str``.

:data:`BENCHES` names them without importing them: a benchmark's module (with its GL and its
reference libraries) is imported only when it is looked up to run, so that the command line's
other commands (``vebuild check``) work where moderngl is missing."""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from pathlib import Path
from types import ModuleType
from typing import Any

from vebuild.errors import VebuildError

_NAMES = ("calibration", "cctv", "cli", "detect", "edit", "house", "orient", "real", "render", "rooms", "single-view",
          "solver", "texture")
#: The benchmarks that measure data the user gives (``--data DIR``), not data of their own.
_WITH_DATA = ("real",)


class _Benches(Mapping[str, ModuleType]):
    """Name → module, each imported at its first look-up."""

    def __getitem__(self, name: str) -> ModuleType:
        if name not in _NAMES:
            raise KeyError(name)
        return importlib.import_module(f"{__name__}.{name.replace('-', '_')}")  # single-view: single_view.py

    def __iter__(self) -> Iterator[str]:
        return iter(_NAMES)

    def __len__(self) -> int:
        return len(_NAMES)


BENCHES: Mapping[str, ModuleType] = _Benches()


def run_bench(name: str, *, quick: bool, progress: bool, data: str | None = None) -> tuple[dict[str, Any], str]:
    """Run the benchmark ``name``; its figures and their table. ``data``: ``--data DIR``, which
    only the benchmarks of :data:`_WITH_DATA` take (and require)."""
    bench = BENCHES[name]
    if name in _WITH_DATA:
        figures = bench.run(quick=quick, progress=progress, data=None if data is None else Path(data))
    elif data is not None:
        raise VebuildError(f"bench {name}: --data is for {', '.join(_WITH_DATA)} only; {name} measures data of "
                           "its own")
    else:
        figures = bench.run(quick=quick, progress=progress)
    return figures, bench.table(figures)
