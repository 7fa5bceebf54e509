"""Solve the model from the pins in the project: ``vebuild solve [--recalibrate]`` (paper §3.1, §3.2).

Reads the calibration stage's cameras and markers (``vebuild calibrate``, ``vebuild register``:
``calibration``), the model and its observations, solves every node's joint and parameters (with
``recalibrate`` jointly with the cameras and markers), writes the solved values back into
``model.nodes`` and the uncertainties and residuals into ``model_solution`` (see
scenes/FORMAT.md). The caller saves the project.

The stages are kept apart: the solve never writes into ``calibration``. Its priors are always the
calibration stage's (never an earlier solve's output, which would count the same marks again), so
re-running it gives the same figures. A re-calibrating solve writes its cameras into
``model_solution.cameras`` and its markers into ``model_solution.markers``; a plain one writes no
cameras (later stages then use the calibration's).

Every projection goes through each photo's lens distortion (its calibration record's
``distortion``). Re-calibrating with intrinsics refines a photo's k1 too where its record gives k1
a 1σ above 0, held by that prior; the refined k1, its 1σ and its corner displacement go into the
re-calibrated camera record (``source`` says it was refined). A k1 with a 1σ of 0 or null stays as
calibrated.
"""

from __future__ import annotations

import copy
from functools import partial
from typing import Any

import numpy as np

from vebuild import __version__, camera
from vebuild.analysis.scans import surface_observations as scan_surfaces
from vebuild.calibration.lsq import is_numeric_failure
from vebuild.calibration.positions import ReferenceDistance, check_scale_distances
from vebuild.camera import ImageCamera
from vebuild.constants import Z95
from vebuild.errors import CalibrationError, ProjectError, VebuildError
from vebuild.model.constraints import CONFLICT_TOL_M, conflict_message, conflicts, relation_records
from vebuild.model.determination import axis_records
from vebuild.model.residuals import MarkerObservation
from vebuild.model.restart import restart_nodes, troubled_nodes
from vebuild.model.scan_fit import ScanProblem
from vebuild.model.scene import Model
from vebuild.model.solution import handle_covariances, solution_at
from vebuild.model.solver import FINAL_PRIOR_SCALE, MarkerData, Problem, ProblemOptions, staged_start
from vebuild.project import Project, decode, json_path, provenance
from vebuild.project.camera_groups import recalibration_groups
from vebuild.project.decode import cameras_from_calibration, load_model
from vebuild.project.records import camera_record, distortion_record, json_values, value_sigma
from vebuild.project.units import length_unit

from . import fixed_camera
from .camera_group_records import solved_group_records
from .register import recalibration_cameras, recalibration_k1_sigmas
from .solve_words import refusal

#: The solve from the first guess gives up after this many iterations and the staged start takes
#: over: where it found the minimum it took 9 (the generated house) to 27 (the generated rooms of
#: `vebuild bench rooms`); where it did not, it ran to the solver's 100 without converging.
DIRECT_MAX_ITERATIONS = 50

#: A pinned handle must project in front of its camera and no farther outside the image than this
#: share of its size; otherwise the pin is on a vertex that camera cannot see.
VISIBLE_MARGIN = 0.25


def solve_project(project: Project, recalibrate: bool = False, refine_intrinsics: bool = True) -> dict[str, Any]:
    """Solve the model (and with ``recalibrate`` the cameras and markers); write and return results.

    When re-calibrating, each camera's focal length and principal point take part too, held by
    their calibration covariance (``refine_intrinsics``), so that their uncertainty reaches the
    model's; without, they are taken as exact.
    """
    data = project.data
    before = _current_solution(data, recalibrate, refine_intrinsics)
    cameras = cameras_from_calibration(project)
    if recalibrate:  # a registered photo held by its registration's own prior (actions/register.py)
        cameras = recalibration_cameras(project, cameras, refine_intrinsics)
    model, pins, edges = load_model(project)
    cal = data["calibration"]
    origin = cal.get("origin_marker")
    markers = decode.markers(data)
    marker_obs, distances = [], []
    if recalibrate:
        for p in data["photos"]:
            for n, uv in decode.sightings(p).items():
                if n in markers:
                    marker_obs.append(MarkerObservation(p["id"], n, uv))
        node_names = {n.name for n in model.nodes}
        for d in decode.reference_distances(data):
            # A distance to a marker that no calibrated photo places yet waits for that photo.
            ends_known = all(e in markers or e.split(":", 1)[0] in node_names for e in (d.a, d.b))
            if d.role == "scale" and ends_known:
                distances.append(d)
        check_recalibration_scale(project, model, markers, distances)
    surveyed = list(decode.markers(data, "surveyed"))
    fixed_pins = [p for p in pins if p.fixed]
    options = ProblemOptions(click_sigma_px=project.settings["click_sigma_px"], prior_scale=FINAL_PRIOR_SCALE,
                             recalibrate=recalibrate, refine_intrinsics=refine_intrinsics,
                             k1_sigma=recalibration_k1_sigmas(project, distortion_sigmas(project))
                             if recalibrate else {},
                             camera_groups=recalibration_groups(data, cameras, project.path)
                             if recalibrate else {})
    marker_data = MarkerData(markers, [origin, *surveyed], marker_obs, distances)
    scans = any(s.get("use_in_solve") for s in data.get("scans") or [])

    def final_solve(staged: bool) -> tuple[Problem, Any]:
        if staged:  # the parents first, from their own marks: a start the final solve can use
            staged_start(model, cameras, fixed_pins, edges, project.settings["click_sigma_px"])
        # Laser scans marked use_in_solve: their points observe the faces nearest them (FORMAT.md "Laser scans").
        surfaces = scan_surfaces(project, model) if scans else []
        problem = (partial(ScanProblem, surfaces=surfaces) if surfaces else Problem)(
            model, cameras, fixed_pins, edges, options=options, markers=marker_data)
        x0 = problem.x0()
        problem.check_finite(x0, "at the start of the solve")
        sol = problem.solve(x0, robust=True, **({} if staged else {"max_iterations": DIRECT_MAX_ITERATIONS}))
        problem.check_finite(sol.x, "at the end of the solve")
        return problem, sol

    def solve_once() -> tuple[Problem, Any, Any]:
        # From the first guess at once, kept where it plainly found the minimum (Problem.plausible);
        # else (and always with scans, whose faces are matched on the start) from the staged start.
        direct = None if scans else _attempt(lambda: final_solve(staged=False))
        problem, sol = direct if direct is not None and direct[0].plausible(direct[1]) else final_solve(staged=True)
        return problem, sol, solution_at(problem, sol.x, sol.iterations)

    repaired = None  # the problem re-started from the pins of the nodes in doubt, where one was
    try:
        problem, sol, solution = solve_once()
        found = conflicts(model, problem.model_vector(sol.x))
        if solution.undetermined or found:
            # Before anything is called undetermined or contradictory, the nodes in doubt are
            # re-started from their own pins (vebuild/model/restart.py) and the model solved again.
            doubt = troubled_nodes(problem, sol.x, solution.undetermined, [n for _, r, _ in found for n in r.nodes()])
            if doubt and restart_nodes(model, cameras, fixed_pins, edges, project.settings["click_sigma_px"], doubt):
                again = _attempt(solve_once)
                repaired = None if again is None else again[0]
                if again is not None and _better(model, again, solution, found):
                    problem, sol, solution = again
                    found = conflicts(model, problem.model_vector(sol.x))
    except VebuildError as e:
        first, _, details = str(e).partition("\n")
        raise VebuildError(f"{project.path}: {first}\n{details or 'details: $.model'}") from None
    except (ValueError, np.linalg.LinAlgError) as e:
        if not is_numeric_failure(e):  # LinAlgError is a ValueError: a singular matrix is numeric too
            raise
        raise VebuildError(f"{project.path}: the solve failed numerically ({e}): an observation or a node's "
                           "dimensions make it degenerate; check the pins of the nodes last edited\n"
                           "details: $.model") from None
    xm = problem.model_vector(sol.x)
    if found:
        raise VebuildError(f"{project.path}: {conflict_message(found)}")
    if solution.undetermined:
        # The rank is judged at the best start there was: the repaired one where a repair ran.
        start = problem if repaired is None or len(repaired.names) != len(problem.names) else repaired
        raise refusal(project, problem, sol, solution, start.clip(start.x0()))
    _check_visible(project, problem, xm, solution.cameras)
    model.set_vector(xm)
    data["model"]["nodes"] = model.to_dict()
    result = {**_results(problem, solution, model, xm, recalibrate), "lengths": length_unit(data).word}
    if model.relations:  # how closely each relation holds after the solve (FORMAT.md model_solution)
        result["relations"] = relation_records(model)
    if recalibrate:
        result["cameras"], result["markers"] = recalibrated_records(data, solution, problem)
        if problem.layout.groups:  # one focal length, principal point and k1 per camera group
            result["camera_groups"] = solved_group_records(problem, solution)
    result["warnings"] = uncalibrated_pin_warnings(data, cameras)
    if recalibrate:
        result["warnings"] += fixed_camera.recalibration_warnings(data)
    result["refined_intrinsics"] = bool(recalibrate and refine_intrinsics)
    if before is not None and reproduces(before[1], result):
        # The same inputs, the same figures: the recorded solution stands, so that nothing computed
        # from it (the textures) is made stale by the solver's last nanometres.
        data["model"]["nodes"], data["model_solution"] = before
        return before[1]
    data["model_solution"] = result
    result["check_distances"] = final_check_distances(project)
    provenance.stamp(data, "model_solution")  # what it was computed from (vebuild.project.provenance)
    return result


def _better(model: Model, again: tuple[Problem, Any, Any], solution: Any, found: list[Any]) -> bool:
    """Whether a solve after a re-start is kept: it leaves fewer relations missing, or as few and
    fewer parameters undetermined."""
    problem, sol, sol2 = again
    found2 = conflicts(model, problem.model_vector(sol.x))
    return (len(found2), len(sol2.undetermined)) < (len(found), len(solution.undetermined))


def _attempt(solve: Any) -> Any:
    """``solve()``, or None where it fails as a solve can (a residual not finite, a degenerate
    system): what the staged start is there to avoid, so that the staged solve has its say."""
    try:
        return solve()
    except VebuildError:
        return None
    except (ValueError, np.linalg.LinAlgError) as e:
        if not is_numeric_failure(e):
            raise
        return None


#: How closely a re-run on unchanged inputs must give the recorded figures for the recorded
#: solution to stand: a share of each figure's 1σ. The Levenberg–Marquardt stopping test
#: (tol 1e-10 on the relative cost gain) leaves the end point within about 4e-4 σ of the minimum
#: (tests/test_solve_stages.py derives it), so two honest runs agree within 1e-3 σ; anything farther
#: is a different answer and is written.
REPRODUCED_SIGMA = 1e-3
#: Below this (metres or degrees) two values are the same whatever their 1σ (held values have σ 0).
REPRODUCED_FLOOR = 1e-9


def _current_solution(data: dict[str, Any], recalibrate: bool,
                      refine_intrinsics: bool) -> tuple[list[Any], dict[str, Any]] | None:
    """The model's nodes and the recorded solution (deep copies), where that solution is current
    (:func:`vebuild.project.provenance.stale`) and was solved the same way; else None."""
    import copy

    old = data.get("model_solution")
    if not isinstance(old, dict) or bool(old.get("recalibrated")) != recalibrate \
            or old.get("refined_intrinsics", None) != bool(recalibrate and refine_intrinsics):
        return None
    if any(s.stage == "model_solution" for s in provenance.stale(data)):
        return None
    return copy.deepcopy(data["model"]["nodes"]), copy.deepcopy(old)


def reproduces(old: dict[str, Any], new: dict[str, Any]) -> bool:
    """Whether a new solution gives the recorded one's figures: every node's degree of freedom and
    parameter (value, 1σ) and every handle within :data:`REPRODUCED_SIGMA` of its 1σ (the 1σ
    relatively), and the same outliers."""
    if set(old.get("nodes", {})) != set(new["nodes"]) or old.get("outliers") != new.get("outliers"):
        return False
    for name, entry in new["nodes"].items():
        for part in ("dofs", "params", "handles"):
            a, b = old["nodes"][name].get(part, {}), entry[part]
            if set(a) != set(b):
                return False
            for k, v in b.items():
                s_new = np.asarray([np.inf if x is None else x for x in np.ravel(v["sigma"])], float)
                s_old = np.asarray([np.inf if x is None else x for x in np.ravel(a[k]["sigma"])], float)
                s = np.where(np.isfinite(s_new), s_new, 0.0)
                if np.any(np.abs(np.subtract(np.ravel(v["value"]), np.ravel(a[k]["value"])))
                          > REPRODUCED_SIGMA * s + REPRODUCED_FLOOR):
                    return False
                if np.any(np.isfinite(s_new) != np.isfinite(s_old)):
                    return False
                fin = np.isfinite(s_new)
                if np.any(np.abs(s_new[fin] - s_old[fin]) > REPRODUCED_SIGMA * s_new[fin] + REPRODUCED_FLOOR):
                    return False
    return True


def uncalibrated_pin_warnings(data: dict[str, Any], cameras: dict[str, ImageCamera]) -> list[str]:
    """One warning per photo whose pins or edge observations the solve leaves out because the photo
    has no camera in the calibration (its camera was deleted, or it was never calibrated or
    registered), naming the photo, how many, and the command that gives it a camera."""
    left: dict[str, list[int]] = {}
    for key, k in (("pins", 0), ("edge_observations", 1)):
        for obs in (data.get("model") or {}).get(key, []):
            if obs["photo"] not in cameras and (key != "pins" or obs.get("fixed", True)):
                left.setdefault(obs["photo"], [0, 0])[k] += 1
    out = []
    unplaced = (data.get("calibration") or {}).get("unplaced") or {}
    left_out = (data.get("calibration") or {}).get("left_out") or {}
    for pid, (pins, edges) in sorted(left.items()):
        what = " and ".join(f"{n} {word}{'s' if n != 1 else ''}" for n, word in
                            ((pins, "pin"), (edges, "edge observation")) if n)
        seg = any(p["id"] == pid and p.get("vanishing_segments") for p in data["photos"])
        if pid in left_out:
            fix = ("Calibrate (`vebuild calibrate`) once what the calibration left it out for is fixed (the "
                   "calibration's warnings say what)")
        elif pid in unplaced:
            fix = (f"Register this photo (`vebuild register PROJECT {pid}`): the calibration could not place it "
                   "(its warnings say why)")
        elif seg:
            fix = "`vebuild calibrate` (it has vanishing segments)"
        else:
            fix = f"`vebuild register PROJECT {pid}`"
        out.append(f"photo '{pid}' has no calibrated camera, so its {what} are left out of the solve; give it a "
                   f"camera with {fix}, then solve again")
    return out


def final_check_distances(project: Project) -> list[dict[str, Any]]:
    """Every reference distance of role ``check``, measured on the final (just solved) model by
    :func:`vebuild.analysis.measure.check_distances`: measured, known, difference, its 1σ and 95 %
    interval, and whether the difference lies within it. Where the lengths are relative (no scale
    given) a measurement cannot be compared with a tape: ``within_ci95`` is then null and
    ``lengths`` says ``"relative"``."""
    from vebuild.analysis.measure import check_distances
    from vebuild.analysis.solved import SolvedModel

    if not any(d.role == "check" for d in decode.reference_distances(project.data)):
        return []
    out = [c.to_json() for c in check_distances(project, SolvedModel.from_project(project))]
    if length_unit(project.data).relative:
        out = [{**c, "within_ci95": None, "lengths": "relative"} for c in out]
    return out


def distortion_sigmas(project: Project) -> dict[str, float]:
    """photo id → the 1σ of its lens distortion's k1, from its calibration record's
    ``distortion.k1.sigma`` (FORMAT.md), for the photos that have one; a null 1σ (undetermined,
    or not given) counts as 0: that k1 is held as calibrated. Raises a ProjectError naming the
    field where the 1σ is not a number ≥ 0."""
    out = {}
    for pid, rec in (project.data.get("calibration") or {}).get("cameras", {}).items():
        d = rec.get("distortion")
        if d is None:
            continue
        where = json_path(["calibration", "cameras", pid, "distortion", "k1", "sigma"])
        k1 = d.get("k1")
        s = k1.get("sigma") if isinstance(k1, dict) else None
        if s is None:
            out[pid] = 0.0
            continue
        if isinstance(s, bool) or not isinstance(s, int | float) or not (np.isfinite(s) and s >= 0):
            raise ProjectError(project.path, where, f"expected the 1σ of k1 as a number ≥ 0 (or null), got {s!r}")
        out[pid] = float(s)
    return out


def check_recalibration_scale(project: Project, model: Model, markers: dict[str, np.ndarray],
                              distances: list[ReferenceDistance]) -> None:
    """Before a re-calibrating solve: the scale distances must not contradict each other, as
    ``vebuild calibrate`` requires (:func:`check_scale_distances`), measured where the calibration
    places the markers and, once the model has been solved, where the model puts the handles.
    The ratio of two implied scales does not depend on the present scale, so a contradiction
    shows there as it did before calibration. Raises a ProjectError at $.reference_distances."""
    solved = bool(project.data.get("model_solution"))
    X: dict[str, np.ndarray] = {}
    for d in distances:
        for end in (d.a, d.b):
            if end in X:
                continue
            if ":" not in end:
                if end in markers:
                    X[end] = markers[end]
                continue
            node, handle = end.split(":", 1)
            prim = model.node(node).primitive if solved and node in {n.name for n in model.nodes} else None
            if prim is not None and handle in prim.handle_names():
                X[end] = model.handle_world(node, handle)
    try:
        check_scale_distances(X, distances)
    except CalibrationError as e:
        raise ProjectError(project.path, "$.reference_distances", e.detail) from None


def _maybe_unseen(problem: Problem, pins: list[dict[str, Any]], xm: np.ndarray, T: dict[str, np.ndarray],
                  cameras: dict[str, ImageCamera]) -> list[int]:
    """The indices of the pins (of a calibrated photo) whose vertex may lie behind its camera or
    outside the image by VISIBLE_MARGIN, found for all pins at once (a house has ten thousand): the
    batched projection, with a pixel's leeway for its rounding; each is then checked one by one."""
    idx = [i for i, p in enumerate(pins) if p["photo"] in cameras]
    if not idx:
        return []
    X = problem.handle_positions(xm, T)[[problem.handle_row(pins[i]["node"], pins[i]["handle"]) for i in idx]]
    cams = [cameras[pins[i]["photo"]] for i in idx]
    Rs, Cs = np.array([c.R for c in cams]), np.array([c.C for c in cams])
    z = np.einsum("nj,nj->n", Rs[:, 2], X - Cs)
    with np.errstate(all="ignore"):
        uv = camera.project_each(np.array([c.K for c in cams]), Rs, Cs, X,
                                 np.array([(c.lens.k1, c.lens.k2) for c in cams]))
    size = np.array([[c.width, c.height] for c in cams], float)
    inside = np.all((uv >= -VISIBLE_MARGIN * size + 1.0) & (uv <= (1 + VISIBLE_MARGIN) * size - 1.0), axis=1)
    return [i for i, ok in zip(idx, (z > 1e-9) & inside, strict=True) if not ok]


def _check_visible(project: Project, problem: Problem, xm: np.ndarray, cameras: dict[str, ImageCamera]) -> None:
    T = problem.model.world_transforms(xm)
    pins = project.data["model"].get("pins", [])
    for i in _maybe_unseen(problem, pins, xm, T, cameras):
        p = pins[i]
        cam = cameras[p["photo"]]
        X = problem.model.handle_world(p["node"], p["handle"], xm, T)
        in_front = camera.world_to_camera(cam.R, cam.C, X)[2] > 0
        uv = camera.project(cam.K, cam.R, cam.C, X, cam.lens) if in_front else None
        w, hgt = cam.width, cam.height
        if uv is None or not (-VISIBLE_MARGIN * w <= uv[0] <= (1 + VISIBLE_MARGIN) * w
                              and -VISIBLE_MARGIN * hgt <= uv[1] <= (1 + VISIBLE_MARGIN) * hgt):
            where = "behind the camera" if uv is None else f"at ({uv[0]:.0f}, {uv[1]:.0f}), outside the image"
            raise VebuildError(f"{project.path}: a pin on {p['node']}'s corner {p['handle']} in photo '{p['photo']}' "
                               f"is one the solved model puts {where}: the pin is on a corner this camera cannot "
                               "see (the wrong corner, or the wrong photo?); drag it onto the right corner, or "
                               "remove it (F over it unfixes it)\n"
                               f"details: $.model.pins[{i}] ({p['node']}:{p['handle']})")


def _vs(v: Any, s: Any) -> dict[str, Any]:
    """value, 1σ and, for a scalar with a finite σ, its 95 % interval."""
    out = value_sigma(v, s)
    if np.ndim(v) == 0:
        out["ci95"] = [float(v - Z95 * s), float(v + Z95 * s)] if np.isfinite(s) else None
    return out


def _results(problem: Problem, solution: Any, model: Model, xm: np.ndarray, recalibrate: bool) -> dict[str, Any]:
    sig = np.sqrt(np.maximum(np.diag(solution.covariance), 0.0))
    handles = handle_covariances(problem, solution.x, solution.covariance)
    by_name = {n: j for j, n in enumerate(problem.names)}
    by_name.update({m: by_name[rep] for m, rep in problem.alias.items() if rep in by_name})  # equal: shared
    axes = axis_records(problem, solution)
    prior_only = set(solution.prior_only)
    held = held_by_relations(problem, sig)

    def determined_by(full: str, entered: bool) -> dict[str, str]:
        """Where a solved parameter's value comes from (FORMAT.md ``determined_by``): a relation
        that holds it (``held_by``: which), the photos, only its own entered value, or the photos
        measuring from what only entered values place (a box's position on a floor whose size was
        entered)."""
        if full not in by_name:
            return {}
        if full in held:
            return {"determined_by": "relation", "held_by": held[full]}
        if full not in prior_only:
            return {"determined_by": "observations"}
        return {"determined_by": "entered value" if entered else "observations and entered values"}

    nodes = {}
    for n in model.nodes:
        sq, sp = model.slices[n.name]
        entry: dict[str, Any] = {"joint": n.joint.type, "dofs": {}, "params": {}, "handles": {}}
        for k, dof in enumerate(n.joint.dof_names):
            j = by_name.get(f"{n.name}.{dof}")
            value, s = xm[sq][k], (sig[j] if j is not None else 0.0)
            if n.joint.dof_kinds[k] == "angle":
                value, s, dof = np.degrees(value), np.degrees(s), dof + "_deg"
            entry["dofs"][dof] = {**_vs(value, s), **n.entered_record(n.joint.dof_names[k]),  # entered: FORMAT.md
                                  **determined_by(f"{n.name}.{n.joint.dof_names[k]}",
                                                  n.entered_sigma(n.joint.dof_names[k]) is not None)}
        if n.primitive is not None:
            for k, pname in enumerate(n.primitive.PARAMS):
                j = by_name.get(f"{n.name}.{pname}")
                entry["params"][pname] = {**_vs(xm[sp][k], sig[j] if j is not None else 0.0),
                                          **n.entered_record(pname),  # entered values: FORMAT.md
                                          **determined_by(f"{n.name}.{pname}", n.entered_sigma(pname) is not None)}
            for h in n.primitive.handle_names():
                pos, cov = handles[f"{n.name}:{h}"]
                entry["handles"][h] = _vs(pos, np.sqrt(np.maximum(np.diag(cov), 0.0)))
        if n.name in axes:
            entry["axis"] = axes[n.name]  # a solved hinge's or slider's axis: FORMAT.md
        nodes[n.name] = entry
    pins = [{"photo": p.photo, "node": p.node, "handle": p.handle, "residual_px": [float(a) for a in d]}
            for p, d in zip(problem.pins, solution.residuals_px["pins"], strict=True)]
    edges = [{"photo": e.photo, "node": e.node, "edge": e.edge, "residual_px": [float(a) for a in d]}
             for e, d in zip(problem.edges, solution.residuals_px["edges"], strict=True)]
    all_res = np.concatenate([np.ravel(d) for k in ("pins", "edges", "markers") for d in solution.residuals_px[k]]
                             or [np.zeros(0)])
    return {
        "software": f"vebuild {__version__}",
        "recalibrated": recalibrate,
        "nodes": nodes,
        "pins": pins,
        "edge_observations": edges,
        "rms_px": float(np.sqrt(np.mean(all_res**2))) if all_res.size else 0.0,
        "variance_factor": solution.variance_factor,
        "outliers": solution.outliers,
        "iterations": solution.iterations,
        "covariance": covariance_record(problem, solution),
    }


#: A solved parameter whose 1σ (metres, radians) is at most this is held by the flush or aligned
#: relations its column moves, not measured: their hard rows, whitened by HARD_SIGMA_M (1 µm),
#: leave it a σ of that order over the lever, while no photo measures anything to better than a
#: fraction of a pixel's footprint (tenths of a millimetre in a room). The tenth of a millimetre
#: to which a relation is reported to hold (CONFLICT_TOL_M) parts the two.
RELATION_HELD_SIGMA = CONFLICT_TOL_M


def held_by_relations(problem: Problem, sig: np.ndarray) -> dict[str, str]:
    """``node.param`` → the relations (as the Model tab lists them) that hold it: every solved model
    parameter with a 1σ of at most RELATION_HELD_SIGMA whose column moves a flush or aligned
    relation."""
    out = {}
    for j, name in enumerate(problem.names):
        rels = [problem.hard[k].label() for k in problem.column_hard[j]]
        if rels and sig[j] <= RELATION_HELD_SIGMA:
            out[name] = ", ".join(rels)
    out.update({m: out[rep] for m, rep in problem.alias.items() if rep in out})
    return out


def covariance_record(problem: Problem, solution: Any) -> dict[str, Any]:
    """The joint covariance of the solved model parameters (and re-calibrated markers), for
    measurements between any two points (their correlations matter): names in file units
    (``node.param`` metres, ``node.dof_deg`` degrees, ``marker:NAME.x`` metres) and the matrix.
    Cameras are left out: no point of the model moves with them."""
    layout = problem.layout
    blocks = [layout.model, *layout.markers.values()]
    keep = layout.model_and_markers()
    names, s = layout.file_names(blocks), layout.file_scale(blocks)
    # The members of an equal group share one unknown: each is listed with its row (correlation 1),
    # so a measurement through any of them carries the shared σ, correlations included.
    index = {n: j for j, n in enumerate(layout.model.names)}
    tied = [(m, index[rep]) for m, rep in problem.alias.items() if m != rep and rep in index]
    n_model = len(layout.model)
    order = np.r_[np.arange(n_model), [j for _, j in tied], np.arange(n_model, len(keep))].astype(int)
    keep, s = keep[order], s[order]
    names = names[:n_model] + [f"{m}_deg" if layout.model.kinds[j] == "angle" else m for m, j in tied] + \
        names[n_model:]
    cov = solution.covariance[np.ix_(keep, keep)] * s[:, None] * s[None, :]
    return {"parameters": names, "matrix": json_values(cov)}


#: Fields of a calibration camera record that describe the vanishing-point calibration's own fit;
#: a re-calibrated record (``model_solution.cameras``) leaves them out.
CALIBRATION_DIAGNOSTICS = ("vanishing_points", "marker_residuals_px", "rms_px", "exif_focal_check")
#: What a refined lens distortion's ``source`` says, after the calibration's.
REFINED_SOURCE = "refined by vebuild solve --recalibrate"


def recalibrated_records(data: dict[str, Any], solution: Any, problem: Problem
                         ) -> tuple[dict[str, Any], dict[str, Any]]:
    """The re-calibrated cameras (photo id → a record with the fields of ``calibration.cameras[id]``
    and ``"recalibrated": true``) and markers (name → ``{"position", "sigma"}``) for
    ``model_solution`` (paper §3.2); the calibration's records are left as they are. A refined lens
    distortion goes into the re-calibrated record, and a held one has its corner displacement
    recomputed for the refined K."""
    cal = data["calibration"]
    cameras: dict[str, Any] = {}
    marker_res: dict[str, dict[str, Any]] = {}
    for m, d in zip(problem.marker_obs, solution.residuals_px["markers"], strict=True):
        marker_res.setdefault(m.photo, {})[m.marker] = json_values(d)
    for cid, cam in solution.cameras.items():
        rec = copy.deepcopy(cal["cameras"][cid])
        # The calibration's own diagnostics stay with the calibration; the record says what the
        # re-calibration found.
        for key in CALIBRATION_DIAGNOSTICS:
            rec.pop(key, None)
        rec["marker_residuals_px"] = marker_res.get(cid, {})
        old = rec.get("distortion")
        distortion = None
        # k2 is held as calibrated: its record is kept as it was
        k2_rec = (old or {}).get("k2") or {}
        held_k2 = {"k2": cam.lens.k2, "k2_sigma": float(k2_rec.get("sigma") or 0.0),
                   "k2_source": k2_rec.get("source")}
        if cid in solution.k1_sigma:
            source = str(old.get("source", "")) if old else ""
            if REFINED_SOURCE not in source:
                source = f"{source}; {REFINED_SOURCE}" if source else REFINED_SOURCE
            distortion = distortion_record(cam.K, cam.width, cam.height, cam.lens.k1, solution.k1_sigma[cid], source,
                                           **held_k2)
        elif old is not None:
            k1_sig = problem.options.k1_sigma.get(cid, 0.0)
            distortion = distortion_record(cam.K, cam.width, cam.height, cam.lens.k1, k1_sig,
                                           str(old.get("source", "")), **held_k2)
            if old.get("k1", {}).get("sigma") is None:
                distortion["k1"]["sigma"] = distortion["corner_displacement_px"]["sigma"] = None
        rec.update(camera_record(cam.K, cam.R, cam.C, cam.covariance, distortion), recalibrated=True)
        cameras[cid] = rec
    markers: dict[str, Any] = {}
    for name, pos in solution.markers.items():
        if name in cal["markers"] and name in solution.marker_covariance:
            sigma = np.sqrt(np.maximum(np.diag(solution.marker_covariance[name]), 0.0))
            markers[name] = {"position": json_values(pos), "sigma": json_values(sigma)}
    return cameras, markers
