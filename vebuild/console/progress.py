"""Progress bars of the command line (tqdm), as the callbacks the library's long stages take."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from .terminal import shown


@contextmanager
def progress_bar(enabled: bool, desc: str = "texturing",
                 unit: str = "photo") -> Iterator[Callable[[int, int, str], None]]:
    """A tqdm bar, as a ``progress(done, total, label)`` callback: over photos for
    :func:`texture_project`, over frames for a video (``desc``, ``unit``)."""
    from .bars import Bar

    bar = Bar(total=None, desc=desc, unit=unit, disable=not enabled)

    def step(done: int, total: int, photo: str) -> None:
        bar.total, bar.n = total, done
        bar.set_postfix_str(shown(photo))
        bar.refresh()

    try:
        yield step
    finally:
        bar.close()
