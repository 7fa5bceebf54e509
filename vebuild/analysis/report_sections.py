"""The report's section for the analyses a project records (FORMAT.md, ``analyses``).

Each record is a name and the words of a ``vebuild analyse`` command (``["distance", "cabinet:v4",
"table.top@top"]``): the report runs exactly that command on the project, with its images written
into the report's folder, and shows its table, its image and its figures, so that the report
shows what the project file gives now, and the command line that reproduces each result.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import shlex
from typing import Any, NoReturn

from vebuild.actions.report import Report, esc
from vebuild.errors import ProjectError, VebuildError
from vebuild.project.atomic import write_text

#: Analyses that write an image, and whether they need something more to do so (trajectory: a view).
_IMAGE_WHEN = {"sightline": None, "viewshed": None, "lighting": None, "trajectory": "view"}


class _Parser(argparse.ArgumentParser):
    """An argparse parser that never prints or exits: every complaint is a :class:`VebuildError`
    (the stored words are data in a project file, not a command line a person is typing)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs["add_help"] = False  # -h/--help would print and exit; refused in :func:`parse`
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


#: Words that ask for help rather than an analysis.
_HELP_WORDS = ("-h", "--help")


def parse(project_file: str, words: list[str], where: str | None = None) -> argparse.Namespace:
    """The ``vebuild analyse`` arguments of one recorded command (``where``: its place in the
    project, ``$.analyses[i]``). It never prints or exits: a bad command, or one that asks for help,
    is a :class:`VebuildError` saying what was expected."""
    from vebuild.analysis.cli import add_analyse_parsers

    expected = ("expected the words of a `vebuild analyse` command after the project, such as "
                "[\"distance\", \"cabinet:v4\", \"table.top@top\"]")
    if not isinstance(words, list) or not all(isinstance(w, str) for w in words):
        raise VebuildError(f"{where + ': ' if where else ''}{expected}; got {words!r}")
    at = f"{where}: " if where else ""
    # A recorded command is run, never explained: help would print and exit instead of analysing
    # (argparse also takes an abbreviation such as '--he' for '--help').
    asks = [w for w in words if w in _HELP_WORDS or (len(w) >= 3 and "--help".startswith(w))]
    if asks:
        raise VebuildError(f"{at}the command asks for help ({asks[0]!r}), which is not an analysis; {expected}")
    parser = _Parser(prog="vebuild")
    add_analyse_parsers(parser.add_subparsers(dest="command", parser_class=_Parser))
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            return parser.parse_args(["analyse", project_file, *words])
    except argparse.ArgumentError as e:
        raise VebuildError(f"{at}{e}; {expected}") from None
    except VebuildError as e:
        raise VebuildError(f"{at}{e}; {expected}") from None
    except SystemExit:  # an action that prints and exits (argparse's version, say)
        raise VebuildError(f"{at}{' '.join(words)!r} is not an analysis command; {expected}") from None


def analyses(project: Any, rep: Report, records: list[dict[str, Any]]) -> str:
    parts = ["<p>Each analysis the project records, run again for this report; the command line reproduces it "
             "(`--json OUT` writes its figures). Lengths in metres; intervals at 95 %.</p>"]
    (rep.folder / "figures").mkdir(exist_ok=True)
    for i, rec in enumerate(records):
        where = f"$.analyses[{i}]"
        words = list(rec["command"])
        try:
            args = parse(str(project.path), words)
            kind = args.analysis_name
            image = None
            if kind in _IMAGE_WHEN and (_IMAGE_WHEN[kind] is None or getattr(args, _IMAGE_WHEN[kind], None)):
                image = f"images/analysis-{i + 1}.png"
                args.out = str(rep.folder / image)
            text, figures = args.handler(args, project)
        except VebuildError as e:
            raise ProjectError(project.path, f"{where}.command", str(e)) from None
        figures = {k: v for k, v in figures.items() if not str(k).endswith("_png")}  # paths of this run
        fig_name = f"figures/analysis-{i + 1}.json"
        write_text(rep.folder / fig_name, json.dumps({"analysis": kind, "command": words, **figures}, indent=2,
                                                     sort_keys=True, allow_nan=False) + "\n")
        text = text.replace(str(rep.folder) + "/", "")
        parts.append(f"<h3>{esc(rec['name'])}</h3>")
        if rec.get("description"):
            parts.append(f"<p>{esc(rec['description'])}</p>")
        command = "vebuild analyse " + shlex.quote(project.path.name) + " " + " ".join(shlex.quote(w) for w in words)
        parts.append(f"<p class='small'>{esc(command)} &nbsp; (figures: <a href='{fig_name}'>{fig_name}</a>)</p>")
        parts.append(f"<pre class='small'>{esc(text)}</pre>")
        if image and (rep.folder / image).is_file():
            rep.images.append(rep.folder / image)
            parts.append(f"<figure><img src='{image}'></figure>")
    return "".join(parts)
