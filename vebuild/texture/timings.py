"""Seconds spent per stage of a texture extraction, summed over photos (``vebuild texture
--timings``, ``vebuild bench texture``)."""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import moderngl


@dataclass
class Timings:
    """Seconds spent per stage, summed over photos."""

    seconds: dict[str, float] = field(default_factory=lambda: defaultdict(float))

    @contextmanager
    def stage(self, name: str, ctx: moderngl.Context | None = None) -> Iterator[None]:
        """Time the ``with`` block; with ``ctx``, the GPU's work in it too (waited for)."""
        t = time.perf_counter()
        yield
        if ctx is not None:
            ctx.finish()
        self.seconds[name] += time.perf_counter() - t
