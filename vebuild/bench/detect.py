"""``vebuild bench detect``: automatic vanishing segments on generated 12 MP photos and the example's.

Photos: :mod:`vebuild.bench.detect_photos` (ray-cast rooms, 4000 × 3000, JPEG, blur, noise, lens
distortion on half, views 3vp, 2vp, 1vp, frontal, corridor; cached). For each photo, timed: the
proposals (:func:`vebuild.actions.detect.propose`: grey conversion, LSD, sub-pixel refinement,
grouping; the JPEG's decoding is timed apart), then the photo calibrated from every proposal with
its own 1σ (:func:`vebuild.calibration.photo.calibrate_photo`, as ``vebuild calibrate`` does it,
with the EXIF focal prior told the photos' real 4 %).

Figures: ``vp_within_{1,3,5}deg_share`` the share of the true vanishing directions a photo
shows (:func:`_shown`) whose best estimate lies within 1°, 3°, 5° (the York Urban measure: the
angle between the estimated and the true direction, up to sign, to the nearest estimated one). A
photo's best estimate is its calibrated rotation where the photo was calibrated, otherwise the
vanishing directions the detector names in its message (``PhotoProposals.directions``: a photo
showing one direction, with EXIF's focal length and the principal point at the centre); a
direction neither gives counts as missed. ``vps_from_the_detector_alone`` counts the shown
directions within 3° that came from the detector's own directions. ``..._calibrated``: the same
from the calibrated rotations alone (a photo not calibrated misses all its directions);
``_all``: over all three directions of every photo, shown or not;
``_two_directions_visible``: over the photos whose edges show two directions (:func:`_visible`);
``grouping_vp_within_3deg_share`` the same for the grouping's own frame (principal point
at the centre, no distortion); ``focal_rel_error_median``/``_p90`` of the calibrated focal length
over the photos whose calibration is ``3vp`` or ``2vp`` (a frontal or one-point view's f is EXIF's);
``focal_coverage_95`` the share of those whose true f lies inside the reported 95 % interval;
``detect_ms_per_photo`` (median) and ``decode_ms_per_photo``; ``no_result`` photos with no
proposal or a refused calibration. The reference run in the same process: the same photos
calibrated from simulated careful clicks (:func:`vebuild.synthetic.add_segments`, 0.7 px, 4–6 per
axis, plumb-line middle points on long edges), ``*_ratio`` = detected / clicked; and LSD alone at
full resolution (``lsd_full_resolution_ms``). The same figures over the example's six photos
(scenes/room, 1600 × 1200, known cameras), prefixed ``room_``.

Goals: ≥ 95 % of vanishing points within 3°, focal median ≤ 1.5 %, < 1 s per 12 MP photo.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from vebuild.actions.detect import propose
from vebuild.calibration.photo import calibrate_photo
from vebuild.calibration.priors import FocalPrior
from vebuild.errors import VebuildError
from vebuild.project.images import decode_photo
from vebuild.resources import example_project_dir
from vebuild.synthetic import SyntheticPhoto, add_segments

from .detect_photos import exif_record, generated_photos

GOALS = {"vp_within_3deg_share": 0.95, "focal_rel_error_median": 0.015, "detect_ms_per_photo": 1000.0}
N_PHOTOS, N_QUICK = 100, 12


def _axis_errors_deg(R_true: np.ndarray, D: np.ndarray | None, seen: np.ndarray) -> list[float]:
    """Angle of each true axis to the nearest (up to sign) estimated direction that was seen."""
    out = []
    for k in range(3):
        best = 180.0
        if D is not None:
            for j in range(D.shape[1]):
                if seen[j]:
                    c = min(1.0, abs(float(R_true[:, k] @ D[:, j])))
                    best = min(best, float(np.degrees(np.arccos(c))))
        out.append(best)
    return out


def _one(pixels: np.ndarray, photo: dict[str, Any], truth: dict[str, Any], exif_sigma_rel: float,
         rng: np.random.Generator | None) -> dict[str, Any]:
    K = np.array(truth["K"])
    R = np.array(truth["R"])
    t0 = time.perf_counter()
    props = propose(pixels, photo)
    ms = 1000.0 * (time.perf_counter() - t0)
    row: dict[str, Any] = {"photo": photo["id"], "kind": truth.get("kind", ""), "detect_ms": ms,
                           "message": props.message}
    prior = FocalPrior(truth["exif_focal_px"], exif_sigma_rel * truth["exif_focal_px"], "exif")
    segs: dict[str, list] = {a: [] for a in "xyz"}
    sig: dict[str, list] = {a: [] for a in "xyz"}
    for p in props.segments:
        segs[p.axis].append(np.array(p.points or p.segment))
        sig[p.axis].append(p.sigma_px)
    segs = {a: v for a, v in segs.items() if v}
    sig = {a: v for a, v in sig.items() if a in segs}
    row.update(_calibrated(segs, sig, photo, prior, K, R, "detected"))
    # The detector's own vanishing directions (those its message names): what a photo it could
    # not calibrate is scored by (one direction only, or a refused calibration).
    own = np.array(props.directions, float).T if props.directions else None
    row["detector_axis_err"] = _axis_errors_deg(R, own, np.ones(len(props.directions), bool))
    row["best_axis_err"] = row["detected_axis_err"] if row["detected_mode"] is not None else row["detector_axis_err"]
    if rng is not None:  # the reference: careful clicks on the same camera
        cam = SyntheticPhoto(photo["id"], truth.get("kind", ""), photo["width"], photo["height"], K, R,
                             np.array(truth["C"]), k1=truth["k1"])
        try:
            add_segments(cam, rng, noise_px=0.7, middle_points=2)
            clicks = {a: s for a, s in cam.segments.items() if len(s)}
            row.update(_calibrated(clicks, None, photo, prior, K, R, "clicked", click=0.7))
        except (VebuildError, ValueError, np.linalg.LinAlgError):
            row["clicked_focal_err"] = None
    return row


def _calibrated(segs: dict, sig: dict | None, photo: dict, prior: FocalPrior, K: np.ndarray, R: np.ndarray,
                tag: str, click: float = 1.0) -> dict[str, Any]:
    out: dict[str, Any] = {f"{tag}_focal_err": None, f"{tag}_axis_err": [180.0] * 3, f"{tag}_covered": None,
                           f"{tag}_mode": None}
    if len(segs) < 2:
        return out
    try:
        cal = calibrate_photo(segs, photo["width"], photo["height"], photo=photo["id"], click_sigma_px=click,
                              segment_sigma_px=sig, exif_focal=prior)
    except VebuildError as e:
        out[f"{tag}_refused"] = str(e)
        return out
    # The calibrated rotation places all three vanishing points (a third from the two others).
    out[f"{tag}_axis_err"] = _axis_errors_deg(R, cal.R, np.ones(3, bool))
    out[f"{tag}_mode"] = cal.mode
    f_true = K[0, 0]
    out[f"{tag}_focal_err"] = abs(cal.f / f_true - 1.0)
    out[f"{tag}_covered"] = bool(abs(cal.f - f_true) <= 1.96 * cal.f_sigma)
    return out


def _visible(segments: np.ndarray, truth: dict[str, Any]) -> bool:
    """Whether the detected edges (before grouping) include two world directions with at least
    two edges each, by the true camera: end points within 3 px of the true vanishing line (an
    oracle that tells a photo with too little in it from a grouping that failed)."""
    from vebuild.calibration.lines import _distances
    from vebuild.camera import Lens, undistort_pixels

    if len(segments) == 0:
        return False
    K, R = np.array(truth["K"]), np.array(truth["R"])
    u = undistort_pixels(K, segments.reshape(-1, 2), Lens(float(truth["k1"]))).reshape(-1, 4)
    d = _distances(u, K @ R)
    lab = np.argmin(d, axis=1)
    ok = d[np.arange(len(d)), lab] < 3.0
    return int(np.sum(np.bincount(lab[ok], minlength=3) >= 2)) >= 2


#: A photo shows a vanishing direction when the line detector finds, before any grouping, at least
#: this many edges along it (by the true camera: end points within 3 px of the line through the
#: edge's midpoint and the true vanishing point) ...
SHOWN_MIN_EDGES = 2
#: ... of this total length, as a share of the photo's diagonal (100 px on a 12 MP photo).
SHOWN_MIN_LENGTH_DIAG = 0.02


def _shown(segments: np.ndarray, truth: dict[str, Any]) -> list[bool]:
    """Which of the three true vanishing directions the photo shows (:data:`SHOWN_MIN_EDGES`,
    :data:`SHOWN_MIN_LENGTH_DIAG`): the same oracle as :func:`_visible`, per direction."""
    from vebuild.calibration.lines import _distances
    from vebuild.camera import Lens, undistort_pixels

    if len(segments) == 0:
        return [False] * 3
    K, R = np.array(truth["K"]), np.array(truth["R"])
    u = undistort_pixels(K, segments.reshape(-1, 2), Lens(float(truth["k1"]))).reshape(-1, 4)
    d = _distances(u, K @ R)
    lab = np.argmin(d, axis=1)
    ok = d[np.arange(len(d)), lab] < 3.0
    length = np.hypot(u[:, 2] - u[:, 0], u[:, 3] - u[:, 1])
    diag = float(np.hypot(truth["width"], truth["height"]))
    return [bool(np.sum(ok & (lab == k)) >= SHOWN_MIN_EDGES
                 and np.sum(length[ok & (lab == k)]) >= SHOWN_MIN_LENGTH_DIAG * diag) for k in range(3)]


def _summary(rows: list[dict[str, Any]], prefix: str = "") -> dict[str, Any]:
    axis = np.array([r["best_axis_err"] for r in rows], float).ravel()
    calibrated = np.array([r["detected_axis_err"] for r in rows], float).ravel()
    vp_rows = [r for r in rows if r["detected_mode"] in ("3vp", "2vp")]
    fe = np.array([r["detected_focal_err"] for r in vp_rows], float)
    cov = [r["detected_covered"] for r in vp_rows]
    ref = np.array([r.get("clicked_focal_err") for r in vp_rows if r.get("clicked_focal_err") is not None], float)
    ms = np.array([r["detect_ms"] for r in rows])
    shown = np.array([r.get("shown", [True] * 3) for r in rows], bool).ravel()
    from_detector = np.repeat([r["detected_mode"] is None for r in rows], 3)
    out = {
        "photos": len(rows),
        "vps_shown": int(shown.sum()),
        "vp_within_1deg_share": float(np.mean(axis[shown] <= 1.0)) if shown.any() else None,
        "vp_within_3deg_share": float(np.mean(axis[shown] <= 3.0)) if shown.any() else None,
        "vp_within_5deg_share": float(np.mean(axis[shown] <= 5.0)) if shown.any() else None,
        "vp_within_1deg_share_calibrated": float(np.mean(calibrated[shown] <= 1.0)) if shown.any() else None,
        "vp_within_3deg_share_calibrated": float(np.mean(calibrated[shown] <= 3.0)) if shown.any() else None,
        "vp_within_5deg_share_calibrated": float(np.mean(calibrated[shown] <= 5.0)) if shown.any() else None,
        "vp_within_1deg_share_all": float(np.mean(axis <= 1.0)),
        "vp_within_3deg_share_all": float(np.mean(axis <= 3.0)),
        "vp_within_5deg_share_all": float(np.mean(axis <= 5.0)),
        "vp_within_3deg_share_all_calibrated": float(np.mean(calibrated <= 3.0)),
        "vps_from_the_detector_alone": int(np.sum(shown & from_detector & (axis <= 3.0))),
        "grouping_vp_within_3deg_share": float(np.mean(np.array([r["grouping_axis_err"] for r in rows]) <= 3.0)),
        "focal_photos": len(fe),
        "focal_rel_error_median": float(np.median(fe)) if len(fe) else None,
        "focal_rel_error_p90": float(np.percentile(fe, 90)) if len(fe) else None,
        "focal_coverage_95": float(np.mean(cov)) if cov else None,
        "detect_ms_per_photo": float(np.median(ms)),
        "detect_ms_max": float(np.max(ms)),
        "no_result": int(sum(r["detected_focal_err"] is None for r in rows)),
    }
    vis = [r for r in rows if r.get("two_directions_visible", True)]
    ax_vis = np.array([r["best_axis_err"] for r in vis], float).ravel()
    out["photos_two_directions_visible"] = len(vis)
    for t in (1, 3, 5):
        out[f"vp_within_{t}deg_share_two_directions_visible"] = float(np.mean(ax_vis <= t)) if len(vis) else None
    if len(ref) and len(fe):
        out["clicked_focal_rel_error_median"] = float(np.median(ref))
        out["focal_rel_error_median_ratio"] = float(np.median(fe) / max(np.median(ref), 1e-12))
    return {prefix + k: v for k, v in out.items()}


def run(quick: bool = False, progress: bool = True, seed: int = 2107, *, n: int | None = None,
        width: int = 4000, height: int = 3000, room: bool = True, clutter: int | None = None) -> dict[str, Any]:
    """The figures over ``n`` generated photos (default 100, 12 with ``quick``) of ``width`` ×
    ``height`` pixels, (``room``) over the example's six photos, and over ``clutter`` street photos
    (:mod:`.detect_clutter`; default 40, 10 with ``quick``, none where ``n`` is given)."""
    import cv2

    from vebuild.calibration.lines import detect_lines, group_manhattan, to_grey

    from .detect_clutter import N_CLUTTER, N_CLUTTER_QUICK, clutter_figures

    if clutter is None:
        clutter = 0 if n is not None else (N_CLUTTER_QUICK if quick else N_CLUTTER)
    n = n if n is not None else (N_QUICK if quick else N_PHOTOS)
    photos = generated_photos(n, width=width, height=height, seed=seed, progress=progress)
    rows, decode_ms = [], []
    rng = np.random.default_rng(seed)
    items: Any = photos
    if progress:
        from vebuild.console.bars import Bar

        items = Bar(photos, desc="detecting", unit="photo")
    for g in items:
        T = g.truth
        data = g.path.read_bytes()
        t0 = time.perf_counter()
        pixels = decode_photo(data, g.path.name, g.path, "")
        decode_ms.append(1000.0 * (time.perf_counter() - t0))
        photo = {"id": g.path.stem, "width": T["width"], "height": T["height"], "exif": exif_record(T)}
        row = _one(pixels, photo, T, T["exif_focal_sigma_rel"], rng)
        found = detect_lines(to_grey(pixels))
        fr = group_manhattan(found.segments, T["width"], T["height"],
                             focal_prior=(T["exif_focal_px"], T["exif_focal_sigma_rel"] * T["exif_focal_px"]),
                             sigma_px=found.sigma_px)
        seen = np.array([np.any(fr.labels == j) for j in range(3)]) if fr is not None else np.zeros(3, bool)
        row["grouping_axis_err"] = _axis_errors_deg(np.array(T["R"]), fr.directions if fr else None, seen)
        row["two_directions_visible"] = _visible(found.segments, T)
        row["shown"] = _shown(found.segments, T)
        rows.append(row)
    figures: dict[str, Any] = {"generator": "vebuild.bench.detect_photos (ray-cast rooms, JPEG)",
                               "width": width, "height": height}
    figures.update(_summary(rows))
    figures["decode_ms_per_photo"] = float(np.median(decode_ms))
    # LSD alone on the full-resolution photo: the reference of the detection's time.
    pixels = decode_photo(photos[0].path.read_bytes(), photos[0].path.name, photos[0].path, "")
    grey = to_grey(pixels).astype(np.uint8)
    t0 = time.perf_counter()
    cv2.createLineSegmentDetector(cv2.LSD_REFINE_NONE).detect(grey)
    figures["lsd_full_resolution_ms"] = 1000.0 * (time.perf_counter() - t0)
    figures["detect_ms_ratio_to_lsd_full_resolution"] = (figures["detect_ms_per_photo"]
                                                         / figures["lsd_full_resolution_ms"])
    if room:
        figures.update(_summary(_room_rows(), "room_"))
    if clutter:
        figures.update(clutter_figures(clutter)[0])
    figures["goals"] = GOALS
    figures["per_photo"] = [{k: v for k, v in r.items() if not k.startswith("clicked_") or k == "clicked_focal_err"}
                            for r in rows]
    return figures


def _room_rows() -> list[dict[str, Any]]:
    from vebuild.calibration.lines import detect_lines, group_manhattan, to_grey

    folder = example_project_dir()
    doc = json.loads((folder / "room.vebuild.json").read_text())
    truth = json.loads((folder / "ground_truth.json").read_text())
    rows = []
    for photo in doc["photos"]:
        T = truth["photos"][photo["id"]]
        path = folder / Path(photo["file"])
        pixels = decode_photo(path.read_bytes(), path.name, path, "")
        exif_f = photo["exif"]["focal_length_px"]
        t = {"K": T["K"], "R": T["R"], "C": T["C"], "k1": T["distortion"]["k1"], "exif_focal_px": exif_f,
             "kind": "room"}
        row = _one(pixels, {k: photo[k] for k in ("id", "width", "height", "exif")}, t, 0.03, None)
        found = detect_lines(to_grey(pixels))
        fr = group_manhattan(found.segments, photo["width"], photo["height"], focal_prior=(exif_f, 0.03 * exif_f),
                             sigma_px=found.sigma_px)
        seen = np.array([np.any(fr.labels == j) for j in range(3)]) if fr is not None else np.zeros(3, bool)
        row["grouping_axis_err"] = _axis_errors_deg(np.array(T["R"]), fr.directions if fr else None, seen)
        rows.append(row)
    return rows


def table(figures: dict[str, Any]) -> str:
    def fmt(v: Any) -> str:
        if v is None:
            return "—"
        if isinstance(v, float):
            return f"{v:.4g}"
        return str(v)

    lines = ["automatic vanishing segments (vebuild detect)", ""]
    keys = ["photos", "vps_shown", "vp_within_1deg_share", "vp_within_3deg_share", "vp_within_5deg_share",
            "vp_within_1deg_share_calibrated", "vp_within_3deg_share_calibrated", "vp_within_5deg_share_calibrated",
            "vps_from_the_detector_alone",
            "vp_within_1deg_share_all", "vp_within_3deg_share_all", "vp_within_5deg_share_all",
            "vp_within_3deg_share_all_calibrated",
            "grouping_vp_within_3deg_share", "photos_two_directions_visible",
            "vp_within_1deg_share_two_directions_visible", "vp_within_3deg_share_two_directions_visible",
            "vp_within_5deg_share_two_directions_visible", "focal_photos", "focal_rel_error_median",
            "focal_rel_error_p90",
            "focal_coverage_95", "clicked_focal_rel_error_median", "focal_rel_error_median_ratio",
            "detect_ms_per_photo", "detect_ms_max", "no_result"]
    lines.append(f"  {'figure':<46} {'generated 12 MP':>16} {'example room':>14}   goal")
    for k in keys:
        goal = GOALS.get(k)
        lines.append(f"  {k:<46} {fmt(figures.get(k)):>16} {fmt(figures.get('room_' + k)):>14}   "
                     + ("" if goal is None else (f"≥ {goal:g}" if k.startswith("vp_") else f"≤ {goal:g}")))
    lines.append(f"  {'decode_ms_per_photo':<46} {fmt(figures.get('decode_ms_per_photo')):>16}")
    lines.append(f"  {'lsd_full_resolution_ms':<46} {fmt(figures.get('lsd_full_resolution_ms')):>16}   "
                 "(reference: LSD alone on the full image)")
    if figures.get("clutter_photos"):
        lines += ["", "street photos with clutter (1600 × 1200: cobbles, trees, wires, railings, roofs)"]
        lines += [f"  {k:<46} {fmt(v):>16}" for k, v in figures.items() if k.startswith("clutter_")]
    return "\n".join(lines)
