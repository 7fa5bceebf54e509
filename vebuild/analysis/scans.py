"""Laser scans against the model: registration from targets, the scan in the project frame, the
deviation of the scan from each face of the model, and the scan's points as observations of the
solve.

- :func:`register_scan`: the targets' project points resolved (markers, ``node:handle``,
  ``node@face:s,t``: the syntax of ``vebuild analyse``, :mod:`.points`), the similarity from the
  scan's frame into the project frame fitted by Umeyama's method with its covariance
  (:mod:`vebuild.calibration.similarity`), and the ``$.scans[]`` entry made;
- :func:`scan_points_world`: the registered points (decimated) in the project frame, for drawing;
- :func:`face_deviations`: per face of the model, the signed distance of the scan points nearest to
  it (median, 95th percentile of the distance, count);
- :func:`surface_observations`: points assigned to flat faces, for :class:`~vebuild.model.scan_fit.ScanProblem`.

Distances are to the model as ``model.nodes`` gives it (a solve writes its solution there).
Signed: positive in front of the face (the side its outward normal points to: outside a box, into
the room from a room's wall). A point farther than ``max_distance`` from every face is not the
model's (furniture not modelled, a person, the view through a window) and is counted apart.

Layer 6 of DESIGN.md: numpy only.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.calibration.similarity import PARAMETERS, DegenerateTargets, Similarity, fit_similarity
from vebuild.calibration.similarity import jacobian as similarity_jacobian
from vebuild.errors import ProjectError, VebuildError
from vebuild.model.scan_fit import SurfaceObservation, face_handles
from vebuild.model.scene import Model
from vebuild.project import decode
from vebuild.project.records import json_values
from vebuild.project.scans import (
    DEFAULT_POINT_SIGMA_M,
    PointCloud,
    Target,
    check_target_names,
    dropped_words,
    load_point_cloud,
)

from .solved import SolvedModel

Array = NDArray[np.float64]

#: A scan point farther than this from every face is not counted as the model's (metres).
MAX_DISTANCE_M = 0.10
#: Points drawn per scan in the windows, at most.
DRAW_POINTS = 200_000
#: Points per scan used as observations of the solve, at most (a regular subsample).
SOLVE_POINTS = 5000
#: Points per scan compared with the model at most (a regular subsample: the medians and
#: percentiles of 200 000 points are those of the whole scan to well under its noise), so that a
#: scan of millions of points is checked in seconds (about 1 s per 20 000 points on 170 triangles).
CHECK_POINTS = 200_000
#: Points per chunk of the point-to-triangle distances (memory: chunk × triangles × 3 floats).
CHUNK = 2048


# ----------------------------------------------------------------------------------------------
# Project points and registration


def _project_model(project: Any) -> SolvedModel:
    """The model with its solution where solved, else the model as written (no covariance)."""
    data = project.data
    if data.get("model_solution") and (data["model_solution"].get("covariance") is not None):
        return SolvedModel.from_project(project)
    markers = decode.markers(data, "final") if data.get("calibration") else {}
    markers.update(decode.markers(data, "surveyed"))
    if (data.get("model") or {}).get("nodes"):
        model = decode.model(project, decode.markers(data, "joints") if not data.get("calibration") else None)
    else:
        model = Model([])
    return SolvedModel.build(model, [], np.zeros(0), np.zeros((0, 0)), [], markers, where=str(project.path))


def resolve_points(project: Any, texts: Sequence[str], where: Sequence[str]) -> Array:
    """World positions of project points written as :data:`~vebuild.analysis.points.POINT_SYNTAX`
    (not pixels): markers (calibrated or surveyed), handles and face points of the model."""
    from .points import parse_point

    solved = _project_model(project)
    out = []
    for text, w in zip(texts, where, strict=True):
        if text.split(":", 1)[0] in ("photo", "view") and "@" in text:
            raise VebuildError(f"{project.path}: {w}: {text!r}: a target is a marker or a model point "
                               "(node:handle, node@face:s,t), not a pixel")
        try:
            out.append(solved.world(parse_point(text, solved)))
        except VebuildError as e:
            markers = ", ".join(sorted(solved.marker_col)) or "none placed"
            raise VebuildError(f"{project.path}: {w}: unknown project point {text!r}: {e} (markers: {markers})"
                               ) from None
    return np.array(out, float).reshape(-1, 3)


def registration_record(targets: Sequence[Target], project_xyz: Array, where: str) -> dict[str, Any]:
    """The ``registration`` object of a scan entry: targets, similarity, covariance, rms, residuals."""
    X = np.array([t.scan_xyz for t in targets], float).reshape(-1, 3)
    try:
        fit = fit_similarity(X, project_xyz)
    except DegenerateTargets as e:
        raise VebuildError(f"{where}: {e}") from None
    sim = fit.similarity
    res = [{"name": t.name, "residual_m": json_values(r), "distance_m": float(np.linalg.norm(r))}
           for t, r in zip(targets, fit.residuals, strict=True)]
    cov = fit.covariance if np.all(np.isfinite(fit.covariance)) else None
    return {
        "targets": [{"name": t.name, "scan_xyz": list(t.scan_xyz), "point": t.point, "project_xyz": json_values(p)}
                    for t, p in zip(targets, project_xyz, strict=True)],
        "similarity": {"scale": sim.scale, "rotation": json_values(sim.rotation),
                       "translation": json_values(sim.translation)},
        "covariance": None if cov is None else {"parameters": list(PARAMETERS), "matrix": json_values(cov)},
        "sigma_m": float(fit.sigma) if np.isfinite(fit.sigma) else None,
        "redundancy": fit.redundancy,
        "rms_m": fit.rms,
        "residuals": res,
    }


def register_scan(project: Any, targets: Sequence[Target], where: str = "--target") -> dict[str, Any]:
    """Resolve ``targets`` against the project and fit the scan's registration (its record)."""
    check_target_names(targets, where)
    if len(targets) < 3:
        raise VebuildError(f"{project.path}: {where}: {len(targets)} target{'s' if len(targets) != 1 else ''} given; "
                           "a registration needs at least 3 targets not on one line")
    P = resolve_points(project, [t.point for t in targets], [f"{where} {t.name}" for t in targets])
    return registration_record(targets, P, f"{project.path}: {where}")


#: How far a target's project point may have moved since its scan was registered before the
#: registration is called stale, metres: a tenth of a millimetre, far below any scan's noise and far
#: above the rounding of the recorded coordinates.
DRIFT_TOLERANCE_M = 1e-4


def registration_drift(project: Any, index: int) -> list[str]:
    """Why ``$.scans[index]``'s registration no longer matches the project: each target whose
    project point (a marker, a model vertex or face point) now lies elsewhere than where it was
    when the scan was registered, by more than :data:`DRIFT_TOLERANCE_M`; [] where none moved."""
    reg = project.data["scans"][index]["registration"]
    targets = reg["targets"]
    try:
        now = resolve_points(project, [t["point"] for t in targets],
                             [f"$.scans[{index}].registration.targets[{k}].point" for k in range(len(targets))])
    except VebuildError as e:
        return [f"scan {index}: a target's project point can no longer be found ({e}); register the scan again "
                f"with `vebuild scan add`"]
    out = []
    for t, p in zip(targets, now, strict=True):
        moved = float(np.linalg.norm(p - np.asarray(t["project_xyz"], float)))
        if moved > DRIFT_TOLERANCE_M:
            out.append(f"scan {index}: target {t['name']} ({t['point']}) now lies {moved * 1000:.1f} mm from where it "
                       "was when the scan was registered (the model or the markers changed since); the "
                       "registration is stale: register the scan again with `vebuild scan add`")
    return out


def similarity_of(project: Any, index: int) -> Similarity:
    """The recorded similarity of ``$.scans[index]`` (scan frame → project frame)."""
    rec = project.data["scans"][index]["registration"]["similarity"]
    R = np.asarray(rec["rotation"], float)
    if np.abs(R @ R.T - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
        raise ProjectError(project.path, f"$.scans[{index}].registration.similarity.rotation",
                           "expected a rotation (orthonormal rows, determinant +1)")
    return Similarity(float(rec["scale"]), R, np.asarray(rec["translation"], float))


def _decimate(n: int, max_points: int | None) -> NDArray[np.intp]:
    if max_points is None or n <= max_points:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, max_points).astype(np.intp))


def registered_cloud(project: Any, index: int, max_points: int | None = None) -> PointCloud:
    """The points of ``$.scans[index]`` in the project frame (regularly decimated to ``max_points``)."""
    cloud = load_point_cloud(project, index)
    keep = _decimate(len(cloud.points), max_points)
    P = similarity_of(project, index).apply(cloud.points[keep])
    return PointCloud(P, None if cloud.colours is None else cloud.colours[keep], cloud.format)


def scan_points_world(project: Any, scan_index: int, max_points: int = DRAW_POINTS
                      ) -> tuple[Array, NDArray[np.uint8]]:
    """(N, 3) points of the scan in the project frame, at most ``max_points``, and (N, 3) sRGB
    colours (grey where the scan has none)."""
    cloud = registered_cloud(project, scan_index, max_points)
    colours = cloud.colours if cloud.colours is not None else np.full((len(cloud.points), 3), 200, np.uint8)
    return cloud.points, colours


# ----------------------------------------------------------------------------------------------
# Distances to the model's faces


@dataclass(frozen=True)
class WorldFaces:
    """The model's faces in the world: per face its node, name, and triangles (m, 3, 3)."""

    names: list[tuple[str, str]]  # (node, face)
    triangles: Array  # (T, 3, 3)
    face_of: NDArray[np.intp]  # (T,) index into names
    flat: list[bool]


def world_faces(model: Model, segments: int = 32) -> WorldFaces:
    T = model.world_transforms()
    names: list[tuple[str, str]] = []
    tris, owner, flat = [], [], []
    for node in model.nodes:
        if node.primitive is None:
            continue
        mesh = node.primitive.mesh(segments=segments)
        W = mesh.vertices @ T[node.name][:3, :3].T + T[node.name][:3, 3]
        for k, face in enumerate(mesh.face_names):
            sel = mesh.face_ids == k + 1
            if not sel.any():
                continue
            owner.append(np.full(int(sel.sum()), len(names)))
            tris.append(W[mesh.faces[sel]])
            names.append((node.name, face))
            try:
                face_handles(node.primitive, face)
                flat.append(True)
            except ValueError:
                flat.append(False)
    if not tris:
        return WorldFaces([], np.zeros((0, 3, 3)), np.zeros(0, np.intp), [])
    return WorldFaces(names, np.concatenate(tris), np.concatenate(owner).astype(np.intp), flat)


def _triangle_distances(P: Array, tri: Array) -> Array:
    """(n, T) signed distance from each point to each triangle (sign: the triangle's normal side)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    ap = P[:, None, :] - a[None]
    dplane = np.einsum("ntk,tk->nt", ap, n)
    q = ap - dplane[..., None] * n[None]
    e0, e1 = b - a, c - a
    d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)
    d20, d21 = np.einsum("ntk,tk->nt", q, e0), np.einsum("ntk,tk->nt", q, e1)
    den = np.maximum(d00 * d11 - d01 * d01, 1e-300)
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    inside = (v >= 0) & (w >= 0) & (v + w <= 1)
    edge = np.full(dplane.shape, np.inf)
    for p0, p1 in ((a, b), (b, c), (c, a)):
        e = p1 - p0
        t = np.clip(np.einsum("ntk,tk->nt", P[:, None, :] - p0[None], e) / np.maximum((e * e).sum(1), 1e-300), 0, 1)
        edge = np.minimum(edge, np.linalg.norm(P[:, None, :] - (p0[None] + t[..., None] * e[None]), axis=-1))
    dist = np.where(inside, np.abs(dplane), edge)
    return np.where(dplane < 0, -dist, dist)


def nearest_faces(P: Array, faces: WorldFaces, max_distance: float = MAX_DISTANCE_M) -> tuple[NDArray[np.intp], Array]:
    """Per point the index of its nearest face (−1 beyond ``max_distance`` from every face) and
    its signed distance to that face (NaN where −1)."""
    P = np.asarray(P, float).reshape(-1, 3)
    face = np.full(len(P), -1, np.intp)
    dist = np.full(len(P), np.nan)
    if not len(faces.triangles):
        return face, dist
    lo = faces.triangles.reshape(-1, 3).min(axis=0) - max_distance
    hi = faces.triangles.reshape(-1, 3).max(axis=0) + max_distance
    for s in range(0, len(P), CHUNK):
        Q = P[s : s + CHUNK]
        near = np.all((Q >= lo) & (Q <= hi), axis=1)
        if not near.any():
            continue
        D = _triangle_distances(Q[near], faces.triangles)
        k = np.argmin(np.abs(D), axis=1)
        d = D[np.arange(len(k)), k]
        ok = np.abs(d) <= max_distance
        idx = np.flatnonzero(near)
        face[s + idx[ok]] = faces.face_of[k[ok]]
        dist[s + idx[ok]] = d[ok]
    return face, dist


def _registration_covariance(project: Any, index: int) -> Array | None:
    rec = project.data["scans"][index]["registration"].get("covariance")
    if rec is None:
        return None
    C = np.array(rec["matrix"], dtype=float)
    return C if C.shape == (7, 7) and np.all(np.isfinite(C)) else None


def project_model_as_written(project: Any) -> Model:
    """The model of ``model.nodes`` (the solved values once solved)."""
    data = project.data
    if not (data.get("model") or {}).get("nodes"):
        raise VebuildError(f"{project.path}: $.model: the project has no model to compare the scan with")
    return decode.model(project, decode.markers(data, "joints") if not data.get("calibration") else None)


def face_deviations(project: Any, scan_index: int, max_distance: float = MAX_DISTANCE_M,
                    max_points: int | None = CHECK_POINTS) -> dict[str, Any]:
    """Per face of the model: how far the registered scan's points nearest to it lie from it.

    Returns ``{"scan", "file", "points", "unassigned", "max_distance_m", "faces": [{"node", "face",
    "count", "median_m" (signed), "p95_m" (of the distance), "rms_m"}], "world", "signed"}``:
    the last two are the points used and their signed distances (NaN: unassigned), for maps.
    """
    if not max_distance > 0:
        raise VebuildError(f"--max-distance: expected a distance above 0 m, got {max_distance!r}")
    model = project_model_as_written(project)
    cloud = registered_cloud(project, scan_index, max_points)
    faces = world_faces(model)
    idx, d = nearest_faces(cloud.points, faces, max_distance)
    sim = similarity_of(project, scan_index)
    cov = _registration_covariance(project, scan_index)
    rows = []
    for k, (node, face) in enumerate(faces.names):
        sel = idx == k
        if not sel.any():
            continue
        dk = d[sel]
        row = {"node": node, "face": face, "count": int(sel.sum()), "median_m": float(np.median(dk)),
               "p95_m": float(np.percentile(np.abs(dk), 95)), "rms_m": float(np.sqrt(np.mean(dk**2))),
               "registration_sigma_m": None}
        if cov is not None:
            tri = faces.triangles[faces.face_of == k]
            n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).sum(axis=0)
            if np.linalg.norm(n) > 0:
                n = n / np.linalg.norm(n)
                centre = (cloud.points[sel].mean(axis=0) - sim.translation) @ sim.rotation / sim.scale
                g = n @ similarity_jacobian(sim, centre)
                row["registration_sigma_m"] = float(np.sqrt(max(g @ cov @ g, 0.0)))
        rows.append(row)
    entry = project.data["scans"][scan_index]
    return {"scan": scan_index, "file": entry["file"], "points": int(len(cloud.points)),
            "scan_points": int(entry["point_count"]), "dropped": dropped_words(entry),
            "warnings": registration_drift(project, scan_index),
            "unassigned": int(np.sum(idx < 0)), "max_distance_m": float(max_distance), "faces": rows,
            "world": cloud.points, "signed": d}


def surface_observations(project: Any, model: Model, max_distance: float = MAX_DISTANCE_M,
                         max_points: int = SOLVE_POINTS) -> list[SurfaceObservation]:
    """The points of every scan with ``use_in_solve`` assigned to the flat face of ``model`` (its
    state before the solve) nearest to each, within ``max_distance``."""
    out: list[SurfaceObservation] = []
    faces = None
    for i, entry in enumerate(project.data.get("scans") or []):
        if not entry.get("use_in_solve"):
            continue
        faces = faces or world_faces(model)
        cloud = registered_cloud(project, i, max_points)
        idx, _ = nearest_faces(cloud.points, faces, max_distance)
        sigma = float(entry.get("point_sigma_m", DEFAULT_POINT_SIGMA_M))
        for k, (node, face) in enumerate(faces.names):
            sel = idx == k
            if sel.any() and faces.flat[k]:
                out.append(SurfaceObservation(node, face, cloud.points[sel], sigma))
    return out


def deviation_table(result: dict[str, Any]) -> str:
    """The per-face deviation table as text (``vebuild scan check``)."""
    used = f"{result['points']} points" if result["points"] == result["scan_points"] else \
        f"{result['points']} of its {result['scan_points']} points (a regular subsample)"
    lines = [f"scan {result['scan']} ({result['file']}): {used}, {result['unassigned']} farther "
             f"than {result['max_distance_m'] * 1000:.0f} mm from every face",
             *([f"{result['dropped']} (not counted above)"] if result.get("dropped") else []),
             f"{'face':<32} {'points':>8} {'median mm':>10} {'p95 mm':>8} {'rms mm':>8}"]
    for r in result["faces"]:
        lines.append(f"{r['node'] + ':' + r['face']:<32} {r['count']:>8} {r['median_m'] * 1000:>10.1f} "
                     f"{r['p95_m'] * 1000:>8.1f} {r['rms_m'] * 1000:>8.1f}")
    lines.append("median: signed (positive in front of the face); p95: of the distance")
    lines += [f"warning: {w}" for w in result.get("warnings", [])]
    return "\n".join(lines)
