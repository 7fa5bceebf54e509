"""The report's camera sections, one stage at a time: the vanishing-point calibration
(``calibration.cameras``, each photo's mode and its reason), then the final cameras, those a
re-calibrating solve wrote (``model_solution.cameras``) or, where it wrote none, the calibration's,
said in words."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from vebuild.console.tables import exif_check_words, failed_check_words
from vebuild.project import Project
from vebuild.project.units import length_unit

from .page import Report, esc, fmt, table

LENS_NOTE = ("The lens is the division model's k1 (x_u = x_d / (1 + k1 r² + k2 r⁴) on f-normalised coordinates, "
             "r = |x_d|; k1 &lt; 0 barrel; k2, the second term of a wide or fisheye lens, shown where it was "
             "estimated or is not 0) and how far it moves the photo's farthest corner; a pinhole where no "
             "distortion was estimated or given.")


def lens(camera: Mapping[str, Any]) -> str:
    """A camera record's lens distortion in words: k1 ± 1σ (and k2 ± 1σ where it was estimated or is
    not 0) and the corner displacement, or pinhole."""
    d = camera.get("distortion")
    if not d:
        return "pinhole"
    k1, corner = d["k1"], d.get("corner_displacement_px") or {}
    text = f"k1 {k1['value']:+.4f} ± {k1['sigma'] or 0:.4f}"
    k2 = d.get("k2") or {}
    if k2 and (k2.get("value") or k2.get("sigma")):  # a second term estimated or given
        text += f", k2 {k2['value']:+.4f} ± {k2.get('sigma') or 0:.4f}"
    if corner:
        text += f", corners {corner['value']:.1f} ± {corner.get('sigma') or 0:.1f} px"
    return text + f" ({d.get('source', '')})"


def _pm(values: Any, sigmas: Any, digits: int) -> str:
    return " / ".join(f"{v:.{digits}f} ± {s or 0:.{digits}f}" for v, s in zip(values, sigmas, strict=True))


def camera_rows(records: Mapping[str, Mapping[str, Any]], mode: bool,
                rms: Mapping[str, float | None] | None = None) -> list[list[Any]]:
    """One row per camera record; ``rms`` (photo id → px) in place of the records' own ``rms_px``."""
    rows = []
    for pid, c in records.items():
        row = [pid] + ([c.get("mode", "")] if mode else [])
        rows.append(row + [f"{c['focal_px']['value']:.1f} ± {c['focal_px']['sigma'] or 0:.1f}",
                           fmt(c["principal_point"]["value"], 1),
                           _pm(c["ypr_deg"]["value"], c["ypr_deg"]["sigma"], 2),
                           _pm(c["position"]["value"], c["position"]["sigma"], 3),
                           lens(c), fmt(rms.get(pid) if rms is not None else c.get("rms_px"), 2)])
    return rows


def solve_rms(solution: Mapping[str, Any], records: Mapping[str, Mapping[str, Any]]) -> dict[str, float | None]:
    """Photo id → the RMS (px, over both image axes) of the re-calibrating solve's residuals in that
    photo: its pins, edge observations and marker sightings (``model_solution.pins``,
    ``edge_observations``, the record's ``marker_residuals_px``); None where it has none."""
    import numpy as np

    out: dict[str, float | None] = {}
    for pid, c in records.items():
        res = [r["residual_px"] for key in ("pins", "edge_observations") for r in solution.get(key, [])
               if r.get("photo") == pid]
        res += list((c.get("marker_residuals_px") or {}).values())
        flat = np.concatenate([np.ravel(np.asarray(r, float)) for r in res]) if res else np.zeros(0)
        out[pid] = float(np.sqrt(np.mean(flat**2))) if flat.size else None
    return out


def _header(symbol: str, mode: bool, rms: str = "RMS px") -> list[str]:
    return ["photo"] + (["mode"] if mode else []) + ["focal px", "principal point px", "yaw / pitch / roll °",
                                                      f"position x / y / z {symbol}", "lens", rms]


def calibration(project: Project, rep: Report) -> None:
    cal = project.data["calibration"]
    unit = length_unit(project.data)
    cams = cal["cameras"]
    body = ("<p>The cameras of the calibration stage: vanishing points, markers and placement (paper §2; "
            "`vebuild calibrate`, `vebuild register`), before any re-calibration with the model. Values ± 1σ. "
            f"{LENS_NOTE}</p>"
            + (f"<p class='warn'>{esc(unit.note)}.</p>" if unit.relative else "")
            + table(_header(unit.symbol, True), camera_rows(cams, True), {2, 3, 4, 5, 7}, wide=True))
    overwritten = sorted(pid for pid, c in cams.items() if c.get("recalibrated"))
    if overwritten:
        body += (f"<p class='warn'>The calibration records of {', '.join(overwritten)} were replaced by an "
                 "earlier re-calibrating solve: they are not the vanishing-point calibration. Run `vebuild "
                 "calibrate` and `vebuild solve --recalibrate` again to keep the stages apart.</p>")
    body += "<h3>Calibration mode of each photo</h3><ul class='lim'>" + "".join(
        f"<li>{esc(pid)}: {esc(c.get('mode', '?'))}: {esc(c.get('mode_reason', 'no reason recorded'))}</li>"
        for pid, c in cams.items()) + "</ul>"
    body += _placement(cams) + _lines(project, cams)
    body += _groups(cal.get("camera_groups") or [])
    checks = {pid: c["exif_focal_check"] for pid, c in cams.items() if isinstance(c.get("exif_focal_check"), Mapping)}
    if checks:
        body += ("<h3>EXIF focal lengths against the vanishing points</h3><p>Each as EXIF relative to the "
                 "vanishing points' own estimate (positive: EXIF says longer); beyond the limit EXIF is not "
                 "combined.</p><ul class='lim'>" + "".join(_exif_item(pid, c) for pid, c in checks.items()) + "</ul>")
    failed = [c for c in cal.get("failed_checks") or [] if isinstance(c, Mapping)]
    if failed:
        body += ("<p class='bad'>FAILED: the calibration fails its check distances (each beyond its limit in σ): "
                 + "; ".join(esc(failed_check_words(dict(c))) for c in failed) + ".</p>")
    left_out = cal.get("left_out") or {}
    if left_out:
        why = "; ".join(f"{esc(pid)} ({esc(u.get('reason', '') if isinstance(u, Mapping) else u)})"
                        for pid, u in left_out.items())
        body += f"<p class='warn'>Left out of the calibration (no camera; nothing in the model rests on it): {why}.</p>"
    unplaced = cal.get("unplaced") or {}
    if unplaced:
        body += "<p class='warn'>Calibrated but not placed: " + "; ".join(
            f"{esc(pid)} ({esc(u.get('reason', '') if isinstance(u, Mapping) else u)})"
            for pid, u in unplaced.items()) + ".</p>"
    rep.add("Calibration (vanishing points)", body)


def _placement(cams: Mapping[str, Mapping[str, Any]]) -> str:
    """Each photo placed alone (``placement``): its origin, where its scale came from and its camera's
    height above the floor ± 1σ, in metres or said to be relative."""
    rows = []
    for pid, c in cams.items():
        pl = c.get("placement") or {}
        if pl.get("how") != "alone":
            continue
        if pl.get("lengths") == "relative":
            height, scale = "1 (the unit of length)", "none: lengths are relative, the camera's height is 1"
        else:
            h = pl.get("camera_height_m") or {}
            height = f"{h['value']:.3f} ± {h.get('sigma') or 0:.3f} m" if h.get("value") is not None else "—"
            scale = str(pl.get("scale") or "—")
        rows.append([pid, str(pl.get("origin") or "—"), scale, height])
    if not rows:
        return ""
    return ("<h3>Photos placed alone: origin, scale and camera height</h3><p>A photo placed alone stands on the "
            "floor (z = 0) by itself: its origin, where its scale comes from, and its camera's height above the "
            "floor ± 1σ, which carries the scale's uncertainty into every length measured on it.</p>"
            + table(["photo", "origin", "scale from", "camera height"], rows, {3}))


def _lines(project: Project, cams: Mapping[str, Mapping[str, Any]]) -> str:
    """The vanishing lines of each photo, axis by axis: how many were marked, used and left out (each
    left-out one by its number in the photo's marks, and why), and the RMS residual of those used."""
    photos = {p["id"]: p for p in project.data["photos"]}
    rows = []
    for pid, c in cams.items():
        marks = (photos.get(pid) or {}).get("vanishing_segments") or {}
        for axis, vp in sorted((c.get("vanishing_points") or {}).items()):
            if not isinstance(vp, Mapping):
                continue
            rejected = [r for r in vp.get("rejected") or [] if isinstance(r, Mapping)]
            n = len(marks.get(axis) or vp.get("residuals_px") or [])
            why = "; ".join(f"{int(r['segment'])}: {r.get('reason', '')} (misfit {r.get('misfit_sigmas', 0):.1f}σ)"
                            for r in rejected)
            rows.append([pid, axis, n, n - len(rejected), why or "none", fmt(vp.get("rms_px"), 2)])
    if not rows:
        return ""
    return ("<h3>Vanishing lines used and left out</h3><p>Each photo's lines by world axis: those used fix its "
            "vanishing point; a line that does not meet the others' point (clutter, a slope, another building) is "
            "left out by a robust fit and named by its index among the photo's lines of that axis (from 0, as "
            "`vebuild calibrate` names it; grey and crossed on the photo as marked). RMS: the residual of the "
            "lines used.</p>"
            + table(["photo", "axis", "marked", "used", "left out (why)", "RMS px"], rows, {2, 3, 5}))


def _groups(groups: list[Mapping[str, Any]]) -> str:
    """The calibration's camera groups (``calibration.camera_groups``): one row per group, its
    shared f, principal point and k1 ± 1σ, then the photos released from it and why."""
    if not groups:
        return ""
    rows, notes = [], []
    for g in groups:
        if g.get("shared"):
            f, c, d = g["focal_px"], g["principal_point"], g["distortion"]
            rows.append([g["id"], g["source"], ", ".join(g.get("calibrated", g["photos"])),
                         f"{f['value']:.1f} ± {f['sigma'] or 0:.1f}", _pm(c["value"], c["sigma"], 1),
                         f"{d['k1']:+.4f} ± {d['sigma'] or 0:.4f}"])
        else:
            rows.append([g["id"], g["source"], ", ".join(g["photos"]), "not shared", "", ""])
        notes += [f"{pid} left camera group {g['id']}: {why}" for pid, why in (g.get("released") or {}).items()]
        if g.get("note"):
            notes.append(f"camera group {g['id']}: {g['note']}")
    return ("<h3>Camera groups</h3><p>Photos of one camera share its focal length, principal point and lens "
            "distortion, solved together from all their vanishing lines. Values ± 1σ.</p>"
            + table(["camera group", "from", "photos", "focal px", "principal point px", "lens k1"], rows, {3, 4, 5})
            + ("<ul class='lim'>" + "".join(f"<li class='warn'>{esc(n)}</li>" for n in notes) + "</ul>"
               if notes else ""))


def _k1(d: Mapping[str, Any]) -> str:
    """A camera group's k1 ± 1σ, or held where it was not solved for (its σ 0 in the calibration's
    record, none and ``refined`` false in the solve's)."""
    if not d.get("sigma") or d.get("refined") is False:
        return f"{d['k1']:+.4f} (held)"
    return f"{d['k1']:+.4f} ± {d['sigma']:.4f}"


def _solved_groups(solved: list[Mapping[str, Any]], calibrated: list[Mapping[str, Any]]) -> str:
    """The re-calibrated camera groups (``model_solution.camera_groups``): each group's one focal
    length, principal point and k1 ± 1σ from the solve, beside the calibration's (its record in
    ``calibration.camera_groups``; "—" where it has none shared)."""
    if not solved:
        return ""
    cal = {g.get("id"): g for g in calibrated if g.get("shared")}
    rows = []
    for g in solved:
        c = cal.get(g["id"])
        f, pp = g["focal_px"], g["principal_point"]
        rows.append([g["id"], ", ".join(g["photos"]),
                     f"{c['focal_px']['value']:.1f} ± {c['focal_px']['sigma'] or 0:.1f}" if c else "—",
                     f"{f['value']:.1f} ± {f['sigma'] or 0:.1f}",
                     _pm(c["principal_point"]["value"], c["principal_point"]["sigma"], 1) if c else "—",
                     _pm(pp["value"], pp["sigma"], 1),
                     _k1(c["distortion"]) if c else "—", _k1(g["distortion"])])
    return ("<h3>Camera groups re-calibrated</h3><p>The photos of one camera share one focal length, principal "
            "point and lens k1 in the re-calibrating solve too: each group's values ± 1σ (the solve's covariance "
            "over the group's shared intrinsics), beside the calibration's (the camera groups table of the "
            "calibration above). Its photos' rows in the table above repeat them; held: k1 was not solved for.</p>"
            + table(["camera group", "photos", "focal px (calibration)", "focal px (final)",
                     "principal point px (calibration)", "principal point px (final)", "lens k1 (calibration)",
                     "lens k1 (final)"], rows, {2, 3, 4, 5, 6, 7}, wide=True))


def _exif_item(pid: str, check: Mapping[str, Any]) -> str:
    """One photo's ``exif_focal_check`` as a list item, marked where it is beyond the limit."""
    words = esc(f"{pid}: {exif_check_words(dict(check))}")
    if "combined" not in check:  # a record of an earlier vebuild
        return f"<li>{words}</li>"
    cls = " class='warn'" if check["sigmas"] > check["limit_sigmas"] else ""
    return f"<li{cls}>{words}; {'combined' if check['combined'] else 'not combined'}</li>"


def final_cameras(project: Project, rep: Report) -> None:
    """The cameras every later part of the report draws with (:func:`vebuild.project.decode.cameras`)."""
    sol = project.data.get("model_solution") or {}
    recal = sol.get("cameras") or {}
    unit = length_unit(project.data)
    title = "Final cameras (re-calibrated with the model)"
    if recal:
        kept = [pid for pid in project.data["calibration"]["cameras"] if pid not in recal]
        body = ("<p>The cameras solved jointly with the model and the markers (paper §3.2; `vebuild solve "
                "--recalibrate`), their calibration above taken as priors. Values ± 1σ. These cameras draw the "
                "textures, the renders and the plan view of this report."
                + (f" Not re-calibrated, so their final cameras are the calibration's: {esc(', '.join(kept))}."
                   if kept else "") + "</p>"
                + table(_header(unit.symbol, False, "RMS px (solve)"), camera_rows(recal, False, solve_rms(sol, recal)),
                        {1, 2, 3, 4, 6}, wide=True)
                + "<p>RMS px (solve): the residuals of the photo's pins, edges and marker sightings in the "
                  "re-calibrating solve; in the table above, those of its vanishing segments and markers in the "
                  "calibration.</p>"
                + _solved_groups(sol.get("camera_groups") or [],
                                 project.data["calibration"].get("camera_groups") or []))
    elif sol.get("recalibrated"):
        body = ("<p class='warn'>The solve re-calibrated the cameras, but the project keeps no re-calibrated "
                "cameras apart from the calibration (a project solved by an earlier vebuild); the final cameras "
                "are the records of the calibration table above.</p>")
    else:
        body = ("<p>The solve did not re-calibrate the cameras (`vebuild solve` without --recalibrate): the final "
                "cameras are the calibration's, in the table above.</p>")
    rep.add(title, body)
