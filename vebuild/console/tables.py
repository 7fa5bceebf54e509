"""Plain-text tables of results, for the terminal."""

from __future__ import annotations

from typing import Any

from vebuild.project.units import METRES, LengthUnit, record_unit


def _pm(vs: dict[str, Any], fmt: str, scale: float = 1.0) -> str:
    """'value ± sigma' of a {"value", "sigma"} object; '?' where σ is undetermined."""
    v, s = vs["value"], vs["sigma"]
    if isinstance(v, list):
        vals = ", ".join(format(x * scale, fmt) for x in v)
        sig = ", ".join("?" if x is None else format(x * scale, fmt) for x in s)
        return f"({vals}) ± ({sig})"
    return f"{format(v * scale, fmt)} ± {'?' if s is None else format(s * scale, fmt)}"


def _figure(vs: dict[str, Any], fmt: str, unit: str = "") -> str:
    """A solved value ± 1σ (with ``unit``), with where it comes from where that is not the photos
    alone (FORMAT.md ``determined_by``): entered (held exactly it reads 'entered', never '± 0';
    entered with a 1σ it shows that 1σ beside the solved one), held by a relation (which; never
    '± 0.000' nor '-0.000'), only its own entered value (no photo shows it), or measured in the
    photos from what only entered values place; another held value reads 'held'."""
    u = f" {unit}" if unit else ""
    source = vs.get("determined_by")
    if source == "relation":
        return f"{format(vs['value'] + 0.0, fmt)}{u} (held by relation {vs.get('held_by', '')})".replace(" )", ")")
    if source == "entered value":
        return _figure({k: v for k, v in vs.items() if k != "determined_by"}, fmt, unit) + \
            " (entered value only: no photo shows it)"
    if source == "observations and entered values":
        return f"{_pm(vs, fmt)}{u} (from the photos, measured from entered values)"
    if vs.get("entered"):
        s = vs.get("entered_sigma") or 0.0
        if s == 0:
            return f"{format(vs['value'], fmt)}{u} (entered)"
        shown = f"{1000 * s:.1f} mm" if unit == "m" else f"{s:g}"
        return f"{_pm(vs, fmt)}{u} (entered ± {shown})"
    if vs["sigma"] == 0 and not isinstance(vs["value"], list):
        # Not a solve's unknown: held by its joint or a relation, never "± 0" (nor "-0.000").
        return f"{format(vs['value'] + 0.0, fmt)}{u} (held)"
    return f"{_pm(vs, fmt)}{u}"


def _sigma(s: float | None) -> str:
    """A 1σ, or "?" where the data do not determine it (recorded as null)."""
    return "?" if s is None else f"{s:.3f}"


def failed_check_words(c: dict[str, Any]) -> str:
    """A calibration record's ``failed_checks`` entry in words: measured against the tape, how
    many σ, and the limit it is beyond."""
    return (f"check distance {c['a']}–{c['b']}: measured {c['measured']:.3f} ± {c['measured_sigma']:.3f} m against "
            f"{c['distance']:.3f} m known ({c['sigmas']:+.1f}σ, beyond the ±{c['limit_sigmas']:g}σ limit)")


def exif_check_words(check: dict[str, Any]) -> str:
    """A calibration record's ``exif_focal_check`` in words, with the one sign convention of the
    calibration (vebuild.calibration.priors.ExifCheck): EXIF relative to the vanishing points'
    estimate, positive where EXIF says longer. A record written by an earlier vebuild, which held
    the estimate relative to EXIF, is turned round to it."""
    exif = check["exif_focal_px"]
    if "lines_focal_px" not in check:  # (f − f_EXIF) / f_EXIF, the estimate after placement
        old, sigma_rel = check["difference_rel"], check["sigma_rel"]
        return (f"EXIF's focal length {exif:.1f} px is {100 * (1.0 / (1.0 + old) - 1.0):+.1f} % from the estimate "
                f"({abs(old) / sigma_rel:.1f}σ of their difference)")
    lines, z, limit = check["lines_focal_px"], check["sigmas"], check["limit_sigmas"]
    return (f"EXIF's focal length {exif:.1f} px is {100 * check['difference_rel']:+.1f} % from the vanishing points' "
            f"{lines['value']:.1f} ± {lines['sigma']:.1f} px ({z:.1f}σ of their difference"
            + (f", beyond the {limit:g}σ limit)" if z > limit else ")"))


def calibration_table(result: dict[str, Any]) -> str:
    """Per photo: mode, f, principal point, yaw/pitch/roll, position, their 1σ, and residuals."""
    origin = result.get("origin") or f"marker '{result['origin_marker']}'"
    unit = record_unit(result)
    units = "; lengths are RELATIVE (no scale given: the camera's height is 1)" if unit.relative else ""
    lines = [f"calibration ({result['software']}); origin {origin}{units}; values ± 1σ", ""]
    for pid, cam in result["cameras"].items():
        lines += [
            f"photo {pid}: mode {cam['mode']} — {cam['mode_reason']}",
            f"  focal length     {_pm(cam['focal_px'], '.1f')} px   (from {cam['focal_source']})",
            f"  principal point  {_pm(cam['principal_point'], '.1f')} px",
            f"  yaw/pitch/roll   {_pm(cam['ypr_deg'], '.3f')} °",
            f"  position         {_pm(cam['position'], '.3f')} "
            + ("(relative units)" if record_unit(cam.get("placement") or {}).relative or unit.relative else "m"),
        ]
        if cam.get("placement", {}).get("how") == "alone":
            lines.append(f"  placed alone     scale from {cam['placement']['scale']}")
        if fixed := cam.get("fixed_camera"):
            others = ", ".join(p for p in fixed["stills"] if p != pid)
            lines.append(f"  fixed camera     one camera with {others} (stills of one video: calibrated as one photo, "
                         "the residuals are of all their marks)")
        vp = "  ".join(f"{a}: {v['rms_px']:.2f} px ({len(v['residuals_px'])} segments"
                       + (f", {len(v['rejected'])} rejected" if v.get("rejected") else "") + ")"
                       for a, v in cam["vanishing_points"].items())
        if vp:
            lines.append(f"  residuals        segments {vp}")
        if cam["marker_residuals_px"]:
            worst = max(cam["marker_residuals_px"].items(), key=lambda kv: kv[1][0] ** 2 + kv[1][1] ** 2)
            lines.append(f"                   markers: {len(cam['marker_residuals_px'])}, largest "
                         f"{(worst[1][0] ** 2 + worst[1][1] ** 2) ** 0.5:.2f} px ({worst[0]}); all, RMS "
                         f"{cam['rms_px']:.2f} px")
        if "exif_focal_check" in cam:
            c = cam["exif_focal_check"]
            used = "" if "combined" not in c else "; combined" if c["combined"] else "; not combined"
            lines.append(f"  EXIF check       {exif_check_words(c)}{used}")
        lines.append("")
    lines += camera_group_lines(result.get("camera_groups") or [])
    lines.append("markers (relative units: the camera height is 1):" if unit.relative else "markers (m):")
    for n, m in result["markers"].items():
        sig = ", ".join("?" if s is None else f"{s:.3f}" for s in m["sigma"])
        lines.append(f"  {n:<12} ({', '.join(f'{x:.3f}' for x in m['position'])}) ± ({sig})")
    if result["reference_distances"] and unit.relative:
        lines += ["", "reference distances (known in m; measured in relative units: the camera height is 1, so not "
                  "compared):"]
        for d in result["reference_distances"]:
            lines.append(f"  {d['a']}–{d['b']:<10} {d['role']:<6} known {d['distance']:.3f} ± {d['sigma']:.3f} m   "
                         f"measured {d['measured']:.3f} ± {_sigma(d['measured_sigma'])} (relative units)")
    elif result["reference_distances"]:
        lines += ["", "reference distances (m):"]
        for d in result["reference_distances"]:
            lines.append(f"  {d['a']}–{d['b']:<10} {d['role']:<6} known {d['distance']:.3f} ± {d['sigma']:.3f}   "
                         f"measured {d['measured']:.3f} ± {_sigma(d['measured_sigma'])}   "
                         f"difference {1000 * (d['measured'] - d['distance']):+.1f} mm")
    if result.get("checked_after_solve") and not result["reference_distances"]:
        lines += ["", "reference distances (m):"]
    for d in result.get("checked_after_solve") or []:
        lines.append(f"  {d['a']}–{d['b']}  check  known {d['distance']:.3f} ± {d['sigma']:.3f}   ends on a model "
                     "vertex: checked on the solved model by `vebuild solve`")
    if result.get("failed_checks"):
        lines += ["", "FAILED checks (the calibration fails them):"] + [f"  - {failed_check_words(c)}"
                                                                     for c in result["failed_checks"]]
    if result["warnings"]:
        lines += ["", "warnings:"] + [f"  - {w}" for w in result["warnings"]]
    return "\n".join(lines)


def model_table(result: dict[str, Any]) -> str:
    """Per node: its joint's degrees of freedom and its dimensions, ± 1σ, then the residuals."""
    unit = record_unit(result)
    lines = [f"model ({result['software']}{', re-calibrated' if result['recalibrated'] else ''}); values ± 1σ, "
             "from the photos unless marked"
             + ("; lengths are RELATIVE (no scale given: the camera's height is 1)" if unit.relative else ""), ""]
    m = "(relative units)" if unit.relative else "m"
    for name, node in result["nodes"].items():
        dofs = ", ".join(f"{k} {_figure(v, '.3f')}" for k, v in node["dofs"].items())
        lines.append(f"{name}  [{node['joint']}{': ' + dofs if dofs else ''}]")
        if node["params"]:
            dims = ", ".join(f"{k} {_figure(v, '.4f', m)}" for k, v in node["params"].items())
            lines.append(f"    {dims}")
    res = [(p["photo"], p["node"], p["handle"], (p["residual_px"][0] ** 2 + p["residual_px"][1] ** 2) ** 0.5)
           for p in result["pins"]]
    lines += ["", f"residuals: {len(result['pins'])} pins, {len(result['edge_observations'])} edge observations, "
              f"RMS {result['rms_px']:.2f} px"]
    if res:
        worst = max(res, key=lambda r: r[3])
        lines.append(f"    largest pin residual {worst[3]:.2f} px ({worst[1]}:{worst[2]} in photo '{worst[0]}')")
    if result["outliers"]:
        lines += ["", "outliers (more than 4σ from the solved model; check these marks):"]
        lines += [f"  - {o}" for o in result["outliers"]]
    lines += recalibrated_group_lines(result.get("camera_groups") or [])
    lines += relation_lines(result.get("relations") or [])
    lines += check_distance_lines(result.get("check_distances") or [], unit)
    if result.get("warnings"):
        lines += ["", "warnings:"] + [f"  - {w}" for w in result["warnings"]]
    return "\n".join(lines)


def recalibrated_group_lines(groups: list[dict[str, Any]]) -> list[str]:
    """Per camera group re-calibrated as one camera (``model_solution.camera_groups``): its photos,
    its one f, principal point and k1, ± 1σ."""
    if not groups:
        return []
    lines = ["", "camera groups, re-calibrated as one camera each (values ± 1σ):"]
    for g in groups:
        d = g["distortion"]
        k1 = f"{d['k1']:+.4f} ± {d['sigma']:.4f}" if d.get("sigma") is not None else f"{d['k1']:+.4f} (held)"
        lines += [f"  {g['id']}: photos {', '.join(g['photos'])}",
                  f"    focal length {_pm(g['focal_px'], '.1f')} px, principal point "
                  f"{_pm(g['principal_point'], '.1f')} px, lens k1 {k1}"]
    return lines


def relation_lines(relations: list[dict[str, Any]]) -> list[str]:
    """The model's relations (``model_solution.relations``), each with how closely it holds."""
    if not relations:
        return []
    lines = ["", "relations (each kept by the solve; how far it misses):"]
    for r in relations:
        what = r.get("name") or (f"equal {', '.join(r['params'])}" if r["type"] == "equal"
                                 else f"{r['type']} {r['a']} – {r['b']}")
        miss = f"{r['residual_deg']:.2g}°" if "residual_deg" in r else f"{1000 * r['residual_m']:.2g} mm"
        lines.append(f"  - {what}: {miss}")
    return lines


def check_distance_lines(checks: list[dict[str, Any]], unit: LengthUnit = METRES) -> list[str]:
    """The check distances measured on the final model (``model_solution.check_distances``): each
    with measured, known, the difference with its 1σ and 95 % interval, and within/outside."""
    if not checks:
        return []
    if unit.relative:
        out = ["", "check distances, not compared (lengths are relative units; the tape's are not):"]
        return out + [f"  {c['a']}–{c['b']}  known {c['known_m']:.4f} (tape)   found {c['measured_m']:.4f} "
                      f"± {c['measured_sigma_m']:.4f} (relative units)" for c in checks]
    out = ["", "check distances on the final model (m; difference in mm, its 1σ and 95 % interval):"]
    for c in checks:
        lo, hi = (1000 * v for v in c["difference_ci95_m"])
        verdict = "within" if c["within_ci95"] else "OUTSIDE"
        out.append(f"  {c['a']}–{c['b']}  measured {c['measured_m']:.4f} ± {c['measured_sigma_m']:.4f}   known "
                   f"{c['known_m']:.4f} ± {c['known_sigma_m']:.4f}   difference {1000 * c['difference_m']:+.1f} "
                   f"± {1000 * c['difference_sigma_m']:.1f} mm, 95 % {lo:+.1f} to {hi:+.1f} mm: {verdict} "
                   "its 95 % interval")
    return out


def texture_table(record: dict[str, Any], unit: LengthUnit = METRES) -> str:
    """The faces' coverage and the photos' gains of a ``textures`` record; texels per metre, or per
    relative unit (``unit``: the project's, :mod:`vebuild.project.units`)."""
    lines = [f"{'face':<28} {'texels':>11} {'t/' + unit.symbol:>6} {'seen':>6}  photos"]
    for f in record["faces"]:
        w, h = f["rect"][2:]
        lines.append(f"{f['node'] + '.' + f['face']:<28} {f'{w}×{h}':>11} {f['texels_per_metre'][0]:>6.0f} "
                     f"{100 * f['seen_fraction']:>5.1f}%  {', '.join(f['photos']) or '-'}")
    lines.append("")
    lines.append(f"{'photo':<10} {'order':>5} {'gain r, g, b':>22} {'overlap':>8}")
    for p in record["photos"]:
        g = ", ".join(f"{v:.3f}" for v in p["gain"])
        lines.append(f"{p['id']:<10} {p['order']:>5} {g:>22} {p['overlap_texels']:>8}")
    lines.append("")
    lines += [f"atlas page {k}: {p['width']}×{p['height']}  {p['atlas']}  (coverage: {p['coverage']})"
              for k, p in enumerate(record["pages"])]
    lines += [f"warning: {w}" for w in record.get("warnings", [])]
    if unit.relative:
        lines.append(f"texels per relative unit (t/rel.): {unit.note}")
    return "\n".join(lines)


def camera_group_lines(groups: list[dict[str, Any]]) -> list[str]:
    """Per camera group (calibration.camera_groups): its camera, photos, f, c and k1 ± 1σ."""
    if not groups:
        return []
    lines = ["camera groups (photos of one camera share f, c and k1; values ± 1σ):"]
    for g in groups:
        lines.append(f"  {g['id']} ({g['source']}): photos {', '.join(g['photos'])}")
        if not g.get("shared"):
            lines.append("    not shared: fewer than two of its photos could share intrinsics")
            continue
        d = g["distortion"]
        lines += [f"    focal length     {_pm(g['focal_px'], '.1f')} px   (from {g['focal_source']})",
                  f"    principal point  {_pm(g['principal_point'], '.1f')} px",
                  f"    lens k1          {d['k1']:+.4f} ± {d['sigma']:.4f} ({d['source']})"]
        for pid, why in (g.get("released") or {}).items():
            lines.append(f"    released         {pid}: {why}")
        if g.get("note"):
            lines.append(f"    note             {g['note']}")
    return [*lines, ""]
