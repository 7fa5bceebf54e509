"""The model as files other software opens: glTF 2.0 binary (.glb) and Wavefront OBJ + MTL (pure numpy).

glTF keeps everything: a root node ``vebuild world`` turns vebuild's right-handed +Z-up world into
glTF's +Y-up one (world (x, y, z) → glTF (x, z, −y); metres kept); under it one glTF node per
model node (groups too) with its name and its pose relative to its parent, each primitive's mesh in
its own local frame, one mesh primitive per atlas page, the atlas PNGs embedded byte for byte as
the project records them, unlit materials (``KHR_materials_unlit``: the textures already hold the
photographed light), and the named views and calibrated photos as perspective cameras.
glTF cameras are pinholes with the principal point at the centre: each camera's ``extras`` give
its K and the principal point's offset, and a photo's lens distortion, which glTF cannot express,
as ``extras.distortion`` (:func:`distortion_extras`: the division model's name and k1, its
definition, and how far it moves the photo's corners); a viewer that ignores it shows the photo's
pinhole view, off the photo by up to that displacement.

What no photo saw travels too (:mod:`vebuild.render.export_observed`): each atlas page's
coverage map is embedded byte for byte as a second image and texture (nearest filtering, same
``TEXCOORD_0``), referenced from its material's ``extras.vebuild_coverage`` with the colour of
texels no photo saw; each mesh primitive's ``extras.vebuild_seen`` gives the share of its surface
some photo saw and each face's ``seen_fraction`` (as ``textures.faces`` records them), so that
another viewer can mark the inferred surfaces as vebuild's renders do.

OBJ has no hierarchy and no cameras: every primitive node becomes one object (``o``/``g``) with its
vertices in world coordinates, written +Y up as OBJ readers expect (OBJ (x, y, z) = world
(x, z, −y), so Blender's default import, forward −Z up Y, shows vebuild's own coordinates); the MTL
points at copies of the atlas pages written next to the OBJ.

Both writers are atomic: every file goes to a temporary name beside its target and is renamed over
it only when all of them were written, so an error leaves nothing half-written.
"""

from __future__ import annotations

import json
import os
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from vebuild import __version__
from vebuild.camera import ImageCamera, distortion_displacement_px, focal_to_fov
from vebuild.errors import VebuildError
from vebuild.project import Project
from vebuild.project.decode import TexturePage, camera_records, photo_camera, view_camera
from vebuild.project.outputs import begin_stage, check_file
from vebuild.project.provenance import inputs_sha256, stage_hashes, stale_record
from vebuild.render.export_observed import (  # COVERAGE_EXTRAS: re-exported, the keys of the format
    COVERAGE_EXTRAS,  # noqa: F401
    SEEN_EXTRAS,
    add_coverage,
    seen_extras,
)
from vebuild.render.scene import RenderScene, load_scene
from vebuild.texture import layout as lay

Array = NDArray[np.float64]

FORMATS = {".glb": "glb", ".obj": "obj"}
#: Name of the glTF root node that turns the +Z-up world into glTF's +Y-up frame.
ROOT_NAME = "vebuild world"
#: Rotation of the root node: −90° about x, so world +Z becomes glTF +Y (quaternion x, y, z, w).
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
ROOT_QUATERNION = [-float(np.sqrt(0.5)), 0.0, 0.0, float(np.sqrt(0.5))]
#: Near plane of the exported cameras (metres); glTF's far plane is left infinite.
ZNEAR_M = 0.05
#: glTF camera local axes in vebuild camera axes: x right, y up (image v down), looking along −z.
GL_FROM_CV = np.diag([1.0, -1.0, -1.0])

_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_FLOAT, _UNSIGNED_SHORT, _UNSIGNED_INT = 5126, 5123, 5125
_LINEAR, _LINEAR_MIPMAP_LINEAR, _CLAMP_TO_EDGE = 9729, 9987, 33071

_GLB_MAGIC, _CHUNK_JSON, _CHUNK_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942


@dataclass
class Part:
    """The triangles of one primitive node on one atlas page (or all of them, untextured)."""

    page: int  # atlas page, −1 when untextured
    positions: Array  # (n, 3) node's local frame, metres
    normals: Array  # (n, 3) local
    atlas: Array  # (n, 2) texels on the page
    colour: Array  # (n, 3) linear RGB of each vertex's face (used untextured)
    face_ids: NDArray[np.int32]  # (n,) global face id of each vertex
    triangles: NDArray[np.int64]  # (m, 3) into this part's vertices


@dataclass
class NodeExport:
    name: str
    parent: str | None
    world: Array  # 4×4 world_from_node
    local: Array  # 4×4 parent_from_node (world_from_node for a node attached to the world)
    extras: dict[str, Any]
    parts: list[Part]


@dataclass
class ExportResult:
    """What was written, for the command line to print."""

    path: Path
    format: str
    files: list[Path]
    nodes: int
    meshes: int
    primitives: int
    triangles: int
    cameras: list[str]
    pages: list[Path]
    textured: bool
    warnings: list[str] = field(default_factory=list)


@dataclass
class _Contents:
    project: Project
    scene: RenderScene
    nodes: list[NodeExport]
    cameras: list[tuple[str, str, ImageCamera]]  # (name, "view" | "photo", camera)
    pages: list[TexturePage]
    warnings: list[str]


# -- what goes in ----------------------------------------------------------------------------------


def export_model(project: Project, path: str | os.PathLike[str], format: str | None = None) -> ExportResult:
    """Write the project's model to ``path`` as glTF binary or OBJ (by ``format``, else its suffix)."""
    path = Path(path)
    check_file(project, path, "export", ".obj" if path.suffix.lower() == ".obj" else ".glb")
    fmt = format or FORMATS.get(path.suffix.lower())
    if fmt not in ("glb", "obj"):
        raise VebuildError(f"{path}: unknown export format {path.suffix or '(no extension)'!r}; expected "
                           "a file name ending in .glb (glTF 2.0 binary) or .obj (Wavefront OBJ + MTL)")
    return export_glb(project, path) if fmt == "glb" else export_obj(project, path)


def export_glb(project: Project, path: str | os.PathLike[str]) -> ExportResult:
    """Write the model, its textures and its cameras as one glTF 2.0 binary file."""
    path = Path(path)
    _check_target(project, path)
    contents = _collect(project)
    doc, binary = gltf_document(contents)
    data = glb_bytes(doc, binary)
    _write_atomically([(path, data)])
    n_prims = sum(len(m["primitives"]) for m in doc.get("meshes", []))
    return ExportResult(path, "glb", [path], len(doc["nodes"]) - 1 - len(contents.cameras),
                        len(doc.get("meshes", [])), n_prims, _triangles(contents),
                        [name for name, _, _ in contents.cameras], [p.path for p in contents.pages],
                        contents.scene.textured, contents.warnings)


def export_obj(project: Project, path: str | os.PathLike[str]) -> ExportResult:
    """Write the model as OBJ (world coordinates, +Y up) with an MTL and copies of the atlas pages."""
    path = Path(path)
    _check_target(project, path)
    contents = _collect(project)
    files = obj_files(contents, path)
    for f, _ in files[:-1]:  # the MTL and the page copies beside it (the OBJ was checked above)
        check_file(project, f, "export")
    _write_atomically(files)
    warnings = list(contents.warnings)
    if contents.cameras:
        warnings.append(f"OBJ holds no cameras: the {len(contents.cameras)} view and photo camera(s) are left out "
                        "(export to .glb to keep them)")
    n_nodes = sum(1 for n in contents.nodes if n.parts)
    return ExportResult(path, "obj", [f for f, _ in files], len(contents.nodes), n_nodes,
                        sum(len(n.parts) for n in contents.nodes), _triangles(contents),
                        [], [f for f, _ in files if f.suffix == ".png"], contents.scene.textured, warnings)


def _triangles(contents: _Contents) -> int:
    return sum(len(p.triangles) for n in contents.nodes for p in n.parts)


def _collect(project: Project) -> _Contents:
    scene = load_scene(project)
    warnings = list(scene.warnings)
    model = scene.model
    world = model.world_transforms()
    by_key = {(f.node, f.name): f for f in scene.mesh.faces}
    face_page = np.array([f.page for f in scene.mesh.faces], np.int64)
    pages = scene.page_files if scene.textured else []  # read and hash-checked once, by the scene
    if not scene.textured:
        warnings.append("exported untextured: each face in its recorded average colour, or grey where there is none "
                        "(glTF: vertex colours COLOR_0; OBJ: one material per face)")
    nodes = []
    for node in model.nodes:
        T = world[node.name]
        local = T if node.parent is None else np.linalg.inv(world[node.parent]) @ T
        extras: dict[str, Any] = {"joint": node.joint.to_dict()["type"]}
        parts: list[Part] = []
        if node.primitive is not None:
            extras["primitive"] = node.primitive.to_dict()
            mesh = node.primitive.mesh(None, lay.SEGMENTS)
            gid, atlas = lay.node_atlas(node.name, mesh, by_key)
            tri_face = gid[mesh.faces[:, 0]]
            tri_page = face_page[tri_face - 1] if scene.textured else np.full(len(tri_face), -1)
            for page in np.unique(tri_page):
                tris = mesh.faces[tri_page == page]
                used, inverse = np.unique(tris.ravel(), return_inverse=True)
                parts.append(Part(int(page), mesh.vertices[used], mesh.normals[used], atlas[used],
                                  scene.face_colour[gid[used] - 1], gid[used],
                                  inverse.reshape(-1, 3).astype(np.int64)))
        nodes.append(NodeExport(node.name, node.parent, T, local, extras, parts))
    cameras: list[tuple[str, str, ImageCamera]] = []
    for view in project.data.get("views", []):
        cameras.append((view["name"], "view", view_camera(view)))
    calibrated = camera_records(project.data)  # the final cameras (re-calibrated where solved so)
    for photo in project.data["photos"]:
        if photo["id"] in calibrated:
            cameras.append((f"photo {photo['id']}", "photo", photo_camera(project, photo["id"])))
    return _Contents(project, scene, nodes, cameras, pages, warnings)


# -- glTF ------------------------------------------------------------------------------------------


class _Buffer:
    """The binary chunk: buffer views appended at 4-byte boundaries."""

    def __init__(self) -> None:
        self.chunks: list[bytes] = []
        self.size = 0
        self.views: list[dict[str, Any]] = []
        self.accessors: list[dict[str, Any]] = []

    def view(self, data: bytes, target: int | None = None) -> int:
        entry: dict[str, Any] = {"buffer": 0, "byteOffset": self.size, "byteLength": len(data)}
        if target is not None:
            entry["target"] = target
        pad = (-len(data)) % 4
        self.chunks.append(data + bytes(pad))
        self.size += len(data) + pad
        self.views.append(entry)
        return len(self.views) - 1

    def accessor(self, array: NDArray[Any], kind: str, target: int, bounds: bool = False) -> int:
        comp = {np.dtype(np.float32): _FLOAT, np.dtype(np.uint16): _UNSIGNED_SHORT,
                np.dtype(np.uint32): _UNSIGNED_INT}[array.dtype]
        a = np.ascontiguousarray(array)
        entry: dict[str, Any] = {"bufferView": self.view(a.tobytes(), target), "componentType": comp,
                                 "count": int(len(a)), "type": kind}
        if bounds:
            entry["min"] = [float(v) for v in a.min(axis=0)]
            entry["max"] = [float(v) for v in a.max(axis=0)]
        self.accessors.append(entry)
        return len(self.accessors) - 1

    def bytes(self) -> bytes:
        return b"".join(self.chunks)


def _trs(T: Array) -> dict[str, list[float]]:
    """glTF translation and unit rotation quaternion (x, y, z, w) of a rigid 4×4 transform."""
    R = T[:3, :3]
    if not (np.allclose(R.T @ R, np.eye(3), atol=1e-9) and np.linalg.det(R) > 0):
        raise ValueError("not a rigid transform")
    q = Rotation.from_matrix(R).as_quat()
    q = q / np.linalg.norm(q)
    out: dict[str, list[float]] = {}
    if np.any(T[:3, 3] != 0):
        out["translation"] = [float(v) for v in T[:3, 3]]
    if not np.allclose(q, [0, 0, 0, 1], atol=0, rtol=0):
        out["rotation"] = [float(v) for v in q]
    return out


def gltf_document(contents: _Contents) -> tuple[dict[str, Any], bytes]:
    """The glTF JSON document and its binary chunk."""
    project, scene = contents.project, contents.scene
    buf = _Buffer()
    doc: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": f"vebuild {__version__}", "extras": _provenance(contents)},
        "scene": 0,
        "scenes": [{"name": str(project.data.get("name") or project.path.name), "nodes": [0]}],
        "nodes": [{"name": ROOT_NAME, "rotation": ROOT_QUATERNION, "children": [],
                   "extras": {"note": f"turns vebuild's world (right-handed, {_units(project)}, +Z up) into glTF's "
                                      "+Y up"}}],
    }
    materials: list[dict[str, Any]] = []
    page_material: dict[int, int] = {}
    if scene.textured:
        used = sorted({p.page for n in contents.nodes for p in n.parts})
        doc["images"], doc["textures"] = [], []
        doc["samplers"] = [{"magFilter": _LINEAR, "minFilter": _LINEAR_MIPMAP_LINEAR,
                            "wrapS": _CLAMP_TO_EDGE, "wrapT": _CLAMP_TO_EDGE}]
        for k in used:
            page = contents.pages[k]
            doc["images"].append({"name": PurePosixPath(page.relative).name, "mimeType": "image/png",
                                  "bufferView": buf.view(page.data)})
            doc["textures"].append({"name": f"atlas page {k}", "sampler": 0, "source": len(doc["images"]) - 1})
            page_material[k] = len(materials)
            materials.append({"name": f"atlas page {k}",
                              "pbrMetallicRoughness": {"baseColorTexture": {"index": len(doc["textures"]) - 1},
                                                       "metallicFactor": 0.0, "roughnessFactor": 1.0},
                              "doubleSided": True, "extensions": {"KHR_materials_unlit": {}}})
        add_coverage(doc, buf, contents, used, [materials[page_material[k]] for k in used])
        doc["extensionsUsed"] = ["KHR_materials_unlit"]
    else:
        # Lit: with no photographed light in the colours, shading is what shows the shapes.
        page_material[-1] = 0
        materials.append({"name": "face colours (untextured)",
                          "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                                                   "metallicFactor": 0.0, "roughnessFactor": 1.0},
                          "doubleSided": True})
    doc["materials"] = materials

    index = {n.name: i + 1 for i, n in enumerate(contents.nodes)}
    meshes: list[dict[str, Any]] = []
    for n in contents.nodes:
        gnode: dict[str, Any] = {"name": n.name}
        try:
            gnode.update(_trs(n.local))
        except ValueError:
            gnode["matrix"] = [float(v) for v in n.local.T.ravel()]  # column-major
        gnode["extras"] = n.extras
        if n.parts:
            prims = []
            for part in n.parts:
                attributes = {
                    "POSITION": buf.accessor(part.positions.astype(np.float32), "VEC3", _ARRAY_BUFFER, bounds=True),
                    "NORMAL": buf.accessor(_unit(part.normals).astype(np.float32), "VEC3", _ARRAY_BUFFER),
                }
                if scene.textured:
                    w, h = contents.pages[part.page].size
                    uv = part.atlas / np.array([w, h], float)
                    attributes["TEXCOORD_0"] = buf.accessor(uv.astype(np.float32), "VEC2", _ARRAY_BUFFER)
                else:
                    attributes["COLOR_0"] = buf.accessor(np.clip(part.colour, 0, 1).astype(np.float32), "VEC3",
                                                         _ARRAY_BUFFER)
                itype = np.uint16 if len(part.positions) <= 65535 else np.uint32
                prim: dict[str, Any] = {"attributes": attributes,
                                        "indices": buf.accessor(part.triangles.ravel().astype(itype), "SCALAR",
                                                                _ELEMENT_ARRAY_BUFFER),
                                        "material": page_material[part.page], "mode": 4}
                seen = seen_extras(contents, part)
                if seen is not None:
                    prim["extras"] = {SEEN_EXTRAS: seen}
                prims.append(prim)
            meshes.append({"name": n.name, "primitives": prims})
            gnode["mesh"] = len(meshes) - 1
        doc["nodes"].append(gnode)
    for n in contents.nodes:
        parent = doc["nodes"][0] if n.parent is None else doc["nodes"][index[n.parent]]
        parent.setdefault("children", []).append(index[n.name])
    if meshes:
        doc["meshes"] = meshes

    cameras = []
    for name, kind, cam in contents.cameras:
        f = float(cam.K[1, 1])
        # glTF cameras have no principal point: record K and its offset from the image centre.
        offset = [float(cam.K[0, 2] - cam.width / 2), float(cam.K[1, 2] - cam.height / 2)]
        extras: dict[str, Any] = {"source": kind, "K": np.asarray(cam.K, float).tolist(), "width": int(cam.width),
                                  "height": int(cam.height), "principal_point_offset_px": offset}
        if not cam.lens.is_pinhole:
            extras["distortion"] = distortion_extras(cam)
        cameras.append({"name": name, "type": "perspective",
                        "perspective": {"yfov": focal_to_fov(f, cam.height),
                                        "aspectRatio": float(cam.width / cam.height), "znear": ZNEAR_M},
                        "extras": extras})
        pose = np.eye(4)
        pose[:3, :3] = np.asarray(cam.R, float).T @ GL_FROM_CV
        pose[:3, 3] = np.asarray(cam.C, float)
        doc["nodes"][0]["children"].append(len(doc["nodes"]))
        doc["nodes"].append({"name": name, "camera": len(cameras) - 1, **_trs(pose)})
    if cameras:
        doc["cameras"] = cameras

    binary = buf.bytes()
    if buf.accessors:
        doc["accessors"] = buf.accessors
    if buf.views:
        doc["bufferViews"] = buf.views
        doc["buffers"] = [{"byteLength": len(binary)}]
    return doc, binary


#: How ``extras.distortion`` defines the lens (vebuild/camera.py), for a reader with no vebuild.
DIVISION_MODEL = ("division model (Fitzgibbon 2001): with x_d = (u - c) / f the normalised coordinate of a pixel u "
                  "as the lens put it (c the principal point and f the focal length of K, in pixels), the pinhole's "
                  "is x_u = x_d / (1 + k1 r^2 + k2 r^4), r = |x_d|; k1 < 0 is barrel distortion; k2 is 0 (absent) "
                  "for the one-term model")


def distortion_extras(cam: ImageCamera) -> dict[str, Any]:
    """A photo camera's lens distortion for its glTF ``extras`` (glTF has no lens model)."""
    out = {"model": "division", "k1": float(cam.lens.k1), "definition": DIVISION_MODEL,
           "corner_displacement_px": distortion_displacement_px(cam.K, cam.width, cam.height, cam.lens)}
    if cam.lens.k2 != 0.0:
        out["k2"] = float(cam.lens.k2)
    return out


def _unit(v: Array) -> Array:
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.where(n > 0, v / np.where(n > 0, n, 1.0), v)


def _units(project: Project, metres: str = "metres") -> str:
    """The unit of the exported lengths, in words: metres, or relative units where the project has
    no scale (:mod:`vebuild.project.units`; glTF's metres are then the camera's height)."""
    from vebuild.project.units import RELATIVE_UNITS, length_unit

    return RELATIVE_UNITS if length_unit(project.data).relative else metres


def _provenance(contents: _Contents) -> dict[str, Any]:
    project = contents.project
    out: dict[str, Any] = {
        "project": project.path.name,
        "inputs_sha256": inputs_sha256(project.data),  # FORMAT.md "Inputs digest"
        "units": _units(project, "metre"),
        "world": "vebuild: right-handed, +Z up; the root node 'vebuild world' rotates it to glTF's +Y up",
        "textured": contents.scene.textured,
    }
    record = project.data.get("textures")
    if contents.pages:
        out["texture_pages"] = [{"atlas": p.relative, "sha256": p.sha256, "width": p.size[0], "height": p.size[1]}
                                for p in contents.pages]
        if record and record.get("input_hash"):
            out["textures_input_hash"] = record["input_hash"]
    solution = project.data.get("model_solution") or {}
    if "rms_px" in solution:
        out["model_rms_px"] = solution["rms_px"]
    # what it was made from (vebuild.project.provenance): each stage record's SHA-256, and the stale ones
    out["stages"], out["stale"] = stage_hashes(project.data), stale_record(project.data)
    return out


def glb_bytes(doc: dict[str, Any], binary: bytes) -> bytes:
    """A GLB container: 12-byte header, the JSON chunk (space-padded), the BIN chunk (zero-padded)."""
    text = json.dumps(doc, ensure_ascii=False, separators=(",", ":"), allow_nan=False).encode("utf-8")
    text += b" " * ((-len(text)) % 4)
    chunks = struct.pack("<II", len(text), _CHUNK_JSON) + text
    if binary:
        binary += bytes((-len(binary)) % 4)
        chunks += struct.pack("<II", len(binary), _CHUNK_BIN) + binary
    return struct.pack("<III", _GLB_MAGIC, 2, 12 + len(chunks)) + chunks


def read_glb(data: bytes) -> tuple[dict[str, Any], bytes]:
    """The JSON document and binary chunk of a GLB file (for tests and checks)."""
    magic, version, length = struct.unpack_from("<III", data, 0)
    if magic != _GLB_MAGIC or version != 2 or length != len(data):
        raise ValueError("not a glTF 2.0 binary file")
    n, kind = struct.unpack_from("<II", data, 12)
    doc = json.loads(data[20:20 + n].decode("utf-8"))
    binary = b""
    if 20 + n < len(data):
        m, kind = struct.unpack_from("<II", data, 20 + n)
        binary = data[28 + n:28 + n + m]
    return doc, binary


# -- OBJ -------------------------------------------------------------------------------------------


def _obj_name(text: str) -> str:
    return re.sub(r"\s+", "_", text.strip()) or "unnamed"


def obj_files(contents: _Contents, path: Path) -> list[tuple[Path, bytes]]:
    """The OBJ, its MTL and the atlas copies, as (path, bytes), textures first and the OBJ last."""
    project, scene = contents.project, contents.scene
    stem = path.stem
    mtl = path.with_suffix(".mtl")
    files: list[tuple[Path, bytes]] = []
    head = [f"# vebuild {__version__}: the model of {project.path.name} (inputs SHA-256 {inputs_sha256(project.data)})",
            f"# Units: {_units(project)}. Axes: +Y up, right-handed: OBJ (x, y, z) = vebuild world (x, z, -y).",
            "# Blender's default OBJ import (forward -Z, up Y) gives back vebuild's world coordinates (+Z up)."]
    mtl_lines = [head[0], ""]
    face_material: dict[int, str] = {}
    if scene.textured:
        for page in contents.pages:
            if not any(p.page == page.index for n in contents.nodes for p in n.parts):
                continue
            name = f"{stem}_atlas_{page.index}.png"
            files.append((path.with_name(name), page.data))
            mtl_lines += [f"# atlas page {page.index}: {page.relative} (SHA-256 {page.sha256})",
                          f"newmtl atlas_{page.index}", "Ka 1 1 1", "Kd 1 1 1", "Ks 0 0 0", "illum 1",
                          f"map_Kd {name}", ""]
    else:
        mtl_lines.append("# untextured: each face in its average colour (Kd, linear RGB); grey where none was recorded")
        for f in scene.mesh.faces:
            c = np.clip(scene.face_colour[f.id - 1], 0, 1)
            face_material[f.id] = _obj_name(f"{f.node}.{f.name}")
            mtl_lines += [f"newmtl {face_material[f.id]}", f"Kd {c[0]:.6f} {c[1]:.6f} {c[2]:.6f}", "Ks 0 0 0",
                          "illum 1", ""]
    lines = head + [f"mtllib {mtl.name}", ""]
    base = 1
    for n in contents.nodes:
        if not n.parts:
            continue
        lines += [f"o {_obj_name(n.name)}", f"g {_obj_name(n.name)}"]
        if n.parent is not None:
            lines.append(f"# parent: {n.parent}")
        R, t = n.world[:3, :3], n.world[:3, 3]
        for part in n.parts:
            P = (part.positions @ R.T + t) @ Z_UP_TO_Y_UP.T
            N = _unit(part.normals @ R.T) @ Z_UP_TO_Y_UP.T
            lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in P]
            lines += [f"vn {x:.6f} {y:.6f} {z:.6f}" for x, y, z in N]
            tri = part.triangles + base
            if scene.textured:
                w, h = contents.pages[part.page].size
                uv = part.atlas / np.array([w, h], float)
                lines += [f"vt {u:.7f} {1.0 - v:.7f}" for u, v in uv]  # OBJ's v grows upward
                lines.append(f"usemtl atlas_{part.page}")
                lines += [f"f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}" for a, b, c in tri]
            else:
                tri_face = part.face_ids[part.triangles[:, 0]]
                for fid in np.unique(tri_face):
                    lines.append(f"usemtl {face_material[int(fid)]}")
                    lines += [f"f {a}//{a} {b}//{b} {c}//{c}" for a, b, c in tri[tri_face == fid]]
            base += len(part.positions)
    files.append((mtl, ("\n".join(mtl_lines) + "\n").encode("utf-8")))
    files.append((path, ("\n".join(lines) + "\n").encode("utf-8")))
    return files


# -- writing ---------------------------------------------------------------------------------------


def _check_target(project: Project, path: Path) -> None:
    folder = path.parent
    if path.is_dir():
        raise VebuildError(f"{path}: is a folder; give a file name ending in .glb or .obj")
    if not folder.exists():
        raise VebuildError(f"{path}: the output folder {folder} does not exist; create it first")
    if not folder.is_dir():
        raise VebuildError(f"{path}: {folder} is not a folder")
    if not os.access(folder, os.W_OK):
        raise VebuildError(f"{path}: the output folder {folder} cannot be written (permission denied)")
    check_file(project, path, "export")
    begin_stage(project, folder)


def _write_atomically(files: list[tuple[Path, bytes]]) -> None:
    """Write every file beside its target, then rename them in order (:func:`vebuild.project.atomic.write_many`);
    on error leave no temporary file behind."""
    from vebuild.project.atomic import write_many

    target = files[-1][0]
    for final, _ in files:
        if final.is_dir():
            raise VebuildError(f"{target}: cannot write {final} (it is a folder); nothing was written")
    try:
        write_many(files)
    except OSError as e:
        done = getattr(e, "replaced", [])
        written = f"only {', '.join(str(f) for f in done)} were replaced" if done else "nothing was written"
        raise VebuildError(f"{target}: cannot write {e.filename or target} ({e.strerror or e}); {written}") from None
