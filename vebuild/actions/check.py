"""``vebuild check``: everything the later commands read from a project, decoded as they decode it.

The decoding is :func:`vebuild.analysis.project_check.decode_project`, which every command that
reads a project runs after loading it (:func:`~vebuild.analysis.project_check.load_checked`): what
``check`` refuses, every command refuses with the same message, and what a command would refuse
on reading the project, ``check`` refuses. This adds the stale results and the audit trail.
"""

from __future__ import annotations

from dataclasses import dataclass

from vebuild.analysis.project_check import decode_project
from vebuild.project import Project
from vebuild.project.provenance import AuditProblem, Stale, inputs_sha256, stale, verify_audit

__all__ = ["Status", "check_project", "project_status"]


def check_project(project: Project) -> list[str]:
    """Decode everything the commands rely on (:func:`vebuild.analysis.project_check.decode_project`,
    which every command runs at load); lines describing it, for the check's report.

    Raises
    ------
    ProjectError (a VebuildError) naming the file, the JSON path and what was expected.
    """
    return decode_project(project)


@dataclass(frozen=True)
class Status:
    """Whether a project's results are current and its audit trail whole (``vebuild check``).

    ``stale``: the stale results (vebuild.project.provenance.stale); ``audit``: the breaks in the
    audit chain; ``lines``: both in words, for the check's report; ``clean``: neither.
    """

    stale: list[Stale]
    audit: list[AuditProblem]
    lines: list[str]

    @property
    def clean(self) -> bool:
        return not self.stale and not self.audit


def project_status(project: Project) -> Status:
    """The stale results and the audit trail's breaks, with lines saying so (or that all is current)."""
    data = project.data
    found = stale(data, str(project.path))
    breaks = verify_audit(data)
    lines = [f"stale: {s.message}" for s in found]
    present = [s for s in ("calibration", "model_solution", "textures") if isinstance(data.get(s), dict)]
    if present and not found:
        lines.append(f"current: {', '.join(present)} (each computed from the project as it is now)")
    trail = data.get("audit") or []
    if not trail:
        lines.append("audit trail: none (no command of this vebuild has changed the project yet)")
    elif not breaks:
        last = trail[-1]
        lines.append(f"audit trail: {len(trail)} command(s), the chain verified; the file is as `vebuild "
                     f"{last['command']}` wrote it ({last['time']})")
    lines += [f"audit trail: {b.message}" for b in breaks]
    # What every output made from the project as it is now names it by (FORMAT.md, "Inputs digest").
    lines.append(f"inputs SHA-256: {inputs_sha256(data)} (what outputs made from it now record)")
    return Status(found, breaks, lines)
