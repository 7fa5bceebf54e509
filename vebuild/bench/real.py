"""``vebuild bench real --data DIR``: calibration scored on real photographs with surveyed cameras.

The data (:mod:`vebuild.bench.real_layout`): multi-view sets of real photos whose true K, R and
camera centres were surveyed (Strecha's sets, from openMVG/SfM_quality_evaluation; research-use
data, never bundled with vebuild). Each set is cut into groups of consecutive photos,
:data:`GROUP_MAX` at most (a photographer's 3–10 photos of one place); ``--quick`` takes the first
group of each set. Each group is worked as a user works it, in a temporary folder (the photos
linked, not copied): the project made (``vebuild new``'s API), the markers clicked
(:mod:`vebuild.bench.real_markers`: 8–18 points matched across the photos and triangulated with the
true cameras, clicked at their true projections + 1 px Gaussian noise, seeded: the bench's
stand-in for a user's clicks), the origin at the marker seen in the most photos, a scale distance
from it to the marker farthest from it and a check distance between the two farthest apart of the
others (both known to :data:`DISTANCE_SIGMA_M`, their lengths from the triangulated points), then
``vebuild detect`` with every proposal accepted (as "accept all"; x axes chosen from the markers,
the default) and ``vebuild calibrate``. No EXIF: the photos have none. A group whose photos share
fewer than :data:`MIN_MARKERS` such points is not worked (``not_worked``: no user could tie them).

Scoring, per photo, against the surveyed camera. vebuild's world frame is its own (z up, x and y
along the building, origin at the origin marker), so it is aligned to the survey's: the rotation
W from the photos' rotations (each photo's Rᵢᵀ R_trueᵢ; the one most others agree with within
:data:`CONSENSUS_DEG`, then the chordal mean of those within :data:`WRONG_AXES_DEG` of it: a
photo whose axes were turned wrong cannot move it), the origin at the origin marker's surveyed
position and the scale 1 (the scale distance is the survey's): the gauge the reported covariances
are in. Figures: ``focal_rel_error_median`` (the true f the mean of the survey's fx and fy, which
differ by 0.2 %), ``focal_coverage_95`` (true f inside f ± 1.96σ), ``principal_point_coverage_95``
(inside the 2D 95 % ellipse, χ²₂ 5.99; the survey's principal point as written), over every
calibrated photo; ``rotation_coverage_95`` (ω = log(R_true Wᵀ R̂ᵀ) inside the 95 % region of the
reported ω covariance, χ²₃ 7.81) and ``position_coverage_95`` (χ²₃ 7.81 on the centre's error),
over the placed photos whose axes are right; ``unoriented_accepted``: placed photos whose rotation
is more than :data:`WRONG_AXES_DEG` off (axes turned a quarter about z, or worse) yet not left
out; ``check_distance_failures``: check distances measured more than :data:`CHECK_LIMIT_SIGMAS` σ
off (or with no σ); ``k1_within_2sigma_share``: photos whose estimated k1 lies within 2σ of zero (the photos are
undistorted). ``position_similarity_rms_m``: the centres' RMS after a free similarity (Umeyama)
over the placed photos with right axes, and its scale. The reference run in the same process: the
paper's closed form (:func:`vebuild.calibration.photo.closed_form_calibration`) on the same
detected segments, ``reference_focal_rel_error_median``.

Goals (on the two development sets): coverages of f, principal point and rotation ≥ 0.90, focal
median ≤ 2 %, no photo with wrong axes accepted, k1 within 2σ of zero (share ≥ 0.95).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from vebuild.errors import VebuildError

from .real_layout import SurveyedPhoto, SurveyedSet, find_sets
from .real_markers import CLICK_NOISE_PX, MIN_MARKERS, Track, cached_tracks, choose_markers, true_projection

GROUP_MAX = 8
DISTANCE_SIGMA_M = 0.01
CONSENSUS_DEG = 5.0
WRONG_AXES_DEG = 10.0
CHECK_LIMIT_SIGMAS = 5.0
CHI2_2_95, CHI2_3_95 = 5.991465, 7.814728
GOALS = {"focal_rel_error_median": 0.02, "focal_coverage_95": 0.90, "principal_point_coverage_95": 0.90,
         "rotation_coverage_95": 0.90, "unoriented_accepted": 0, "k1_within_2sigma_share": 0.95}
DATA_HELP = ("the Strecha sets Herz-Jesus-P25 and fountain-P11 of openMVG/SfM_quality_evaluation (research-use "
             "data, not bundled with vebuild; docs/accuracy.md)")


def groups(photos: tuple[SurveyedPhoto, ...], size: int = GROUP_MAX) -> list[tuple[SurveyedPhoto, ...]]:
    """The photos in consecutive groups of ``size`` at most, as even as can be."""
    n = -(-len(photos) // size)
    bounds = np.linspace(0, len(photos), n + 1).round().astype(int)
    return [photos[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


def make_project(folder: Path, name: str, photos: tuple[SurveyedPhoto, ...], markers: list[Track],
                 rng: np.random.Generator) -> tuple[Path, dict[str, Any]]:
    """The group's project file in ``folder`` (photos linked into it) with its markers' clicks and
    the two distances; returns the file and the truth of what was put in it."""
    from vebuild.project import new_photo_entry, new_project, save_project

    data = new_project(name)
    (folder / "images").mkdir(parents=True)
    names = [f"m{k + 1:02d}" for k in range(len(markers))]
    for ph in photos:
        link = folder / "images" / ph.image.name
        os.symlink(ph.image.resolve(), link)
        entry = new_photo_entry(folder, link, ph.id)
        obs = {}
        for n, t in zip(names, markers, strict=True):
            q = true_projection(ph, t.X) if ph.id in t.photos else None
            if q is not None:
                obs[n] = [round(float(v), 3) for v in q + rng.normal(0.0, CLICK_NOISE_PX, 2)]
        if obs:
            entry["marker_observations"] = obs
        data["photos"].append(entry)
    data["markers"] = [{"name": n} for n in names]
    X = {n: t.X for n, t in zip(names, markers, strict=True)}
    origin = names[0]  # choose_markers puts the most-seen first
    far = max(names[1:], key=lambda n: float(np.linalg.norm(X[n] - X[origin])))
    rest = [n for n in names if n not in (origin, far)]
    a, b = max(((p, q) for i, p in enumerate(rest) for q in rest[i + 1:]),
               key=lambda pq: float(np.linalg.norm(X[pq[0]] - X[pq[1]])))
    data["origin_marker"] = origin
    data["reference_distances"] = [
        {"a": origin, "b": far, "distance": round(float(np.linalg.norm(X[far] - X[origin])), 4),
         "sigma": DISTANCE_SIGMA_M, "role": "scale"},
        {"a": a, "b": b, "distance": round(float(np.linalg.norm(X[a] - X[b])), 4), "sigma": DISTANCE_SIGMA_M,
         "role": "check"}]
    path = folder / f"{name}.vebuild.json"
    save_project(path, data)
    seen = {p["id"]: len(p.get("marker_observations") or {}) for p in data["photos"]}
    return path, {"origin": X[origin], "markers_seen": seen}


def work_group(path: Path) -> tuple[dict[str, Any] | None, str | None, dict[str, str], dict[str, float | None]]:
    """``vebuild detect`` (accept all) then ``vebuild calibrate`` on the project: the calibration
    (None where refused), the refusal, each photo's detection message, and each photo's focal
    length by the paper's closed form on the same segments (the reference)."""
    from vebuild.actions.calibrate import calibrate_project
    from vebuild.actions.detect import detect_project
    from vebuild.calibration.photo import closed_form_calibration
    from vebuild.project import decode, load_project, save_project

    project = load_project(path)
    messages = {props.photo: f"{props.message}; {written} segments written"
                for props, written in detect_project(project)}
    save_project(project)
    project = load_project(path)
    reference: dict[str, float | None] = {}
    for photo in project.data["photos"]:
        segs = decode.photo_marks(photo).segments
        try:
            K, _ = closed_form_calibration(segs, photo["width"], photo["height"], photo=photo["id"])
            reference[photo["id"]] = float(K[0, 0])
        except (VebuildError, ValueError, np.linalg.LinAlgError):
            reference[photo["id"]] = None
    try:
        result = calibrate_project(project)
    except VebuildError as e:
        return None, str(e), messages, reference
    save_project(project)
    return result, None, messages, reference


def frame_rotation(pairs: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray | None, list[bool]]:
    """W (survey → vebuild world) from (R̂, R_true) pairs, and which pairs agree with it within
    :data:`WRONG_AXES_DEG`: each pair's Wᵢ = R̂ᵢᵀ R_trueᵢ; the one most others agree with within
    :data:`CONSENSUS_DEG` (ties: the least summed angle), then the chordal mean of those near it."""
    from vebuild.camera import log_so3, nearest_rotation

    if not pairs:
        return None, []
    Ws = [Re.T @ Rt for Re, Rt in pairs]
    ang = np.array([[np.degrees(np.linalg.norm(log_so3(a @ b.T))) for b in Ws] for a in Ws])
    best = max(range(len(Ws)), key=lambda i: (int(np.sum(ang[i] < CONSENSUS_DEG)), -float(ang[i].sum())))
    near = [bool(a < WRONG_AXES_DEG) for a in ang[best]]
    W = nearest_rotation(sum(w for w, ok in zip(Ws, near, strict=True) if ok))
    return W, near


def _number(v: Any) -> float:
    """A JSON number, NaN for null (a σ the calibration could not give)."""
    return float("nan") if v is None else float(v)


def _matrix(rows: Any) -> np.ndarray:
    return np.array([[_number(v) for v in row] for row in rows] if np.ndim(rows) == 2
                    else [_number(v) for v in rows], float)


def _inside(e: np.ndarray, cov: np.ndarray, limit: float) -> bool:
    """Whether e lies inside the region eᵀ Σ⁻¹ e ≤ limit; a region not given (a σ null, Σ
    singular) holds nothing."""
    if not np.all(np.isfinite(cov)):
        return False
    try:
        return bool(e @ np.linalg.solve(cov, e) <= limit)
    except np.linalg.LinAlgError:
        return False


def score_group(photos: tuple[SurveyedPhoto, ...], result: dict[str, Any] | None, origin_X: np.ndarray,
                ) -> tuple[list[dict[str, Any]], list[dict[str, Any]], dict[str, Any]]:
    """Per photo rows, the check distances, and the group's alignment (see the module's docstring)."""
    from vebuild.calibration.similarity import DegenerateTargets, umeyama
    from vebuild.camera import log_so3

    cams = (result or {}).get("cameras", {})
    unplaced = (result or {}).get("unplaced", {})
    left_out = (result or {}).get("left_out", {})
    rows: list[dict[str, Any]] = []
    for ph in photos:
        row: dict[str, Any] = {"photo": ph.id, "f_true": ph.focal_px}
        rec = cams.get(ph.id) or unplaced.get(ph.id)
        if result is None:
            row["status"] = "refused"
        elif ph.id in cams:
            row["status"] = "placed"
        elif ph.id in unplaced:
            row["status"] = "unplaced"
        else:
            row["status"] = "left out" if ph.id in left_out else "not calibrated"
            row["reason"] = (left_out.get(ph.id) or {}).get("reason", "no vanishing segments")
        if rec is not None:
            f, f_sig = rec["focal_px"]["value"], _number(rec["focal_px"]["sigma"])
            row.update(mode=rec["mode"], mode_reason=rec.get("mode_reason"), f=f,
                       f_sigma=f_sig if np.isfinite(f_sig) else None,
                       focal_rel_error=abs(f / ph.focal_px - 1.0), R=np.array(rec["R"], float))
            d = np.array(rec["principal_point"]["value"], float) - ph.principal_point
            cov_pp = (_matrix(rec["covariance"])[1:3, 1:3] if "covariance" in rec
                      else np.diag(np.square(_matrix(rec["principal_point"]["sigma"]))))
            row["focal_covered"] = bool(abs(f - ph.focal_px) <= 1.959964 * f_sig)
            row["principal_point_error_px"] = float(np.linalg.norm(d))
            row["principal_point_covered"] = _inside(d, cov_pp, CHI2_2_95)
            row["interval_missing"] = not (np.isfinite(f_sig) and np.all(np.isfinite(cov_pp)))
            prior = rec.get("vanishing_point_prior") or {}
            if prior.get("K") is not None:  # before the markers: the vanishing points' own
                row["f_vanishing_points"] = float(prior["K"][0][0])
                row["k1_vanishing_points"] = (prior.get("k1") or {}).get("value")
            dist = rec.get("distortion")
            if dist is not None:
                row["k1"], row["k1_sigma"] = dist["k1"]["value"], dist["k1"]["sigma"]
        rows.append(row)
    by_id = {ph.id: ph for ph in photos}
    with_R = [r for r in rows if "R" in r]
    W, near = frame_rotation([(r["R"], by_id[r["photo"]].R) for r in with_R])
    for r, ok in zip(with_R, near, strict=True):
        ph, R = by_id[r["photo"]], r.pop("R")
        assert W is not None
        Rt = ph.R @ W.T
        w = log_so3(Rt @ R.T)
        r["rotation_error_deg"] = float(np.degrees(np.linalg.norm(w)))
        r["axes_right"] = ok
        r["unoriented_accepted"] = bool(not ok and r["status"] == "placed")
        if r["status"] == "placed" and ok:
            cov = _matrix(cams[r["photo"]]["covariance"])
            r["rotation_covered"] = _inside(w, cov[3:6, 3:6], CHI2_3_95)
            e = np.array(cams[r["photo"]]["position"]["value"], float) - W @ (ph.C - origin_X)
            r["position_error_m"] = float(np.linalg.norm(e))
            r["position_covered"] = _inside(e, cov[6:9, 6:9], CHI2_3_95)
            r["interval_missing"] = r["interval_missing"] or not np.all(np.isfinite(cov))
    align: dict[str, Any] = {"frame_photos": int(sum(near))}
    good = [r for r in rows if r.get("position_error_m") is not None]
    if len(good) >= 3:
        try:
            sim = umeyama([by_id[r["photo"]].C for r in good], [cams[r["photo"]]["position"]["value"] for r in good])
            fit = [sim.apply(by_id[r["photo"]].C) for r in good]
            res = [np.linalg.norm(np.array(cams[r["photo"]]["position"]["value"]) - y) for r, y in
                   zip(good, fit, strict=True)]
            align.update(similarity_scale=float(sim.scale), similarity_rms_m=float(np.sqrt(np.mean(np.square(res)))))
        except DegenerateTargets:
            pass
    checks = []
    for d in (result or {}).get("reference_distances", []):
        if d["role"] == "check":
            z = (d["measured"] - d["distance"]) / float(np.hypot(_number(d["measured_sigma"]), d["sigma"]))
            checks.append({"a": d["a"], "b": d["b"], "known_m": d["distance"], "measured_m": d["measured"],
                           "z": float(z) if np.isfinite(z) else None,
                           "failed": not bool(abs(z) <= CHECK_LIMIT_SIGMAS)})  # no σ measured: failed
    return rows, checks, align


def summary(rows: list[dict[str, Any]], checks: list[dict[str, Any]], groups_refused: int = 0) -> dict[str, Any]:
    """The figures over some photos' rows (a set's, or all)."""
    def share(key: str) -> float | None:
        v = [r[key] for r in rows if key in r]
        return float(np.mean(v)) if v else None

    def median(key: str) -> float | None:
        v = [r[key] for r in rows if r.get(key) is not None]
        return float(np.median(v)) if v else None

    k1 = [abs(r["k1"]) <= 2.0 * r["k1_sigma"] for r in rows if r.get("k1_sigma") and r.get("k1") is not None]
    sims = [r for r in rows if "similarity_rms_m" in r]
    return {
        "photos": len(rows),
        "calibrated": sum(r["status"] in ("placed", "unplaced") for r in rows),
        "placed": sum(r["status"] == "placed" for r in rows),
        "unplaced": sum(r["status"] == "unplaced" for r in rows),
        "left_out": sum(r["status"] in ("left out", "not calibrated") for r in rows),
        "refused": sum(r["status"] == "refused" for r in rows),
        "not_worked": sum(r["status"] == "not worked" for r in rows),
        "groups_refused": groups_refused,
        "focal_rel_error_median": median("focal_rel_error"),
        "focal_rel_error_p90": (float(np.percentile([r["focal_rel_error"] for r in rows if "focal_rel_error" in r],
                                                    90)) if any("focal_rel_error" in r for r in rows) else None),
        "reference_focal_rel_error_median": median("reference_focal_rel_error"),
        "focal_coverage_95": share("focal_covered"),
        "principal_point_error_px_median": median("principal_point_error_px"),
        "principal_point_coverage_95": share("principal_point_covered"),
        "rotation_error_deg_median": median("rotation_error_deg"),
        "rotation_coverage_95": share("rotation_covered"),
        "position_error_m_median": median("position_error_m"),
        "position_coverage_95": share("position_covered"),
        "position_similarity_rms_m": (float(np.median([r["similarity_rms_m"] for r in sims])) if sims else None),
        "unoriented_accepted": sum(bool(r.get("unoriented_accepted")) for r in rows),
        "wrong_axes": sum(r.get("axes_right") is False for r in rows),
        "check_distances": len(checks),
        "check_distance_failures": sum(c["failed"] for c in checks),
        "intervals_missing": sum(bool(r.get("interval_missing")) for r in rows),
        "k1_estimated": len(k1),
        "k1_within_2sigma_share": float(np.mean(k1)) if k1 else None,
        "mode_counts": {m: sum(r.get("mode") == m for r in rows) for m in sorted({r["mode"] for r in rows
                                                                                   if r.get("mode")})},
    }


def run(quick: bool = False, progress: bool = True, data: Path | None = None, seed: int = 44) -> dict[str, Any]:
    if data is None:
        raise VebuildError(f"bench real: expected --data DIR, the photo sets with surveyed cameras: {DATA_HELP}")
    sets = find_sets(Path(data))
    figures: dict[str, Any] = {"data": str(data), "click_noise_px": CLICK_NOISE_PX, "group_max": GROUP_MAX,
                               "sets": {}}
    all_rows: list[dict[str, Any]] = []
    all_checks: list[dict[str, Any]] = []
    refused_total = 0
    for s in sets:
        rows, checks, refused = _run_set(s, quick, progress, seed)
        figures["sets"][s.name] = {**summary(rows, checks, refused), "check_distances_measured": checks}
        all_rows += rows
        all_checks += checks
        refused_total += refused
    figures.update(summary(all_rows, all_checks, refused_total))
    figures["goals"] = GOALS
    figures["goals_met"] = _goals_met(figures)
    figures["per_photo"] = all_rows
    return figures


def _run_set(s: SurveyedSet, quick: bool, progress: bool, seed: int
             ) -> tuple[list[dict[str, Any]], list[dict[str, Any]], int]:
    import sys

    rows: list[dict[str, Any]] = []
    checks: list[dict[str, Any]] = []
    refused = 0
    for k, group in enumerate(groups(s.photos)[:1] if quick else groups(s.photos)):
        if progress:
            print(f"bench real: {s.name}, photos {group[0].id}–{group[-1].id}", file=sys.stderr)
        tracks = cached_tracks(group)
        markers = choose_markers(tracks, group)
        if len(markers) < MIN_MARKERS:  # not the calibration's failure: counted apart, not scored
            why = (f"the photos share {len(markers)} points seen in 3 photos or more, fewer than the {MIN_MARKERS} "
                   "markers a user would click")
            rows += [{"photo": ph.id, "f_true": ph.focal_px, "status": "not worked", "reason": why, "set": s.name,
                      "group": k, "markers": len(markers)} for ph in group]
            continue
        rng = np.random.default_rng([seed, k, len(s.name)])
        with tempfile.TemporaryDirectory(prefix="vebuild-bench-real-") as tmp:
            name = f"{s.name}-{k}"
            path, truth = make_project(Path(tmp) / name, name, group, markers, rng)
            result, refusal, messages, reference = work_group(path)
        g_rows, g_checks, align = score_group(group, result, truth["origin"])
        refused += result is None
        for r in g_rows:
            r.update(set=s.name, group=k, detect=messages.get(r["photo"]), markers=len(markers),
                     markers_seen=truth["markers_seen"][r["photo"]], **align)
            ref = reference.get(r["photo"])
            r["reference_focal_rel_error"] = None if ref is None else abs(ref / r["f_true"] - 1.0)
            if refusal is not None:
                r["reason"] = refusal
        rows += g_rows
        checks += [{**c, "group": k} for c in g_checks]
    return rows, checks, refused


def _goals_met(fig: dict[str, Any]) -> bool:
    for key, goal in GOALS.items():
        v = fig.get(key)
        if v is None:
            return False
        if key == "unoriented_accepted" and v > goal:
            return False
        if key == "focal_rel_error_median" and v > goal:
            return False
        if key not in ("unoriented_accepted", "focal_rel_error_median") and v < goal:
            return False
    return True


def table(fig: dict[str, Any]) -> str:
    names = list(fig["sets"])
    cols = [*names, "all"]

    def get(col: str, key: str) -> Any:
        return (fig if col == "all" else fig["sets"][col]).get(key)

    def cell(v: Any, scale: float = 1.0, digits: int = 3) -> str:
        if v is None:
            return "–"
        if isinstance(v, bool) or isinstance(v, int):
            return str(int(v))
        return f"{scale * v:.{digits}f}"

    width = max(16, *(len(c) + 2 for c in cols))
    lines = [f"calibration on real photographs with surveyed cameras ({fig['data']}); markers clicked with "
             f"{fig['click_noise_px']:g} px noise, detect's proposals accepted, groups of ≤ {fig['group_max']} photos",
             "", f"{'figure':<38}" + "".join(f"{c:>{width}}" for c in cols) + "   goal"]
    rows = [("photos", "photos", 1, 0), ("calibrated", "calibrated", 1, 0), ("placed", "placed", 1, 0),
            ("unplaced (calibrated, not placed)", "unplaced", 1, 0), ("left out", "left_out", 1, 0),
            ("refused (whole group refused)", "refused", 1, 0),
            (f"not worked (< {MIN_MARKERS} markers)", "not_worked", 1, 0),
            ("focal error median %", "focal_rel_error_median", 100, 2),
            ("focal error p90 %", "focal_rel_error_p90", 100, 2),
            ("  paper §2 closed form, median %", "reference_focal_rel_error_median", 100, 2),
            ("focal coverage 95 %", "focal_coverage_95", 1, 3),
            ("principal point error median px", "principal_point_error_px_median", 1, 1),
            ("principal point coverage 95 %", "principal_point_coverage_95", 1, 3),
            ("rotation error median °", "rotation_error_deg_median", 1, 3),
            ("rotation coverage 95 %", "rotation_coverage_95", 1, 3),
            ("position error median m", "position_error_m_median", 1, 3),
            ("position coverage 95 %", "position_coverage_95", 1, 3),
            ("position after similarity, RMS m", "position_similarity_rms_m", 1, 3),
            ("photos with wrong axes", "wrong_axes", 1, 0), ("  placed anyway (unoriented_accepted)",
                                                              "unoriented_accepted", 1, 0),
            ("check distances", "check_distances", 1, 0),
            (f"  off by > {CHECK_LIMIT_SIGMAS:g}σ (check_distance_failures)", "check_distance_failures", 1, 0),
            ("intervals not given (σ null)", "intervals_missing", 1, 0), ("k1 estimated", "k1_estimated", 1, 0),
            ("k1 within 2σ of 0, share", "k1_within_2sigma_share", 1, 3)]
    goal_text = {"focal_rel_error_median": "≤ 2 %", "focal_coverage_95": "≥ 0.90",
                 "principal_point_coverage_95": "≥ 0.90", "rotation_coverage_95": "≥ 0.90",
                 "unoriented_accepted": "0", "k1_within_2sigma_share": "≥ 0.95"}
    for label, key, scale, digits in rows:
        lines.append(f"{label:<38}" + "".join(f"{cell(get(c, key), scale, digits):>{width}}" for c in cols)
                     + f"   {goal_text.get(key, '')}")
    modes = ", ".join(f"{m} {n}" for m, n in fig["mode_counts"].items())
    lines += ["", f"modes: {modes or 'none'}", f"goals: {'met' if fig['goals_met'] else 'NOT met'}"]
    lines += ["", "per photo (f error / its 1σ; * outside the 95 % interval or region; k1 ± 1σ):",
              f"  {'set':<16}{'photo':<7}{'status':<17}{'mode':<6}{'f err %':>9}{'z':>7}{'pp px':>8}{'rot °':>8}"
              f"{'pos m':>8}  k1"]
    for r in fig["per_photo"]:
        def flag(key: str, r: dict[str, Any] = r) -> str:
            return "*" if r.get(key) is False else " "

        status = r["status"] + (" (axes)" if r.get("axes_right") is False else "")
        f_err = (f"{100 * (r['f'] / r['f_true'] - 1):+.1f}{flag('focal_covered')}" if "f" in r else "–")
        z = f"{(r['f'] - r['f_true']) / r['f_sigma']:+.1f}" if r.get("f_sigma") else "–"
        pp = f"{r['principal_point_error_px']:.0f}{flag('principal_point_covered')}" if "f" in r else "–"
        rot = f"{r['rotation_error_deg']:.2f}{flag('rotation_covered')}" if "rotation_error_deg" in r else "–"
        pos = f"{r['position_error_m']:.2f}{flag('position_covered')}" if "position_error_m" in r else "–"
        k1 = (f"{r['k1']:+.4f} ± {r['k1_sigma']:.4f}" if r.get("k1_sigma") else
              "–" if r.get("k1") is None else f"{r['k1']:+.4f} (σ null)")
        lines.append(f"  {r['set'][:15]:<16}{r['photo'][:6]:<7}{status:<17}{r.get('mode') or '–':<6}{f_err:>9}{z:>7}"
                     f"{pp:>8}{rot:>8}{pos:>8}  {k1}")
    return "\n".join(lines)
