"""The report's plan view: the scene seen from above, to scale, as SVG.

Drawn from the final figures: the model's faces' edges (its footprint) from the solved model
(``model.nodes``), the cameras (:func:`vebuild.project.decode.cameras`: re-calibrated where the
solve re-calibrated them) with their horizontal fields of view as wedges, the calibrated markers
(re-calibrated positions where the solution has them) and the evidence markers; a scale bar, the
world axes and the origin. The drawing is printed at a round scale (1 : 20, 1 : 50 …) chosen so that
it fits the page, its size given in millimetres, so that a ruler on the printed page measures the
scene. Numbers are written with fixed formatting: the same project gives the same bytes.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.project import Project

from .page import esc

Array = NDArray[np.float64]

#: The largest drawing on the page, millimetres (A4 less the margins, and room for the caption).
MAX_WIDTH_MM, MAX_HEIGHT_MM = 160.0, 200.0
#: The scales the plan may be printed at (1 : N), the largest that fits is taken.
SCALES = (10, 20, 25, 50, 100, 200, 250, 500, 1000, 2000, 2500, 5000, 10000)
#: Margin around the drawing, millimetres on paper.
MARGIN_MM = 8.0
#: Length of a camera's field-of-view wedge, millimetres on paper.
WEDGE_MM = 14.0
#: How many points trace a curved outline (a cylinder's rim) in the plan.
OUTLINE_POINTS = 48

AXIS_COLOURS = {"x": "#c81e1e", "y": "#1e8c1e"}


@dataclass(frozen=True)
class PlanCamera:
    id: str
    position: Array  # (3,)
    left: Array  # (2,) unit, the left edge of the image's field of view in the plan
    right: Array  # (2,)


def footprint(project: Project) -> list[Array]:
    """The model's edges (and curved outlines) in world coordinates, each an (n, 3) polyline, in
    the order of ``model.nodes``."""
    from vebuild.project import decode

    model = decode.model(project, final_markers(project.data))
    T = model.world_transforms()
    lines = []
    for n in model.nodes:
        prim = n.primitive
        if prim is None:
            continue
        M = T[n.name]
        H = prim.handles() @ M[:3, :3].T + M[:3, 3]
        index = {h: k for k, h in enumerate(prim.handle_names())}
        for _, a, b in prim.edges():
            lines.append(H[[index[a], index[b]]])
        for o in prim.outline_points(OUTLINE_POINTS):
            lines.append(o @ M[:3, :3].T + M[:3, 3])
    return lines


def final_markers(data: Mapping[str, Any]) -> dict[str, Array]:
    """Marker positions after the last stage: the re-calibrated ones (``model_solution.markers``)
    where the solution has them, else the calibration's."""
    from vebuild.project import decode

    out = decode.markers(data)
    for name, m in ((data.get("model_solution") or {}).get("markers") or {}).items():
        out[name] = np.asarray(m["position"], float)
    return out


def plan_cameras(project: Project) -> list[PlanCamera]:
    """Each final camera's position and the plan directions of its image's left and right edges
    (through the principal point's row)."""
    from vebuild.project import decode

    out = []
    for pid, cam in decode.cameras(project).items():
        Kinv = np.linalg.inv(cam.K)
        cy = cam.K[1, 2]
        dirs = []
        for u in (0.0, float(cam.width)):
            d = cam.R.T @ (Kinv @ np.array([u, cy, 1.0]))
            d2 = d[:2]
            n = np.linalg.norm(d2)
            dirs.append(d2 / n if n > 1e-9 else np.zeros(2))  # looking straight down: no wedge
        out.append(PlanCamera(pid, np.asarray(cam.C, float), dirs[0], dirs[1]))
    return out


def _round_length(x: float) -> float:
    """The largest 1, 2 or 5 × 10^k not above x."""
    k = math.floor(math.log10(x))
    for m in (5.0, 2.0, 1.0):
        if m * 10**k <= x:
            return m * 10**k
    return 10.0**k


def _f(x: float) -> str:
    """A coordinate on paper, in millimetres, fixed to a hundredth (``-0.00`` written ``0.00``)."""
    s = f"{x:.2f}"
    return "0.00" if s == "-0.00" else s


def _length_words(metres: float) -> str:
    return f"{metres * 100:g} cm" if metres < 1 else f"{metres:g} m"


def plan_svg(project: Project, max_height_mm: float = MAX_HEIGHT_MM) -> tuple[str, dict[str, Any]]:
    """The plan view as SVG text, and what it shows (its scale, its extent, what it counts) for the
    caption; at most :data:`MAX_WIDTH_MM` wide and ``max_height_mm`` high on paper, at the largest
    of :data:`SCALES` that fits."""
    from vebuild.project.units import length_unit

    data = project.data
    unit = length_unit(data)
    lines = footprint(project)
    cams = plan_cameras(project)
    markers = final_markers(data)
    evidence = [(m["label"], np.asarray(m["position"], float)) for m in data.get("evidence_markers", [])]
    pts = [ln[:, :2] for ln in lines] + [c.position[None, :2] for c in cams]
    pts += [p[None, :2] for p in markers.values()] + [p[None, :2] for _, p in evidence] + [np.zeros((1, 2))]
    P = np.concatenate(pts)
    lo, hi = P.min(axis=0), P.max(axis=0)
    span = np.maximum(hi - lo, 1e-3)
    room_w, room_h = MAX_WIDTH_MM - 2 * MARGIN_MM, max_height_mm - 2 * MARGIN_MM - 12.0
    # Relative units have no scale on paper: the drawing is fitted and the bar reads in those units.
    fits = [n for n in SCALES if span[0] * 1000 / n <= room_w and span[1] * 1000 / n <= room_h]
    if fits and not unit.relative:
        scale_n = fits[0]
        s = 1000.0 / scale_n  # millimetres on paper per metre
    else:
        scale_n = 0
        s = min(room_w / span[0], room_h / span[1])
    height = span[1] * s + 2 * MARGIN_MM + 12.0  # room below for the scale bar
    bar = _round_length(float(max(span)) / 5)
    ratio = f", 1 : {scale_n} as printed" if scale_n else ""
    legend = f"plan view, from above{ratio}"
    # Wide enough for the scale bar's words (2.6 mm type: about 1.6 mm a character), however small the scene.
    width = max(span[0] * s + 2 * MARGIN_MM, 2 * MARGIN_MM + bar * s + 3.0 + 1.6 * len(legend))

    def xy(p: Iterable[float]) -> tuple[str, str]:
        x, y = list(p)[:2]
        return _f(MARGIN_MM + (x - lo[0]) * s), _f(MARGIN_MM + (hi[1] - y) * s)

    out = [f"<svg xmlns='http://www.w3.org/2000/svg' width='{_f(width)}mm' height='{_f(height)}mm' "
           f"viewBox='0 0 {_f(width)} {_f(height)}' font-family='DejaVu Sans, sans-serif'>",
           f"<rect x='0' y='0' width='{_f(width)}' height='{_f(height)}' fill='#ffffff'/>"]
    out.append("<g fill='none' stroke='#555555' stroke-width='0.25' stroke-linecap='round'>")
    for ln in lines:
        out.append("<polyline points='" + " ".join(",".join(xy(p)) for p in ln) + "'/>")
    out.append("</g>")
    # The world axes at the origin, each as long as the scale bar.
    ox, oy = xy((0.0, 0.0))
    for axis, d in (("x", (bar, 0.0)), ("y", (0.0, bar))):
        ex, ey = xy(d)
        colour = AXIS_COLOURS[axis]
        out.append(f"<line x1='{ox}' y1='{oy}' x2='{ex}' y2='{ey}' stroke='{colour}' stroke-width='0.5'/>")
        out.append(f"<text x='{ex}' y='{ey}' dx='1' dy='-1' font-size='3' fill='{colour}'>+{axis}</text>")
    out.append(f"<circle cx='{ox}' cy='{oy}' r='1' fill='none' stroke='#000000' stroke-width='0.35'/>"
               f"<text x='{ox}' y='{oy}' dx='1.5' dy='6.5' font-size='2.6'>origin (z up, towards you)</text>")
    # Cameras and their fields of view.
    for c in cams:
        cx, cy = xy(c.position)
        if np.any(c.left) and np.any(c.right):
            L = WEDGE_MM / s
            ax, ay = xy(c.position[:2] + L * c.left)
            bx, by = xy(c.position[:2] + L * c.right)
            out.append(f"<path d='M{cx},{cy} L{ax},{ay} L{bx},{by} Z' fill='#2060c0' fill-opacity='0.15' "
                       "stroke='#2060c0' stroke-width='0.3'/>")
        out.append(f"<circle cx='{cx}' cy='{cy}' r='1.1' fill='#2060c0'/>"
                   f"<text x='{cx}' y='{cy}' dx='1.6' dy='-1.2' font-size='3' fill='#2060c0'>{esc(c.id)}</text>")
    for name in sorted(markers):
        mx, my = xy(markers[name])
        out.append(f"<rect x='{_f(float(mx) - 0.8)}' y='{_f(float(my) - 0.8)}' width='1.6' height='1.6' "
                   f"fill='#e08000'/><text x='{mx}' y='{my}' dx='1.2' dy='2.8' font-size='2.4' "
                   f"fill='#a05000'>{esc(name)}</text>")
    for label, p in evidence:
        ex, ey = xy(p)
        out.append(f"<circle cx='{ex}' cy='{ey}' r='1.2' fill='#aa1414'/><text x='{ex}' y='{ey}' dx='1.5' "
                   f"dy='1' font-size='3' font-weight='bold' fill='#aa1414'>{esc(label)}</text>")
    # The scale bar, in four parts alternately filled.
    bx0, by0 = MARGIN_MM, height - MARGIN_MM - 2.0
    seg = bar * s / 4
    for k in range(4):
        fill = "#000000" if k % 2 == 0 else "#ffffff"
        out.append(f"<rect x='{_f(bx0 + k * seg)}' y='{_f(by0)}' width='{_f(seg)}' height='1.5' fill='{fill}' "
                   "stroke='#000000' stroke-width='0.2'/>")
    bar_text = f"{bar:g} {unit.symbol}" if unit.relative else _length_words(bar)
    out.append(f"<text x='{_f(bx0)}' y='{_f(by0 - 1.2)}' font-size='2.6'>0</text>"
               f"<text x='{_f(bx0 + bar * s)}' y='{_f(by0 - 1.2)}' font-size='2.6' text-anchor='end'>"
               f"{esc(bar_text)}</text>"
               f"<text x='{_f(bx0 + bar * s + 3)}' y='{_f(by0 + 1.5)}' font-size='2.6'>{esc(legend)}</text>")
    out.append("</svg>")
    info = {"scale": scale_n, "bar": bar, "cameras": len(cams), "markers": len(markers), "edges": len(lines),
            "evidence_markers": len(evidence), "extent": [float(v) for v in span]}
    return "\n".join(out) + "\n", info
