"""``vebuild bench calibration``: accuracy and speed of calibration on random synthetic cameras.

Scenes of four photos (two tilted 3-vanishing-point views, a level 2-point view whose vertical
vanishing point is at infinity, and a frontal 1-point view using its EXIF focal length) with
0.7 px click noise. Each photo is calibrated by vebuild and, as the reference run in the same
process, by the paper's method alone (per-axis vanishing points and closed-form K, R:
:func:`closed_form_calibration`). Errors against the known cameras are summarised by median and
95th percentile; "ratio" figures divide vebuild's by the reference's. The 1σ consistency figure
is the RMS of (error / reported 1σ): near 1 when the reported uncertainty is honest.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from tqdm import tqdm

from ..calibration.photo import FocalPrior, calibrate_photo, closed_form_calibration
from ..calibration.positions import PhotoInput, ReferenceDistance, place_cameras
from ..camera import log_so3
from ..errors import CalibrationError
from ..synthetic import EXIF_FOCAL_ERROR_REL, ROOM, random_scene, scale_reference

KINDS = ("3vp", "3vp", "2vp", "1vp")
NOISE_PX = 0.7
GOALS = {"focal_rel_error_median": 0.005, "focal_rel_error_p95": 0.02, "failures": 0}


def _rot_err_deg(R_true: np.ndarray, R: np.ndarray) -> float:
    return float(np.degrees(np.linalg.norm(log_so3(R_true @ R.T))))


def run(quick: bool = False, progress: bool = True, n_cameras: int | None = None, seed: int = 2026) -> dict[str, Any]:
    """Calibrate ⌈n_cameras / 4⌉ random scenes (200 cameras, 40 with quick); return the figures."""
    n_cameras = n_cameras or (40 if quick else 200)
    rng = np.random.default_rng(seed)
    n_scenes = -(-n_cameras // len(KINDS))
    rows: list[dict[str, Any]] = []
    ref_rows: list[dict[str, float]] = []
    t_ours = t_ref = t_place = 0.0
    failures: list[str] = []
    diag = float(np.linalg.norm(ROOM))
    for s in tqdm(range(n_scenes), desc="bench calibration", unit="scene", disable=not progress):
        photos, markers = random_scene(rng, KINDS, noise_px=NOISE_PX)
        inputs, cals = [], {}
        try:
            for ph in photos:
                focal = ph.exif_focal_px
                assert focal is not None  # random_scene gives every photo an EXIF focal length
                exif = FocalPrior(focal, EXIF_FOCAL_ERROR_REL * focal, "exif")
                t0 = time.perf_counter()
                cal = calibrate_photo(ph.segments, ph.width, ph.height, photo=ph.id, click_sigma_px=NOISE_PX,
                                      exif_focal=exif)
                t1 = time.perf_counter()
                K_ref, R_ref = closed_form_calibration(ph.segments, ph.width, ph.height, photo=ph.id, focal=exif)
                t2 = time.perf_counter()
                t_ours += t1 - t0
                t_ref += t2 - t1
                cals[ph.id] = cal
                inputs.append(PhotoInput(ph.id, cal.K, cal.R, cal.covariance, ph.markers))
                f = ph.K[0, 0]
                ref_rows.append({"focal": abs(K_ref[0, 0] - f) / f, "rot": _rot_err_deg(ph.R, R_ref),
                                 "pp": float(np.linalg.norm(K_ref[:2, 2] - ph.K[:2, 2]))})
            a, b, d = scale_reference(photos, markers)
            t0 = time.perf_counter()
            placement = place_cameras(inputs, origin="O", distances=[ReferenceDistance(a, b, d, 0.002)],
                                      click_sigma_px=NOISE_PX)
            t_place += time.perf_counter() - t0
        except CalibrationError as e:
            failures.append(f"scene {s}: {e}")
            continue
        for ph in photos:
            cam = placement.cameras[ph.id]
            f = ph.K[0, 0]
            sig = np.sqrt(np.diag(cam.covariance))
            w = log_so3(ph.R @ cam.R.T)
            rows.append({
                "kind": ph.kind,
                "mode": cals[ph.id].mode,
                "focal": abs(cam.K[0, 0] - f) / f,
                "pp": float(np.linalg.norm(cam.K[:2, 2] - ph.K[:2, 2])),
                "rot": float(np.degrees(np.linalg.norm(w))),
                "pos": float(np.linalg.norm(cam.C - ph.C)),
                "z_focal": (cam.K[0, 0] - f) / sig[0],
                "z_rot": w / sig[3:6],
                "z_pos": (cam.C - ph.C) / sig[6:9],
            })

    def col(key: str, rs: list[dict[str, Any]] = rows) -> np.ndarray:
        return np.array([r[key] for r in rs], float)

    n = len(rows)
    out: dict[str, Any] = {
        "cameras": n,
        "failures": len(failures),
        "click_noise_px": NOISE_PX,
        "third_vp_near_infinity_share": float(np.mean([r["mode"] != "3vp" for r in rows])) if n else 0.0,
        "mode_share_3vp": float(np.mean([r["mode"] == "3vp" for r in rows])) if n else 0.0,
        "mode_share_2vp": float(np.mean([r["mode"] == "2vp" for r in rows])) if n else 0.0,
        "mode_share_1vp": float(np.mean([r["mode"] == "1vp" for r in rows])) if n else 0.0,
    }
    for key, name, scale in (("focal", "focal_rel_error", 1.0), ("pp", "principal_point_error_px", 1.0),
                             ("rot", "rotation_error_deg", 1.0), ("pos", "position_error_m", 1.0),
                             ("pos", "position_rel_error", 1.0 / diag)):
        v = col(key) * scale
        out[f"{name}_median"] = float(np.median(v)) if n else float("nan")
        out[f"{name}_p95"] = float(np.percentile(v, 95)) if n else float("nan")
    for kind in ("3vp", "2vp", "1vp"):
        rs = [r for r in rows if r["kind"] == kind]
        out[f"focal_rel_error_median_{kind}"] = float(np.median(col("focal", rs))) if rs else float("nan")
        out[f"rotation_error_deg_median_{kind}"] = float(np.median(col("rot", rs))) if rs else float("nan")
    out["sigma_consistency_focal"] = float(np.sqrt(np.mean(col("z_focal") ** 2))) if n else float("nan")
    out["sigma_consistency_rotation"] = float(np.sqrt(np.mean(np.concatenate([r["z_rot"] for r in rows]) ** 2)))
    out["sigma_consistency_position"] = float(np.sqrt(np.mean(np.concatenate([r["z_pos"] for r in rows]) ** 2)))
    n_photos = len(ref_rows)
    for key, name in (("focal", "focal_rel_error"), ("rot", "rotation_error_deg"), ("pp", "principal_point_error_px")):
        ref = np.array([r[key] for r in ref_rows])
        out[f"reference_{name}_median"] = float(np.median(ref))
        out[f"reference_{name}_p95"] = float(np.percentile(ref, 95))
        out[f"{name}_median_ratio_vs_reference"] = out[f"{name}_median"] / max(out[f"reference_{name}_median"], 1e-300)
    out["time_per_photo_ms"] = 1000.0 * t_ours / max(n_photos, 1)
    out["reference_time_per_photo_ms"] = 1000.0 * t_ref / max(n_photos, 1)
    out["time_ratio_vs_reference"] = t_ours / max(t_ref, 1e-12)
    out["placement_time_per_photo_ms"] = 1000.0 * t_place / max(n, 1)
    out["goals_met"] = bool(out["focal_rel_error_median"] <= GOALS["focal_rel_error_median"]
                            and out["focal_rel_error_p95"] <= GOALS["focal_rel_error_p95"] and not failures)
    out["failure_messages"] = failures[:10]
    return out


def table(fig: dict[str, Any]) -> str:
    """The figures as a text table: vebuild against the paper's closed form."""
    lines = [f"calibration benchmark: {fig['cameras']} synthetic cameras, {fig['click_noise_px']} px click noise, "
             f"{fig['failures']} failures",
             f"modes: 3vp {100 * fig['mode_share_3vp']:.0f} %, 2vp {100 * fig['mode_share_2vp']:.0f} %, "
             f"1vp {100 * fig['mode_share_1vp']:.0f} % (third vanishing point near infinity or absent: "
             f"{100 * fig['third_vp_near_infinity_share']:.0f} %)",
             "",
             f"{'figure':<30}{'vebuild median':>16}{'p95':>10}{'paper §2 median':>17}{'p95':>10}{'ratio':>8}"]
    for name, label, unit in (("focal_rel_error", "focal length error", "%"),
                              ("principal_point_error_px", "principal point error", "px"),
                              ("rotation_error_deg", "rotation error", "°")):
        k = 100.0 if unit == "%" else 1.0
        lines.append(f"{label + ' (' + unit + ')':<30}{k * fig[name + '_median']:>16.3f}{k * fig[name + '_p95']:>10.3f}"
                     f"{k * fig['reference_' + name + '_median']:>17.3f}{k * fig['reference_' + name + '_p95']:>10.3f}"
                     f"{fig[name + '_median_ratio_vs_reference']:>8.2f}")
    lines.append(f"{'position error (m)':<30}{fig['position_error_m_median']:>16.4f}"
                 f"{fig['position_error_m_p95']:>10.4f}")
    lines.append(f"{'position error (% of room)':<30}{100 * fig['position_rel_error_median']:>16.3f}"
                 f"{100 * fig['position_rel_error_p95']:>10.3f}")
    lines += ["",
              f"1σ consistency, RMS(error/σ): focal {fig['sigma_consistency_focal']:.2f}, rotation "
              f"{fig['sigma_consistency_rotation']:.2f}, position {fig['sigma_consistency_position']:.2f}",
              f"time per photo: {fig['time_per_photo_ms']:.1f} ms (paper §2 closed form "
              f"{fig['reference_time_per_photo_ms']:.1f} ms, ratio {fig['time_ratio_vs_reference']:.1f}); "
              f"placement {fig['placement_time_per_photo_ms']:.1f} ms per photo",
              f"goals (median focal error ≤ 0.5 %, 95th percentile ≤ 2 %, no failure): "
              f"{'met' if fig['goals_met'] else 'NOT met'}"]
    for m in fig["failure_messages"]:
        lines.append(f"  failure: {m}")
    return "\n".join(lines)
