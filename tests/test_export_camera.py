"""`vebuild export PROJECT --camera PHOTO --out FILE.glb`: one calibrated photo with no model as a
glTF scene (vebuild/render/export_camera.py): the camera, the photo as a plane on its rays, the
floor grid, the axes and the saved measurements, checked by the Khronos validator and against
vebuild's own projection (principal point off centre, with and without lens distortion)."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
from gltf_validation import validate
from handoff_project import make_project
from scipy.spatial.transform import Rotation

from vebuild.analysis.recorded import run_recorded
from vebuild.camera import project as project_points
from vebuild.cli import main
from vebuild.errors import VebuildError
from vebuild.project import load_project, save_project
from vebuild.render.export import ROOT_NAME, ROOT_QUATERNION, read_glb
from vebuild.render.export_camera import PLANE_ERROR_PX

#: float32 positions in the file: a point ~40 m away is stored to ~4 µm, under 1/1000 px at these
#: focal lengths; this is what "exact" means for what the file stores.
FLOAT32_PX = 1e-3
#: A lens of a wide camera: barrel distortion that moves the photo's corners by ~30 px.
K1 = -0.04


def _accessor(doc: dict, binary: bytes, i: int) -> np.ndarray:
    a = doc["accessors"][i]
    view = doc["bufferViews"][a["bufferView"]]
    n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[a["type"]]
    dtype = {5126: np.float32, 5123: np.uint16, 5125: np.uint32}[a["componentType"]]
    raw = binary[view["byteOffset"]:view["byteOffset"] + view["byteLength"]]
    return np.frombuffer(raw, dtype=dtype, count=a["count"] * n).reshape(a["count"], n).astype(float)


def _world(doc: dict) -> dict[str, np.ndarray]:
    """Each node's 4×4 transform into vebuild's world (+Z up): the glTF world, then the root's turn undone."""
    def local(node: dict) -> np.ndarray:
        T = np.eye(4)
        if "rotation" in node:
            T[:3, :3] = Rotation.from_quat(node["rotation"]).as_matrix()
        if "translation" in node:
            T[:3, 3] = node["translation"]
        return T

    out: dict[str, np.ndarray] = {}

    def walk(i: int, parent: np.ndarray) -> None:
        T = parent @ local(doc["nodes"][i])
        out[doc["nodes"][i]["name"]] = T
        for c in doc["nodes"][i].get("children", []):
            walk(c, T)

    walk(0, np.eye(4))
    undo = np.eye(4)
    undo[:3, :3] = Rotation.from_quat(ROOT_QUATERNION).as_matrix().T  # vebuild world from glTF world
    return {k: undo @ v for k, v in out.items()}


@pytest.fixture(scope="module", params=[0.0, K1], ids=["pinhole", "k1"])
def exported(request, tmp_path_factory):
    h = make_project(tmp_path_factory.mktemp("camera-glb"), k1=request.param)
    out = h.path.parent / "camera.glb"
    assert main(["export", str(h.path), "--camera", "p", "--out", str(out)]) == 0
    doc, binary = read_glb(out.read_bytes())
    return h, out, doc, binary


def test_camera_glb_passes_the_khronos_validator(exported):
    _, out, doc, _ = exported
    report = validate(out)
    assert report["info"]["hasTextures"] and report["issues"]["numWarnings"] == 0
    assert doc["nodes"][0]["name"] == ROOT_NAME and doc["nodes"][0]["rotation"] == ROOT_QUATERNION


def test_the_glTF_camera_is_the_photo_s(exported):
    """yfov from f and the height, the aspect ratio, the pose: a viewer using the glTF camera as it is
    (principal point at the centre) puts every point where vebuild does, shifted by the principal
    point's offset, which the camera's extras give."""
    h, _, doc, _ = exported
    cam = h.cam
    (gcam,) = doc["cameras"]
    p = gcam["perspective"]
    f = cam.K[1][1]
    assert p["yfov"] == pytest.approx(2 * np.arctan(cam.height / 2 / f), rel=1e-12)
    assert p["aspectRatio"] == pytest.approx(cam.width / cam.height, rel=1e-12)
    offset = np.asarray(gcam["extras"]["principal_point_offset_px"])
    assert np.linalg.norm(offset) > 10  # the fixture's principal point is off centre
    T = _world(doc)["photo p"]
    X = np.c_[np.random.default_rng(0).uniform(-3, 3, (50, 2)) + np.asarray(cam.C)[:2], np.zeros(50)]
    x = (X - T[:3, 3]) @ T[:3, :3]  # glTF camera frame: looking along −z, y up
    front = x[:, 2] < -0.1
    t = np.tan(p["yfov"] / 2)
    u = (x[front, 0] / -x[front, 2] / (t * p["aspectRatio"]) + 1) / 2 * cam.width
    v = (1 - x[front, 1] / -x[front, 2] / t) / 2 * cam.height
    np.testing.assert_allclose(np.c_[u, v] + offset, project_points(cam.K, cam.R, cam.C, X[front]), atol=1e-6)
    assert p["zfar"] > doc["nodes"][[n["name"] for n in doc["nodes"]].index("photo p plane")]["extras"]["distance"]


def test_each_photo_pixel_lies_on_its_own_ray(exported):
    """The photo plane: every vertex projects through vebuild's camera (lens included) onto the pixel
    its texture coordinate names; and a floor point seen through the plane (the glTF's pinhole camera
    as a viewer draws it) falls on the texel vebuild projects it to, within the plane's stated error."""
    h, _, doc, binary = exported
    cam = h.cam
    names = [n["name"] for n in doc["nodes"]]
    node = doc["nodes"][names.index("photo p plane")]
    prim = doc["meshes"][node["mesh"]]["primitives"][0]
    pos = _accessor(doc, binary, prim["attributes"]["POSITION"])
    uv = _accessor(doc, binary, prim["attributes"]["TEXCOORD_0"]) * [cam.width, cam.height]
    tris = _accessor(doc, binary, prim["indices"]).astype(int).reshape(-1, 3)
    T = _world(doc)["photo p plane"]
    P = pos @ T[:3, :3].T + T[:3, 3]
    got = project_points(cam.K, cam.R, cam.C, P, cam.lens)
    assert np.max(np.linalg.norm(got - uv, axis=1)) < FLOAT32_PX
    err = node["extras"]["texture_error_px"]
    assert (err == 0.0) == (cam.lens.is_pinhole) and err <= PLANE_ERROR_PX
    assert len(tris) == 2 if cam.lens.is_pinhole else len(tris) > 2
    # Floor points through the plane: the ray from the camera to X meets the plane at Q; the texel the
    # plane shows at Q is where vebuild's camera (with its lens) puts X.
    x = (P - cam.C) @ np.asarray(cam.R).T  # vebuild camera frame
    q = x[:, :2] / x[:, 2:]
    X = h.ph.truth("F1"), h.ph.truth("F2"), h.ph.truth("box_foot"), h.ph.truth("O")
    for Xw in X:
        xc = np.asarray(cam.R) @ (Xw - np.asarray(cam.C))
        s = xc[:2] / xc[2]
        a, b, c = q[tris[:, 0]], q[tris[:, 1]], q[tris[:, 2]]
        M = np.stack([b - a, c - a], axis=2)
        lam = np.linalg.solve(M, (s - a)[..., None])[..., 0]
        w = np.c_[1 - lam.sum(1), lam]
        k = int(np.argmax(np.all(w >= -1e-9, axis=1)))
        assert np.all(w[k] >= -1e-9)
        texel = w[k] @ uv[tris[k]]
        want = project_points(cam.K, cam.R, cam.C, Xw[None], cam.lens)[0]
        assert np.linalg.norm(texel - want) <= PLANE_ERROR_PX + FLOAT32_PX, (texel, want)


def test_floor_grid_axes_and_measurements(exported):
    h, _, doc, binary = exported
    project = load_project(h.path)
    nodes = {n["name"]: n for n in doc["nodes"]}
    world = _world(doc)
    grid = nodes["floor grid (z = 0)"]
    g = _accessor(doc, binary, doc["meshes"][grid["mesh"]]["primitives"][0]["attributes"]["POSITION"])
    g = g @ world["floor grid (z = 0)"][:3, :3].T + world["floor grid (z = 0)"][:3, 3]
    assert doc["meshes"][grid["mesh"]]["primitives"][0]["mode"] == 1  # lines
    assert np.max(np.abs(g[:, 2])) < 1e-9
    spacing = grid["extras"]["spacing"]
    assert spacing == 1.0 and np.allclose(np.round(g[:, :2] / spacing), g[:, :2] / spacing, atol=1e-5)
    # The grid reaches every measured point and the camera's foot.
    x0, x1, y0, y1 = grid["extras"]["bounds_xy"]
    for name in ("F1", "F2", "box_foot"):
        X = h.ph.truth(name)
        assert x0 <= X[0] <= x1 and y0 <= X[1] <= y1, name
    axes = doc["meshes"][nodes["axes"]["mesh"]]["primitives"][0]
    a = _accessor(doc, binary, axes["attributes"]["POSITION"]).reshape(3, 2, 3)
    colours = _accessor(doc, binary, axes["attributes"]["COLOR_0"]).reshape(3, 2, 3)
    assert np.allclose(a[:, 1] - a[:, 0], np.eye(3) * spacing) and np.allclose(colours[:, 0], np.eye(3))
    # Each measurement: a line named by its label, its figures those `vebuild analyse` gives.
    for i, rec in enumerate(project.data["analyses"]):
        _, result = run_recorded(project, i, rec)
        (m,) = result.figures["measurements"]
        (name,) = [n for n in nodes if n.startswith(rec["name"] + ":")]
        ex = nodes[name]["extras"]
        assert ex["value"] == m["value_m"] and ex["sigma"] == m["sigma_m"] and ex["ci95"] == m["ci95_m"]
        assert ex["command"] == rec["command"] and f"{m['value_m']:.3f} m" in name
        prim = doc["meshes"][nodes[name]["mesh"]]["primitives"][0]
        ends = _accessor(doc, binary, prim["attributes"]["POSITION"])
        ends = ends @ world[name][:3, :3].T + world[name][:3, 3]
        clicks = np.asarray(ex["clicks"])
        foot = project_points(h.cam.K, h.cam.R, h.cam.C, ends[:1], h.cam.lens)[0]
        assert np.linalg.norm(foot - clicks[0]) < FLOAT32_PX  # the foot (first floor point) on its click
        if m["quantity"] == "height":
            assert ends[1][2] - ends[0][2] == pytest.approx(m["value_m"], abs=1e-5)
            assert np.allclose(ends[1][:2], ends[0][:2], atol=1e-6)
        else:
            assert np.linalg.norm(ends[1] - ends[0]) == pytest.approx(m["value_m"], abs=1e-5)
            assert np.linalg.norm(project_points(h.cam.K, h.cam.R, h.cam.C, ends[1:], h.cam.lens)[0] - clicks[1]) \
                < FLOAT32_PX


def test_out_on_a_project_with_no_model_hands_on_its_one_photo(tmp_path, capsys):
    h = make_project(tmp_path / "p")
    out = tmp_path / "p" / "only.glb"
    assert main(["export", str(h.path), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "the calibrated camera with no model" in text and "photo p, 2 measurement(s)" in text
    assert "principal point offset" in text and "floor grid every 1" in text
    magic, version, length = struct.unpack_from("<III", out.read_bytes(), 0)
    assert magic == 0x46546C67 and version == 2 and length == out.stat().st_size


@pytest.mark.parametrize("args, said", [
    (["--camera", "q", "--out", "x.glb"], "--camera q: the project has no photo 'q'; its photos are p"),
    (["--camera", "p", "--out", "x.obj"], "with --camera, expected a file name ending in .glb"),
    (["--camera", "p", "--out", "nowhere/x.glb"], "the output folder"),
])
def test_bad_requests_are_named(tmp_path, capsys, args, said):
    h = make_project(tmp_path / "p")
    args = [a if not a.endswith((".glb", ".obj")) else str(tmp_path / a) for a in args]
    assert main(["export", str(h.path), *args]) != 0
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err


def test_an_uncalibrated_photo_is_named_with_what_to_do(tmp_path, capsys):
    h = make_project(tmp_path / "p")
    project = load_project(h.path)
    project.data.pop("calibration")
    save_project(project)
    assert main(["export", str(h.path), "--out", str(tmp_path / "x.glb")]) != 0
    err = capsys.readouterr().err
    assert "no photo is calibrated yet; run `vebuild calibrate" in err


def test_a_measurement_of_another_photo_is_not_drawn(tmp_path):
    from vebuild.actions.handoff import measurement_items

    h = make_project(tmp_path / "p")
    project = load_project(h.path)
    assert [it["record"] for it in measurement_items(project, "p")] == ["box height", "F1 to F2"]
    project.data["analyses"][1]["command"][2] = "other"
    assert [it["record"] for it in measurement_items(project, "p")] == ["box height"]
    with pytest.raises(VebuildError, match="no photo 'other'|other"):
        from vebuild.actions.handoff import calibrated_photo
        calibrated_photo(project, "other")
    json.dumps(measurement_items(project, "p"))  # plain data, for data.js


def test_a_photo_turned_by_its_exif_orientation_is_handed_on_upright(tmp_path):
    """glTF textures and Blender ignore EXIF orientation: a photo stored on its side (orientation 6)
    is embedded as an upright copy of the pixels vebuild shows, and the note says so."""
    import io

    from PIL import Image

    from vebuild.project.handoff_image import handoff_image
    from vebuild.project.images import sha256_bytes

    h = make_project(tmp_path / "p")
    shown = np.zeros((1200, 1600, 3), np.uint8)
    shown[:, :800] = (200, 30, 30)  # left half red as shown
    stored = Image.fromarray(shown).transpose(Image.Transpose.ROTATE_90)  # 1200 × 1600 on its side
    exif = Image.Exif()
    exif[274] = 6  # display turned 90° clockwise
    buf = io.BytesIO()
    stored.save(buf, "JPEG", quality=95, exif=exif)
    project = load_project(h.path)
    (h.path.parent / "photos" / "p.jpg").write_bytes(buf.getvalue())
    project.data["photos"][0]["sha256"] = sha256_bytes(buf.getvalue())
    save_project(project)
    image = handoff_image(load_project(h.path), "p", 4096)
    assert not image.original and image.size == (1600, 1200) and "turned upright by its EXIF orientation" in image.note
    pixels = np.asarray(Image.open(io.BytesIO(image.data)).convert("RGB")).astype(float)
    assert pixels[:, :700, 0].mean() > 150 and pixels[:, 900:, 0].mean() < 40  # red on the left, as shown
    assert handoff_image(load_project(h.path), "p", 800).size == (800, 600)


def test_which_photo_the_viewer_shows_is_asked_where_several_are_calibrated(tmp_path, capsys):
    import copy

    h = make_project(tmp_path / "p")
    project = load_project(h.path)
    second = copy.deepcopy(project.data["photos"][0])
    second["id"] = "q"
    project.data["photos"].append(second)
    project.data["calibration"]["cameras"]["q"] = copy.deepcopy(project.data["calibration"]["cameras"]["p"])
    save_project(project)
    assert main(["export", str(h.path), "--html", str(tmp_path / "viewer")]) != 0
    assert "2 photos are calibrated (p, q); say which with --camera PHOTO" in capsys.readouterr().err
    assert main(["export", str(h.path), "--html", str(tmp_path / "viewer"), "--camera", "q"]) == 0
    assert '"cameras":["photo-q"]' in (tmp_path / "viewer" / "data.js").read_text()


def test_camera_with_html_on_a_project_with_a_model_is_refused(textured_room, capsys):
    assert main(["export", str(textured_room), "--html", str(textured_room.parent / "v"), "--camera", "p1"]) != 0
    err = capsys.readouterr().err
    assert "--camera p1: the project has a model, and its viewer shows every photo; leave out --camera" in err
