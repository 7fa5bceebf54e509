"""`vebuild export`: glTF 2.0 binary and OBJ + MTL, checked against the scene they came from.

The example room is calibrated, solved and textured once (50 texels per metre on 256-texel pages,
so that the atlas spans several pages and nodes have one mesh primitive per page). Every .glb is
checked by the Khronos glTF validator (npm package gltf-validator, which .ci/run installs).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh
from gltf_validation import validate
from PIL import Image
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from vebuild import __version__
from vebuild.actions.texture import texture_project
from vebuild.camera import Lens
from vebuild.camera import project as project_points
from vebuild.cli import main
from vebuild.errors import VebuildError
from vebuild.project import load_project, save_project
from vebuild.project.decode import photo_camera, view_camera
from vebuild.project.provenance import inputs_sha256
from vebuild.render.export import ROOT_NAME, export_model, read_glb
from vebuild.render.scene import load_scene
from vebuild.texture.merge import srgb8_to_linear
from vebuild.texture.options import Options

REPO = Path(__file__).resolve().parents[1]
ROOM = REPO / "scenes" / "room"
#: World positions survive float32 in the node's local frame (rooms of a few metres: ~5e-7 m).
POSITION_TOL_M = 1e-5
#: Atlas coordinates survive float32 UVs on pages of a few hundred texels.
ATLAS_TOL_TEXELS = 1e-3
#: world (x, y, z) → glTF / OBJ (x, z, −y).
Y_UP = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
VIEWS = [
    {"name": "from the door", "position": [4.5, 0.5, 1.6], "look_at": [1.0, 2.5, 0.8], "fov_deg": 70.0,
     "width": 1280, "height": 720},
    {"name": "tilted", "position": [1.0, 1.0, 1.2], "direction": [1.0, 1.0, -0.2], "roll_deg": 15.0,
     "focal_length_mm": 28.0, "width": 800, "height": 1000},
]


@pytest.fixture(scope="module")
def textured(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("export") / "room"
    shutil.copytree(ROOM, folder)
    proj = folder / "room.vebuild.json"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["calibrate", str(proj), "--quiet"]) == 0
        assert main(["solve", str(proj)]) == 0
    project = load_project(proj)
    record, _ = texture_project(project, Options(texels_per_metre=50.0, page_size=256))
    assert len(record["pages"]) > 1
    project.data["views"] = project.data.get("views", []) + VIEWS  # the example's, and a roll and a focal length
    save_project(project)
    return proj


@pytest.fixture(scope="module")
def exported(textured: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    out = tmp_path_factory.mktemp("out")
    project = load_project(textured)
    glb, obj = export_model(project, out / "room.glb"), export_model(project, out / "room.obj")
    return {"project": project, "scene": load_scene(project), "glb": glb, "obj": obj}


def _copy_project(proj: Path, dest: Path) -> Path:
    shutil.copytree(proj.parent, dest)
    return dest / proj.name


# -- reading glTF back (independently of the exporter) ---------------------------------------------

_DTYPES = {5126: np.float32, 5123: np.uint16, 5125: np.uint32, 5121: np.uint8}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def _accessor(doc: dict, binary: bytes, i: int) -> np.ndarray:
    a = doc["accessors"][i]
    v = doc["bufferViews"][a["bufferView"]]
    n = a["count"] * _WIDTH[a["type"]]
    arr = np.frombuffer(binary, _DTYPES[a["componentType"]], n, v.get("byteOffset", 0) + a.get("byteOffset", 0))
    return arr.reshape(a["count"], -1).astype(np.float64)


def _local(node: dict) -> np.ndarray:
    T = np.eye(4)
    if "matrix" in node:
        return np.array(node["matrix"], float).reshape(4, 4).T
    if "rotation" in node:
        T[:3, :3] = Rotation.from_quat(node["rotation"]).as_matrix()  # x, y, z, w as glTF
    if "translation" in node:
        T[:3, 3] = node["translation"]
    return T


def _worlds(doc: dict) -> tuple[list[np.ndarray], dict[int, int]]:
    """Each node's glTF world transform, and each node's parent index."""
    parent = {c: i for i, n in enumerate(doc["nodes"]) for c in n.get("children", [])}
    out: list[np.ndarray | None] = [None] * len(doc["nodes"])

    def world(i: int) -> np.ndarray:
        if out[i] is None:
            out[i] = _local(doc["nodes"][i]) if i not in parent else world(parent[i]) @ _local(doc["nodes"][i])
        return out[i]

    return [world(i) for i in range(len(doc["nodes"]))], parent


def _to_vebuild(T_gltf_world: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Y_UP.T
    return T @ T_gltf_world


def _node_vertices(scene, name: str) -> np.ndarray:
    nodes = np.array([f.node for f in scene.mesh.faces])
    return nodes[scene.mesh.face_of_vertex - 1] == name


def _assert_same_points(got: np.ndarray, want: np.ndarray, tol: float, what: str) -> None:
    assert got.shape == want.shape, what
    d1, _ = cKDTree(want).query(got)
    d2, _ = cKDTree(got).query(want)
    assert max(d1.max(), d2.max()) < tol, f"{what}: {max(d1.max(), d2.max())}"


# -- glTF ------------------------------------------------------------------------------------------


def test_glb_reloads_with_the_scenes_geometry_and_hierarchy(exported):
    scene, path = exported["scene"], exported["glb"].path
    model = scene.model
    loaded = trimesh.load(path, process=False)
    parents = loaded.graph.transforms.parents
    names = {n.name for n in model.nodes}
    # The hierarchy: every model node (groups too) under its parent, the roots under "vebuild world".
    assert parents[ROOT_NAME] == loaded.graph.base_frame
    for n in model.nodes:
        assert parents[n.name] == (n.parent or ROOT_NAME), n.name
    assert "table" in names and model.node("table").primitive is None
    # Geometry: each primitive node's world vertices, after undoing the +Y-up root, are the scene's.
    by_node: dict[str, list[np.ndarray]] = {}
    for gnode in loaded.graph.nodes_geometry:
        T, geom = loaded.graph[gnode]
        owner = gnode
        while owner not in names:  # a node with several primitives holds them in child nodes
            owner = parents[owner]
        v = trimesh.transform_points(loaded.geometry[geom].vertices, _to_vebuild(T))
        by_node.setdefault(owner, []).append(v)
    prim_nodes = [n.name for n in model.nodes if n.primitive is not None]
    assert sorted(by_node) == sorted(prim_nodes)
    for name in prim_nodes:
        want = scene.mesh.vertices[_node_vertices(scene, name)]
        _assert_same_points(np.concatenate(by_node[name]), want, POSITION_TOL_M, name)
    assert exported["glb"].triangles == len(scene.mesh.triangles)


def test_glb_meshes_are_local_with_atlas_uvs_one_primitive_per_page(exported):
    scene, project = exported["scene"], exported["project"]
    doc, binary = read_glb(exported["glb"].path.read_bytes())
    worlds, _ = _worlds(doc)
    sizes = [(p["width"], p["height"]) for p in project.data["textures"]["pages"]]
    image_of_material = {}
    for m, mat in enumerate(doc["materials"]):
        tex = doc["textures"][mat["pbrMetallicRoughness"]["baseColorTexture"]["index"]]
        image_of_material[m] = doc["images"][tex["source"]]["name"]
    several = 0
    for i, gnode in enumerate(doc["nodes"]):
        if "mesh" not in gnode:
            continue
        name = gnode["name"]
        sel = _node_vertices(scene, name)
        pages_of = np.array([f.page for f in scene.mesh.faces])[scene.mesh.face_of_vertex[sel] - 1]
        prims = doc["meshes"][gnode["mesh"]]["primitives"]
        assert len(prims) == len(np.unique(pages_of)), name
        several += len(prims) > 1
        n_tris = 0
        for prim in prims:
            page = int(re.fullmatch(r"atlas_(\d+)_[0-9a-f]{12}\.png", image_of_material[prim["material"]]).group(1))
            a = doc["accessors"][prim["attributes"]["POSITION"]]
            P = _accessor(doc, binary, prim["attributes"]["POSITION"])
            assert np.array_equal(np.float32(a["min"]), P.min(axis=0)) and np.array_equal(np.float32(a["max"]),
                                                                                            P.max(axis=0))
            X = trimesh.transform_points(P, _to_vebuild(worlds[i]))
            uv = _accessor(doc, binary, prim["attributes"]["TEXCOORD_0"])
            assert uv.min() >= 0 and uv.max() <= 1
            here = sel & (np.array([f.page for f in scene.mesh.faces])[scene.mesh.face_of_vertex - 1] == page)
            want_X, want_A = scene.mesh.vertices[here], scene.mesh.atlas[here]
            # Vertices of different faces share positions: match by position (mm) and atlas texel.
            _, k = cKDTree(np.c_[want_X * 1e3, want_A]).query(np.c_[X * 1e3, uv * sizes[page]])
            assert len(X) == here.sum()
            assert np.abs(X - want_X[k]).max() < POSITION_TOL_M
            assert np.abs(uv * sizes[page] - want_A[k]).max() < ATLAS_TOL_TEXELS
            # Counter-clockwise from outside, as the scene: each triangle's normal agrees with NORMAL.
            tri = _accessor(doc, binary, prim["indices"]).astype(int).reshape(-1, 3)
            N = _accessor(doc, binary, prim["attributes"]["NORMAL"]) @ _to_vebuild(worlds[i])[:3, :3].T
            cross = np.cross(X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]])
            assert (np.einsum("ij,ij->i", cross, N[tri].mean(axis=1)) > 0).all(), name
            n_tris += len(tri)
        assert n_tris == np.isin(scene.mesh.triangles[:, 0], np.flatnonzero(sel)).sum()
    assert several > 0  # the fixture's pages split some nodes


def test_glb_embeds_the_atlas_pngs_byte_for_byte_with_unlit_materials(exported, textured):
    project = exported["project"]
    doc, binary = read_glb(exported["glb"].path.read_bytes())
    pages = project.data["textures"]["pages"]
    assert len(doc["images"]) == 2 * len(pages)  # the atlases, then their coverage maps (test_observed.py)
    for image, page in zip(doc["images"], pages, strict=False):
        view = doc["bufferViews"][image["bufferView"]]
        data = binary[view["byteOffset"]:view["byteOffset"] + view["byteLength"]]
        assert image["mimeType"] == "image/png"
        assert data == (project.folder / page["atlas"]).read_bytes()
    assert doc["extensionsUsed"] == ["KHR_materials_unlit"] and "extensionsRequired" not in doc
    for mat in doc["materials"]:
        pbr = mat["pbrMetallicRoughness"]
        assert pbr["metallicFactor"] == 0.0 and pbr["roughnessFactor"] == 1.0
        assert mat["extensions"] == {"KHR_materials_unlit": {}}
    asset = doc["asset"]
    assert asset["version"] == "2.0" and asset["generator"] == f"vebuild {__version__}"
    assert asset["extras"]["inputs_sha256"] == inputs_sha256(json.loads(textured.read_text()))
    assert [p["sha256"] for p in asset["extras"]["texture_pages"]] == [p["atlas_sha256"] for p in pages]
    # The root turns +Z (up in vebuild) into glTF's +Y.
    root = _local(doc["nodes"][0])
    assert doc["nodes"][0]["name"] == ROOT_NAME and doc["scenes"][doc["scene"]]["nodes"] == [0]
    np.testing.assert_allclose(root[:3, :3] @ [0, 0, 1.0], [0, 1.0, 0], atol=1e-15)


def test_glb_cameras_are_the_views_and_the_photos(exported):
    project = exported["project"]
    doc, _ = read_glb(exported["glb"].path.read_bytes())
    photos = [p["id"] for p in project.data["photos"]]
    views = project.data["views"]
    cams = {c["name"]: c for c in doc["cameras"]}
    assert list(cams) == [v["name"] for v in views] + [f"photo {p}" for p in photos]
    assert len(views) > len(VIEWS)
    worlds, parent = _worlds(doc)
    X = exported["scene"].mesh.vertices
    for i, gnode in enumerate(doc["nodes"]):
        if "camera" not in gnode:
            continue
        assert parent[i] == 0
        cam = doc["cameras"][gnode["camera"]]
        name = cam["name"]
        assert gnode["name"] == name
        if name.startswith("photo "):
            ref = photo_camera(project, name.removeprefix("photo "))
            look = ref.R[2]
        else:
            view = next(v for v in views if v["name"] == name)
            ref = view_camera(view)
            look = np.subtract(view["look_at"], view["position"]) if "look_at" in view else np.array(view["direction"])
        W = _to_vebuild(worlds[i])
        np.testing.assert_allclose(W[:3, 3], ref.C, atol=1e-12)
        np.testing.assert_allclose(-W[:3, 2], look / np.linalg.norm(look), atol=1e-12)  # looks along −Z
        np.testing.assert_allclose(W[:3, 1], -ref.R[1], atol=1e-12)  # +Y up is image up (roll kept)
        p = cam["perspective"]
        assert p["aspectRatio"] == pytest.approx(ref.width / ref.height) and p["znear"] == 0.05
        assert p["yfov"] == pytest.approx(2 * np.arctan(ref.height / 2 / ref.K[1, 1]))
        if name == "from the door":  # 70° across 1280 px
            assert p["yfov"] == pytest.approx(2 * np.arctan(np.tan(np.radians(35)) * 720 / 1280))
        if name == "tilted":  # 28 mm on a 36 mm frame
            assert p["yfov"] == pytest.approx(2 * np.arctan(500 / (28 / 36 * 800)))
        # A viewer's projection lands where vebuild's does, up to the principal point's offset.
        x = (X - W[:3, 3]) @ W[:3, :3]
        front = x[:, 2] < -0.1
        t = np.tan(p["yfov"] / 2)
        u = (x[front, 0] / -x[front, 2] / (t * p["aspectRatio"]) + 1) / 2 * ref.width
        v = (1 - x[front, 1] / -x[front, 2] / t) / 2 * ref.height
        offset = ref.K[:2, 2] - [ref.width / 2, ref.height / 2]
        np.testing.assert_allclose(np.c_[u, v] + offset, project_points(ref.K, ref.R, ref.C, X[front]), atol=1e-6)
        if not name.startswith("photo "):
            assert cam["extras"]["principal_point_offset_px"] == [0.0, 0.0]


def test_glb_passes_the_khronos_validator(exported):
    report = validate(exported["glb"].path)
    assert report["info"]["hasTextures"] and report["info"]["totalTriangleCount"] == exported["glb"].triangles
    assert report["info"]["extensionsUsed"] == ["KHR_materials_unlit"]


def test_glb_carries_a_photos_lens_distortion_in_its_camera_extras(textured, tmp_path):
    from vebuild.camera import distortion_displacement_px
    from vebuild.project.records import distortion_record

    proj = _copy_project(textured, tmp_path / "lens")
    project = load_project(proj)
    cams = project.data["calibration"]["cameras"]
    photo = project.data["photos"][1]
    K = np.asarray(cams[photo["id"]]["K"], float)
    k1 = -0.045  # a wide lens: barrel distortion of a few per cent at the corners
    cams[photo["id"]]["distortion"] = distortion_record(K, photo["width"], photo["height"], k1, 0.002, "test")
    save_project(project)
    res = export_model(load_project(proj), tmp_path / "lens.glb")
    doc, _ = read_glb(res.path.read_bytes())
    by_name = {c["name"]: c for c in doc["cameras"]}
    lens = by_name[f"photo {photo['id']}"]["extras"]["distortion"]
    assert lens["model"] == "division" and lens["k1"] == k1
    assert "x_u = x_d / (1 + k1 r^2 + k2 r^4), r = |x_d|" in lens["definition"]
    assert lens["corner_displacement_px"] == pytest.approx(
        distortion_displacement_px(K, photo["width"], photo["height"], Lens(k1)), rel=1e-12)
    assert lens["corner_displacement_px"] > 10  # visible: why a viewer must not ignore it
    # pinholes (every view, every other photo but p6, the example's wide lens) carry none, as before
    # lenses were modelled
    lensed = {f"photo {pid}" for pid, c in cams.items() if "distortion" in c}
    assert lensed == {f"photo {photo['id']}", "photo p6"}
    assert {n for n, c in by_name.items() if "distortion" in c["extras"]} == lensed
    validate(res.path)  # extras are free-form: the file stays valid glTF


# -- OBJ -------------------------------------------------------------------------------------------


def test_obj_reloads_with_the_scenes_vertices_and_textures(exported):
    scene, project, res = exported["scene"], exported["project"], exported["obj"]
    path = res.path
    text = path.read_text()
    assert "+Y up" in text.splitlines()[1] and "metres" in text.splitlines()[1]
    pages = project.data["textures"]["pages"]
    for k, page in enumerate(pages):
        copy = path.with_name(f"room_atlas_{k}.png")
        assert copy.read_bytes() == (project.folder / page["atlas"]).read_bytes()
        assert f"map_Kd {copy.name}" in path.with_suffix(".mtl").read_text()
    loaded = trimesh.load(path, split_objects=True, group_material=True, process=False)
    got: dict[str, list] = {}
    for gname, g in loaded.geometry.items():
        node, page = re.fullmatch(r"(.+)_atlas_(\d+)", gname).groups()
        page = int(page)
        w, h = pages[page]["width"], pages[page]["height"]
        img = np.asarray(g.visual.material.image.convert("RGB"))
        assert np.array_equal(img, np.asarray(Image.open(project.folder / pages[page]["atlas"]).convert("RGB")))
        X = np.asarray(g.vertices) @ Y_UP  # undo (x, z, −y)
        # Counter-clockwise from outside: each triangle's normal agrees with its vertices' vn.
        cross = np.cross(X[g.faces[:, 1]] - X[g.faces[:, 0]], X[g.faces[:, 2]] - X[g.faces[:, 0]])
        assert (np.einsum("ij,ij->i", cross, (np.asarray(g.vertex_normals) @ Y_UP)[g.faces].mean(axis=1)) > 0).all()
        A = np.c_[g.visual.uv[:, 0] * w, (1 - g.visual.uv[:, 1]) * h]
        got.setdefault(node, []).append(np.c_[X * 1e3, A, np.full(len(X), page)])
    pages_of = np.array([f.page for f in scene.mesh.faces])[scene.mesh.face_of_vertex - 1]
    for n in scene.model.nodes:
        if n.primitive is None:
            assert n.name not in got
            continue
        sel = _node_vertices(scene, n.name)
        want = np.c_[scene.mesh.vertices[sel] * 1e3, scene.mesh.atlas[sel], pages_of[sel]]
        mine = np.concatenate(got[n.name])
        _assert_same_points(mine, want, POSITION_TOL_M * 1e3, n.name)  # mm and texels, both well inside
    assert sum(len(g.faces) for g in loaded.geometry.values()) == len(scene.mesh.triangles)
    assert any("no cameras" in w for w in res.warnings)


# -- untextured ------------------------------------------------------------------------------------


@pytest.mark.parametrize("how", ["no textures", "page missing"])
def test_untextured_exports_face_colours_and_says_so(textured, tmp_path, how):
    proj = _copy_project(textured, tmp_path / "room")
    project = load_project(proj)
    if how == "no textures":
        del project.data["textures"]
        save_project(project)
    else:
        (proj.parent / project.data["textures"]["pages"][1]["atlas"]).unlink()
    scene = load_scene(project)
    res = export_model(project, tmp_path / "u.glb")
    assert not res.textured and any("exported untextured" in w for w in res.warnings)
    assert any(("no textures yet" if how == "no textures" else "missing") in w for w in res.warnings)
    doc, binary = read_glb(res.path.read_bytes())
    assert "images" not in doc and "extensionsUsed" not in doc and len(doc["materials"]) == 1
    worlds, _ = _worlds(doc)
    # Each vertex carries its face's colour: match vertices to the scene's by position and normal.
    key = np.c_[scene.mesh.vertices, scene.mesh.normals]
    tree = cKDTree(key)
    n = 0
    for i, gnode in enumerate(doc["nodes"]):
        if "mesh" not in gnode:
            continue
        (prim,) = doc["meshes"][gnode["mesh"]]["primitives"]
        W = _to_vebuild(worlds[i])
        X = trimesh.transform_points(_accessor(doc, binary, prim["attributes"]["POSITION"]), W)
        N = _accessor(doc, binary, prim["attributes"]["NORMAL"]) @ W[:3, :3].T
        d, k = tree.query(np.c_[X, N])
        assert d.max() < 1e-4
        colour = _accessor(doc, binary, prim["attributes"]["COLOR_0"])
        # Abutting faces of one orientation (the pieces of a wall) share corners: any of those faces.
        for c, near in zip(colour, tree.query_ball_point(np.c_[X, N], 1e-4), strict=True):
            want = scene.face_colour[scene.mesh.face_of_vertex[near] - 1]
            assert np.abs(want - c).max(axis=1).min() < 1e-6
        n += len(X)
    assert n == len(scene.mesh.vertices)
    if how == "page missing":  # the recorded average colours, not all grey
        avg = {(f["node"], f["face"]): f["average_colour_srgb"] for f in project.data["textures"]["faces"]}
        floor = next(f for f in scene.mesh.faces if f.node == "floor")
        np.testing.assert_allclose(scene.face_colour[floor.id - 1],
                                   srgb8_to_linear(np.array(avg[("floor", "top")], np.uint8)))
    validate(res.path)
    # OBJ: one material per face with its colour.
    obj = export_model(project, tmp_path / "u.obj")
    mtl = obj.path.with_suffix(".mtl").read_text()
    assert obj.pages == [] and "map_Kd" not in mtl
    kd = dict(re.findall(r"newmtl (\S+)\nKd (.+)\n", mtl))
    for f in scene.mesh.faces:
        np.testing.assert_allclose([float(v) for v in kd[f"{f.node}.{f.name}"].split()], scene.face_colour[f.id - 1],
                                   atol=1e-6)
    loaded = trimesh.load(obj.path, force="mesh", process=False)
    _assert_same_points(np.asarray(loaded.vertices) @ Y_UP, scene.mesh.vertices, POSITION_TOL_M, "untextured OBJ")


# -- bad output paths ------------------------------------------------------------------------------


def _nothing_written(folder: Path, before: set[str]) -> None:
    assert {p.name for p in folder.iterdir()} == before


def test_bad_output_paths_are_clear_errors_and_write_nothing(exported, tmp_path):
    project = exported["project"]
    with pytest.raises(VebuildError, match=r"nope/room\.glb: the output folder .*nope does not exist; create it first"):
        export_model(project, tmp_path / "nope" / "room.glb")
    with pytest.raises(VebuildError, match=r"room\.gltf: unknown export format '\.gltf'; expected a file name ending "
                                           r"in \.glb \(glTF 2\.0 binary\) or \.obj"):
        export_model(project, tmp_path / "room.gltf")
    with pytest.raises(VebuildError, match=r"room: unknown export format '\(no extension\)'"):
        export_model(project, tmp_path / "room")
    (tmp_path / "a.glb").mkdir()
    with pytest.raises(VebuildError, match=r"a\.glb: is a folder; give a file name ending in \.glb or \.obj"):
        export_model(project, tmp_path / "a.glb")
    (tmp_path / "file").write_text("")
    with pytest.raises(VebuildError, match=r"file is not a folder"):
        export_model(project, tmp_path / "file" / "room.obj")
    # One of the OBJ's companions cannot be written: nothing is, not even the texture copies.
    (tmp_path / "b.mtl").mkdir()
    before = {p.name for p in tmp_path.iterdir()}
    with pytest.raises(VebuildError, match=r"b\.obj: cannot write .*b\.mtl \(it is a folder\); nothing was written"):
        export_model(project, tmp_path / "b.obj")
    _nothing_written(tmp_path, before)
    # A folder that cannot be written (root may write anywhere but /sys).
    if os.geteuid() == 0:
        ro = Path("/sys")
        message = r"/sys/room\.glb: cannot write .*/sys/room\.glb \(.+\); nothing was written"
    else:
        ro = tmp_path / "read-only"
        ro.mkdir()
        ro.chmod(0o555)
        message = r"read-only/room\.glb: the output folder .*read-only cannot be written \(permission denied\)"
    try:
        with pytest.raises(VebuildError, match=message):
            export_model(project, ro / "room.glb")
    finally:
        if ro != Path("/sys"):
            ro.chmod(0o755)
    assert not list(tmp_path.glob(".*.tmp")) and not list(tmp_path.glob(".*.vebuild-tmp"))


# -- the command -----------------------------------------------------------------------------------


def test_vebuild_export_runs_end_to_end(textured, tmp_path, capsys):
    glb, obj = tmp_path / "room.glb", tmp_path / "room.obj"
    assert main(["export", str(textured), "--out", str(glb)]) == 0
    out = capsys.readouterr().out
    assert f"wrote {glb} (glTF 2.0 binary" in out
    assert "17 node(s), 15 mesh(es)" in out and "170 triangles" in out
    data = load_project(textured).data
    names = [v["name"] for v in data["views"]] + [f"photo {c}" for c in data["calibration"]["cameras"]]
    assert f"  {len(names)} camera(s): {', '.join(names)}\n" in out
    # 6 pages of 256²: the faces no photo sees have token charts (12 pages with full charts)
    assert "6 texture page(s), embedded" in out
    assert main(["export", str(textured), "--out", str(obj)]) == 0
    out = capsys.readouterr().out
    assert f"wrote {obj} (Wavefront OBJ + MTL" in out and "room_atlas_2.png" in out
    assert "warning: OBJ holds no cameras" in out and not re.search(r"^  \d+ camera\(s\)", out, re.M)
    assert read_glb(glb.read_bytes())[0]["asset"]["generator"] == f"vebuild {__version__}"
    assert main(["export", str(textured), "--out", str(tmp_path / "x.stl")]) == 2
    err = capsys.readouterr().err
    assert "vebuild export: error:" in err and "unknown export format '.stl'" in err and "Traceback" not in err
    assert main(["export", str(tmp_path / "missing.vebuild.json"), "--out", str(glb)]) == 2
    assert "missing.vebuild.json" in capsys.readouterr().err
