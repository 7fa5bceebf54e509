"""What the modelling screen draws over a photo, in that photo's pixel coordinates (paper Figures
1–3, 5 and 7): the user's vanishing segments in their axis' colour with their residuals, the fitted
vanishing points, the calibrated camera's horizon and world axes, markers, the model's projected
edges (white), the user's edges (red), handles (filled where fixed) and observation residuals.

Plain data, no GL: :meth:`vebuild.edit.session.EditSession.overlay` computes it, the screen maps it
to the window and draws it, tests read it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

RGBA = tuple[float, float, float, float]

#: One colour per world axis, as in the paper's Figure 1 (x red, y green, z blue).
AXIS_COLOURS: dict[str, RGBA] = {"x": (0.95, 0.25, 0.2, 1.0), "y": (0.25, 0.85, 0.3, 1.0), "z": (0.3, 0.55, 1.0, 1.0)}
WHITE: RGBA = (1.0, 1.0, 1.0, 1.0)
RED: RGBA = (1.0, 0.15, 0.15, 1.0)
YELLOW: RGBA = (1.0, 0.9, 0.1, 1.0)
MAGENTA: RGBA = (1.0, 0.2, 0.9, 1.0)
ORANGE: RGBA = (1.0, 0.6, 0.1, 1.0)
CYAN: RGBA = (0.2, 0.95, 0.95, 1.0)
GREY: RGBA = (0.7, 0.7, 0.7, 0.8)


@dataclass
class Line:
    """A segment from (u1, v1) to (u2, v2), pixels of the photo. ``kind`` says what it is:
    ``segment`` (a vanishing segment; ``key`` = (axis, index)), ``vp-ray`` (midpoint to vanishing
    point), ``horizon``, ``axis`` (world axis from the origin), ``edge`` (a projected model edge;
    ``key`` = (node, edge)), ``user-edge`` (an edge observation; ``key`` = index), ``residual``."""

    p: tuple[float, float, float, float]
    colour: RGBA
    width: float = 1.5
    kind: str = ""
    key: object = None
    label: str | None = None
    arrow: bool = False  # draw an arrow head at the second end (directed vanishing segments)


@dataclass
class Point:
    """A point at (u, v): ``kind`` is ``vp`` (a vanishing point), ``marker`` (an observed marker),
    ``marker-projected`` (where the calibration puts it), ``handle`` (``key`` = (node, handle)),
    ``pin`` (a fixed vertex), ``origin``."""

    uv: tuple[float, float]
    colour: RGBA
    radius: float = 4.0
    filled: bool = True
    kind: str = ""
    key: object = None
    label: str | None = None


@dataclass
class Overlay:
    photo: str
    lines: list[Line] = field(default_factory=list)
    points: list[Point] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # one line each, shown beside the photo

    def of_kind(self, kind: str) -> tuple[list[Line], list[Point]]:
        return [ln for ln in self.lines if ln.kind == kind], [p for p in self.points if p.kind == kind]
