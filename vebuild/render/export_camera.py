"""One calibrated photo as a glTF 2.0 scene with no model: ``vebuild export PROJECT --camera PHOTO
--out FILE.glb`` (docs/export.md).

The file holds, under the root node ``vebuild world`` that turns vebuild's +Z-up world into glTF's
+Y-up one exactly as the model's export does (:mod:`vebuild.render.export`):

- the photo's camera (``photo ID``): a perspective camera, ``yfov`` from f and the photo's height,
  ``aspectRatio`` its width over its height, ``znear`` :data:`~vebuild.render.export.ZNEAR_M` and a
  ``zfar`` beyond the photo plane; its ``extras`` as the model export writes them (K, the
  principal point's offset, the lens distortion);
- the **photo plane** (``photo ID plane``), a child of the camera node: a mesh at depth ``d`` in
  front of the camera (beyond every other thing in the file), textured with the photo (unlit), each
  of its vertices on the ray of the photo pixel whose texture coordinate it carries. A glTF camera
  cannot shift its principal point, so a viewer that uses the glTF camera as it is frames the
  photo off centre by the principal point's offset, yet every pixel still lies on its own ray: what
  the file's geometry shows lines up with the photo. The plane at depth d is the pinhole image
  plane scaled by d / f; with lens distortion (k1 ≠ 0) the vertices are the rays of a grid of the
  photo's pixels *undistorted* (division model), so the texture, stretched between them, is the
  photo undistorted to the pinhole camera the glTF holds; the grid is refined until the straight
  texture interpolation between vertices is within :data:`PLANE_ERROR_PX` of the exact
  undistortion everywhere (the figure reached is in the plane node's ``extras``);
- the **floor grid** (``floor grid (z = 0)``): lines every ``spacing`` (1 m, or 1 relative unit,
  coarser over large floors) over the floor the photo shows, through the world's origin;
- the **axes** (``axes``): +x red, +y green, +z blue from the origin, one grid spacing long;
- each saved single-view **measurement** as a line node named by its label (value, 1σ and 95 %
  interval), with the figures and the command's words in its ``extras``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild import __version__
from vebuild.camera import ImageCamera, distort_pixels, focal_to_fov, undistort_normalised
from vebuild.project import Project
from vebuild.project.handoff_image import HandoffImage
from vebuild.project.provenance import inputs_sha256
from vebuild.render.export import (
    _ARRAY_BUFFER,
    _CLAMP_TO_EDGE,
    _LINEAR,
    GL_FROM_CV,
    ROOT_NAME,
    ROOT_QUATERNION,
    ZNEAR_M,
    _Buffer,
    _trs,
    distortion_extras,
)

Array = NDArray[np.float64]

#: Longest side of the photo embedded as the plane's texture (pixels): what every GPU takes.
MAX_TEXTURE_PX = 4096
#: The photo plane's texture follows the exact undistortion within this (photo pixels).
PLANE_ERROR_PX = 0.05
#: The floor grid covers the floor the photo shows up to this many camera heights from the camera.
GRID_REACH_HEIGHTS = 15.0
#: At most this many grid cells along a side: the spacing grows (1, 2, 5, 10, ...) until it fits.
GRID_MAX_CELLS = 40
#: The photo plane lies this much beyond the farthest other thing drawn; zfar this much beyond it.
PLANE_MARGIN = 1.25
#: Line colours (linear RGB): floor grid, measurements; the axes are red, green and blue.
GRID_RGB = (0.75, 0.75, 0.75)
MEASURE_RGB = (0.05, 0.53, 1.0)
_LINES, _TRIANGLES = 1, 4
_UNSIGNED_INT = np.uint32


@dataclass
class SceneLine:
    """A line to draw: its node name (the label) and its world ends, with the node's extras."""

    name: str
    ends: Array  # (2, 3) vebuild world
    extras: dict[str, Any] = field(default_factory=dict)


@dataclass
class CameraScene:
    """What a camera-only scene was made of (for the command line and the web viewer)."""

    photo: str
    plane_distance: float
    plane_error_px: float
    plane_grid: tuple[int, int]
    grid_spacing: float
    grid_bounds: tuple[float, float, float, float]  # x0, x1, y0, y1
    lines: int
    image_note: str


# -- geometry ----------------------------------------------------------------------------------------


def floor_extent(cam: ImageCamera, points: list[Array]) -> tuple[float, tuple[float, float, float, float]]:
    """The grid's spacing and bounds (x0, x1, y0, y1): the floor the photo shows within
    :data:`GRID_REACH_HEIGHTS` camera heights, the origin, the camera's foot and ``points``."""
    from vebuild.camera import pixel_rays_world

    C = np.asarray(cam.C, float)
    h = abs(float(C[2])) or 1.0
    u, v = np.meshgrid(np.linspace(0, cam.width, 17), np.linspace(0, cam.height, 13))
    d = pixel_rays_world(cam.K, cam.R, np.stack([u.ravel(), v.ravel()], axis=1), cam.lens)
    xy = [np.zeros(2), C[:2]] + [np.asarray(p, float)[:2] for p in points]
    if C[2] > 0:
        down = d[:, 2] < -1e-3
        hits = C + d[down] * (-C[2] / d[down, 2])[:, None]
        near = np.linalg.norm(hits[:, :2] - C[:2], axis=1) <= GRID_REACH_HEIGHTS * h
        xy += list(hits[near, :2])
    P = np.array(xy)
    lo, hi = P.min(axis=0), P.max(axis=0)
    size = float(max(hi - lo)) or 1.0
    spacing = 1.0
    for step in (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0):
        spacing = step
        if step >= 1.0 and size / step <= GRID_MAX_CELLS:
            break
    lo = np.floor(lo / spacing) * spacing
    hi = np.ceil(hi / spacing) * spacing
    return spacing, (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1]))


def grid_lines(spacing: float, bounds: tuple[float, float, float, float]) -> Array:
    """The floor grid as line segments (n, 2, 3)."""
    x0, x1, y0, y1 = bounds
    xs = np.arange(round((x1 - x0) / spacing) + 1) * spacing + x0
    ys = np.arange(round((y1 - y0) / spacing) + 1) * spacing + y0
    segs = [[[x, y0, 0.0], [x, y1, 0.0]] for x in xs] + [[[x0, y, 0.0], [x1, y, 0.0]] for y in ys]
    return np.array(segs, float)


def _plane_mesh(cam: ImageCamera, n: int) -> tuple[Array, Array, NDArray[np.int64]]:
    """The photo plane at depth 1 in vebuild's camera frame over an n-cell grid along the longer side:
    positions (k, 3), texture coordinates (k, 2) and triangles."""
    W, H = cam.width, cam.height
    nu = max(1, round(n * W / max(W, H)))
    nv = max(1, round(n * H / max(W, H)))
    u, v = np.meshgrid(np.linspace(0.0, W, nu + 1), np.linspace(0.0, H, nv + 1))
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    K = np.asarray(cam.K, float)
    x = undistort_normalised((uv - K[:2, 2]) / K[0, 0], cam.lens)
    pos = np.c_[x, np.ones(len(x))]
    tex = uv / np.array([W, H], float)
    idx = np.arange(len(uv)).reshape(nv + 1, nu + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tris = np.concatenate([np.stack([a, d, b], 1), np.stack([b, d, c], 1)])
    return pos, tex, tris.astype(np.int64)


def plane_error_px(cam: ImageCamera, pos: Array, tex: Array, tris: NDArray[np.int64]) -> float:
    """The largest distance (photo pixels) between where the plane's straight interpolation takes
    the texture and the exact undistortion, at each triangle's centroid and edge midpoints."""
    K = np.asarray(cam.K, float)
    scale = np.array([cam.width, cam.height], float)
    worst = 0.0
    for w in ([1 / 3, 1 / 3, 1 / 3], [0.5, 0.5, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]):
        wa = np.asarray(w)
        p = np.einsum("k,tkj->tj", wa, pos[tris])  # on the plane at depth 1: normalised pinhole coordinates
        t = np.einsum("k,tkj->tj", wa, tex[tris]) * scale
        exact = distort_pixels(K, p[:, :2] * K[0, 0] + K[:2, 2], cam.lens)
        worst = max(worst, float(np.max(np.linalg.norm(exact - t, axis=1))))
    return worst


def photo_plane(cam: ImageCamera) -> tuple[Array, Array, NDArray[np.int64], float]:
    """The photo plane at depth 1 (see :func:`_plane_mesh`), refined until within :data:`PLANE_ERROR_PX`."""
    n = 1
    while True:
        pos, tex, tris = _plane_mesh(cam, n)
        err = 0.0 if cam.lens.is_pinhole else plane_error_px(cam, pos, tex, tris)
        if err <= PLANE_ERROR_PX or n >= 512:
            return pos, tex, tris, err
        n *= 2


# -- the document ------------------------------------------------------------------------------------


def _unlit(name: str, rgb: tuple[float, float, float] | None = None, texture: int | None = None) -> dict[str, Any]:
    pbr: dict[str, Any] = {"metallicFactor": 0.0, "roughnessFactor": 1.0}
    if rgb is not None:
        pbr["baseColorFactor"] = [*rgb, 1.0]
    if texture is not None:
        pbr["baseColorTexture"] = {"index": texture}
    return {"name": name, "pbrMetallicRoughness": pbr, "doubleSided": True, "extensions": {"KHR_materials_unlit": {}}}


def _lines_primitive(buf: _Buffer, segs: Array, material: int, colours: Array | None = None) -> dict[str, Any]:
    pts = segs.reshape(-1, 3).astype(np.float32)
    attributes = {"POSITION": buf.accessor(pts, "VEC3", _ARRAY_BUFFER, bounds=True)}
    if colours is not None:
        attributes["COLOR_0"] = buf.accessor(colours.reshape(-1, 3).astype(np.float32), "VEC3", _ARRAY_BUFFER)
    return {"attributes": attributes, "material": material, "mode": _LINES}


def camera_document(project: Project, cam: ImageCamera, image: HandoffImage,
                    lines: list[SceneLine]) -> tuple[dict[str, Any], bytes, CameraScene]:
    """The camera-only glTF document, its binary chunk and what it holds (module docstring)."""
    from vebuild.project.units import RELATIVE_UNITS, length_unit

    unit = length_unit(project.data)
    units = RELATIVE_UNITS if unit.relative else "metres"
    buf = _Buffer()
    name = f"photo {cam.id}"
    R, C = np.asarray(cam.R, float), np.asarray(cam.C, float)
    spacing, bounds = floor_extent(cam, [p for line in lines for p in line.ends])
    grid = grid_lines(spacing, bounds)
    axes = np.array([[[0, 0, 0], [spacing, 0, 0]], [[0, 0, 0], [0, spacing, 0]], [[0, 0, 0], [0, 0, spacing]]], float)
    drawn = np.concatenate([grid.reshape(-1, 3), axes.reshape(-1, 3)] + [ln.ends for ln in lines])
    depth = float(np.max((drawn - C) @ R.T[:, 2]))
    d = PLANE_MARGIN * max(depth, 2.0 * abs(C[2]), 1.0)
    pos, tex, tris, err = photo_plane(cam)

    materials = [_unlit(f"{name} (the photo)", texture=0), _unlit("floor grid", GRID_RGB),
                 _unlit("axes (vertex colours)", (1.0, 1.0, 1.0)), _unlit("measurement", MEASURE_RGB)]
    doc: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": f"vebuild {__version__}", "extras": {
            "project": project.path.name, "inputs_sha256": inputs_sha256(project.data),
            "units": "relative" if unit.relative else "metre", "contents": f"the calibrated camera of photo "
            f"{cam.id!r} with no model: the photo as a plane at the camera's frustum, the floor grid (z = 0), the "
            "axes and the saved single-view measurements",
            "world": "vebuild: right-handed, +Z up; the root node 'vebuild world' rotates it to glTF's +Y up",
            "photo_image": image.note}},
        "extensionsUsed": ["KHR_materials_unlit"],
        "scene": 0,
        "scenes": [{"name": str(project.data.get("name") or project.path.name), "nodes": [0]}],
        "nodes": [{"name": ROOT_NAME, "rotation": ROOT_QUATERNION, "children": [],
                   "extras": {"note": f"turns vebuild's world (right-handed, {units}, +Z up) into glTF's +Y up"}}],
        "materials": materials,
        "samplers": [{"magFilter": _LINEAR, "minFilter": _LINEAR, "wrapS": _CLAMP_TO_EDGE, "wrapT": _CLAMP_TO_EDGE}],
        "images": [{"name": f"photo {cam.id}", "mimeType": image.mime, "bufferView": buf.view(image.data)}],
        "textures": [{"name": f"photo {cam.id}", "sampler": 0, "source": 0}],
    }
    meshes: list[dict[str, Any]] = []

    def add(node: dict[str, Any], mesh: dict[str, Any] | None = None, parent: int = 0) -> int:
        if mesh is not None:
            meshes.append(mesh)
            node["mesh"] = len(meshes) - 1
        doc["nodes"].append(node)
        doc["nodes"][parent].setdefault("children", []).append(len(doc["nodes"]) - 1)
        return len(doc["nodes"]) - 1

    # The camera, and the photo plane in its frame (glTF camera axes: x right, y up, looking along −z).
    K = np.asarray(cam.K, float)
    f = float(K[1, 1])
    extras: dict[str, Any] = {"source": "photo", "K": K.tolist(), "width": int(cam.width), "height": int(cam.height),
                              "principal_point_offset_px": [float(K[0, 2] - cam.width / 2),
                                                            float(K[1, 2] - cam.height / 2)],
                              "photo_plane": f"{name} plane"}
    if not cam.lens.is_pinhole:
        extras["distortion"] = distortion_extras(cam)
    doc["cameras"] = [{"name": name, "type": "perspective",
                       "perspective": {"yfov": focal_to_fov(f, cam.height),
                                       "aspectRatio": float(cam.width / cam.height),
                                       "znear": ZNEAR_M, "zfar": float(PLANE_MARGIN * d)},
                       "extras": extras}]
    pose = np.eye(4)
    pose[:3, :3] = R.T @ GL_FROM_CV
    pose[:3, 3] = C
    cam_node = add({"name": name, "camera": 0, **_trs(pose)})
    gl = (pos * d) @ GL_FROM_CV  # vebuild camera frame → glTF camera frame (GL_FROM_CV is its own inverse)
    itype = np.uint16 if len(gl) <= 65535 else _UNSIGNED_INT
    plane = {"attributes": {"POSITION": buf.accessor(gl.astype(np.float32), "VEC3", _ARRAY_BUFFER, bounds=True),
                            "NORMAL": buf.accessor(np.tile([0.0, 0.0, 1.0], (len(gl), 1)).astype(np.float32), "VEC3",
                                                   _ARRAY_BUFFER),
                            "TEXCOORD_0": buf.accessor(tex.astype(np.float32), "VEC2", _ARRAY_BUFFER)},
             "indices": buf.accessor(tris.ravel().astype(itype), "SCALAR", 34963), "material": 0, "mode": _TRIANGLES}
    nu = int(round(np.sqrt(len(tris) / 2 * cam.width / cam.height)))
    plane_extras = {"vebuild_role": "photo plane", "photo": cam.id, "distance": float(d),
                    "how": "each vertex lies on the ray of the photo pixel its texture coordinate names, at depth "
                           "'distance' in front of the camera: the pinhole image plane scaled by distance / f" +
                           (", the pixels undistorted by the division model's k1 (the texture is the photo "
                            "undistorted)" if not cam.lens.is_pinhole else ""),
                    "texture_error_px": float(err), "image": image.note}
    add({"name": f"{name} plane", "extras": plane_extras},
        {"name": f"{name} plane", "primitives": [plane]}, parent=cam_node)
    add({"name": "floor grid (z = 0)", "extras": {"vebuild_role": "floor grid", "spacing": spacing,
                                                   "bounds_xy": list(bounds), "units": units}},
        {"name": "floor grid", "primitives": [_lines_primitive(buf, grid, 1)]})
    colours = np.repeat(np.eye(3), 2, axis=0)
    add({"name": "axes", "extras": {"vebuild_role": "axes", "length": spacing,
                                    "colours": "+x red, +y green, +z blue (vebuild's world, +Z up)"}},
        {"name": "axes", "primitives": [_lines_primitive(buf, axes, 2, colours)]})
    for line in lines:
        add({"name": line.name, "extras": {"vebuild_role": "measurement", **line.extras,
                                           "ends": np.asarray(line.ends, float).tolist()}},
            {"name": line.name, "primitives": [_lines_primitive(buf, np.asarray(line.ends, float)[None], 3)]})
    doc["meshes"] = meshes
    binary = buf.bytes()
    doc["accessors"] = buf.accessors
    doc["bufferViews"] = buf.views
    doc["buffers"] = [{"byteLength": len(binary)}]
    info = CameraScene(cam.id, float(d), float(err), (nu, int(round(len(tris) / 2 / max(nu, 1)))), spacing, bounds,
                       len(lines), image.note)
    return doc, binary, info
