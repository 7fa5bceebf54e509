"""The report's "Measurements on the photos": every single-view measurement the project records
(``analyses`` whose command is one of :data:`vebuild.analysis.single_view.SINGLE_VIEW_CLICKS`), run
again through :mod:`vebuild.analysis.recorded` as every recorded analysis is, drawn on its photo and
tabled with its 1σ and 95 % interval.

Each photo with measurements is shown once, reduced to the report's width
(:data:`vebuild.render.sizes.IMAGE_WIDTH`), with each measurement drawn where it was clicked: the
measured length as a cyan line between its last two clicks (the foot and the top of a height, the
two ends of a distance or length), with a bar across each end, numbered and labelled with its value
and 95 % interval beside one of its ends (where the label covers no measured line and no other
label); the clicks that only set the reference (the wall's foot line, the raised surface, the
plane's points) as white rings joined in their pairs. The same project gives the same PNG bytes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from vebuild.analysis.single_view import SINGLE_VIEW_CLICKS
from vebuild.errors import VebuildError
from vebuild.render.sizes import IMAGE_WIDTH

from .page import Report, esc, fmt, still_words, table

if TYPE_CHECKING:
    from vebuild.project import Project

#: The measured line and its label (sRGB); the reference clicks.
MEASURED_RGB = (0, 230, 255)
REFERENCE_RGB = (255, 255, 255)
TITLE = "Measurements on the photos"


@dataclass(frozen=True)
class Drawn:
    """One measurement of a recorded single-view analysis: its number in the report, the analysis
    (``$.analyses`` index and name), its photo, its clicks (photo pixels, in the kind's order) and its
    figures (:meth:`vebuild.analysis.measure.Measurement.to_json`)."""

    number: int
    analysis: int
    name: str
    kind: str
    photo: str
    clicks: tuple[tuple[float, float], ...]
    figures: Mapping[str, Any]

    def value(self) -> tuple[float, float | None, tuple[float, float] | None, str]:
        """Value, 1σ and 95 % interval (None where undetermined), and the unit's symbol."""
        unit = "m" if "value_m" in self.figures else "rel."
        key = "m" if unit == "m" else "relative"
        ci = self.figures.get(f"ci95_{key}")
        return (float(self.figures[f"value_{key}"]), self.figures.get(f"sigma_{key}"),
                (float(ci[0]), float(ci[1])) if ci else None, unit)

    def label(self) -> str:
        """The label drawn beside it: number, value and 95 % interval."""
        v, _, ci, unit = self.value()
        # Plain ASCII and Latin-1 only: the drawing font has no other glyphs.
        interval = f", 95 %: [{ci[0]:.3f}, {ci[1]:.3f}]" if ci else ", interval undetermined"
        return f"{self.number}: {v:.3f} {unit}{interval}"


def is_single_view(words: Any) -> bool:
    """Whether recorded words are those of a single-view measurement (their first word its kind)."""
    return isinstance(words, list) and bool(words) and words[0] in SINGLE_VIEW_CLICKS


def _clicks(request: Any, words: Sequence[str]) -> tuple[float, ...]:
    """The clicked pixels of a parsed single-view request, U V in order: its ``pixels``, or the
    numbers among its words where a request keeps them otherwise."""
    pixels = getattr(request, "pixels", None)
    if pixels is not None:
        return tuple(float(x) for x in pixels)
    out = []
    skip = False
    for w in words[1:]:
        if skip:
            skip = False
            continue
        if w.startswith("--"):
            skip = "=" not in w
            continue
        out.append(float(w))
    return tuple(out)


def measurements(project: Project, rep: Report) -> list[Drawn]:
    """Every single-view measurement the project records, each analysis run once for the report
    (kept in ``rep.recorded`` for the section "Analyses")."""
    from vebuild.analysis.recorded import run_recorded

    out: list[Drawn] = []
    for i, rec in enumerate(project.data.get("analyses") or []):
        words = rec.get("command")
        if not is_single_view(words):
            continue
        request, result = rep.recorded.get(i) or run_recorded(project, i, rec)
        rep.recorded[i] = (request, result)
        kind = request.name
        per = 2 * len(SINGLE_VIEW_CLICKS[kind])
        pixels = _clicks(request, words)
        rows = list(result.figures.get("measurements") or [])
        if len(pixels) != per * len(rows):
            raise VebuildError(f"{project.path}: $.analyses[{i}].command: {len(rows)} measurement(s) from "
                               f"{len(pixels)} pixel coordinates; expected {per} for each")
        photo = str(result.figures.get("photo") or getattr(request, "photo", ""))
        for k, fig in enumerate(rows):
            chunk = pixels[k * per:(k + 1) * per]
            clicks = tuple((chunk[j], chunk[j + 1]) for j in range(0, per, 2))
            out.append(Drawn(len(out) + 1, i, str(rec["name"]), kind, photo, clicks, fig))
    return out


def drawn_photo(project: Project, index: int, drawn: Sequence[Drawn], width: int = IMAGE_WIDTH) -> np.ndarray:
    """Photo ``index`` at ``width`` pixels wide with the measurements ``drawn`` on it (module docstring)."""
    from PIL import ImageDraw, ImageFont

    from .marked_photos import label, on_image, photo_image

    img, s = photo_image(project, index, width)
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default(size=max(14, width // 48))
    lw = max(2, round(width / 320))
    r = 3 * lw
    lines = []
    for d in drawn:
        pts = [on_image(u, v, s) for u, v in d.clicks]
        ref, (a, b) = pts[:-2], pts[-2:]
        lines.append((a, b))
        for j in range(0, len(ref) - 1, 2):
            draw.line([ref[j], ref[j + 1]], fill=REFERENCE_RGB, width=1)
        for x, y in ref:
            draw.ellipse([(x - r, y - r), (x + r, y + r)], outline=REFERENCE_RGB, width=1)
        draw.line([a, b], fill=MEASURED_RGB, width=lw)
        along = np.subtract(b, a)
        n = float(np.hypot(along[0], along[1]))
        side = (np.array([-along[1], along[0]]) / n if n > 1e-9 else np.array([1.0, 0.0])) * 2 * r
        for end in (a, b):
            draw.line([tuple(np.asarray(end) - side), tuple(np.asarray(end) + side)], fill=MEASURED_RGB, width=lw)
    taken: list[tuple[float, float, float, float]] = []
    for d, (a, b) in zip(drawn, lines, strict=True):
        text = d.label()
        box = draw.textbbox((0, 0), text, font=font)
        w, h = box[2] - box[0] + 4, box[3] - box[1] + 4
        # Beside an end (the top of a height first), where it covers no measured line and no other label.
        gap = 2 * r + 4
        spots = [(e[0] + gap, e[1] - h / 2) for e in (b, a)] + [(e[0] - gap - w, e[1] - h / 2) for e in (b, a)] \
            + [(e[0] - w / 2, e[1] - gap - h) for e in (b, a)] + [(e[0] - w / 2, e[1] + gap) for e in (b, a)]
        spots = [(min(max(x, 2.0), img.width - 2 - w), min(max(y, 2.0), img.height - 2 - h)) for x, y in spots]
        at = next((xy for xy in spots if _free((xy[0], xy[1], xy[0] + w, xy[1] + h), lines, taken, lw)), spots[0])
        taken.append((at[0], at[1], at[0] + w, at[1] + h))
        label(draw, (at[0] + 2, at[1] + 2), text, MEASURED_RGB, font, img.width, img.height)
    return np.asarray(img)


def _free(rect: tuple[float, float, float, float], lines: Sequence[tuple[Any, Any]],
          taken: Sequence[tuple[float, float, float, float]], margin: float) -> bool:
    """Whether a label's rectangle stays clear of every drawn line (by ``margin``) and every label."""
    x0, y0, x1, y1 = rect[0] - margin, rect[1] - margin, rect[2] + margin, rect[3] + margin
    for a, b in lines:
        t = np.linspace(0.0, 1.0, 200)[:, None]
        p = (1 - t) * np.asarray(a, float) + t * np.asarray(b, float)
        if np.any((p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)):
            return False
    return not any(x0 < q[2] and q[0] < x1 and y0 < q[3] and q[1] < y1 for q in taken)


def section(project: Project, rep: Report) -> None:
    """The section (nothing where the project records no single-view measurement)."""
    drawn = measurements(project, rep)
    if not drawn:
        return
    from vebuild.project.units import RELATIVE_UNITS

    ids = [p["id"] for p in project.data["photos"]]
    relative = any("value_relative" in d.figures for d in drawn)
    lengths = f"in {RELATIVE_UNITS} (no scale was given)" if relative else "in metres"
    figs = []
    for index, pid in enumerate(ids):
        on = [d for d in drawn if d.photo == pid]
        if not on:
            continue
        src = rep.image(f"measured-{index + 1}.png", drawn_photo(project, index, on),
                        {"Software": "vebuild", "Source": project.data["photos"][index]["file"],
                         "Source SHA-256": project.data["photos"][index]["sha256"]})
        figs.append(f"<figure><img src='{src}'><figcaption>photo {esc(pid)}: "
                    f"{', '.join(f'{d.number} {d.name}' for d in on)}; each measured line in cyan, numbered, with "
                    "its value and 95 % interval; the reference clicks as white rings"
                    f"{esc(still_words(project.data['photos'][index]))}</figcaption></figure>")
    rows = []
    unit = "rel." if relative else "m"
    sigma_unit = "rel." if relative else "mm"  # as `vebuild analyse` prints them: 1σ in mm beside metres
    for d in drawn:
        v, sigma, ci, _ = d.value()
        shown = "undetermined" if sigma is None else f"{sigma:.4f}" if relative else f"{1000 * sigma:.2f}"
        rows.append([d.number, d.name, d.photo, d.kind, d.figures.get("what", ""), fmt(v), shown,
                     f"{fmt(ci[0])} – {fmt(ci[1])}" if ci else "undetermined", f"analysis {d.analysis + 1}"])
    clicks = project.settings["click_sigma_px"]
    body = ("<p>Each measurement made on a single calibrated photo, against the floor (z = 0): no model is "
            f"needed. Lengths {esc(lengths)}. The 1σ and the 95 % interval come from the photo's calibration "
            f"(its focal length, principal point, rotation, lens and camera height, with their correlations) "
            f"and from each click's 1σ of {clicks:g} px; what they do not cover is under Limitations. Each is "
            "reproduced by the command under Analyses.</p>"
            + table(["#", "measurement", "photo", "kind", "what", f"value {unit}", f"1σ {sigma_unit}",
                     f"95 % interval {unit}", "command"], rows, {0, 5, 6, 7}, wide=True)
            + "".join(figs))
    rep.add(TITLE, body)
