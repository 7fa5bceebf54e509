"""Benchmarks run by ``vebuild bench NAME``: each module has ``run(quick, progress) -> figures``
(a flat dict whose keys name the quantity and its unit) and ``table(figures) -> str``."""

from __future__ import annotations

from types import ModuleType

from . import calibration, edit, render, solver, texture

BENCHES: dict[str, ModuleType] = {"calibration": calibration, "edit": edit, "render": render, "solver": solver,
                                  "texture": texture}
