"""The analyses a project records (FORMAT.md, ``analyses``): each a name and the words of a
``vebuild analyse`` command after the project (``["distance", "cabinet:v4", "table.top@top"]``),
parsed here into the typed request they describe (:mod:`vebuild.analysis.requests`), by the
command line's own grammar and mapping, so that a recorded analysis and the command a person
types always mean the same. Parsing never prints or exits: a bad command, or one that asks for
help, is a :class:`~vebuild.errors.VebuildError` saying what was expected."""

from __future__ import annotations

import argparse
import contextlib
import io
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from vebuild.errors import VebuildError

if TYPE_CHECKING:
    from vebuild.project import Project

from .quiet_parser import QuietParser
from .requests import AnalysisResult, Request
from .requests_geometry import TrajectoryRequest
from .requests_person import WORD as PERSON_HEIGHT
from .requests_person import person_command
from .single_view import single_view_command

#: Words that ask for help rather than an analysis.
_HELP_WORDS = ("-h", "--help")
_EXPECTED = ("expected the words of a `vebuild analyse` command after the project, such as "
             "[\"distance\", \"cabinet:v4\", \"table.top@top\"]")


def parse_recorded(words: Any, where: str | None = None) -> Request:
    """The request of one recorded command (``where``: its place in the project, ``$.analyses[i]``,
    which then begins each message)."""
    from .parsers import add_analyse_parsers, request_from_args

    at = f"{where}: " if where else ""
    if not isinstance(words, list) or not all(isinstance(w, str) for w in words):
        raise VebuildError(f"{at}{_EXPECTED}; got {words!r}")
    # A recorded command is run, never explained: help would print and exit instead of analysing
    # (argparse also takes an abbreviation such as '--he' for '--help').
    asks = [w for w in words if w in _HELP_WORDS or (len(w) >= 3 and "--help".startswith(w))]
    if asks:
        raise VebuildError(f"{at}the command asks for help ({asks[0]!r}), which is not an analysis; {_EXPECTED}")
    parser = QuietParser(prog="vebuild")
    add_analyse_parsers(parser.add_subparsers(dest="command", parser_class=QuietParser))
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            args = parser.parse_args(["analyse", "PROJECT", *words])
    except argparse.ArgumentError as e:
        raise VebuildError(f"{at}{e}; {_EXPECTED}") from None
    except VebuildError as e:
        raise VebuildError(f"{at}{e}; {_EXPECTED}") from None
    except SystemExit:  # an action that prints and exits (argparse's version, say)
        raise VebuildError(f"{at}{' '.join(words)!r} is not an analysis command; {_EXPECTED}") from None
    return request_from_args(args)


def parse_recorded_trajectory(words: Any, where: str | None = None) -> TrajectoryRequest:
    """The trajectory request of one recorded command (the viewer draws them); a recorded command
    of another analysis is a :class:`VebuildError`."""
    request = parse_recorded(words, where)
    if not isinstance(request, TrajectoryRequest):
        raise VebuildError(f"{where + ': ' if where else ''}expected a trajectory, got a {request.name} analysis")
    return request


def run_recorded(project: Any, index: int, record: dict[str, Any],
                 image: str | None = None) -> tuple[Request, AnalysisResult]:
    """Run the recorded analysis ``record`` (``$.analyses[index]``) on the project again (the report
    and the web viewer show what the project gives now), its image, if it makes one, written to
    ``image``: the request and its result. A record that no longer runs is a ProjectError naming
    ``$.analyses[index].command``."""
    from vebuild.errors import ProjectError

    try:
        request = parse_recorded(list(record["command"]))
        if image is not None:
            request = request.with_image(image) or request
        return request, request.run(project)
    except VebuildError as e:
        raise ProjectError(project.path, f"$.analyses[{index}].command", str(e)) from None


def measure_clicked(project: Project, kind: str, photo: str,
                    clicks: Sequence[Sequence[float]]) -> tuple[list[str], AnalysisResult]:
    """One single-view measurement clicked on ``photo`` (or a person-height:
    :func:`~.requests_person.person_command`): the words saved for it
    (:func:`~.single_view.single_view_command`; record them as ``{"name", "description", "command": words}``)
    and the result of the request parsed from those words, as ``vebuild analyse PROJECT *words``
    runs it: its ``table`` is the text the command line prints, its ``figures["measurements"][0]``
    the value, 1σ and 95 % interval. A click that cannot be measured is a :class:`VebuildError`
    (a :class:`~.single_view.SingleViewError` naming the photo and the click) whose text is a sentence for the
    screen."""
    if kind == PERSON_HEIGHT:  # the top of the head, then the foot point (or the two feet)
        if len(clicks) not in (2, 3):
            raise VebuildError(f"a {kind} takes the top of the head and the foot point (or the two feet), got "
                               f"{len(clicks)} clicked points")
        words = person_command(photo, clicks[0], list(clicks[1:]))
    else:
        words = single_view_command(kind, photo, clicks)
    return words, parse_recorded(words).run(project)
