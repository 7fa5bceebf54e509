"""Sight lines (paper §5.1, witness statement evaluation).

A witness's eye is a world point, or a person standing (eyes :data:`STANDING_EYE_M` above the
floor) or sitting (:data:`SITTING_EYE_M`) at a floor spot. A target is a world point, or an object
(a node of the model and its descendants). Visibility is decided by exact ray casting against the
model's triangles (:mod:`vebuild.analysis.rays`), never by sampling an image:

- a target point is visible when the segment from the eye to it crosses no surface (surfaces within
  1 mm of either end do not count, so a mark on a wall is seen from the wall's front);
- an object's visible share is the share of its surface area seen from the eye: its faces are
  sampled uniformly by area (a seeded, reproducible sample of :data:`OBJECT_SAMPLES` points); a
  sample is seen when it faces the eye and the segment to it is clear. The share carries its 95 %
  sampling interval (Wilson score interval).

The witness's view is rendered headless with the target highlighted; its PNG carries its
provenance. The same question asked from every place on the floor is a viewshed
(:mod:`vebuild.analysis.viewshed`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from vebuild.analysis.observed import blocker_unobserved, object_rays
from vebuild.analysis.rays import Occluders
from vebuild.camera import ImageCamera, fov_to_focal, intrinsic_matrix, look_rotation, project, world_to_camera
from vebuild.constants import Z95
from vebuild.errors import VebuildError
from vebuild.render.scene import RenderScene

if TYPE_CHECKING:
    from vebuild.model.scene import Model
    from vebuild.project import Project


Array = NDArray[np.float64]

STANDING_EYE_M = 1.6
SITTING_EYE_M = 1.2
#: Samples of an object's surface for a sight line.
OBJECT_SAMPLES = 4000
#: Seed of the surface samples (the same project gives the same figures).
SAMPLE_SEED = 0
DEFAULT_FOV_DEG = 60.0


# -- inputs ------------------------------------------------------------------------------------

def parse_floats(text: str, n: int, option: str) -> Array:
    """'1.5,2,0.3' → array of ``n`` floats; a clear error naming ``option`` otherwise."""
    parts = [p for p in str(text).replace(" ", "").split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != n or not all(math.isfinite(v) for v in values):
        shape = ",".join("XYZ"[:n]) if n <= 3 else f"{n} numbers"
        raise VebuildError(f"{option}: expected {shape} in metres, separated by commas (such as "
                           f"{','.join(['1.5', '2.0', '1.6'][:n])}), got {text!r}")
    return np.array(values)


@dataclass(frozen=True)
class Eye:
    """Where the witness's eye is: ``position`` (world, m); ``kind`` 'point', 'standing' or
    'sitting'; the floor ``spot`` (x, y) and eye height for a person."""

    position: Array
    kind: str = "point"
    spot: tuple[float, float] | None = None
    height: float | None = None

    @classmethod
    def person(cls, x: float, y: float, posture: str = "standing") -> Eye:
        h = {"standing": STANDING_EYE_M, "sitting": SITTING_EYE_M}.get(posture)
        if h is None:
            raise VebuildError(f"posture: expected standing or sitting, got {posture!r}")
        return cls(np.array([x, y, h], float), posture, (float(x), float(y)), h)

    def record(self) -> dict[str, Any]:
        d: dict[str, Any] = {"kind": self.kind, "position_m": rounded(self.position)}
        if self.spot is not None:
            d["spot_m"] = rounded(self.spot)
            d["eye_height_m"] = self.height
        return d


@dataclass(frozen=True)
class Target:
    """A target: a world ``point``, or the object ``node`` (its ``nodes``: it and its descendants
    that have faces)."""

    point: Array | None = None
    node: str | None = None
    nodes: tuple[str, ...] = ()

    @property
    def label(self) -> str:
        if self.node is not None:
            return f"'{self.node}'"
        assert self.point is not None  # a target is a point or an object
        return "(" + ", ".join(f"{v:.3f}" for v in self.point) + ")"

    def record(self) -> dict[str, Any]:
        if self.node is not None:
            return {"object": self.node, "nodes": list(self.nodes)}
        return {"point_m": rounded(self.point)}


def rounded(v: Any, nd: int = 6) -> list[float]:
    """A vector as the JSON records write it: ``nd`` decimals, never -0.0."""
    return [round(float(x), nd) + 0.0 for x in v]  # + 0.0: no "-0.0"


def scene_margin(occ: Occluders) -> float:
    """How far outside the scene's bounding box a point may be: the box's diagonal (a witness in
    the street outside a window is fine; one 100 m away is a typing error)."""
    lo, hi = occ.bounds()
    return float(np.linalg.norm(hi - lo))


def check_in_scene(occ: Occluders, point: Array, what: str) -> None:
    """An error if ``point`` is off the scene (see :func:`scene_margin`) or below the floor."""
    lo, hi = occ.bounds()
    m = scene_margin(occ)
    p = np.asarray(point, float)
    if np.any(p < lo - m) or np.any(p > hi + m):
        u = occ.unit.symbol
        raise VebuildError(f"{what} ({', '.join(f'{v:g}' for v in p)}) is off the scene: the model spans "
                           f"x {lo[0]:.2f}…{hi[0]:.2f}, y {lo[1]:.2f}…{hi[1]:.2f}, z {lo[2]:.2f}…{hi[2]:.2f} {u} "
                           f"(points up to {m:.1f} {u} outside it are accepted"
                           + (f"; {occ.unit.note}" if occ.unit.relative else "") + ")")
    if p[2] < -1e-9 and len(p) == 3:
        raise VebuildError(f"{what} ({', '.join(f'{v:g}' for v in p)}) is below the floor (z < 0)")


def check_eye(occ: Occluders, eye: Eye) -> None:
    """An error if the eye is off the scene or inside an object."""
    what = f"the eye of the person {eye.kind} at ({eye.spot[0]:g}, {eye.spot[1]:g})" if eye.spot else "the eye point"
    check_in_scene(occ, eye.position, what)
    inside = occ.inside(eye.position)[0]
    if inside is not None:
        raise VebuildError(f"{what} ({', '.join(f'{v:g}' for v in eye.position)}) is inside the object "
                           f"'{inside}'; a witness cannot see from there; choose another place")


def target_point(occ: Occluders, point: Sequence[float]) -> Target:
    p = np.asarray(point, float)
    check_in_scene(occ, p, "the target point")
    inside = occ.inside(p)[0]
    if inside is not None:
        raise VebuildError(f"the target point ({', '.join(f'{v:g}' for v in p)}) is inside the object "
                           f"'{inside}' and cannot be seen; choose a point on its surface, or the object "
                           f"itself (--object {inside})")
    return Target(point=p)


def lighting_target(model: Model, target: str) -> None:
    """A lighting comparison's ``--target``: a node of ``model`` (a VebuildError listing them if not)."""
    if target not in model.index:
        known = ", ".join(repr(n.name) for n in model.nodes)
        raise VebuildError(f"the target {target!r} is no node of the model; the nodes are: {known}")


def target_object(occ: Occluders, node: str) -> Target:
    model = occ.scene.model
    if node not in model.index:
        known = ", ".join(n for n in occ.node_names)
        raise VebuildError(f"--object: the model has no node called {node!r}; the objects are: {known}")
    nodes = tuple(n for n in model.subtree(node) if len(occ.triangles_of(n)))
    if not nodes:
        raise VebuildError(f"--object: the node {node!r} has no surfaces (no primitive, nor any below it)")
    return Target(node=node, nodes=nodes)


def sample_surface(occ: Occluders, nodes: Sequence[str], n: int, seed: int = SAMPLE_SEED) -> tuple[Array, Array]:
    """``n`` points uniformly by area over the nodes' triangles, and their outward normals."""
    P, N, _ = sample_surface_triangles(occ, nodes, n, seed)
    return P, N


def sample_surface_triangles(occ: Occluders, nodes: Sequence[str], n: int,
                             seed: int = SAMPLE_SEED) -> tuple[Array, Array, NDArray[np.intp]]:
    """:func:`sample_surface`, and the triangle each point lies on."""
    tris = np.concatenate([occ.triangles_of(x) for x in nodes])
    area = occ.area[tris]
    rng = np.random.default_rng(seed)
    pick = tris[rng.choice(len(tris), size=n, p=area / area.sum())]
    a, b = rng.random(n), rng.random(n)
    flip = a + b > 1.0
    a[flip], b[flip] = 1.0 - a[flip], 1.0 - b[flip]
    P = occ.v0[pick] + a[:, None] * occ.e1[pick] + b[:, None] * occ.e2[pick]
    return P, occ.normal[pick], pick


def wilson95(k: int, n: int) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion k / n."""
    if n == 0:
        return (0.0, 1.0)
    p, z2 = k / n, Z95 ** 2
    c = (p + z2 / (2 * n)) / (1 + z2 / n)
    h = Z95 * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    return max(0.0, c - h), min(1.0, c + h)


# -- one sight line ----------------------------------------------------------------------------

@dataclass
class SightLine:
    """The answer for one eye and one target (see the module's docstring).

    visible : a point: whether it is seen; an object: whether any of it is seen.
    visible_share, share_ci95, samples : an object: the share of its surface area seen, its 95 %
        sampling interval and the number of samples (None for a point).
    distance_m : eye to the target point, or to the centre of the object's surface.
    blocker : the nearest surface in the way: node, face, distance from the eye (m), point (None if
        nothing blocks: a visible point, or an object whose every front-facing sample is seen).
    blocked_by : an object: the share of its samples hidden by each node (first surface in the way).
    unobserved : an object: which part of the answer rests on surfaces no photo saw
        (:func:`vebuild.analysis.observed.object_rays`; None where the scene cannot tell). A
        blocker says the same of itself in its ``"unobserved"`` (True, False or None).
    """

    eye: Eye
    target: Target
    visible: bool
    distance_m: float
    visible_share: float | None = None
    share_ci95: tuple[float, float] | None = None
    samples: int | None = None
    facing_share: float | None = None
    blocker: dict[str, Any] | None = None
    blocked_by: dict[str, float] = field(default_factory=dict)
    unobserved: dict[str, Any] | None = None

    def record(self) -> dict[str, Any]:
        d: dict[str, Any] = {"eye": self.eye.record(), "target": self.target.record(), "visible": self.visible,
                             "distance_m": round(self.distance_m, 6)}
        if self.visible_share is not None:  # an object target: its share, interval and facing share
            assert self.share_ci95 is not None and self.facing_share is not None
            d.update({"visible_share": round(self.visible_share, 6),
                      "visible_share_ci95": [round(v, 6) for v in self.share_ci95],
                      "facing_share": round(self.facing_share, 6), "samples": self.samples,
                      "blocked_share_by_node": {k: round(v, 6) for k, v in self.blocked_by.items()},
                      "unobserved": self.unobserved})
        d["blocker"] = self.blocker
        return d


def _blocker(occ: Occluders, eye: Array, t: float, tri: int, end: Array) -> dict[str, Any]:
    return {"node": occ.node_of(tri), "face": occ.face_of(tri), "distance_from_eye_m": round(float(t), 6),
            "point_m": None, "unobserved": blocker_unobserved(occ, eye, end, float(t), int(tri))}


def sight_line(occ: Occluders, eye: Eye, target: Target, samples: int = OBJECT_SAMPLES,
               seed: int = SAMPLE_SEED) -> SightLine:
    """Is ``target`` visible from ``eye``? (See :class:`SightLine`.) Checks the eye first."""
    check_eye(occ, eye)
    E = eye.position
    if target.point is not None:
        T = target.point
        blocked, t, tri = occ.segments_blocked(E[None], T[None])
        res = SightLine(eye, target, not bool(blocked[0]), float(np.linalg.norm(T - E)))
        if blocked[0]:
            res.blocker = _with_point(_blocker(occ, E, t[0], tri[0], T), E, T, t[0])
        return res
    P, N, on_tri = sample_surface_triangles(occ, target.nodes, samples, seed)
    facing = np.einsum("ij,ij->i", E - P, N) > 0.0
    vis = np.zeros(len(P), bool)
    t = np.full(len(P), np.inf)
    tri = np.full(len(P), -1, np.intp)
    idx = np.flatnonzero(facing)
    if len(idx):
        b, t[idx], tri[idx] = occ.segments_blocked(np.broadcast_to(E, (len(idx), 3)), P[idx])
        vis[idx] = ~b
    k = int(vis.sum())
    centre = P.mean(axis=0)
    res = SightLine(eye, target, k > 0, float(np.linalg.norm(centre - E)), k / len(P), wilson95(k, len(P)),
                    len(P), float(facing.mean()))
    res.unobserved = object_rays(occ, E, P, facing, vis, t, tri, on_tri)
    hidden = np.flatnonzero(facing & ~vis)
    if len(hidden):
        nodes = [occ.node_of(i) for i in tri[hidden]]
        names, counts = np.unique(nodes, return_counts=True)
        res.blocked_by = {str(a): float(c) / len(P) for a, c in sorted(zip(names, counts, strict=True),
                                                                        key=lambda x: -x[1])}
        j = hidden[np.argmin(t[hidden])]
        res.blocker = _with_point(_blocker(occ, E, t[j], tri[j], P[j]), E, P[j], t[j])
    return res


def _with_point(b: dict[str, Any], E: Array, T: Array, t: float) -> dict[str, Any]:
    d = (T - E) / np.linalg.norm(T - E)
    b["point_m"] = rounded(E + t * d)
    return b


# -- the witness's view ------------------------------------------------------------------------

def witness_camera(eye: Eye, look_at: Array, fov_deg: float = DEFAULT_FOV_DEG,
                   size: tuple[int, int] = (1280, 720), source: str = "--size") -> ImageCamera:
    """An :class:`ImageCamera` at the eye looking at ``look_at`` (horizontal field of view ``fov_deg``);
    ``source``: where ``size`` came from."""
    if not 1.0 <= fov_deg <= 170.0:
        raise VebuildError(f"--fov: expected a horizontal field of view of 1–170°, got {fov_deg:g}")
    w, h = size
    f = fov_to_focal(math.radians(fov_deg), w)
    K = intrinsic_matrix(f, w / 2, h / 2)
    return ImageCamera("witness", K, look_rotation(np.asarray(look_at, float) - eye.position), eye.position, w, h,
                       source=source)


def target_centre(occ: Occluders, target: Target) -> Array:
    if target.point is not None:
        return target.point
    tris = np.concatenate([occ.triangles_of(x) for x in target.nodes])
    c = occ.v0[tris] + (occ.e1[tris] + occ.e2[tris]) / 3.0
    return (c * occ.area[tris, None]).sum(axis=0) / occ.area[tris].sum()


def draw_point_marker(image: NDArray[np.uint8], cam: ImageCamera, point: Array, visible: bool,
                      colour: tuple[int, int, int] = (255, 190, 0)) -> NDArray[np.uint8]:
    """A cross-hair ring at a world point (solid if visible, dashed otherwise), where ``cam``'s lens
    puts it."""
    from PIL import Image, ImageDraw

    if world_to_camera(cam.R, cam.C, point)[2] <= 0:
        return image
    u, v = project(cam.K, cam.R, cam.C, point, cam.lens)
    img = Image.fromarray(image)
    d = ImageDraw.Draw(img)
    r = max(6, cam.width // 80)
    w = max(2, cam.width // 400)
    for k in range(0, 360, 1 if visible else 30):
        d.arc((u - r, v - r, u + r, v + r), k, k + (1 if visible else 18), fill=colour, width=w)
    for a, b in (((u - 2 * r, v), (u - r / 2, v)), ((u + r / 2, v), (u + 2 * r, v)),
                 ((u, v - 2 * r), (u, v - r / 2)), ((u, v + r / 2), (u, v + 2 * r))):
        d.line((a, b), fill=colour, width=w)
    return np.asarray(img)


def render_witness_view(project: Project, scene: RenderScene, result: SightLine, out: Path,
                        fov_deg: float = DEFAULT_FOV_DEG, size: tuple[int, int] = (1280, 720),
                        lighting: str | None = None, samples: int = 4,
                        extra_text: dict[str, str] | None = None, unobserved: str = "hatch") -> ImageCamera:
    """Render the witness's view of ``result`` to ``out`` (PNG with provenance); the target object
    is highlighted (for a group, its largest part: the renderer highlights one node), a target
    point marked by a ring (dashed when hidden)."""
    from vebuild.gl import headless_context
    from vebuild.project.decode import find_preset
    from vebuild.render.observed import finish_image
    from vebuild.render.png import check_output, provenance, write_png
    from vebuild.render.renderer import Renderer, RenderOptions

    out = check_output(Path(out))
    occ = Occluders(scene)
    cam = witness_camera(result.eye, target_centre(occ, result.target), fov_deg, size)
    preset = find_preset(project, lighting)
    renderer = Renderer(headless_context(), scene, RenderOptions(samples=samples, unobserved=unobserved))
    try:
        renderer.set_lighting(preset)
        if result.target.node is not None:
            renderer.highlight = max(result.target.nodes, key=lambda n: occ.area[occ.triangles_of(n)].sum())
        image = renderer.render(cam)
        marked = renderer.marks_unobserved
    finally:
        renderer.release()
    if result.target.point is not None:
        image = draw_point_marker(image, cam, result.target.point, result.visible)
    options = {"samples": samples, "size": [cam.width, cam.height], "fov_deg": fov_deg, "unobserved": unobserved}
    text = provenance(project, cam, "witness", preset.name, None, scene.page_hashes, options)
    text["vebuild:sightline"] = json.dumps(result.record(), sort_keys=True, ensure_ascii=False)
    text.update(extra_text or {})
    write_png(out, finish_image(image, unobserved, marked, text, scene.mask_hashes), text)
    return cam
