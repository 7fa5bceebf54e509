"""The whole project decoded as the commands decode it: the one check that ``vebuild check`` and
every command that reads a project run after loading it, so that the same project gets the same
answer, with the same message, whichever command reads it.

Loading (:func:`vebuild.project.load_project`) checks the document against the schema and what a
schema cannot say; :func:`decode_project` goes on to decode what each command decodes: the model
and its observations (``solve``, ``render``, ``analyse``), the calibrated and re-calibrated
cameras, the hypotheses, the lighting presets, the views and every image size a render takes from
the project, the recorded analyses (``report`` runs them: the measurements are run here too), the
laser scans and the texture pages (``render``, ``export``). It uses the same functions as those
commands, so it raises the very error they would, and imports no GL.

A stage that writes a part anew does not read that part as it was (:data:`REPLACES`): ``calibrate``
mends a calibration whose camera is broken, ``solve`` a solution, ``texture`` its pages.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

from vebuild.errors import ProjectError, VebuildError
from vebuild.project import Project, load_project
from vebuild.project import decode as dec

if TYPE_CHECKING:
    from collections.abc import Collection

    from vebuild.model.scene import Model

#: The parts of the document each stage writes anew, and so need not decode as they were (the
#: recorded analyses rest on the calibration and the solution: they are not run by those stages).
REPLACES: dict[str, frozenset[str]] = {
    "calibrate": frozenset({"calibration", "model_solution", "analyses"}),
    "solve": frozenset({"model_solution", "analyses"}),
    "texture": frozenset({"textures"}),
    "scan add": frozenset({"scans"}),
}

#: The recorded analyses that make no image and need no GL: run by the check as the report runs
#: them (those of :data:`ON_A_PHOTO` rest on the calibration, the others on the solved model).
#: The single-view measurements (:data:`vebuild.analysis.single_view.SINGLE_VIEW_CLICKS`' kinds).
ON_A_PHOTO = ("photo-height", "floor-distance", "wall-length", "raised-height", "plane-length")
MEASUREMENTS = ("distance", "height", "dimensions", "checks", *ON_A_PHOTO)


def load_checked(path: str | os.PathLike[str], command: str) -> Project:
    """The project at ``path`` loaded and decoded whole (:func:`decode_project`) for ``command``:
    what every command that reads a project opens it with."""
    project = load_project(path)
    decode_project(project, REPLACES.get(command, frozenset()))
    return project


def decode_project(project: Project, replaced: Collection[str] = ()) -> list[str]:
    """Decode everything the commands rely on (but the parts in ``replaced``); lines describing it,
    for the check's report.

    Raises
    ------
    ProjectError (a VebuildError) naming the file, the JSON path and what was expected.
    """
    data = project.data
    lines = []
    if (data.get("calibration") or {}).get("cameras") and "calibration" not in replaced:
        cameras = dec.cameras_from_calibration(project)
        lines.append(f"calibration: {len(cameras)} camera(s), each a pinhole camera with a rotation")
        from vebuild.project.camera_groups import recalibration_groups

        recalibration_groups(data, cameras, project.path)  # what `solve --recalibrate` shares
        sol = data.get("model_solution") or {}
        if sol.get("cameras") and "model_solution" not in replaced:
            dec.cameras(project)  # the re-calibrated ones decoded and checked as the calibration's
            lines.append(f"re-calibration: {len(sol['cameras'])} camera(s) and {len(sol.get('markers') or {})} "
                         "marker(s) in $.model_solution")
    for pid, why in ((data.get("calibration") or {}).get("left_out") or {}).items():
        # A photo the calibration left out has no camera, as every later command will say.
        reason = why.get("reason") if isinstance(why, dict) else why
        lines.append(f"calibration: photo '{pid}' left out, no camera ($.calibration.left_out.{pid}): {reason}")
    if (data.get("model") or {}).get("nodes"):
        model, pins, edges = dec.load_model(project, dec.markers(data, "joints"))
        lines.append(f"model: {len(model.nodes)} node(s), {len(pins)} pin(s), {len(edges)} edge observation(s)")
        _check_hypotheses(project, model)
    if "model_solution" not in replaced:
        _check_model_solution(project)
    for preset in (data.get("lighting") or {}).get("presets", []):
        dec.preset_from_record(preset)
    for view in data.get("views", []):
        dec.view_camera(view)
    _check_analyses(project, run="analyses" not in replaced)
    check_render_sizes(project, replaced)
    if data.get("analyses"):
        lines.append(f"analyses: {len(data['analyses'])} recorded command(s), each a `vebuild analyse` command")
    if data.get("scans") and "scans" not in replaced:  # each scan read, its hash checked, its registration decoded
        from vebuild.project.scans import load_point_cloud

        from .scans import similarity_of

        for i in range(len(data["scans"])):
            load_point_cloud(project, i)
            similarity_of(project, i)
        lines.append(f"laser scans: {len(data['scans'])} scan(s), hashes verified, registrations decoded")
    pages = (data.get("textures") or {}).get("pages", [])
    if pages and "textures" not in replaced:
        present, _ = dec.texture_pages(project)
        read = {p.index for p in present}
        missing = [page["atlas"] for k, page in enumerate(pages) if k not in read]
        lines.append(f"textures: {len(pages) - len(missing)} of {len(pages)} atlas page(s) present, hashes verified"
                     + (f" (missing: {', '.join(missing)}; `vebuild texture` writes them again)" if missing else ""))
    return lines


def _check_analyses(project: Project, run: bool) -> None:
    """Each recorded analysis parsed; each measurement among them (no image, no GL: distance,
    height, dimensions, checks and the single-view measurements) run as the report runs it, where the
    results it rests on are there; and the views and presets the others name found."""
    if not project.data.get("analyses"):
        return  # the analyses' parsers (and the geometry they import) are not needed
    from vebuild.project.hypotheses import find_hypothesis

    from .recorded import parse_recorded, run_recorded

    data = project.data
    solved = bool(data.get("model_solution")) and bool((data.get("model") or {}).get("nodes"))
    calibrated = bool((data.get("calibration") or {}).get("cameras"))
    modelled = bool((data.get("model") or {}).get("nodes"))
    for i, rec in enumerate(data.get("analyses") or []):
        where = f"$.analyses[{i}].command"
        try:
            request = parse_recorded(list(rec["command"]))
            if request.name in MEASUREMENTS:
                if run and (calibrated if request.name in ON_A_PHOTO else solved):
                    run_recorded(project, i, rec)
                continue
            view = getattr(request, "view", None)
            if view is not None:
                dec.find_view(project, view)
            for preset in [*(getattr(request, "presets", None) or ()), getattr(request, "lighting", None)]:
                dec.find_preset(project, preset)
            hypothesis = getattr(request, "hypothesis", None)
            if hypothesis is not None:
                find_hypothesis(project, hypothesis)
            if modelled and calibrated:  # the model stands where the calibration's markers put it
                _check_targets(project, request)
        except ProjectError as e:
            if e.where == where:
                raise
            raise ProjectError(project.path, where, str(e)) from None
        except VebuildError as e:
            raise ProjectError(project.path, where, str(e)) from None


def _check_targets(project: Project, request: Any) -> None:
    """What a recorded sight line or viewshed looks from and for (:meth:`aim`), a trajectory (run
    whole: a few rays) and a lighting comparison's ``--target``, read against the model as the
    analyses read them, in the hypothesis they name, on the untextured scene (no atlas read)."""
    aim = getattr(request, "aim", None)
    if request.name == "lighting":
        from .sightline import lighting_target

        lighting_target(dec.model(project), request.target)
    if aim is None and request.name != "trajectory":
        return
    from vebuild.project.hypotheses import hypothesis_model
    from vebuild.project.units import length_unit
    from vebuild.render.scene import scene_from_model

    from .rays import Occluders

    model = dec.model(project)
    if request.hypothesis is not None:
        model = hypothesis_model(project, model, request.hypothesis)
    occ = Occluders(scene_from_model(model), length_unit(project.data))
    if aim is not None:
        aim(occ)
    else:
        request.trajectory(occ)


def check_render_sizes(project: Project, replaced: Collection[str] = ()) -> None:
    """Every image size a render takes from the project, checked as the render checks it (the
    GL-free limits of :func:`vebuild.render.sizes.check_render_size`): each view's own size
    (``render --view``, ``video``), the report's image of each view and of each calibrated photo,
    and the ``--size`` of each recorded analysis (the report runs it). A photo's own size is not
    a render's: only its report image is checked."""
    from vebuild.render.sizes import IMAGE_WIDTH, check_render_size, image_size, parse_size

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
    calibrated = dec.camera_records(data) if "calibration" not in replaced else {}
    for i, p in enumerate(data["photos"]):
        if p["id"] in calibrated:
            located(*image_size(p["width"], p["height"]),
                    f"the report's image of photo {p['id']!r} ({IMAGE_WIDTH} pixels wide, its height from the "
                    f"aspect of $.photos[{i}], {p['width']}×{p['height']})")
    for i, rec in enumerate(data.get("analyses") or []):
        from .recorded import parse_recorded  # only where analyses are recorded: docs/start-up.md

        size = getattr(parse_recorded(list(rec["command"])), "size", None)
        if size is not None:
            try:
                parse_size(size)
            except VebuildError as e:
                raise ProjectError(project.path, f"$.analyses[{i}].command", str(e)) from None


def _check_hypotheses(project: Project, model: Model) -> None:
    # Each hypothesis applied to the model as render --hypothesis applies it (joint limits and all).
    from vebuild.project.hypotheses import applied_hypothesis

    for i in range(len(project.data.get("hypotheses") or [])):
        applied_hypothesis(project, model, i)


def _check_model_solution(project: Project) -> None:
    # What analyse and report decode of the solution: its nodes and the covariance's shape.
    from .solved import check_model_solution

    check_model_solution(project)
