"""Text from files, printed on the terminal with its control characters shown, not obeyed.

A project's text (case details, names, descriptions, labels, paths, the values an error message
quotes) is the user's or anyone's: a name holding ``ESC]0;…BEL`` would retitle the terminal,
``ESC[2J`` clear it, a carriage return print over the line before it, and a right-to-left override
(U+202E) show ``12.5`` as ``5.21``. :func:`shown` writes each such character as its escape
(``\\x1b``, ``\\r``, ``\\u202e``), and :func:`escaped_output` puts it between every command and
the terminal: everything the command line prints to stdout and stderr passes through it, so that
no text from a file reaches the terminal raw, wherever it is printed. Line breaks and tabs pass.

The progress bars are vebuild's own drawing (a carriage return moves back over the bar): they
write to the stream underneath (:func:`bar_stream`), with any label from a file passed through
:func:`shown`.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import IO, Any

#: What is escaped: the C0 controls but line feed and tab, DEL, the C1 controls, the bidirectional
#: marks, embeddings, overrides and isolates (U+061C, U+200E–U+200F, U+202A–U+202E, U+2066–U+2069),
#: the line and paragraph separators (U+2028, U+2029), and lone surrogates (which no terminal
#: encoding can write).
CONTROLS = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069"
                      "\ud800-\udfff]")


def _escape(m: re.Match[str]) -> str:
    c = ord(m.group())
    return f"\\x{c:02x}" if c < 0x100 else f"\\u{c:04x}"


def shown(text: str) -> str:
    """``text`` with every character of :data:`CONTROLS` written as its escape (``\\x1b``, ``\\u202e``)."""
    return CONTROLS.sub(_escape, text)


class EscapingStream:
    """A text stream that writes everything through :func:`shown` to the stream ``raw``."""

    def __init__(self, raw: IO[str]) -> None:
        self.raw = raw

    def write(self, text: str) -> int:
        self.raw.write(shown(text))
        return len(text)

    def writelines(self, lines: Any) -> None:
        for line in lines:
            self.write(line)

    def __getattr__(self, name: str) -> Any:  # flush, isatty, fileno, encoding…: the stream's own
        return getattr(self.raw, name)


@contextmanager
def escaped_output() -> Iterator[None]:
    """sys.stdout and sys.stderr as :class:`EscapingStream` while the block runs (as a decorator:
    while the function runs)."""
    saved = sys.stdout, sys.stderr
    sys.stdout = _wrapped(sys.stdout)
    sys.stderr = _wrapped(sys.stderr)
    try:
        yield
    finally:
        sys.stdout, sys.stderr = saved


def _wrapped(stream: Any) -> Any:
    return stream if stream is None or isinstance(stream, EscapingStream) else EscapingStream(stream)


def bar_stream() -> IO[str]:
    """The stream progress bars draw on: stderr beneath its escaping (their labels go through :func:`shown`)."""
    err: Any = sys.stderr
    return err.raw if isinstance(err, EscapingStream) else err
