"""The command line's parser: argparse, which also says "did you mean" for a mistyped word.

A mistyped command (``vebuild calbrate``), analysis, benchmark name or option (``--sise``) gets
the closest names that exist, found with :mod:`difflib`; an option is looked up among those of
the command it was typed after, so ``vebuild render --sise`` suggests ``--size``.
"""

from __future__ import annotations

import argparse
import difflib
import re
from collections.abc import Sequence
from typing import Any, NoReturn

_INVALID_CHOICE = re.compile(r"invalid choice: '((?:[^'\\]|\\.)*)' \(choose from (.*)\)$")
_UNRECOGNIZED = "unrecognized arguments: "


def suggestion(word: str, names: Sequence[str], n: int = 3, cutoff: float = 0.6) -> str:
    """'; did you mean ...?' naming the names closest to ``word``, or '' when none is close."""
    close = difflib.get_close_matches(word, list(names), n=n, cutoff=cutoff)
    if not close and not word.startswith("-"):
        # A prefix typed in full of one name only (``vebuild calib``) is close enough.
        close = [n for n in names if n.startswith(word)][:3] if len(word) >= 3 else []
    if not close:
        return ""
    return "; did you mean " + " or ".join(f"'{c}'" for c in close) + "?"


class SuggestingParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors for a mistyped name suggest the names that exist."""

    def error(self, message: str) -> NoReturn:
        m = _INVALID_CHOICE.search(message)
        if m:
            choices = re.findall(r"'((?:[^'\\]|\\.)*)'", m.group(2))
            message += suggestion(m.group(1), choices)
        elif message.startswith(_UNRECOGNIZED):
            words = message[len(_UNRECOGNIZED):].split()
            options = [o for o in self._option_string_actions if o.startswith("--")]
            for word in words:
                option = word.split("=", 1)[0]
                hint = suggestion(option, options, n=2, cutoff=0.7) if word.startswith("--") else ""
                if hint:
                    message += f"; {option}: {hint.removeprefix('; ')}"
        super().error(message)

    def parse_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                   namespace: argparse.Namespace | None = None) -> argparse.Namespace:
        parsed, extra = self.parse_known_args(args, namespace)
        if extra:
            # Reported by the command the words were typed after, which knows its own options.
            self._innermost(parsed).error(_UNRECOGNIZED + " ".join(extra))
        return parsed

    def _innermost(self, parsed: argparse.Namespace) -> SuggestingParser:
        parser: SuggestingParser = self
        while True:
            sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
            if sub is None:
                return parser
            chosen: Any = sub.choices.get(getattr(parsed, sub.dest, None) or "") if sub.choices else None
            if not isinstance(chosen, SuggestingParser):
                return parser
            parser = chosen


#: The arguments (by ``dest``) whose values name a file or folder, in every command that has them;
#: and those that do only in one command (``photos`` is a list of photo ids elsewhere).
PATH_ARGUMENTS = ("project", "out", "json", "html", "add_photo", "targets", "file")
PATH_ARGUMENTS_OF = {"new": ("photos",), "scan": ("scan",)}


def path_words(parsed: argparse.Namespace) -> set[str]:
    """The words of a parsed command line that name files or folders: what the audit trail records
    relative to the project's folder (vebuild.project.provenance.audit_entry)."""
    dests = PATH_ARGUMENTS + PATH_ARGUMENTS_OF.get(getattr(parsed, "command", None) or "", ())
    out: set[str] = set()
    for dest in dests:
        value = getattr(parsed, dest, None)
        for v in value if isinstance(value, list) else [value]:
            if isinstance(v, str) and v:  # `scan check --scan N` is a number, not a file
                out.add(v)
    return out
