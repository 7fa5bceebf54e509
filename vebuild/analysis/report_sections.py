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
from vebuild.atomic import write_text
from vebuild.errors import ProjectError, VebuildError

#: Analyses that write an image, and whether they need something more to do so (trajectory: a view).
_IMAGE_WHEN = {"sightline": None, "viewshed": None, "lighting": None, "trajectory": "view"}


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise VebuildError(message)


def parse(project_file: str, words: list[str]) -> argparse.Namespace:
    """The ``vebuild analyse`` arguments of one recorded command (errors as VebuildError)."""
    from vebuild.analysis.cli import add_analyse_parsers

    # A recorded command is run, never explained: help would print and exit instead of analysing.
    for word in words:
        if word == "-h" or (len(word) >= 3 and "--help".startswith(word)):
            raise VebuildError(f"{word!r} asks for help, which is not an analysis; record the words of the "
                               "analysis itself, such as [\"distance\", \"cabinet:v4\", \"table.top@top\"]")
    parser = _Parser(prog="vebuild", add_help=False)
    add_analyse_parsers(parser.add_subparsers(dest="command", parser_class=_Parser))
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            return parser.parse_args(["analyse", project_file, *words])
    except SystemExit:  # an action that prints and exits (argparse's help or version)
        raise VebuildError(f"{' '.join(words)!r} is not an analysis command") from None


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
