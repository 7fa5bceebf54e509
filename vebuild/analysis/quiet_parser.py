"""An argparse parser that never prints or exits, for words that are data (a project's recorded
analyses), not a command line a person is typing: every complaint is a
:class:`~vebuild.errors.VebuildError`."""

from __future__ import annotations

import argparse
from typing import Any, NoReturn

from vebuild.errors import VebuildError


class QuietParser(argparse.ArgumentParser):
    """An argparse parser that never prints or exits: every complaint is a :class:`VebuildError`
    (the stored words are data in a project file, not a command line a person is typing)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs["add_help"] = False  # -h/--help would print and exit; refused in :func:`parse_recorded`
        kwargs["exit_on_error"] = False
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        raise VebuildError(message)

    def exit(self, status: int = 0, message: str | None = None) -> NoReturn:
        raise VebuildError(message.strip() if message else f"the command would exit (status {status})")

    def print_help(self, file: Any = None) -> None:
        raise VebuildError("the command asks for help (-h/--help); expected the words of an analysis")

    def print_usage(self, file: Any = None) -> None:
        raise VebuildError("the command asks for its usage; expected the words of an analysis")
