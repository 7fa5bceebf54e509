"""Evidence markers (paper §5.1): labelled points placed on the model's surfaces, shown in every view.

A marker (FORMAT.md, ``evidence_markers``) has a label, a world position on a surface and the node
it lies on. It is placed from a pixel of a photo or a named view (the surface seen there, through
the renderer's ID buffer) or from a world point, which must lie on a surface (within
:data:`ON_SURFACE_M`). Drawn over a rendered image, a marker is a numbered pin with its label;
one hidden behind something from that view is drawn hollow.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image, ImageDraw, ImageFont

from vebuild.camera import PINHOLE, ImageCamera, project, world_to_camera
from vebuild.errors import VebuildError
from vebuild.render.renderer import Renderer
from vebuild.render.scene import RenderScene

if TYPE_CHECKING:
    from vebuild.project import Project


#: A world point farther than this from every surface is not "on a surface".
ON_SURFACE_M = 0.01
#: A marker is visible from a view when nothing lies more than this in front of it.
OCCLUSION_MARGIN_M = 0.02
MARKER_COLOUR = (230, 30, 200)
#: The farthest a world point given for a marker may lie from the origin in any axis: the project
#: file's bound on every position (FORMAT.md, "Bounds"), so that a marker placed is one it can keep.
MAX_COORDINATE_M = 1e4


def nearest_surface(scene: RenderScene, point: NDArray[np.float64]) -> tuple[str, NDArray[np.float64], float]:
    """The node whose surface is nearest to a world point, the nearest surface point, its distance."""
    import trimesh

    mesh = trimesh.Trimesh(scene.mesh.vertices, scene.mesh.triangles, process=False)
    closest, dist, tri = trimesh.proximity.closest_point(mesh, np.asarray(point, float)[None])
    face = scene.mesh.triangle_faces[int(tri[0])]
    return scene.mesh.faces[face - 1].node, closest[0], float(dist[0])


def marker_at_point(scene: RenderScene, label: str, point: Any, description: str = "") -> dict[str, Any]:
    node, closest, dist = nearest_surface(scene, np.asarray(point, float))
    if dist > ON_SURFACE_M:
        shown = [round(float(v), 4) for v in point]
        raise VebuildError(f"evidence marker {label!r}: the point {shown} is {dist:.3f} m from "
                           f"the nearest surface ({node!r}); expected a point on a surface (within "
                           f"{ON_SURFACE_M} m). Place it from a pixel of a photo or view instead")
    return _record(label, closest, node, description)


def marker_at_pixel(renderer: Renderer, cam: ImageCamera, label: str, uv: Sequence[float],
                    description: str = "") -> dict[str, Any]:
    node, point = renderer.pick(cam, float(uv[0]), float(uv[1]))
    if node is None:
        raise VebuildError(f"evidence marker {label!r}: pixel ({uv[0]}, {uv[1]}) of {cam.id!r} shows no surface of "
                           "the model (a point off every surface)")
    return _record(label, point, node, description)


def _record(label: str, point: Any, node: str, description: str) -> dict[str, Any]:
    rec: dict[str, Any] = {"label": label, "position": [round(float(v), 6) for v in point], "node": node}
    if description:
        rec["description"] = description
    return rec


def place_marker(project: Project, label: str, at: str, description: str = "") -> dict[str, Any]:
    """A marker at ``at``: ``X,Y,Z`` (a world point on a surface), ``photo:ID@u,v`` or
    ``view:NAME@u,v`` (the surface seen at that pixel of a photo's camera or a named view)."""
    from vebuild.gl import headless_context
    from vebuild.project.decode import find_view, photo_camera
    from vebuild.render.renderer import RenderOptions
    from vebuild.render.scene import load_scene

    scene = load_scene(project)
    kind, _, rest = at.partition(":")
    if kind in ("photo", "view") and "@" in rest:
        name, _, uv_text = rest.rpartition("@")
        try:
            uv = [float(x) for x in uv_text.split(",")]
        except ValueError:
            uv = []
        if len(uv) != 2 or not all(math.isfinite(v) for v in uv):
            raise VebuildError(f"--at {at!r}: evidence marker {label!r}: expected "
                               f"{kind}:{'ID' if kind == 'photo' else 'NAME'}@u,v with u, v finite numbers of pixels")
        cam = photo_camera(project, name) if kind == "photo" else find_view(project, name)
        renderer = Renderer(headless_context(), scene, RenderOptions(samples=1))
        try:
            return marker_at_pixel(renderer, cam, label, uv, description)
        finally:
            renderer.release()
    try:
        point = [float(x) for x in at.split(",")]
    except ValueError:
        point = []
    if len(point) != 3:
        raise VebuildError(f"--at {at!r}: expected X,Y,Z in metres, photo:ID@u,v or view:NAME@u,v")
    if not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE_M for v in point):
        raise VebuildError(f"--at {at!r}: evidence marker {label!r}: expected X,Y,Z finite numbers of metres, "
                           f"each within ±{MAX_COORDINATE_M:g} m")
    return marker_at_point(scene, label, point, description)


def add_marker(project: Project, rec: dict[str, Any]) -> None:
    """Add (or replace, by label) a marker in the project's data; the caller saves the file."""
    markers = [m for m in project.data.get("evidence_markers", []) if m["label"] != rec["label"]]
    project.data["evidence_markers"] = markers + [rec]


def visible_markers(renderer: Renderer, cam: ImageCamera,
                    markers: Sequence[dict[str, Any]]) -> list[tuple[dict[str, Any], NDArray[np.float64], bool]]:
    """Markers in the image: each with its pixel position (where ``cam``'s lens puts it) and whether
    it is seen (not hidden). Each is tested through a one-pixel ID buffer on its own ray (the
    pinhole pixel of that ray, asked of the pinhole camera, whatever the lens), so a frame loop
    can afford it."""
    pinhole = dataclasses.replace(cam, lens=PINHOLE)
    out = []
    for m in markers:
        X = np.asarray(m["position"], float)
        z = float(world_to_camera(cam.R, cam.C, X)[2])
        if z <= 0:
            continue
        uv = project(cam.K, cam.R, cam.C, X, cam.lens)
        if not (0 <= uv[0] < cam.width and 0 <= uv[1] < cam.height):
            continue
        ray = project(cam.K, cam.R, cam.C, X) if not cam.lens.is_pinhole else uv
        _, seen = renderer.pick(pinhole, float(ray[0]), float(ray[1]))
        seen_depth = float(world_to_camera(cam.R, cam.C, seen)[2]) if seen is not None else np.inf
        out.append((m, uv, z <= seen_depth + OCCLUSION_MARGIN_M))
    return out


def draw_markers(image: NDArray[np.uint8], placed: Sequence[tuple[dict[str, Any], NDArray[np.float64], bool]]
                 ) -> NDArray[np.uint8]:
    """Pins with labels over an image; hidden markers hollow."""
    if not placed:
        return image
    img = Image.fromarray(image, "RGB")
    draw = ImageDraw.Draw(img)
    size = max(11, img.height // 45)
    font = ImageFont.load_default(size=size)
    r = max(4, size // 2)
    for m, (u, v), visible in placed:
        box = (u - r, v - r, u + r, v + r)
        if visible:
            draw.ellipse(box, fill=MARKER_COLOUR, outline=(255, 255, 255), width=2)
        else:
            draw.ellipse(box, outline=MARKER_COLOUR, width=2)
        text = m["label"] + ("" if visible else " (hidden)")
        tb = draw.textbbox((u + r + 3, v - size), text, font=font)
        draw.rectangle((tb[0] - 2, tb[1] - 1, tb[2] + 2, tb[3] + 1), fill=(255, 255, 255))
        draw.text((u + r + 3, v - size), text, fill=(0, 0, 0), font=font)
    return np.asarray(img)
