"""``vebuild analyse PROJECT ANALYSIS …``: the forensic analyses on the command line.

Every subcommand prints a readable table and, with ``--json OUT``, writes its figures as JSON
(atomically): every number's unit is in its key (``value_m``, ``sigma_m``, ``ci95_m``). The JSON
document is ``{"software", "project", "analysis", ...the analysis' own keys}``.

The words of each subcommand and the request they make are in :mod:`vebuild.analysis.parsers`
(shared with the analyses a project records, :mod:`vebuild.analysis.recorded`); here each is run
on the project, loaded and checked as every command loads it. Errors are raised as
:class:`~vebuild.errors.VebuildError` and printed by ``vebuild``'s main.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from vebuild import __version__

from . import parsers


def add_analyse_parsers(sub: Any) -> None:
    """Add the ``analyse`` command group to the top-level subparsers ``sub``, each analysis run by
    :func:`_run`."""
    for q in parsers.add_analyse_parsers(sub).choices.values():
        q.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from vebuild.project.provenance import inputs_sha256, stale_warnings

    from .project_check import load_checked

    project = load_checked(args.project, "analyse")
    for line in stale_warnings(project, "analyse"):  # the stale results it reads (vebuild.project.provenance)
        print(line, file=sys.stderr)
    if args.json:
        from vebuild.project.outputs import check_file

        check_file(project, Path(args.json), "figures")
    request = parsers.request_from_args(args)
    if args.save is not None:
        record = saved_record(project, args.save, args.project)
    result = request.run(project)
    print(result.table)
    if args.save is not None:
        from vebuild.project import save_project

        project.data["analyses"] = [*(project.data.get("analyses") or []), record]
        save_project(project)
        print(f"saved as the analysis {args.save!r} of {project.path.name}: the report states it")
    if args.json:
        write_json(Path(args.json), {"software": f"vebuild {__version__}", "project": project.path.name,
                                     "inputs_sha256": inputs_sha256(project.data), "analysis": request.name,
                                     **result.figures})
        print(f"figures written to {args.json}")
    return 0


def saved_record(project: Any, name: str, project_word: str) -> dict[str, Any]:
    """The record ``--save NAME`` adds to the project's analyses (FORMAT.md ``analyses``): the name
    and the words of this command after the project, less ``--json OUT`` and ``--save NAME``."""
    from vebuild.errors import VebuildError
    from vebuild.project.provenance import current_command

    if not name.strip():
        raise VebuildError(f"{project.path}: --save: expected a name for the analysis, such as \"door height\"")
    taken = {str(a.get("name")) for a in project.data.get("analyses") or []}
    if name in taken:
        raise VebuildError(f"{project.path}: --save {name!r}: the project already has an analysis of that name; "
                           "give another name (nothing was saved)")
    running = current_command()
    words = list(running[1]) if running is not None else []
    words = words[words.index(project_word) + 1:] if project_word in words else words[1:]
    kept: list[str] = []
    skip = False
    for w in words:
        if skip:
            skip = False
        elif w in ("--json", "--save"):
            skip = True
        elif not w.startswith(("--json=", "--save=")):
            kept.append(w)
    return {"name": name, "command": kept}


def write_json(path: Path, doc: dict[str, Any]) -> None:
    """Write ``doc`` to ``path`` atomically (:mod:`vebuild.project.atomic`)."""
    from vebuild.errors import VebuildError
    from vebuild.project.atomic import write_text

    try:
        write_text(path, json.dumps(doc, indent=2, allow_nan=False) + "\n")
    except OSError as e:
        raise VebuildError(f"{path}: cannot write the figures ({e.strerror or e})") from None
