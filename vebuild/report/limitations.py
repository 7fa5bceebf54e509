"""What the figures of a project rest on that a photo did not show, gathered from the project itself.

:func:`limitations` returns the items (plain data, :class:`Limitation`); the report's section
"Limitations" renders them (:func:`limitations_html`). Each item names its kind, says in plain words
what it is and lists the things it concerns:

- ``unseen``: faces of the model that no photo saw, and how their texture was filled
  (``textures.faces[].seen_fraction``, ``textures.options``), with their share of the model's
  surface area;
- ``entered``: dimensions entered from measurements rather than measured in the photos (a node's
  ``hold`` list, a node with ``"solve": false``, a parameter marked ``"entered"`` in the solution);
- ``not-photographed``: parts of the model that no pin or edge in any photo places, held only by
  their joints and entered values;
- ``outliers``: observations the solve flagged (``model_solution.outliers``);
- ``failed-checks``: check distances whose known value lies outside the final model's 95 %
  interval;
- ``calibration-modes``: each photo's calibration mode and its reason;
- ``calibration-failed-checks``: check distances the calibration failed (``calibration.failed_checks``);
- ``left-out``: photos the calibration left out, their marks determining no camera
  (``calibration.left_out``);
- ``unplaced``: photos calibrated but not placed (``calibration.unplaced``);
- ``relative-units``: no scale, lengths in relative units;
- ``single-view``: what a single photo cannot tell (the flat, level floor; feet and hidden corners;
  verticals; the scale; the lens), where photos are placed alone or measured on by themselves.

- ``stale``: results whose inputs changed since they were computed, each with the command that
  brings it up to date (given by the caller: objects with a ``message``, such as
  ``vebuild.project.provenance.stale(data)``'s).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .page import esc

if TYPE_CHECKING:
    from vebuild.analysis.measure import CheckResult
    from vebuild.project import Project

#: How the texture of texels no photo saw is made, by ``textures.options.fill`` (FORMAT.md).
FILL_WORDS = {"push-pull": "filled smoothly from the seen texels around them (push-pull), an invention",
              "average": "filled with the face's average seen colour, an invention"}


@dataclass(frozen=True)
class Limitation:
    """One limitation: its ``kind`` (see the module), a ``title``, a sentence saying what it means,
    and the ``items`` it concerns (one line each)."""

    kind: str
    title: str
    text: str
    items: tuple[str, ...] = ()


@dataclass(frozen=True)
class Entered:
    """A value entered from a measurement, not measured in the photos: ``sigma`` its 1σ in file
    units (0 where none was given: the solve took it as exact)."""

    node: str
    name: str
    sigma: float
    why: str  # "hold", "not solved" or "entered"


def entered_values(project: Project) -> dict[tuple[str, str], Entered]:
    """Every entered value by (node, parameter or joint name): a name in a node's ``hold`` list (or
    an object ``{"name", "sigma"}`` there), every parameter of a node with ``"solve": false``, and
    every ``model_solution.nodes[n].params[p]`` (or ``dofs``) marked ``"entered": true`` (with its
    ``entered_sigma``)."""
    data = project.data
    out: dict[tuple[str, str], Entered] = {}
    sol_nodes = (data.get("model_solution") or {}).get("nodes") or {}
    for n in (data.get("model") or {}).get("nodes", []):
        name = n["name"]
        for h in n.get("hold") or []:
            if isinstance(h, Mapping):
                out[(name, str(h["name"]))] = Entered(name, str(h["name"]), float(h.get("sigma") or 0.0), "hold")
            else:
                out[(name, str(h))] = Entered(name, str(h), 0.0, "hold")
        if n.get("solve") is False:
            rec = sol_nodes.get(name) or {}
            params = list(rec.get("params") or {}) or list((n.get("primitive") or {}).get("params") or {})
            for p in params:
                out.setdefault((name, p), Entered(name, p, 0.0, "not solved"))
    for node, rec in sol_nodes.items():
        for group in ("params", "dofs"):
            for p, v in (rec.get(group) or {}).items():
                if v.get("entered"):
                    out[(node, p)] = Entered(node, p, float(v.get("entered_sigma") or 0.0), "entered")
    return out


def _unseen(data: Mapping[str, Any]) -> list[Limitation]:
    tex = data.get("textures") or {}
    faces = tex.get("faces") or []
    if not faces:
        return []
    area = {f["id"]: float(f["size_m"][0]) * float(f["size_m"][1]) for f in faces}
    total = sum(area.values()) or 1.0
    unseen = [f for f in faces if float(f.get("seen_fraction", 1.0)) <= 0.0]
    unseen_area = sum(area[f["id"]] * (1.0 - float(f.get("seen_fraction", 1.0))) for f in faces)
    options = tex.get("options") or {}
    fill = FILL_WORDS.get(str(options.get("fill")), f"filled by {options.get('fill')!r}")
    if options.get("mode") == "average":
        fill = "each face one colour, the average of what the photos saw of it; " + fill
    by_node: dict[str, list[str]] = {}
    for f in unseen:
        share = 100 * area[f["id"]] / total
        by_node.setdefault(f["node"], []).append(
            f"{f['face']} ({area[f['id']]:.2f} m², {'< 0.1' if share < 0.05 else f'{share:.1f}'} %)")
    items = tuple(f"{node}: {', '.join(names)}" for node, names in sorted(by_node.items()))
    text = (f"{len(unseen)} of the model's {len(faces)} faces were seen by no photo "
            f"({100 * sum(area[f['id']] for f in unseen) / total:.1f} % of its surface area); counting the "
            f"unseen parts of the other faces, {100 * unseen_area / total:.1f} % of the surface is not "
            f"photographed. Their texture is {fill}. Each face no photo saw, with its share of the surface:")
    return [Limitation("unseen", "Surfaces no photo saw", text, items)]


def _not_photographed(data: Mapping[str, Any], entered: Mapping[tuple[str, str], Entered]) -> list[Limitation]:
    model = data.get("model") or {}
    nodes = model.get("nodes") or []
    seen = {p["node"] for p in model.get("pins", [])} | {e["node"] for e in model.get("edge_observations", [])}
    items = []
    for n in nodes:
        if "primitive" not in n or n["name"] in seen:
            continue
        held = sorted(p for (node, p) in entered if node == n["name"])
        joint = (n.get("joint") or {}).get("type", "none")
        how = f"joint {joint}" + (f"; entered: {', '.join(held)}" if held else "")
        items.append(f"{n['name']} ({how})")
    if not items:
        return []
    return [Limitation("not-photographed", "Parts placed from measurements, not photos",
                       "No pin or edge in any photo places these parts: where they are and how large comes "
                       "from their joints and the values entered for them, not from the photos.", tuple(items))]


#: A calibration mode (FORMAT.md ``calibration.cameras[].mode``) in words.
MODE_WORDS = {"3vp": "three vanishing points", "2vp": "two vanishing points", "1vp": "one vanishing point"}


def limitations(project: Project, checks: Sequence[CheckResult] = (), stale: Sequence[Any] = ()) -> list[Limitation]:
    """The project's limitations, in the order the report lists them (see the module).

    ``checks``: the check distances measured on the final model
    (:func:`vebuild.analysis.measure.check_distances`), for the failed ones. ``stale``: the results
    gone stale, each with a ``message`` saying what changed and the command that brings it up to date.
    """
    from vebuild.project.units import length_unit

    data = project.data
    out: list[Limitation] = []
    if stale:
        out.append(Limitation("stale", "Stale results", "These results were computed from inputs that have "
                              "changed since: what they show is not what the project gives now.",
                              tuple(str(s.message) for s in stale)))
    unit = length_unit(data)
    if unit.relative:
        out.append(Limitation("relative-units", "No scale", f"{unit.note}."))
    out += _unseen(data)
    entered = entered_values(project)
    if entered:
        by_node: dict[str, list[str]] = {}
        for e in entered.values():
            by_node.setdefault(e.node, []).append(e.name + (f" ± {e.sigma:.4f}" if e.sigma > 0 else ""))
        items = tuple(f"{node}: {', '.join(names)}"
                      + ("; the node is not solved" if any(e.why == "not solved" for e in entered.values()
                                                          if e.node == node) else "")
                      for node, names in by_node.items())
        out.append(Limitation("entered", "Entered values",
                              "These dimensions were entered (from a tape, a plan, an assumption), not measured in "
                              "the photos; a σ (± 1σ, in file units) is the entered one; a value without one was "
                              "taken as exact.",
                              items))
    out += _not_photographed(data, entered)
    outliers = (data.get("model_solution") or {}).get("outliers") or []
    if outliers:
        out.append(Limitation("outliers", "Outliers", f"The solve flagged {len(outliers)} observation(s) as "
                              "outliers (residual above 4σ): look at them before relying on the figures.",
                              tuple(str(o) for o in outliers)))
    failed = [c for c in checks if not c.within_ci95]
    if failed:
        out.append(Limitation("failed-checks", "Failed check distances",
                              "The known distance lies outside the final model's 95 % interval: the model is "
                              "less accurate there than its σ says.",
                              tuple(f"{c.a} – {c.b}: difference {1000 * c.difference:+.1f} mm, 95 % interval "
                                    f"± {1000 * (c.difference_ci95[1] - c.difference):.1f} mm" for c in failed)))
    cal = data.get("calibration") or {}
    cams = cal.get("cameras") or {}
    if cams:
        out.append(Limitation("calibration-modes", "How each photo was calibrated",
                              "Each photo's calibration: from how many vanishing points, and the first part of its "
                              "reason (the whole reason under Calibration, in the annex).",
                              tuple(f"{pid}: {MODE_WORDS.get(str(c.get('mode')), str(c.get('mode', '?')))}: "
                                    + str(c.get("mode_reason", "no reason recorded")).split(";")[0]
                                    for pid, c in cams.items())))
    out += _single_view(project)
    cal_failed = [c for c in cal.get("failed_checks") or [] if isinstance(c, Mapping)]
    if cal_failed:
        from vebuild.console.tables import failed_check_words

        out.append(Limitation("calibration-failed-checks", "The calibration FAILED its check distances",
                              "These check distances, measured on the calibrated cameras' markers, differ from the "
                              "tape by more than their limit in σ: the cameras or the tape are wrong. Figures resting "
                              "on this calibration are not to be relied on until it is fixed.",
                              tuple(failed_check_words(dict(c)) for c in cal_failed)))
    left_out = cal.get("left_out") or {}
    if left_out:
        out.append(Limitation("left-out", "Photos left out of the calibration",
                              "These photos have no camera: their marks could not determine one. Nothing in the "
                              "model rests on them.",
                              tuple(f"{pid}: {u.get('reason', '') if isinstance(u, Mapping) else u}"
                                    for pid, u in left_out.items())))
    unplaced = cal.get("unplaced") or {}
    if unplaced:
        out.append(Limitation("unplaced", "Photos not placed",
                              "These photos were calibrated but not placed; nothing in the model rests on them.",
                              tuple(f"{pid}: {u.get('reason', '') if isinstance(u, Mapping) else u}"
                                    for pid, u in unplaced.items())))
    return out


def _single_view(project: Project) -> list[Limitation]:
    """What a single photo cannot tell, where the project measures on photos placed alone or records
    single-view measurements: the assumptions those measurements rest on, in plain words."""
    from vebuild.analysis.single_view import SINGLE_VIEW_CLICKS

    data = project.data
    cams = (data.get("calibration") or {}).get("cameras") or {}
    alone = [pid for pid, c in cams.items() if (c.get("placement") or {}).get("how") == "alone"]
    measured = [a for a in data.get("analyses") or [] if isinstance(a.get("command"), list) and a["command"]
                and a["command"][0] in (*SINGLE_VIEW_CLICKS, "person-height")]
    people = any(a["command"][0] == "person-height" for a in measured)
    if not alone and not measured:
        return []
    click = project.settings["click_sigma_px"]
    items = [
        "The floor is taken as one flat, level surface (z = 0) everywhere in the photo. A slope, a step, a "
        "threshold or a sagging floor moves every point measured on it, and no 1σ shows it.",
        "A point off the floor is measured from its foot: the point on the floor straight below it, as clicked. "
        "A foot clicked in the wrong place (hidden, guessed, not straight below) gives a wrong height or length "
        "without any warning.",
        "A corner or foot that something hides, or that lies outside the photo, cannot be clicked: the examiner "
        "has to estimate where it is, and that estimate is not in the 1σ.",
        "Lines marked as vertical (door frames, wall corners) are taken as truly vertical; a leaning one tilts "
        "the camera's calibration and every measurement with it.",
        "One photo cannot tell how far away a point is except through the floor: a point with no visible foot, "
        "on no marked surface, cannot be measured at all.",
        f"The 1σ and 95 % intervals count the calibration's uncertainty and each click's (1σ {click:g} px), "
        "not a click on the wrong point.",
    ]
    for pid in alone:
        pl = cams[pid].get("placement") or {}
        if pl.get("lengths") == "relative":
            items.append(f"{pid}: no scale was given, so the photo gives only proportions: every length is in units "
                         "of the camera's height above the floor, not metres.")
        else:
            items.append(f"{pid}: the scale comes from {pl.get('scale') or 'the scale given'}; an error in it "
                         "(a wrong length, a wrong camera height) makes every length on this photo wrong in the "
                         "same proportion.")
        if not cams[pid].get("distortion"):
            items.append(f"{pid}: no lens distortion was estimated (no marked line had middle points): a lens that "
                         "bends straight lines shifts points near the photo's edges.")
    if people:
        items += [
            "A person's height is that of the figure in its frame as imaged, from the floor under the feet to the "
            "top of the head clicked: the allowances for footwear, head covering, posture and a hidden crown are "
            "the examiner's entries, each with its stated 1σ and source, and the result is only as good as they "
            "are. It is not the person's documented standing height.",
            "Frames of one person on different photos are taken as independently calibrated; frames that share one "
            "calibration (one fixed camera calibrated once) share its error, which no number of frames averages "
            "down. A figure that is not upright (leaning, on a slope) is measured as if it were.",
        ]
    return [Limitation("single-view", "What a single photo cannot tell",
                       "Measurements on a single photo rest on assumptions that the photo itself cannot check:",
                       tuple(items))]


def limitations_html(items: Sequence[Limitation]) -> str:
    if not items:
        return "<p>None found in the project.</p>"
    parts = []
    for lim in items:
        parts.append(f"<h3>{esc(lim.title)}</h3><p>{esc(lim.text)}</p>")
        if lim.items:
            parts.append("<ul class='lim'>" + "".join(f"<li>{esc(i)}</li>" for i in lim.items) + "</ul>")
    return "".join(parts)
