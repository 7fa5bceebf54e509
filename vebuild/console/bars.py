"""The command line's progress bars: tqdm, drawn on the terminal beneath the escaping of
:mod:`.terminal` (a bar's carriage returns are its own drawing; a label from a file goes through
:func:`.terminal.shown` first)."""

from __future__ import annotations

from typing import Any

from tqdm import tqdm

from .terminal import bar_stream


class Bar(tqdm):
    """A tqdm bar on :func:`.terminal.bar_stream` unless given another ``file``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("file", bar_stream())
        super().__init__(*args, **kwargs)
