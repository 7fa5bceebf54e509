"""The report's "Processing record": the stages' status (current or stale, each with its reason and
the command that updates it) and the audit trail (vebuild.project.provenance), as tables, so that a
second examiner can see how the figures came about and check the chain of hashes."""

from __future__ import annotations

from vebuild.project import Project
from vebuild.project.provenance import STAGES, stale, verify_audit

from .page import Report, esc, table

_NAMES = {"calibration": "calibration (vanishing points, placement, registration)",
          "model_solution": "model solution (vebuild solve)", "textures": "textures (vebuild texture)"}
_HASH = 12  # hex digits of a hash shown in the table (the project file holds them whole)


def processing(project: Project, rep: Report) -> None:
    data = project.data
    found = {s.stage: s for s in stale(data, project.path.name)}
    rows = []
    for stage in STAGES:
        if not isinstance(data.get(stage), dict):
            continue
        s = found.get(stage)
        rows.append([_NAMES[stage], "stale" if s else "current", s.reason if s else "computed from the project as "
                     "it is now", s.command if s else ""])
    body = ["<h3>Stages</h3>",
            table(["stage", "status", "why", "brings it up to date"], rows) if rows else "<p>No results yet.</p>"]
    trail = data.get("audit") or []
    body.append("<h3>Audit trail</h3>")
    if not trail:
        body.append("<p>No audit trail: no command of this vebuild has changed the project.</p>")
    else:
        body.append("<p class='small'>Each command that changed the project, with the SHA-256 of the document "
                    "before and after it (of the project file's JSON without <code>audit</code>, keys sorted, "
                    "compact separators, UTF-8; scenes/FORMAT.md, “Audit trail”); the paths in a command are "
                    "relative to the project's folder. When each ran is in the project file (<code>audit[].time"
                    "</code>), not here: the time is the examiner's, and the same commands run again at another "
                    "time give this report byte for byte.</p>")
        body.append(table(["#", "command", "vebuild", "before SHA-256", "after SHA-256"],
                          [[i + 1, " ".join(["vebuild", e["command"], *e["arguments"]]), e["vebuild"],
                            (e["before_sha256"] or "none")[:_HASH] + ("…" if e["before_sha256"] else ""),
                            e["after_sha256"][:_HASH] + "…"] for i, e in enumerate(trail)], numeric={0, 3, 4},
                          wide=True))
        breaks = verify_audit(data)
        body.append("<p class='warn'>" + "<br>".join(esc(b.message) for b in breaks) + "</p>" if breaks else
                    "<p>The chain verifies: each entry starts from the document the one before it wrote, and the "
                    "project file is the document the last one wrote.</p>")
    rep.add("Processing record", "\n".join(body))
