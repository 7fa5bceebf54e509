"""``vebuild check``: everything the later commands read from a project, decoded as they decode it.

Loading (:func:`vebuild.project.load_project`) checks the document against the schema and what a
schema cannot say; this goes on to decode what each command decodes: the model and its
observations (``solve``, ``render``, ``analyse``), the calibrated cameras, the lighting presets,
the recorded analyses (``report``) and the texture pages (``render``, ``export``). It uses the
same functions as those commands, so it reports the very error they would, and imports no GL.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..errors import ProjectError, VebuildError
from ..project import Project
from ..project import decode as dec
from ..project.provenance import AuditProblem, Stale, inputs_sha256, stale, verify_audit

if TYPE_CHECKING:
    from ..model.scene import Model


def check_project(project: Project) -> list[str]:
    """Decode everything the commands rely on; lines describing it, for the check's report.

    Raises
    ------
    ProjectError (a VebuildError) naming the file, the JSON path and what was expected.
    """
    data = project.data
    lines = []
    if (data.get("calibration") or {}).get("cameras"):
        cameras = dec.cameras_from_calibration(project)
        lines.append(f"calibration: {len(cameras)} camera(s), each a pinhole camera with a rotation")
        sol = data.get("model_solution") or {}
        if sol.get("cameras"):
            dec.cameras(project)  # the re-calibrated ones decoded and checked as the calibration's
            lines.append(f"re-calibration: {len(sol['cameras'])} camera(s) and {len(sol.get('markers') or {})} "
                         "marker(s) in $.model_solution")
    if (data.get("model") or {}).get("nodes"):
        model, pins, edges = dec.load_model(project, dec.markers(data, "joints"))
        lines.append(f"model: {len(model.nodes)} node(s), {len(pins)} pin(s), {len(edges)} edge observation(s)")
        _check_hypotheses(project, model)
    _check_model_solution(project)
    for preset in (data.get("lighting") or {}).get("presets", []):
        dec.preset_from_record(preset)
    for view in data.get("views", []):
        dec.view_camera(view)
    _check_analyses(project)
    check_render_sizes(project)
    if data.get("analyses"):
        lines.append(f"analyses: {len(data['analyses'])} recorded command(s), each a `vebuild analyse` command")
    if data.get("scans"):  # each scan's file read and its hash checked, its registration decoded
        from ..analysis.scans import similarity_of
        from ..project.scans import load_point_cloud

        for i in range(len(data["scans"])):
            load_point_cloud(project, i)
            similarity_of(project, i)
        lines.append(f"laser scans: {len(data['scans'])} scan(s), hashes verified, registrations decoded")
    pages = (data.get("textures") or {}).get("pages", [])
    present, _ = dec.texture_pages(project)
    read = {p.index for p in present}
    missing = [page["atlas"] for k, page in enumerate(pages) if k not in read]
    if pages:
        lines.append(f"textures: {len(pages) - len(missing)} of {len(pages)} atlas page(s) present, hashes verified"
                     + (f" (missing: {', '.join(missing)}; `vebuild texture` writes them again)" if missing else ""))
    return lines


def _check_analyses(project: Project) -> None:
    if not project.data.get("analyses"):
        return  # the analyses' parsers (and the geometry they import) are not needed
    from ..analysis.recorded import parse_recorded

    for i, rec in enumerate(project.data.get("analyses") or []):
        try:
            parse_recorded(list(rec["command"]))
        except VebuildError as e:
            raise ProjectError(project.path, f"$.analyses[{i}].command", str(e)) from None


def check_render_sizes(project: Project) -> None:
    """Every image size a render takes from the project, checked as the render checks it (the
    GL-free limits of :func:`vebuild.render.sizes.check_render_size`): each view's own size
    (``render --view``, ``video``), the report's image of each view and of each calibrated photo,
    and the ``--size`` of each recorded analysis (the report runs it). A photo's own size is not
    a render's: only its report image is checked."""
    from ..render.sizes import IMAGE_WIDTH, check_render_size, image_size, parse_size

    def located(width: Any, height: Any, source: str) -> None:  # source: the JSON path and what it is
        try:
            check_render_size(width, height, source)
        except VebuildError as e:
            raise ProjectError(project.path, "", str(e)) from None

    data = project.data
    for i, v in enumerate(data.get("views", [])):
        located(v["width"], v["height"], f"$.views[{i}] (width × height)")
        located(*image_size(v["width"], v["height"]),
                f"the report's image of view {v['name']!r} ({IMAGE_WIDTH} pixels wide, its height from the "
                f"aspect of $.views[{i}], {v['width']}×{v['height']})")
    calibrated = dec.camera_records(data)
    for i, p in enumerate(data["photos"]):
        if p["id"] in calibrated:
            located(*image_size(p["width"], p["height"]),
                    f"the report's image of photo {p['id']!r} ({IMAGE_WIDTH} pixels wide, its height from the "
                    f"aspect of $.photos[{i}], {p['width']}×{p['height']})")
    for i, rec in enumerate(data.get("analyses") or []):
        from ..analysis.recorded import parse_recorded  # only where analyses are recorded: docs/start-up.md

        size = getattr(parse_recorded(list(rec["command"])), "size", None)
        if size is not None:
            try:
                parse_size(size)
            except VebuildError as e:
                raise ProjectError(project.path, f"$.analyses[{i}].command", str(e)) from None


def _check_hypotheses(project: Project, model: Model) -> None:
    # Each hypothesis applied to the model as render --hypothesis applies it (joint limits and all).
    from ..project.hypotheses import applied_hypothesis

    for i in range(len(project.data.get("hypotheses") or [])):
        applied_hypothesis(project, model, i)


def _check_model_solution(project: Project) -> None:
    # What analyse and report decode of the solution: its nodes and the covariance's shape.
    from ..analysis.solved import check_model_solution

    check_model_solution(project)


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
