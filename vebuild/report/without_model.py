"""The report of a project with calibrated photos and no model (one archived photo, or several
photos each placed alone): the sections that need a model are left out, each with one line saying
why, and the reference distances are the calibration's own; what a report needs before it can be
written at all (:func:`not_calibrated`)."""

from __future__ import annotations

from collections.abc import Mapping

from vebuild.project import Project
from vebuild.project.units import RELATIVE_UNITS, length_unit

from .page import Cell, Report, esc, fmt, table

#: Why every section left out is left out (the start of its one line).
NO_MODEL = "Left out: the project has no model (its photos are calibrated, nothing has been modelled)"


def has_model(project: Project) -> bool:
    """Whether the project has a model (``model.nodes``): without one, the report is of the
    calibrated photos and the measurements on them."""
    return bool((project.data.get("model") or {}).get("nodes"))


def not_calibrated(project: Project) -> str:
    """What a project with no calibrated camera lacks before it can be reported, in words, with the
    action that gives it."""
    data = project.data
    name = project.path.name
    photos = data.get("photos") or []
    head = f"{project.path}: no report yet: "
    if not photos:
        return (head + "the project has no photos; add the photo with `vebuild new` or in the modelling screen "
                f"(`vebuild edit {name}`), mark it and run `vebuild calibrate {name}`")
    cal = data.get("calibration") or {}
    why = [f"photo {pid}: {u.get('reason', '') if isinstance(u, Mapping) else u}"
           for key in ("left_out", "unplaced") for pid, u in (cal.get(key) or {}).items()]
    if why:
        return (head + "no photo of the project is calibrated and placed, so nothing in it can be measured or "
                "shown. " + "; ".join(why))
    marked = [p["id"] for p in photos if p.get("vanishing_segments")]
    if not marked:
        return (head + "the photos are not calibrated yet, and no photo has vanishing lines to calibrate it from. "
                f"Mark the lines of each photo (`vebuild detect {name}`, or by hand in `vebuild edit {name}`), "
                f"then run `vebuild calibrate {name}`; a report needs calibrated photos (a model is optional)")
    return (head + f"the photos are not calibrated yet; run `vebuild calibrate {name}` (photos with vanishing "
            f"lines: {', '.join(marked)}); a report needs calibrated photos (a model is optional)")


def _left_out(rep: Report, title: str, why: str) -> None:
    rep.add(title, f"<p class='small'>{esc(NO_MODEL)}: {esc(why)}.</p>")


def final_cameras(project: Project, rep: Report) -> None:
    _left_out(rep, "Final cameras", "no solve re-calibrated the cameras, so the final cameras are the "
              "calibration's, in the table above")


def model(project: Project, rep: Report) -> None:
    _left_out(rep, "Model", "there are no modelled objects, their dimensions or a solve to report; the "
              "measurements on the photos below need none")


def views(project: Project, rep: Report) -> None:
    _left_out(rep, "Evidence views", "a view is a render of the model")


def validation(project: Project, rep: Report) -> None:
    _left_out(rep, "How well the model explains each photo", "this compares each photo with the model rendered "
              "from its camera")


def scans(project: Project, rep: Report) -> None:
    if project.data.get("scans"):
        _left_out(rep, "Laser scans", "a scan is compared with the model's faces")


def hypotheses(project: Project, rep: Report) -> None:
    if project.data.get("hypotheses"):
        _left_out(rep, "Hypotheses", "a hypothesis places the model's objects otherwise")


def checks(project: Project, rep: Report) -> None:
    """The reference and check distances as the calibration measured them between its markers (there
    is no final model to measure them on), each with a verdict where the lengths are in metres."""
    from vebuild.constants import Z95

    refs = project.data.get("reference_distances") or []
    if not refs:
        return
    unit = length_unit(project.data)
    stage = {frozenset((d["a"], d["b"])): d for d in (project.data.get("calibration") or {}).get(
        "reference_distances", [])}
    rows = []
    for d in refs:
        m = stage.get(frozenset((d["a"], d["b"])), {})
        measured, sigma = m.get("measured"), m.get("measured_sigma")
        if measured is None or sigma is None:
            rows.append([f"{d['a']} – {d['b']}", d["role"], fmt(d["distance"]), "not measured (an end not placed)",
                         "—", "—", "—"])
            continue
        if unit.relative:
            rows.append([f"{d['a']} – {d['b']}", d["role"], fmt(d["distance"]), fmt(measured), fmt(sigma), "—",
                         "not compared (relative units)"])
            continue
        s = (float(sigma) ** 2 + float(d.get("sigma") or 0.0) ** 2) ** 0.5
        diff = float(measured) - float(d["distance"])
        verdict = Cell("within", "good") if abs(diff) <= Z95 * s else Cell("OUTSIDE", "bad")
        rows.append([f"{d['a']} – {d['b']}", d["role"], fmt(d["distance"]), fmt(measured), fmt(sigma),
                     f"{1000 * diff:+.1f} ± {1000 * s:.1f}", verdict])
    lengths = f"in {RELATIVE_UNITS}" if unit.relative else "in metres"
    rep.add("Reference and check distances", "<p>Each known distance between two markers as the calibration "
            f"measured it (there is no model to measure it on), {lengths}. The difference is measured − known, "
            "± 1σ of both; the verdict says whether the known distance lies within the 95 % interval. A 'scale' "
            "distance fixed the scale, so its agreement proves little; a 'check' distance is the independent "
            "check.</p>"
            + table(["between", "role", "known m", f"measured {unit.symbol}", f"1σ {unit.symbol}",
                     "difference mm", "verdict"], rows, {2, 3, 4, 5}))
