"""Benchmarks run by ``vebuild bench NAME``: each module has ``run(quick, progress) -> figures``
(a flat dict whose keys name the quantity and its unit) and ``table(figures) -> str``.

:data:`BENCHES` names them without importing them: a benchmark's module (with its GL and its
reference libraries) is imported only when it is looked up to run, so that the command line's
other commands (``vebuild check``) work where moderngl is missing."""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from types import ModuleType

_NAMES = ("calibration", "cli", "detect", "edit", "house", "render", "rooms", "solver", "texture")


class _Benches(Mapping[str, ModuleType]):
    """Name → module, each imported at its first look-up."""

    def __getitem__(self, name: str) -> ModuleType:
        if name not in _NAMES:
            raise KeyError(name)
        return importlib.import_module(f"{__name__}.{name}")

    def __iter__(self) -> Iterator[str]:
        return iter(_NAMES)

    def __len__(self) -> int:
        return len(_NAMES)


BENCHES: Mapping[str, ModuleType] = _Benches()
