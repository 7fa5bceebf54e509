"""Bullet trajectories (paper §5.1): a straight path, its uncertainty cone, and what it meets.

A path is given by two points, the entry and exit holes (world points, or ``node:handle``), or by
one point with an azimuth (degrees counter-clockwise from +X about +Z) and an elevation (degrees
above the horizontal). Every surface the infinite line crosses is listed in order of its signed
distance from the entry point (negative: behind it, toward the shooter), with the angle between the
path and the surface. The surface the bullet stopped at is the first one beyond the exit that the
path meets from outside (a hit on a face's front; the far faces of the holed object do not count);
the surface behind the entry, toward the shooter, likewise. A path that meets nothing leaves the
scene: that is reported, with where it leaves the scene's bounding box, not raised as an error.

The uncertainty cone (95 %): from the two points' 1σ position errors σ_A, σ_B (isotropic, metres),
the line's lateral error at distance t from A is 2-D normal with σ(t)² = (1 − u)² σ_A² + u² σ_B²,
u = t / L, L the holes' separation; its 95 % radius is r(t) = 2.448 σ(t) (√(−2 ln 0.05)), and far
from the holes this is a cone of half-angle atan(2.448 √(σ_A² + σ_B²) / L), with its apex at the
waist u₀ = σ_A² / (σ_A² + σ_B²). A given half-angle makes a cone with its apex at the entry point.
The surfaces the cone may meet beyond the exit and behind the entry are found by casting its
surface lines (:data:`CONE_LINES` of them, and the axis).

Drawing: :func:`path_polylines` gives the path and cone as world polylines (what a viewer draws
as depth-tested lines); :func:`draw_trajectory` draws them over a rendered image, hidden parts
dashed (occlusion by exact ray casting from the camera, not the renderer's depth buffer).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from vebuild.analysis.rays import Hit, Occluders
from vebuild.analysis.sightline import check_in_scene, parse_floats, rounded
from vebuild.camera import ImageCamera, project, world_to_camera
from vebuild.errors import VebuildError

if TYPE_CHECKING:
    from vebuild.project import Project


Array = NDArray[np.float64]

#: Radius of the 95 % region of a 2-D isotropic normal, in σ: √(−2 ln 0.05).
K95_2D = math.sqrt(-2.0 * math.log(0.05))
#: Crossings this close to the entry or exit point are "at" it (metres).
AT_POINT_M = 0.01
#: Lines cast on the cone's surface.
CONE_LINES = 24


def parse_point(occ: Occluders, text: str, option: str) -> Array:
    """'X,Y,Z' (metres) or 'node:handle' → a world point."""
    text = str(text).strip()
    if ":" in text:
        node, handle = text.rsplit(":", 1)
        model = occ.scene.model
        if node not in model.index:
            raise VebuildError(f"{option} {text!r}: the model has no node called {node!r}; the nodes are: "
                               + ", ".join(n.name for n in model.nodes))
        prim = model.node(node).primitive
        if prim is None:
            raise VebuildError(f"{option} {text!r}: the node {node!r} has no primitive, hence no handles")
        if handle not in prim.handle_names():
            raise VebuildError(f"{option} {text!r}: {node!r} ({type(prim).__name__.lower()}) has no handle "
                               f"{handle!r}; its handles are: {', '.join(prim.handle_names())}")
        return model.handle_world(node, handle)
    return parse_floats(text, 3, option)


def direction_from_angles(azimuth_deg: float, elevation_deg: float) -> Array:
    """Unit direction: azimuth counter-clockwise from +X about +Z, elevation above the horizontal."""
    if not (math.isfinite(azimuth_deg) and math.isfinite(elevation_deg)) or not -90.0 <= elevation_deg <= 90.0:
        raise VebuildError(f"--elevation: expected −90…90 degrees above the horizontal, got {elevation_deg:g}")
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


@dataclass
class Trajectory:
    """The answer (see the module's docstring). Distances ``t`` are signed, from the entry point."""

    entry: Array
    direction: Array
    length: float  # entry to exit (0 when given by angles)
    sigma: tuple[float, float] | None = None  # 1σ of entry and exit (m)
    cone_deg: float | None = None  # 95 % half-angle
    hits: list[Hit] = field(default_factory=list)
    stop: Hit | None = None  # first surface met beyond the exit
    source: Hit | None = None  # first surface met behind the entry (toward the shooter)
    leaves_at: Array | None = None  # where the path leaves the scene's box forward, if it hits nothing
    leaves_behind_at: Array | None = None
    cone_stop_nodes: dict[str, float] = field(default_factory=dict)  # share of cone lines stopping on each
    cone_source_nodes: dict[str, float] = field(default_factory=dict)

    @property
    def exit(self) -> Array:
        return self.entry + self.length * self.direction

    @property
    def azimuth_deg(self) -> float:
        return float(np.degrees(np.arctan2(self.direction[1], self.direction[0])))

    @property
    def elevation_deg(self) -> float:
        return float(np.degrees(np.arcsin(np.clip(self.direction[2], -1.0, 1.0))))

    def cone_radius(self, t: float) -> float:
        """95 % radius of the uncertainty region at signed distance t from the entry (0: no cone)."""
        if self.sigma is not None and self.length > 0:
            u = t / self.length
            sa, sb = self.sigma
            return K95_2D * math.sqrt((1 - u) ** 2 * sa ** 2 + u ** 2 * sb ** 2)
        if self.cone_deg:
            return abs(t) * math.tan(math.radians(self.cone_deg))
        return 0.0

    def apex_t(self) -> float:
        if self.sigma is not None and self.length > 0:
            sa, sb = self.sigma
            return self.length * sa ** 2 / max(sa ** 2 + sb ** 2, 1e-300)
        return 0.0

    def where(self, t: float) -> str:
        if abs(t) <= AT_POINT_M:
            return "at entry"
        if self.length > 0 and abs(t - self.length) <= AT_POINT_M:
            return "at exit"
        if t < 0:
            return "behind entry"
        return "between" if t < self.length else "beyond exit"

    def hit_record(self, h: Hit) -> dict[str, Any]:
        return {"node": h.node, "face": h.face, "distance_m": round(h.t, 6), "point_m": rounded(h.point),
                "where": self.where(h.t), "angle_to_surface_deg": round(math.degrees(math.asin(min(1.0, abs(
                    float(h.normal @ self.direction))))), 3),
                "cone_radius_95_m": round(self.cone_radius(h.t), 6)}

    def record(self) -> dict[str, Any]:
        d: dict[str, Any] = {
            "entry_m": rounded(self.entry), "exit_m": rounded(self.exit) if self.length > 0 else None,
            "separation_m": round(self.length, 6), "direction": rounded(self.direction, 9),
            "azimuth_deg": round(self.azimuth_deg, 6), "elevation_deg": round(self.elevation_deg, 6),
            "sigma_m": list(self.sigma) if self.sigma else None,
            "cone_half_angle_95_deg": round(self.cone_deg, 6) if self.cone_deg is not None else None,
            "surfaces": [self.hit_record(h) for h in self.hits],
            "stops_at": self.hit_record(self.stop) if self.stop else None,
            "leaves_scene": self.stop is None,
            "leaves_scene_at_m": rounded(self.leaves_at) if self.leaves_at is not None else None,
            "from_surface": self.hit_record(self.source) if self.source else None,
            "behind_leaves_scene_at_m": rounded(self.leaves_behind_at) if self.leaves_behind_at is not None else None,
        }
        if self.cone_deg:
            d["cone_stops_at_share_by_node"] = {k: round(v, 6) for k, v in self.cone_stop_nodes.items()}
            d["cone_from_share_by_node"] = {k: round(v, 6) for k, v in self.cone_source_nodes.items()}
        return d


def _meets(occ: Occluders, h: Hit, d: Array) -> bool:
    """Whether a line going along ``d`` meets ``h`` from outside (a face's front, or a flat node)."""
    return bool(h.normal @ d < 0) or occ.hull(h.node) is None


def _first_beyond(occ: Occluders, hits: list[Hit], d: Array, t0: float, forward: bool) -> Hit | None:
    if forward:
        cand = [h for h in hits if h.t > t0 + AT_POINT_M and _meets(occ, h, d)]
        return cand[0] if cand else None
    cand = [h for h in hits if h.t < t0 - AT_POINT_M and _meets(occ, h, -d)]
    return cand[-1] if cand else None


def trajectory(occ: Occluders, entry: Array, exit: Array | None = None, direction: Array | None = None,
               sigma: tuple[float, float] | None = None, cone_deg: float | None = None) -> Trajectory:
    """The path through ``entry`` and ``exit`` (or along ``direction`` from ``entry``); see the module."""
    A = np.asarray(entry, float)
    check_in_scene(occ, A, "the entry point" if exit is not None else "the point")
    if exit is not None:
        B = np.asarray(exit, float)
        check_in_scene(occ, B, "the exit point")
        L = float(np.linalg.norm(B - A))
        if L < AT_POINT_M:
            raise VebuildError(f"the entry and exit points are {1000 * L:.1f} mm apart; a direction needs two "
                               f"points at least {1000 * AT_POINT_M:g} mm apart")
        d = (B - A) / L
    else:
        if direction is None:
            raise VebuildError("a trajectory needs an exit point or a direction (azimuth and elevation)")
        d, L = np.asarray(direction, float) / np.linalg.norm(direction), 0.0
        if sigma is not None:
            raise VebuildError("--sigma: an uncertainty from the points' σ needs two points (--from and --to); "
                               "with azimuth and elevation give the cone's half-angle (--cone DEG)")
    if sigma is not None:
        if len(sigma) != 2 or not all(math.isfinite(s) and s >= 0 for s in sigma):
            raise VebuildError(f"--sigma: expected one or two position errors ≥ 0 m, got {sigma}")
        cone_deg = math.degrees(math.atan(K95_2D * math.hypot(*sigma) / L))
    elif cone_deg is not None and not 0.0 <= cone_deg < 90.0:
        raise VebuildError(f"--cone: expected a half-angle of 0–90 degrees, got {cone_deg:g}")
    tr = Trajectory(A, d, L, (float(sigma[0]), float(sigma[1])) if sigma is not None else None, cone_deg)
    tr.hits = occ.line_hits(A, d)
    tr.stop = _first_beyond(occ, tr.hits, d, L, True)
    tr.source = _first_beyond(occ, tr.hits, d, 0.0, False)
    if tr.stop is None:
        tr.leaves_at = A + max(L, occ.exit_distance(A, d)) * d
    if tr.source is None:
        tr.leaves_behind_at = A - occ.exit_distance(A, -d) * d
    if cone_deg:
        tr.cone_stop_nodes, tr.cone_source_nodes = _cone_nodes(occ, tr)
    return tr


def _perpendiculars(d: Array) -> tuple[Array, Array]:
    a = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(d, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(d, e1)


def cone_lines(tr: Trajectory, n: int = CONE_LINES) -> tuple[Array, Array]:
    """The cone's apex and the unit directions (n, 3) of ``n`` lines on its surface (forward sense)."""
    e1, e2 = _perpendiculars(tr.direction)
    a = math.radians(tr.cone_deg or 0.0)
    phi = 2 * np.pi * np.arange(n) / n
    w = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    return tr.entry + tr.apex_t() * tr.direction, math.cos(a) * tr.direction + math.sin(a) * w


def _cone_nodes(occ: Occluders, tr: Trajectory) -> tuple[dict[str, float], dict[str, float]]:
    apex, dirs = cone_lines(tr)
    fwd: dict[str, int] = {}
    back: dict[str, int] = {}
    for k in range(len(dirs) + 1):
        dk = dirs[k] if k < len(dirs) else tr.direction
        hits = occ.line_hits(apex, dk)
        # Beyond the exit's plane (across the path) forward; behind the entry's plane backward.
        s0 = float((tr.exit - apex) @ tr.direction)
        s1 = float((tr.entry - apex) @ tr.direction)
        cos = float(dk @ tr.direction)
        f = _first_beyond(occ, hits, dk, s0 / cos, True)
        b = _first_beyond(occ, hits, dk, s1 / cos, False)
        fwd[f.node if f else "(leaves the scene)"] = fwd.get(f.node if f else "(leaves the scene)", 0) + 1
        back[b.node if b else "(leaves the scene)"] = back.get(b.node if b else "(leaves the scene)", 0) + 1
    n = len(dirs) + 1

    def share(c: dict[str, int]) -> dict[str, float]:
        return {k: v / n for k, v in sorted(c.items(), key=lambda x: -x[1])}
    return share(fwd), share(back)


# -- drawing -----------------------------------------------------------------------------------

def path_extent(tr: Trajectory) -> tuple[float, float]:
    """Signed distances from the entry of the drawn path's ends: the surface behind the entry (or
    the scene's edge) to the surface it stops at (or the scene's edge)."""
    if tr.source:
        t0 = tr.source.t
    else:
        assert tr.leaves_behind_at is not None  # set when nothing is met behind the entry
        t0 = -float(np.linalg.norm(tr.leaves_behind_at - tr.entry))
    if tr.stop:
        t1 = tr.stop.t
    else:
        assert tr.leaves_at is not None  # set when nothing is met beyond the exit
        t1 = float(np.linalg.norm(tr.leaves_at - tr.entry))
    return t0, t1


def path_polylines(tr: Trajectory, generators: int = 8, rings: int = 6, step_m: float = 0.02) -> dict[str, list[Array]]:
    """World polylines to draw: ``path`` (one (n, 3) polyline along the drawn extent) and ``cone``
    (its surface lines and rings at even spacing, following the 95 % radius); points every
    ``step_m``. This is what the walk-through draws as depth-tested lines."""
    t0, t1 = path_extent(tr)
    n = max(2, int(math.ceil((t1 - t0) / step_m)) + 1)
    t = np.linspace(t0, t1, n)
    out: dict[str, list[Array]] = {"path": [tr.entry + t[:, None] * tr.direction], "cone": []}
    if not tr.cone_deg:
        return out
    e1, e2 = _perpendiculars(tr.direction)
    r = np.array([tr.cone_radius(x) for x in t])
    for k in range(generators):
        phi = 2 * np.pi * k / generators
        w = math.cos(phi) * e1 + math.sin(phi) * e2
        out["cone"].append(tr.entry + t[:, None] * tr.direction + r[:, None] * w)
    around = np.linspace(0, 2 * np.pi, 65)
    w = np.cos(around)[:, None] * e1 + np.sin(around)[:, None] * e2
    for ring in np.linspace(t0, t1, rings + 2)[1:-1]:
        out["cone"].append(tr.entry + ring * tr.direction + tr.cone_radius(float(ring)) * w)
    return out


def _draw_polyline(draw: Any, cam: ImageCamera, occ: Occluders, P: Array, colour: tuple[int, int, int],
                   width: int) -> None:
    depth = world_to_camera(cam.R, cam.C, P)[:, 2]
    front = depth > 0.01
    seen = np.zeros(len(P), bool)
    if front.any():
        blocked, _, _ = occ.segments_blocked(np.broadcast_to(cam.C, (int(front.sum()), 3)), P[front], end_eps=0.005)
        seen[front] = ~blocked
    uv = np.full((len(P), 2), np.nan)
    uv[front] = project(cam.K, cam.R, cam.C, P[front], cam.lens)  # through the lens: the path's polyline bends
    lim = 4 * max(cam.width, cam.height)
    for i in range(len(P) - 1):
        if not (front[i] and front[i + 1]) or np.any(np.abs(uv[i:i + 2]) > lim):
            continue
        a, b = tuple(uv[i]), tuple(uv[i + 1])
        if seen[i] and seen[i + 1]:
            draw.line((a, b), fill=colour, width=width)
        elif i % 4 < 2:  # hidden: dashed and thin
            draw.line((a, b), fill=colour, width=1)


def draw_trajectory(image: NDArray[np.uint8], cam: ImageCamera, tr: Trajectory, occ: Occluders) -> NDArray[np.uint8]:
    """The path (red), its cone (orange) and the entry, exit and stopping points over a rendered
    image of ``cam``'s view; parts hidden from the camera by the model are drawn dashed."""
    from PIL import Image, ImageDraw

    img = Image.fromarray(image)
    d = ImageDraw.Draw(img)
    lines = path_polylines(tr)
    w = max(2, cam.width // 320)
    for P in lines["cone"]:
        _draw_polyline(d, cam, occ, P, (255, 150, 30), max(1, w // 2))
    _draw_polyline(d, cam, occ, lines["path"][0], (230, 20, 20), w)
    marks = [(tr.entry, (255, 255, 255))]
    if tr.length > 0:
        marks.append((tr.exit, (255, 255, 255)))
    if tr.stop is not None:
        marks.append((tr.stop.point, (230, 20, 20)))
    for X, colour in marks:
        if world_to_camera(cam.R, cam.C, X)[2] > 0.01:
            u, v = project(cam.K, cam.R, cam.C, X, cam.lens)
            r = 2 * w + 2
            d.ellipse((u - r, v - r, u + r, v + r), outline=colour, width=w)
    return np.asarray(img)


def render_trajectory_view(project: Project, scene: Any, tr: Trajectory, cam: ImageCamera, out: Path,
                           lighting: str | None = None, samples: int = 4, unobserved: str = "hatch") -> None:
    """Render ``cam``'s view headless, draw the trajectory over it, and write a PNG with provenance."""
    from vebuild.gl import headless_context
    from vebuild.project.decode import find_preset
    from vebuild.render.observed import finish_image
    from vebuild.render.png import check_output, provenance, write_png
    from vebuild.render.renderer import Renderer, RenderOptions

    out = check_output(Path(out))
    preset = find_preset(project, lighting)
    renderer = Renderer(headless_context(), scene, RenderOptions(samples=samples, unobserved=unobserved))
    try:
        renderer.set_lighting(preset)
        image = renderer.render(cam)
        marked = renderer.marks_unobserved
    finally:
        renderer.release()
    image = draw_trajectory(image, cam, tr, Occluders(scene))
    text = provenance(project, cam, "view", preset.name, None, scene.page_hashes,
                      {"samples": samples, "size": [cam.width, cam.height], "unobserved": unobserved})
    text["vebuild:trajectory"] = json.dumps(tr.record(), sort_keys=True, ensure_ascii=False)
    write_png(out, finish_image(image, unobserved, marked, text, scene.mask_hashes), text)
