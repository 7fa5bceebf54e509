"""What `vebuild solve` says when it refuses a model (paper §3.1), in the investigator's words.

A refusal says what is true: the observations leave parts of the model undetermined (their rank
at a good start says so: :func:`vebuild.model.restart.start_report`), or the solve could not find
the model from where it started (the observations determine it at the start, or pinned corners
end behind their camera). The first line names the nodes and what to do in the modelling window;
the project file's fields follow on a ``details:`` line, for the expert.
"""

from __future__ import annotations

from typing import Any

from vebuild.errors import UndeterminedError, VebuildError
from vebuild.model.determination import param_words, too_few_observations
from vebuild.model.restart import start_report
from vebuild.model.solver import Problem
from vebuild.project import Project

#: How many names a refusal lists before "…".
NAMES_SHOWN = 12


def _listed(items: list[str]) -> str:
    return ", ".join(items[:NAMES_SHOWN]) + (" …" if len(items) > NAMES_SHOWN else "")


def refusal(project: Project, problem: Problem, sol: Any, solution: Any, x_start: Any = None) -> VebuildError:
    """The error for a solve that leaves ``solution.undetermined``: an UndeterminedError where the
    observations leave those parameters undetermined at the start ``x_start`` too (default: the
    problem's own), else a VebuildError that says the start was bad (how far the solve carried the
    nodes, which corners end behind their camera) and how to give it a better one in the window."""
    x_start = problem.clip(problem.x0()) if x_start is None else x_start
    report = start_report(problem, x_start, sol.x, solution.undetermined)
    if report.bad_start:
        nodes = list(dict.fromkeys([u.rsplit(".", 1)[0] for u in solution.undetermined]
                                   + [n for _, n, _ in report.behind]))
        moved = [f"{n} {report.moved_m[n]:.2f} m" for n in nodes if n in report.moved_m]
        behind = sorted({f"{n}'s corner {h} in photo '{ph}'" for ph, n, h in report.behind})
        why = []
        if report.determined_at_start:
            fixed = _listed([param_words(u) for u in report.determined_at_start])
            why.append(f"at the start the pins determine {fixed}, which the solve's end leaves open")
        if behind:
            why.append(f"the solve ended with {_listed(behind)} behind the camera")
        if moved:
            why.append(f"it carried {_listed(moved)} from where it started")
        return VebuildError(
            f"{project.path}: the solve could not find {_listed(nodes)} from where the model starts, though the pins "
            f"may well be enough: {'; '.join(why)}. In the modelling window, drag {_listed(nodes)} (Select, Esc) "
            "near where the photos show it, on the right side of what it is related to, then press Solve again\n"
            f"details: $.model.nodes ({_listed(solution.undetermined)} undetermined at the solve's end only)")
    words, details = too_few_observations(problem, solution)
    return UndeterminedError(
        f"{project.path}: too few observations: the pins and edges do not fix "
        f"{_listed([param_words(u) for u in solution.undetermined])}. What would: {words}\n"
        f"details: $.model: undetermined {_listed(solution.undetermined)}; {details} (FORMAT.md \"entered value\"); "
        "or mark those nodes \"solve\": false", solution.undetermined)
