"""``vebuild case PROJECT --number … --examiner …``: the case details the report's title page shows
(the project's ``case`` object, FORMAT.md).

Each option given sets its field; an empty text removes it; fields not named stay as they were.
The project is saved through :func:`vebuild.project.save_project`, which validates it first.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from typing import Any

from vebuild.analysis.project_check import load_checked
from vebuild.errors import VebuildError
from vebuild.project import Project, save_project

#: Each field of ``case``: its key, its label on the report's title page, and its ``vebuild case``
#: option, in the order the title page shows them.
CASE_FIELDS: tuple[tuple[str, str, str], ...] = (
    ("number", "case number", "--number"),
    ("examiner", "examiner", "--examiner"),
    ("organisation", "organisation", "--organisation"),
    ("photo_dates", "date(s) of the photos", "--photo-dates"),
    ("question", "the question", "--question"),
    ("declaration", "declaration", "--declaration"),
)


def case_rows(data: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The case's fields that the project gives, as (label, text), in :data:`CASE_FIELDS`' order."""
    case = data.get("case") or {}
    return [(label, str(case[key])) for key, label, _ in CASE_FIELDS if case.get(key)]


def set_case(project: Project, values: Mapping[str, str | None]) -> dict[str, str]:
    """Set the case fields ``values`` (key → text; None: leave it, "": remove it) in the project's
    document; returns the case as it now is. The caller saves the project."""
    unknown = sorted(set(values) - {k for k, _, _ in CASE_FIELDS})
    if unknown:
        raise VebuildError(f"case: unknown field(s) {', '.join(unknown)}; the fields are "
                           + ", ".join(k for k, _, _ in CASE_FIELDS))
    case = dict(project.data.get("case") or {})
    for key, text in values.items():
        if text is None:
            continue
        if text.strip():
            case[key] = text
        else:
            case.pop(key, None)
    if case:
        project.data["case"] = {k: case[k] for k, _, _ in CASE_FIELDS if k in case}
    else:
        project.data.pop("case", None)
    return dict(project.data.get("case") or {})


def _cmd_case(args: argparse.Namespace) -> int:
    project = load_checked(args.project, "case")
    values = {key: getattr(args, key) for key, _, _ in CASE_FIELDS}
    if any(v is not None for v in values.values()):
        set_case(project, values)
        save_project(project)
        print(f"case details written to {project.path}")
    rows = case_rows(project.data)
    for label, text in rows:
        print(f"  {label + ':':<24} {text}")
    if not rows:
        print("  no case details (give --number, --examiner, --organisation, --photo-dates, --question or "
              "--declaration)")
    return 0


def add_case_parser(sub: Any) -> None:
    """Add ``vebuild case`` to the top-level subparsers ``sub``."""
    p = sub.add_parser("case", help="set (or show) the case details on the report's title page")
    p.add_argument("project")
    helps = {"number": "the case (or file) number", "examiner": "who made the reconstruction",
             "organisation": "the examiner's organisation",
             "photo_dates": "when the photos were taken (one date or several, in words or ISO 8601)",
             "question": "what the reconstruction was asked to answer, in the words of the request "
                         "(the report's first page answers it)",
             "declaration": "the examiner's declaration, printed on the title page"}
    for key, _, option in CASE_FIELDS:
        p.add_argument(option, dest=key, metavar="TEXT", help=helps[key] + " (\"\" removes it)")
    p.set_defaults(func=_cmd_case)
