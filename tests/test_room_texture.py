"""A room's mesh through texture extraction and export: every logical face of an L-shaped room
with a door and a window (floor, each wall's inner and outer face with its holes, the wall tops,
the openings' reveals) is seen by some photo and gets texels, in the CPU reference of extraction
and on the GPU; the glTF export of a room passes the Khronos validator."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from vebuild.camera import ImageCamera
from vebuild.model.scene import model_from_dict
from vebuild.texture import layout as lay
from vebuild.texture import reference as ref
from vebuild.texture.options import Options

REPO = Path(__file__).resolve().parents[1]
MARKERS = {"O": np.zeros(3)}
ROOM = {"type": "room", "corners": 6,
        "params": {"c1_x": 5.0, "c2_y": 2.5, "c3_x": 2.5, "c4_y": 4.0, "height": 2.6, "thickness": 0.1,
                   "door_offset": 1.2, "door_width": 0.9, "door_height": 2.05, "door_sill": 0.0,
                   "win_offset": 0.8, "win_width": 1.2, "win_height": 1.1, "win_sill": 0.9},
        "openings": [{"name": "door", "wall": 0, "kind": "door"}, {"name": "win", "wall": 4, "kind": "window"}]}
NODES = [{"name": "room", "primitive": ROOM, "joint": {"type": "marker", "marker": "O", "handle": "f0"}}]
#: Photos in and around the room: (position, looking at). Inside at eye height toward every wall
#: and up at the openings' heads; outside, high, toward each outer face; one from above.
VIEWS = [((4.6, 0.4, 1.6), (0.5, 3.5, 1.0)), ((0.5, 3.6, 1.7), (4.0, 0.8, 1.0)), ((0.6, 0.5, 1.6), (4.5, 2.4, 1.0)),
         ((4.5, 2.1, 1.5), (0.3, 0.3, 1.2)), ((2.0, 1.5, 1.0), (1.6, 0.0, 1.8)), ((0.3, 1.0, 1.2), (1.9, 0.0, 1.0)),
         ((2.2, 2.0, 1.2), (1.1, 4.0, 1.5)), ((0.2, 3.0, 1.2), (1.8, 4.0, 1.4)),
         ((2.5, -6.0, 3.0), (2.5, 2.0, 1.0)), ((11.0, 1.5, 3.0), (2.5, 1.5, 1.0)), ((7.0, 8.0, 3.0), (3.0, 2.5, 1.0)),
         ((-6.0, 2.0, 3.0), (2.5, 2.0, 1.0)), ((2.5, 2.2, 9.0), (2.5, 2.0, 0.0))]
W, H, F = 400, 300, 240.0
#: Texels per metre: the reveals (0.1 m deep) get 3 texels across.
DENSITY = 30.0


def look_at(C: np.ndarray, target: np.ndarray) -> np.ndarray:
    z = (target - C) / np.linalg.norm(target - C)
    x = np.cross(z, [0, 0, 1.0])
    x /= np.linalg.norm(x)
    return np.vstack([x, np.cross(z, x), z])


def cameras() -> list[ImageCamera]:
    K = np.array([[F, 0, W / 2], [0, F, H / 2], [0, 0, 1.0]])
    return [ImageCamera(f"p{k}", K, look_at(np.array(C, float), np.array(T, float)), np.array(C, float), W, H)
            for k, (C, T) in enumerate(VIEWS)]


def room_names(model) -> list[str]:
    return model.node("room").primitive.mesh().face_names


def test_every_face_of_a_room_gets_texels_in_the_reference_extraction() -> None:
    model = model_from_dict(NODES, MARKERS)
    faces = lay.layout(model, DENSITY, 2048, 1024)
    names = room_names(model)
    assert [f.name for f in faces] == names and "door_reveal" in names and "wall0" in names
    mesh = lay.scene_mesh(model, faces)
    cams = cameras()
    photos = (np.full((H, W, 3), 128, np.uint8) for _ in cams)
    sums = ref.accumulate(mesh, cams, photos, Options(texels_per_metre=DENSITY, erode_px=0.0, drop_ratio=0.0))
    for f in faces:
        x0, y0, w, h = f.rect
        views = sums[f.page]["counts"][y0:y0 + h, x0:x0 + w, 0]
        assert (views > 0).sum() >= 3, f"face {f.name}: no photo gives it texels"
    # The door and the window are holes: no texel of their walls' inner faces lies in them.
    for wall, (lo, hi), (z0, z1), axis, at in (("wall0", (1.2, 2.1), (0.0, 2.05), 0, 0.0),
                                                ("wall4", (0.5, 1.7), (0.9, 2.0), 0, 4.0)):
        face = next(f for f in faces if f.name == wall)
        tx = ref.page_texels(mesh, face.page)
        P = tx.position[tx.face == face.id]
        assert len(P) > 100 and np.abs(P[:, 1] - at).max() < 1e-6
        margin = 1.0 / DENSITY  # a texel centre within a texel of the hole's edge may sample the wall
        inside = ((P[:, axis] > lo + margin) & (P[:, axis] < hi - margin) & (P[:, 2] > z0 + margin)
                  & (P[:, 2] < z1 - margin))
        assert not inside.any(), f"{wall}: texels in its opening"


@pytest.fixture(scope="module")
def gl():
    from vebuild.gl import headless_context

    return headless_context()


def test_every_face_of_a_room_gets_texels_on_the_gpu(gl) -> None:
    from vebuild.texture.gpu import Extractor

    model = model_from_dict(NODES, MARKERS)
    faces = lay.layout(model, DENSITY, 2048, 1024)
    mesh = lay.scene_mesh(model, faces)
    ex = Extractor(gl, mesh, Options(texels_per_metre=DENSITY, erode_px=0.0, drop_ratio=0.0))
    try:
        for cam in cameras():
            ex.photo_id_pass(cam)
            ex.upload_photo(cam, np.full((H, W, 3), 128, np.uint8))
            ex.add_photo(cam)
        ex.release_photo()
        seen = {f.id: 0 for f in faces}
        for c in ex.contributions().values():
            for fid, n in c.items():
                seen[fid] += n
    finally:
        ex.release()
    for f in faces:
        assert seen[f.id] > 0, f"face {f.name}: no photo gives it texels on the GPU"


def test_a_room_exports_to_a_valid_gltf(tmp_path: Path) -> None:
    from vebuild.project import load_project
    from vebuild.render.export import export_model, read_glb

    path = tmp_path / "r.vebuild.json"
    path.write_text(json.dumps({"format": "vebuild-project", "version": 1, "name": "r",
                                "settings": {"click_sigma_px": 0.7}, "reference_distances": [], "photos": [],
                                "markers": [{"name": "O"}], "origin_marker": "O",
                                # Not calibrated: a fixed joint rather than the origin marker's.
                                "model": {"nodes": [{**NODES[0], "joint": {"type": "fixed"}}]}}))
    res = export_model(load_project(path), tmp_path / "r.glb")
    doc, _ = read_glb(res.path.read_bytes())
    (room,) = [n for n in doc["nodes"] if n.get("name") == "room"]
    assert room["extras"]["primitive"]["type"] == "room"
    node = shutil.which("node")
    if node is None:
        pytest.fail("Node.js (v18 or later) is needed to run the Khronos glTF validator")
    r = subprocess.run([node, str(REPO / "tests" / "gltf_validate.mjs"), str(res.path)], capture_output=True,
                       text=True, timeout=120, cwd=REPO)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]


def test_a_room_renders_with_its_openings_open(gl) -> None:
    """`vebuild render`'s renderer on a room: from inside, the ID buffer shows the wall around the
    doorway and the window, the sky (nothing) through them, and their reveals at their sides."""
    from vebuild.camera import project
    from vebuild.render.renderer import Renderer, RenderOptions
    from vebuild.render.scene import scene_from_model

    model = model_from_dict(NODES, MARKERS)
    scene = scene_from_model(model)
    r = Renderer(gl, scene, RenderOptions(samples=1, anisotropy=1.0))
    try:
        for C, target, wall, reveal, hole in (
                ((3.4, 2.0, 1.2), (1.65, 0.0, 1.0), "wall0", "door_reveal", (1.65, 0.0, 1.0)),
                ((1.6, 1.5, 1.4), (1.1, 4.0, 1.45), "wall4", "win_reveal", (1.1, 4.0, 1.45))):
            K = np.array([[F, 0, W / 2], [0, F, H / 2], [0, 0, 1.0]])
            cam = ImageCamera("v", K, look_at(np.array(C, float), np.array(target, float)), np.array(C, float), W, H)
            ids, _ = r.id_buffer(cam)
            name = {f.id: f.name for f in scene.mesh.faces}
            u, v = project(cam.K, cam.R, cam.C, np.array(hole, float))
            assert ids[int(v), int(u)] == 0, "the opening's middle shows nothing: it is a hole"
            seen = {name[i] for i in np.unique(ids) if i}
            assert {wall, reveal} <= seen, seen
    finally:
        r.release()
