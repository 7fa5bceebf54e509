"""The report's "Person heights": every person-height the project records
(:mod:`vebuild.analysis.requests_person`), measured again, drawn on its frame and tabled per person.

On each frame (reduced to the report's width): the top of the head clicked as a ring, the foot
point clicked (or each foot, joined, with their midpoint) as a ring, and the vertical measured (from
the foot point on the floor to the height in the image, as the photo's camera and lens show it) as
a magenta line, numbered and labelled with the frame's height. Per person a table: each frame's
height in the image with its 1σ (calibration, clicks), each allowance with its value, 1σ and
source, the frame's height; then the frames combined (:mod:`vebuild.analysis.person_combine`), the
allowances added once, and the 95 % interval in plain words, with what the figure is and is not.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from vebuild.analysis.person import WHAT_IT_IS, PersonFrame
from vebuild.analysis.person_terms import Term, not_entered
from vebuild.render.sizes import IMAGE_WIDTH

from .page import Report, esc, fmt, still_words, table

if TYPE_CHECKING:
    from vebuild.project import Project

TITLE = "Person heights"
#: The vertical measured and its label; the clicks (sRGB).
VERTICAL_RGB = (255, 64, 255)
CLICK_RGB = (255, 255, 255)


def drawn_frame(project: Project, index: int, frames: Sequence[tuple[int, PersonFrame]],
                width: int = IMAGE_WIDTH) -> np.ndarray:
    """Photo ``index`` at ``width`` pixels wide with the person-heights ``frames`` (their numbers
    in the report and the frames) drawn on it (module docstring)."""
    from PIL import ImageDraw, ImageFont

    from vebuild.camera import project as project_points
    from vebuild.project.decode import photo_camera

    from .marked_photos import label, on_image, photo_image

    img, s = photo_image(project, index, width)
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default(size=max(14, width // 48))
    lw = max(2, round(width / 320))
    r = 3 * lw
    taken: list[tuple[float, float]] = []
    for number, f in frames:
        cam = photo_camera(project, f.photo)
        ends = project_points(cam.K, cam.R, cam.C, np.array([f.foot, f.top]), cam.lens)
        a, b = (on_image(float(u), float(v), s) for u, v in ends)
        pts = [on_image(float(u), float(v), s) for u, v in f.clicks]
        if len(pts) == 3:
            draw.line([pts[1], pts[2]], fill=CLICK_RGB, width=1)
        for x, y in pts:
            draw.ellipse([(x - r, y - r), (x + r, y + r)], outline=CLICK_RGB, width=1)
        draw.line([a, b], fill=VERTICAL_RGB, width=lw)
        for x, y in (a, b):
            draw.line([(x - 2 * r, y), (x + 2 * r, y)], fill=VERTICAL_RGB, width=lw)
        lo, hi = f.ci95
        text = f"{number}: {f.value:.3f} m, 95 %: [{lo:.3f}, {hi:.3f}]"
        box = draw.textbbox((0, 0), text, font=font)
        w, h = box[2] - box[0] + 8, box[3] - box[1] + 8
        mid = (max(a[0], b[0]) + 2 * r + 4, (a[1] + b[1]) / 2)
        # Beside the vertical, stepped down (then up) past the labels already drawn.
        spots = [(mid[0], mid[1] + k * h) for k in (0, 1, -1, 2, -2, 3, -3, 4, -4)]
        at = next((p for p in spots if not any(p[0] < q[0] + w and q[0] < p[0] + w and p[1] < q[1] + h
                                                and q[1] < p[1] + h for q in taken)), spots[0])
        taken.append(at)
        label(draw, at, text, VERTICAL_RGB, font, img.width, img.height)
    return np.asarray(img)


def _term_cells(t: Term) -> list[str]:
    sign = "+" if t.kind.sign > 0 else "−"
    return [t.kind.words, f"{sign}{t.value:.3f}", f"{1000 * t.sigma:.1f}", t.source or "(no source given)"]


def _person_html(person: str | None, frames: Sequence[tuple[int, PersonFrame]]) -> str:
    rows: list[list[object]] = []
    for number, f in frames:
        rows.append([number, f.photo, "height in the image", fmt(f.image_height),
                     f"{1000 * f.sigma_image:.1f} (calibration {1000 * f.sigma_calibration:.1f}, clicks "
                     f"{1000 * f.sigma_clicks:.1f} at {f.click_sigma_px:g} px)", "sole to head-top, as clicked"])
        shown = f.terms if person is None else tuple(t for t in f.terms if not t.kind.per_person)
        for t in shown:
            w, v, sg, src = _term_cells(t)
            rows.append(["", "", w, v, sg, src])
        if person is None:
            lo, hi = f.ci95
            rows.append(["", "", "height in this frame", fmt(f.value), f"{1000 * f.sigma:.1f}",
                         f"between {lo:.3f} and {hi:.3f} m (95 %)"])
        else:  # the person's footwear and head covering come once, below
            y = f.image_height + sum(t.signed for t in shown)
            s = float(np.sqrt(f.sigma_image**2 + sum(t.sigma**2 for t in shown)))
            rows.append(["", "", "this frame, before footwear and head covering", fmt(y), f"{1000 * s:.1f}",
                         "combined with the other frames below"])
    head = ["#", "photo", "", "m", "1σ mm", "source or note"]
    if person is None:
        return ("<h3>Not named as a person</h3><p>Each measured on its own (no <code>--person</code>).</p>"
                + table(head, rows, {0, 3, 4}, wide=True))
    from vebuild.analysis.person_combine import combine

    c = combine(person, [f for _, f in frames])
    for t in c.person_terms:
        w, v, sg, src = _term_cells(t)
        rows.append(["", "all", w + " (once for the person)", v, sg, src])
    missing = sorted(set.intersection(*(set(not_entered([*f.terms, *c.person_terms])) for _, f in frames)))
    lo, hi = c.ci95
    dof = f"{c.dof} degree{'s' if c.dof != 1 else ''} of freedom"
    combined = (f"{len(frames)} frames combined: {c.frames_value:.4f} m, the spread between frames "
                f"{1000 * c.tau:.1f} mm beyond their 1σ ({dof})" if len(frames) > 1 else "one frame")
    return (f"<h3>Person {esc(person)}</h3>" + table(head, rows, {0, 3, 4}, wide=True)
            + f"<p><b>{esc(person)}: between {lo:.2f} and {hi:.2f} m (95 %)</b>; the estimate {c.value:.3f} m; "
            f"{esc(combined)}; footwear and head covering added once for the person, as they are the same in "
            f"every frame. " + (f"No allowance entered for {esc(', '.join(missing))}. " if missing else "")
            + "</p>")


def section(project: Project, rep: Report) -> None:
    """The section (nothing where the project records no person-height)."""
    from vebuild.analysis.person_combine import METHOD
    from vebuild.analysis.requests_person import recorded_person_frames

    recorded = recorded_person_frames(project)
    if not recorded:
        return
    numbered = [(k + 1, f, i) for k, (i, f) in enumerate(recorded)]
    figs = []
    for index, photo in enumerate(project.data["photos"]):
        on = [(n, f) for n, f, _ in numbered if f.photo == photo["id"]]
        if not on:
            continue
        src = rep.image(f"person-{index + 1}.png", drawn_frame(project, index, on),
                        {"Software": "vebuild", "Source": photo["file"], "Source SHA-256": photo["sha256"]})
        figs.append(f"<figure><img src='{src}'><figcaption>photo {esc(photo['id'])}: person-height "
                    f"{', '.join(str(n) for n, _ in on)}; the vertical measured in magenta from the foot point on "
                    "the floor to the height in the image, the clicks as white rings"
                    f"{esc(still_words(photo))}</figcaption></figure>")
    people = sorted({f.person for _, f, _ in numbered if f.person})
    parts = [_person_html(p, [(n, f) for n, f, _ in numbered if f.person == p]) for p in people]
    alone = [(n, f) for n, f, _ in numbered if not f.person]
    if alone:
        parts.append(_person_html(None, alone))
    commands = ", ".join(f"{n}: analysis {i + 1}" for n, _, i in numbered)
    body = (f"<p>Each figure's height is {esc(WHAT_IT_IS)}. The photo measures the line from the floor under the "
            "feet to the top of the head shown, in the posture of that frame; the allowances the examiner entered "
            "(each with its value, 1σ and source) turn it into a height, and where none is entered the table says "
            f"so. Each frame's 1σ comes from its photo's calibration (camera and lens, with their correlations), "
            "each click's 1σ (the project's, or the one entered for the frame) and the allowances' 1σ. Frames of "
            "one person are combined by "
            f"{esc(METHOD)}. Each is reproduced by its command under Analyses ({esc(commands)}).</p>"
            + "".join(parts) + "".join(figs))
    rep.add(TITLE, body)
