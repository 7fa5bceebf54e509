"""The report's first page, for the reader in court: the case, the question asked, the answers
(each measurement the project records, with its interval in plain words), how the model held up
against the independent check distances, and the scaled plan.

Everything here is made from what the later sections show in full (the analyses run once for the
whole report, kept in ``Report.recorded``); this page only says it first, in sentences.
"""

from __future__ import annotations

from typing import Any

from vebuild.project import Project
from vebuild.project.units import length_unit

from .page import Report, esc
from .without_model import NO_MODEL, has_model

#: The first page's plan is at most this high on paper (millimetres), so that it fits under the answers.
PLAN_HEIGHT_MM = 90.0


def _interval(unit: Any, fig: dict[str, Any]) -> str:
    """"2.756 m, between 2.740 and 2.772 m (95 %; 1σ 8 mm)" from a measurement's figures."""
    value = fig.get(unit.key("value"))
    sigma, ci = fig.get(unit.key("sigma")), fig.get(unit.key("ci95"))
    sym = unit.symbol
    if value is None:
        return "not measurable"
    if sigma is None or ci is None:
        return f"{value:.3f} {sym} (its uncertainty could not be computed: do not rely on it)"
    spread = f"1σ {1000 * sigma:.1f} mm" if sym == "m" else f"1σ {sigma:.4f} {sym}"
    return f"{value:.3f} {sym}, between {ci[0]:.3f} and {ci[1]:.3f} {sym} (95 %; {spread})"


def run_analyses(project: Project, rep: Report) -> None:
    """Run every recorded analysis once for the report (its image in the report's folder), kept in
    ``rep.recorded`` for this page, "Measurements on the photos" and "Analyses"."""
    from vebuild.analysis.recorded import run_recorded

    (rep.folder / "images").mkdir(exist_ok=True)
    for i, rec in enumerate(project.data.get("analyses") or []):
        if i not in rep.recorded:
            rep.recorded[i] = run_recorded(project, i, rec, str(rep.folder / f"images/analysis-{i + 1}.png"))


def answers(project: Project, rep: Report) -> list[str]:
    """One sentence per result the recorded analyses give, in the order the project records them."""
    unit = length_unit(project.data)
    out: list[str] = []
    people: set[str] = set()  # each person's combined height said once, however many frames record it
    for i, rec in enumerate(project.data.get("analyses") or []):
        if i not in rep.recorded:
            continue
        _request, result = rep.recorded[i]
        name = str(rec["name"]) + (f" ({rec['description']})" if rec.get("description") else "")
        rows = list(result.figures.get("measurements") or [])
        sight = result.figures.get("sightline")
        person, frame = result.figures.get("combined"), result.figures.get("frame")
        if person is not None:
            if person["person"] not in people:
                people.add(person["person"])
                n = person["frames"]
                out.append(f"the height of {person['person']}, from {n} frame{'s' if n > 1 else ''}: "
                           f"{_interval(unit, person)}.")
        elif frame is not None:
            out.append(f"{rec['name']}: the height of the person in photo {frame['photo']}: "
                       f"{_interval(unit, frame)}.")
        elif sight is not None:
            out.append(f"{name}: {_seen(sight)}.")
        elif rows:
            for fig in rows:
                what = " ".join(str(x) for x in (fig.get("quantity"), fig.get("what")) if x)
                out.append(f"{name}: {what}: {_interval(unit, fig)}." if what else f"{name}: {_interval(unit, fig)}.")
        else:
            first = next((line.strip() for line in result.table.splitlines() if line.strip()), "")
            out.append(f"{name}" + (f": {first}" if first else "") + "; the figures are under Analyses.")
    return out


def _seen(sight: dict[str, Any]) -> str:
    """A sight line's answer in words: seen or not, and how much of an object, with its interval."""
    share, ci = sight.get("visible_share"), sight.get("visible_share_ci95")
    if share is None:
        return "the point can be seen from the eye" if sight.get("visible") else "the point cannot be seen from the eye"
    text = f"{100 * share:.0f} % of the object's surface facing the eye can be seen"
    if ci:
        text += f" (95 %: {100 * ci[0]:.0f} to {100 * ci[1]:.0f} %)"
    return text


def validation_sentence(rep: Report) -> str:
    """How the final model held up against the tapes it was not given (the "check" distances)."""
    checks = [c for c in rep.checks if c.role == "check"]
    if not checks:
        return ("No independent check distance was recorded: nothing here tests the model against a tape it "
                "was not given (see Limitations).")
    inside = [c for c in checks if c.within_ci95]
    n = len(checks)
    text = (f"Checked against {n} distance{'s' if n > 1 else ''} measured at the scene and not used to build the "
            f"model: {len(inside)} of {n} agree{'s' if n == 1 else ''} within {'its' if n == 1 else 'their'} 95 % "
            f"interval{'s' if n > 1 else ''}.")
    for c in checks:
        if not c.within_ci95:
            text += (f" {c.a} – {c.b} does not: {c.measured.value:.3f} m measured against {c.known:.3f} m known "
                     f"({1000 * c.difference:+.1f} mm); the model is less accurate there than its intervals say.")
    return text


def findings(project: Project, rep: Report) -> str:
    """The first page's HTML (the case table, the question, the answers, the check, the plan)."""
    from vebuild.actions.case import case_rows

    data = project.data
    case = data.get("case") or {}
    rows = [(label, text) for label, text in case_rows(data) if label not in ("declaration", "the question")]
    parts = [f"<h1>vebuild report: {esc(data.get('name', project.path.name))}</h1>"]
    if rows:
        parts.append("<table class='case'>" + "".join(f"<tr><td>{esc(a)}</td><td>{esc(b)}</td></tr>" for a, b in rows)
                     + "</table>")
    else:
        parts.append("<p class='warn'>The project records no case details (`vebuild case PROJECT --number … "
                     "--examiner …`).</p>")
    parts.append("<h2>The question</h2>")
    parts.append(f"<p class='question'>{esc(case['question'])}</p>" if case.get("question") else
                 "<p class='warn'>The project records no question (`vebuild case PROJECT --question …`).</p>")
    parts.append("<h2>The answers</h2>")
    said = answers(project, rep)
    if said:
        parts.append("<ol class='answers'>" + "".join(f"<li>{esc(s)}</li>" for s in said) + "</ol>")
    else:
        parts.append("<p>The project records no measurement. Measure with T in the modelling screen or "
                     "`vebuild analyse`; each measurement is then stated here with its interval.</p>")
    parts.append("<p>“95 %” means: were the work repeated with new photos and new clicks of the same quality, "
                 "about 95 in 100 such intervals would hold the true value. The glossary at the end explains the "
                 "other terms.</p>")
    if data.get("model_solution") or data.get("reference_distances"):
        parts.append(f"<p>{esc(validation_sentence(rep))}</p>")
    if data.get("model_solution"):
        parts.append(_plan(project, rep))
    elif not has_model(project):
        parts.append(f"<h2>Plan</h2><p class='small'>{esc(NO_MODEL)}: a plan is drawn from the model's edges.</p>")
    return "<div class='findings'>" + "".join(parts) + "</div>"


def _plan(project: Project, rep: Report) -> str:
    from vebuild.project.atomic import write_text

    from .plan import plan_svg

    svg, info = plan_svg(project, max_height_mm=PLAN_HEIGHT_MM)
    path = rep.folder / "images" / "plan.svg"
    write_text(path, svg)
    rep.images.append(path)
    scale = (f"printed at 1 : {info['scale']} (a millimetre on the page is {info['scale']} mm in the scene)"
             if info["scale"] else "fitted to the page (no scale in metres)")
    return ("<h2>Plan</h2><figure><img class='plan' src='images/plan.svg'><figcaption>The scene from above, "
            + esc(scale) + f": the model's edges (grey), the cameras ({info['cameras']}, blue) with their fields of "
            f"view, the markers ({info['markers']}, orange), the evidence markers (red), the axes +x (red) and +y "
            "(green) from the origin.</figcaption></figure>")
