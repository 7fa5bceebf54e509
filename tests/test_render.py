"""The renderer (paper §5) on the headless GL context, checked by properties of known scenes.

GL runs for real here (Mesa's llvmpipe where there is no GPU); CI installs it. The checks are
independent of the renderer: pixels are traced with trimesh's ray queries from rays built here
from K, R, C, and colours are sampled from the atlas with numpy.
"""

from __future__ import annotations

import json
import re
import shutil

import numpy as np
import pytest
import trimesh
from PIL import Image
from render_scenes import box_on_floor_model, off_centre_camera

from vebuild.actions.render import RenderRequest, render_evidence
from vebuild.camera import ImageCamera, look_rotation, project, stereo_pair
from vebuild.cli import main
from vebuild.errors import ProjectError, VebuildError
from vebuild.gl import headless_context
from vebuild.lighting import AS_PHOTOGRAPHED_LIGHTING
from vebuild.model.scene import model_from_dict
from vebuild.project import load_project
from vebuild.project.decode import preset_from_record
from vebuild.project.provenance import inputs_sha256
from vebuild.render.png import PROVENANCE_KEYS
from vebuild.render.renderer import Renderer, RenderOptions, Stereo
from vebuild.render.scene import load_scene, scene_from_model
from vebuild.render.sizes import parse_size
from vebuild.texture import layout as lay
from vebuild.texture.merge import linear_to_srgb8, srgb8_to_linear

#: Exact sampling for the checks: one sample per pixel, trilinear filtering only.
EXACT = RenderOptions(samples=1, anisotropy=1.0)
#: sRGB levels between a rendered pixel and the numpy bilinear sample of its texel: llvmpipe
#: filters with 8-bit weights and decodes sRGB approximately (texture tests measured 2e-3 in
#: linear light, under one level); 3 levels leaves room for both, while a texel one step off
#: changes a random texture by ~85 levels on average.
TEXEL_TOL_LEVELS = 3


def _textured_scene(rng, texels_per_metre=40.0):
    model = box_on_floor_model()
    faces = lay.layout(model, texels_per_metre, 512, 1024)
    (w, h), = lay.page_sizes(faces)
    page = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    record = {"faces": [{"id": f.id, "node": f.node, "face": f.name, "size_m": list(f.size_m), "page": f.page,
                         "rect": list(f.rect), "average_colour_srgb": [128, 128, 128]} for f in faces]}
    return scene_from_model(model, record, [page]), page


def _trace(scene, cam):
    """For every pixel centre: the hit triangle (−1: none) and world point, by trimesh's ray queries."""
    j, i = np.mgrid[0:cam.height, 0:cam.width]
    pix = np.stack([i + 0.5, j + 0.5, np.ones_like(i, float)], -1).reshape(-1, 3)
    d = (np.linalg.inv(cam.K) @ pix.T).T @ cam.R  # rows: Rᵀ K⁻¹ [u, v, 1]
    mesh = trimesh.Trimesh(scene.mesh.vertices, scene.mesh.triangles, process=False)
    loc, ray, tri = mesh.ray.intersects_location(np.tile(cam.C, (len(d), 1)), d, multiple_hits=False)
    hit_tri = np.full(len(d), -1)
    hit_tri[ray] = tri
    points = np.full((len(d), 3), np.nan)
    points[ray] = loc
    return hit_tri.reshape(cam.height, cam.width), points.reshape(cam.height, cam.width, 3), mesh


def _bilinear_srgb(page, xy):
    """The page sampled bilinearly in linear light at atlas positions xy (texel centres at i + ½)."""
    lin = srgb8_to_linear(page)
    x, y = xy[:, 0] - 0.5, xy[:, 1] - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    h, w = page.shape[:2]
    def at(yy, xx):
        return lin[np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)]
    c = (at(y0, x0) * (1 - fx) * (1 - fy) + at(y0, x0 + 1) * fx * (1 - fy)
         + at(y0 + 1, x0) * (1 - fx) * fy + at(y0 + 1, x0 + 1) * fx * fy)
    return linear_to_srgb8(c).astype(int)


@pytest.fixture(scope="module")
def ctx():
    return headless_context()


# -- where texels land ------------------------------------------------------------------------------


def test_each_texel_lands_on_the_pixel_an_independent_projection_gives(ctx, rng):
    scene, page = _textured_scene(rng)
    cam = off_centre_camera([2.3, -1.2, 1.9], [2.1, 1.4, 0.2])
    r = Renderer(ctx, scene, EXACT)
    img = r.render(cam).astype(int)
    r.release()
    tri, points, mesh = _trace(scene, cam)
    # Atlas position of each traced point, by barycentric interpolation of its triangle's corners.
    hit = tri >= 0
    t = scene.mesh.triangles[tri[hit]]
    bary = trimesh.triangles.points_to_barycentric(scene.mesh.vertices[t], points[hit])
    atlas = np.full(tri.shape + (2,), np.nan)
    atlas[hit] = np.einsum("nk,nkd->nd", bary, scene.mesh.atlas[t])
    # Keep pixels magnified (< 0.7 texel per pixel: the base level is sampled) whose neighbours lie
    # on the same face (no silhouette or face border in the pixel's filter support).
    face = np.where(hit, scene.mesh.face_of_vertex[scene.mesh.triangles[np.maximum(tri, 0), 0]], 0)
    same = np.zeros_like(hit)
    same[1:-1, 1:-1] = ((face[1:-1, 1:-1] > 0) & (face[1:-1, 1:-1] == face[:-2, 1:-1]) & (face[1:-1, 1:-1] ==
                        face[2:, 1:-1]) & (face[1:-1, 1:-1] == face[1:-1, :-2]) & (face[1:-1, 1:-1] == face[1:-1, 2:]))
    step = np.zeros(tri.shape)
    step[:-1, :-1] = np.maximum(np.abs(atlas[1:, :-1] - atlas[:-1, :-1]).max(-1),
                                np.abs(atlas[:-1, 1:] - atlas[:-1, :-1]).max(-1))
    keep = same & (step < 0.7)
    assert keep.sum() > 20000  # most of the image: floor and three faces of the box
    # Stay two texels inside each chart: the gutter around it holds other colours.
    rects = np.array([f.rect for f in scene.mesh.faces], float)[face[keep] - 1]
    a = atlas[keep]
    inside = np.all((a >= rects[:, :2] + 2) & (a <= rects[:, :2] + rects[:, 2:] - 2), axis=1)
    want = _bilinear_srgb(page, a[inside])
    got = img[keep][inside]
    err = np.abs(got - want).max(axis=1)
    assert np.median(err) <= 1
    assert np.mean(err <= TEXEL_TOL_LEVELS) >= 0.99, np.percentile(err, [50, 90, 99, 100])
    # The background is where no ray hits (but for pixel centres within rounding of a silhouette).
    bg = np.array(EXACT.background_srgb)
    assert np.mean(np.all(img[~hit] == bg, axis=-1)) > 0.999


def test_untextured_faces_show_their_colour_and_alpha_is_coverage(ctx):
    scene = scene_from_model(box_on_floor_model())
    assert not scene.textured
    cam = off_centre_camera([2.3, -1.2, 1.9], [2.1, 1.4, 0.2])
    r = Renderer(ctx, scene, RenderOptions(samples=4))
    rgba = r.render_rgba(cam)
    r.release()
    tri, points, _ = _trace(scene, cam)
    inside = rgba[..., 3] == 255
    # Anti-aliased: partial coverage only along silhouettes, and coverage matches the traced hits.
    assert np.mean(inside == (tri >= 0)) > 0.99
    assert 0 < np.mean((rgba[..., 3] > 0) & (rgba[..., 3] < 255)) < 0.02
    # Untextured faces are their colour shaded by the angle to the eye: 0.5 + 0.5 |cos|.
    ok = inside & (tri >= 0)
    n = scene.mesh.normals[scene.mesh.triangles[tri[ok], 0]]
    to_eye = cam.C - points[ok]
    cos = np.abs(np.einsum("ij,ij->i", n, to_eye)) / np.linalg.norm(to_eye, axis=1)
    grey = srgb8_to_linear(np.array([190], np.uint8))[0]
    want = linear_to_srgb8(grey * (0.5 + 0.5 * cos)).astype(int)
    err = np.abs(rgba[ok][:, 0].astype(int) - want)
    assert np.mean(err <= 2) > 0.99


# -- shadows ----------------------------------------------------------------------------------------


def test_a_shadow_falls_where_geometry_says(ctx):
    scene = scene_from_model(box_on_floor_model())
    sun = np.array([-0.6, -0.3, -1.0])  # the shadow falls toward the camera
    ambient = 0.2
    lighting = preset_from_record({"name": "sun", "ambient": [ambient] * 3,
                                   "lights": [{"type": "directional", "direction": sun.tolist(), "intensity": 0.8}]})
    cam = off_centre_camera([0.2, -0.8, 2.6], [2.6, 1.6, 0.0], f=260.0)
    r = Renderer(ctx, scene, RenderOptions(samples=1, shadow_size=2048))
    r.set_lighting(lighting)
    img = srgb8_to_linear(r.render(cam))[..., 0]
    r.release()
    tri, points, mesh = _trace(scene, cam)
    floor_tris = np.flatnonzero(scene.node_of_face[scene.mesh.triangle_faces - 1] == scene.node_names.index("floor"))
    on_floor = np.isin(tri, floor_tris)
    # Independent shadow test: does a ray from the floor point toward the sun hit anything?
    L = -sun / np.linalg.norm(sun)
    P = points[on_floor] + 1e-4 * np.array([0, 0, 1.0])
    blocked = mesh.ray.intersects_any(P, np.tile(L, (len(P), 1)))
    # Leave out a band of 3 cm around the shadow's edge (the filter's soft edge: 1.5 shadow texels
    # of 2.5 mm, and a pixel's footprint here), found by moving each point ± 3 cm sideways.
    side = np.cross(L, [0, 0, 1.0])
    side /= np.linalg.norm(side)
    fwd = np.cross([0, 0, 1.0], side)
    near_edge = np.zeros(len(P), bool)
    for off in (0.03 * side, -0.03 * side, 0.03 * fwd, -0.03 * fwd):
        near_edge |= mesh.ray.intersects_any(P + off, np.tile(L, (len(P), 1))) != blocked
    grey = srgb8_to_linear(np.array([190], np.uint8))[0]
    cos = float(L[2])
    lit_want, dark_want = grey * (ambient + 0.8 * cos), grey * ambient
    value = img[on_floor]
    shadowed = value < 0.5 * (lit_want + dark_want)
    clear = ~near_edge
    assert blocked[clear].sum() > 500 and (~blocked[clear]).sum() > 5000
    assert np.mean(shadowed[clear] == blocked[clear]) > 0.995
    np.testing.assert_allclose(np.median(value[clear & blocked]), dark_want, rtol=0.03)
    np.testing.assert_allclose(np.median(value[clear & ~blocked]), lit_want, rtol=0.03)


@pytest.mark.parametrize("light", [
    {"type": "point", "position": [2.0, 1.0, 1.6], "intensity": 2.0},
    {"type": "spot", "position": [3.4, 2.6, 1.8], "direction": [-1.0, -1.1, -1.2], "outer_cone_deg": 40.0,
     "inner_cone_deg": 35.0, "intensity": 3.0},
])
def test_point_and_spot_light_shadows_fall_where_geometry_says(ctx, light):
    scene = scene_from_model(box_on_floor_model())
    cam = off_centre_camera([0.2, -0.8, 2.6], [2.6, 1.6, 0.0], f=260.0)
    r = Renderer(ctx, scene, RenderOptions(samples=1))
    r.set_lighting(preset_from_record({"name": "lamp", "ambient": [0.1] * 3, "lights": [light]}))
    img = srgb8_to_linear(r.render(cam))[..., 0]
    r.release()
    tri, points, mesh = _trace(scene, cam)
    floor_tris = np.flatnonzero(scene.node_of_face[scene.mesh.triangle_faces - 1] == scene.node_names.index("floor"))
    on_floor = np.isin(tri, floor_tris)
    P = points[on_floor] + 1e-4 * np.array([0, 0, 1.0])
    to_light = np.asarray(light["position"]) - P
    dist = np.linalg.norm(to_light, axis=1)
    L = to_light / dist[:, None]
    blocked = mesh.ray.intersects_any(P, L)
    hits, idx, _ = mesh.ray.intersects_location(P, L, multiple_hits=False)
    # Only occluders between the point and the light count.
    really = np.zeros(len(P), bool)
    really[idx] = np.linalg.norm(hits - P[idx], axis=1) < dist[idx]
    blocked &= really
    grey = srgb8_to_linear(np.array([190], np.uint8))[0]
    E = light["intensity"] * L[:, 2] / dist**2
    if light["type"] == "spot":
        d = np.asarray(light["direction"], float) / np.linalg.norm(light["direction"])
        inside_cone = (-L @ d) > np.cos(np.radians(light["inner_cone_deg"]))
    else:
        inside_cone = np.ones(len(P), bool)
    value = img[on_floor]
    lit_want = grey * (0.1 + E)
    dark_want = grey * 0.1
    decided = inside_cone & (E > 0.15)  # clearly lit where nothing blocks
    is_dark = np.abs(value - dark_want) < np.abs(value - lit_want)
    # 97 %: the soft edge of the filter is a few centimetres wide here and not excluded.
    assert blocked[decided].sum() > 200 and (~blocked[decided]).sum() > 2000
    assert np.mean(is_dark[decided] == blocked[decided]) > 0.97


# -- stereo -----------------------------------------------------------------------------------------


def test_stereo_eyes_are_parallel_and_off_axis():
    cam = off_centre_camera([0, 0, 1.6], [3, 1, 1.2], f=800.0, w=1280, h=720)
    left, right = stereo_pair(cam, 0.063, 2.5)
    np.testing.assert_array_equal(left.R, cam.R)  # parallel, not toe-in
    np.testing.assert_allclose(np.linalg.norm(right.C - left.C), 0.063)
    np.testing.assert_allclose(cam.R @ (right.C - left.C), [0.063, 0, 0], atol=1e-12)
    # A point at the convergence distance on the optical axis lands on one pixel in both eyes;
    # others have parallax f·e·(1/D − 1/z).
    for z in (1.0, 2.5, 10.0):
        X = cam.C + z * cam.R[2]
        uv = [e.K @ e.R @ (X - e.C) for e in (left, right)]
        u = [p[0] / p[2] for p in uv]
        assert u[1] - u[0] == pytest.approx(800 * 0.063 * (1 / 2.5 - 1 / z), abs=1e-9)


def test_rendered_stereo_pair_has_the_expected_parallax(ctx):
    # A lone box seen from 4 m, screen plane at 2.5 m: it lies behind the screen.
    model = model_from_dict([{"name": "box", "primitive": {"type": "box", "params": {"width": 0.3, "depth": 0.3,
                                                                                     "height": 0.3}},
                              "joint": {"type": "fixed", "translation": [4.0, 0.0, 1.45], "rotation_deg": [0, 0, 0]}}])
    scene = scene_from_model(model)
    cam = ImageCamera("c", np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]]), look_rotation([1, 0, 0]),
                      np.array([0.0, 0.0, 1.6]), 640, 480)
    e, D = 0.2, 2.5  # a wide baseline so that parallax is many pixels
    r = Renderer(ctx, scene, RenderOptions(samples=4))
    sbs = r.render_rgba(cam, Stereo("sbs", e, D))
    tb = r.render_rgba(cam, Stereo("tb", e, D))
    ana = r.render(cam, Stereo("anaglyph", e, D))
    mono = r.render_rgba(cam)
    r.release()
    assert sbs.shape == (480, 1280, 4) and tb.shape == (960, 640, 4) and ana.shape == (480, 640, 3)

    def centre_u(rgba):
        a = rgba[..., 3].astype(float)
        return (a.sum(axis=0) * (np.arange(a.shape[1]) + 0.5)).sum() / a.sum()
    z = 4.0 - 0.15  # the box's front face, which the camera sees; its silhouette is that face's
    want = 500 * e * (1 / D - 1 / z)
    uL, uR = centre_u(sbs[:, :640]), centre_u(sbs[:, 640:])
    assert uR - uL == pytest.approx(want, abs=0.5)
    assert centre_u(tb[:480]) == pytest.approx(uL, abs=1e-6)  # the left eye on top
    assert centre_u(tb[480:]) == pytest.approx(uR, abs=1e-6)
    assert centre_u(mono) == pytest.approx(0.5 * (uL + uR), abs=0.5)
    # Anaglyph: the left eye's box is in red, the right eye's in green and blue.
    bg = np.array(RenderOptions().background_srgb)
    lum = np.abs(ana.astype(int) - bg).sum(-1) > 30
    cols = np.flatnonzero(lum.any(axis=0))
    assert cols.min() < uL < cols.max() and cols.min() < uR < cols.max()


# -- evidence views, provenance, validation -------------------------------------------------------


def test_render_writes_the_view_with_its_provenance(textured_room, tmp_path, capsys):
    out = tmp_path / "doorway.png"
    assert main(["render", str(textured_room), "--view", "doorway", "--lighting", "ceiling lamp",
                 "--out", str(out)]) == 0
    assert "written to" in capsys.readouterr().out
    img = Image.open(out)
    assert img.size == (1280, 720)
    text = img.text
    assert set(PROVENANCE_KEYS) <= set(text)
    assert text["vebuild:inputs_sha256"] == inputs_sha256(json.loads(textured_room.read_text()))
    cam = json.loads(text["vebuild:camera"])
    assert cam["kind"] == "view" and cam["name"] == "doorway" and cam["C"] == [3.7, 0.3, 1.6]
    assert json.loads(text["vebuild:lighting"])["lights"][0]["type"] == "point"
    data = json.loads(textured_room.read_text())
    assert json.loads(text["vebuild:textures"]) == [p["atlas_sha256"] for p in data["textures"]["pages"]]
    assert text["Software"].startswith("vebuild ")
    # Reproducible: the same project and options give the same file, byte for byte.
    again = tmp_path / "again.png"
    assert main(["render", str(textured_room), "--view", "doorway", "--lighting", "ceiling lamp",
                 "--out", str(again)]) == 0
    assert again.read_bytes() == out.read_bytes()
    # Darker lighting gives a darker image.
    night = tmp_path / "night.png"
    assert main(["render", str(textured_room), "--view", "doorway", "--lighting", "night, torch",
                 "--out", str(night)]) == 0
    assert np.asarray(Image.open(night)).mean() < np.asarray(img).mean()


def test_rendering_a_photo_explains_the_photo(textured_room, tmp_path):
    project = load_project(textured_room)
    good = render_evidence(project, RenderRequest(out=tmp_path / "p1.png", photo="p1", size=(800, 600),
                                                  validate=True))
    # The model explains the photo where it covers it to within JPEG, texture and exposure noise
    # (measured 8.8 levels at full size); a camera turned by 1° does not.
    assert good.rms_colour_difference < 14.0
    assert good.covered_fraction > 0.95  # the floor, the furniture and the walls fill p1's view
    assert good.overlay.is_file()
    meta = json.loads(Image.open(good.overlay).text["vebuild:validation"])
    assert meta["photo"] == "p1" and meta["rms_colour_difference_srgb_levels"] == pytest.approx(
        good.rms_colour_difference, abs=1e-3)
    cams = project.data["calibration"]["cameras"]
    R = np.asarray(cams["p1"]["R"])
    turn = look_rotation([1, 0, 0]).T @ look_rotation([np.cos(0.0175), np.sin(0.0175), 0]) @ look_rotation([1, 0, 0])
    cams["p1"]["R"] = (R @ turn.T).tolist()
    bad = render_evidence(project, RenderRequest(out=tmp_path / "p1-bad.png", photo="p1", size=(800, 600),
                                                 validate=True))
    assert bad.rms_colour_difference > 1.5 * good.rms_colour_difference


def test_a_photo_is_rendered_through_its_recorded_lens(textured_room, tmp_path):
    from vebuild.project.records import distortion_record

    # The example's photos are pinholes: given a barrel lens they are not, and the render through
    # it no longer lies on the photo (the corners move 2.6 %, 13 px at 800 × 600).
    project = load_project(textured_room)
    good = render_evidence(project, RenderRequest(out=tmp_path / "p1.png", photo="p1", size=(800, 600),
                                                  validate=True))
    assert "distortion" not in json.loads(Image.open(good.out).text["vebuild:camera"])
    photo = project.photo("p1")
    cams = project.data["calibration"]["cameras"]
    cams["p1"]["distortion"] = distortion_record(np.asarray(cams["p1"]["K"]), photo["width"], photo["height"],
                                                 -0.05, 0.001, "test")
    lens = render_evidence(project, RenderRequest(out=tmp_path / "p1-lens.png", photo="p1", size=(800, 600),
                                                  validate=True))
    assert json.loads(Image.open(lens.out).text["vebuild:camera"])["distortion"] == {"model": "division", "k1": -0.05}
    assert lens.camera.lens.k1 == -0.05 and lens.size == (800, 600)
    # measured 13.9 against 8.1 sRGB levels
    assert lens.rms_colour_difference > 1.3 * good.rms_colour_difference
    # Near the principal point the lens moves the image under 0.01 px: the renders agree there
    # (measured 0.0006 levels mean) and not at a corner (15.2 levels), where it moves 13 px.
    a, b = (np.asarray(Image.open(r.out), float) for r in (good, lens))
    assert np.abs(a - b)[280:320, 380:420].mean() < 0.5 and np.abs(a - b)[:60, :80].mean() > 5.0


def test_missing_textures_render_untextured_and_say_so(textured_room, tmp_path, capsys):
    folder = tmp_path / "room"
    shutil.copytree(textured_room.parent, folder)
    proj = folder / textured_room.name
    for f in (folder / "textures").glob("atlas_*.png"):
        f.unlink()
    assert main(["render", str(proj), "--photo", "p2", "--size", "320x240", "--out", str(tmp_path / "u.png")]) == 0
    assert "texture page(s) missing" in capsys.readouterr().out
    assert json.loads(Image.open(tmp_path / "u.png").text["vebuild:textures"]) == []


def test_a_changed_atlas_page_is_refused(textured_room, tmp_path, capsys):
    folder = tmp_path / "room"
    shutil.copytree(textured_room.parent, folder)
    page = next((folder / "textures").glob("atlas_*.png"))
    Image.open(page).transpose(Image.Transpose.FLIP_LEFT_RIGHT).save(page)
    out = tmp_path / "x.png"
    assert main(["render", str(folder / textured_room.name), "--photo", "p1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "changed since `vebuild texture` wrote it" in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize("args, message", [
    (["--view", "nowhere"], r"no view is called 'nowhere'; the views are: 'doorway', 'by the cabinet', 'overview'"),
    (["--photo", "p9"], r"no photo has the id 'p9'"),
    (["--view", "doorway", "--lighting", "moonlight"], r"no lighting preset is called 'moonlight'; the presets are: "
                                                       r"'as-photographed', 'daylight'"),
    (["--view", "doorway", "--size", "0x720"], r"--size: expected WIDTHxHEIGHT"),
    (["--view", "doorway", "--size", "big"], r"--size: expected WIDTHxHEIGHT"),
    (["--view", "doorway", "--size", "90000x720"], r"--size: a 90000×720 image cannot be rendered: expected each "
                                                   r"side 1 to 16384 pixels"),
    (["--view", "doorway", "--size", "9000x9000"], r"--size: .*at most 67,108,864 pixels in all"),
    (["--view", "doorway", "--size", "10000x720", "--stereo", "sbs"],
     r"--size, in stereo side by side \(twice the width\): a 20000×720 image cannot be rendered"),
    (["--view", "doorway", "--eye-separation", "0", "--stereo", "sbs"], r"--eye-separation: expected a distance > 0"),
    (["--view", "doorway", "--validate"], r"--validate compares a render with its photo"),
])
def test_bad_render_requests_get_clear_errors(textured_room, tmp_path, capsys, args, message):
    out = tmp_path / "x.png"
    assert main(["render", str(textured_room), *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert re.search(message, err), err
    assert not out.exists()


def test_an_output_path_that_cannot_be_written_is_refused_before_rendering(textured_room, tmp_path):
    project = load_project(textured_room)
    for out, message in ((tmp_path / "missing" / "x.png", "does not exist"), (tmp_path, "is a folder"),
                         (tmp_path / "x.jpg", "expected an output file ending in .png")):
        with pytest.raises(VebuildError, match=message):
            render_evidence(project, RenderRequest(out=out, view="doorway"))


def test_views_and_presets_are_validated_when_the_project_loads(textured_room, tmp_path):
    data = json.loads(textured_room.read_text())
    cases = [
        (lambda d: d["views"][0].pop("look_at"), r"\$.views\[0\]: expected exactly one of \"look_at\""),
        (lambda d: d["views"][1].update(name="doorway"), r"\$.views\[1\].name: the view name 'doorway' is already"),
        (lambda d: d["views"][0].update(fov_deg=200), r"\$.views\[0\].fov_deg"),
        (lambda d: d["lighting"]["presets"][0]["lights"][0].pop("direction"),
         r"a directional light needs \"direction\""),
        (lambda d: d["lighting"]["presets"][0].update(name="as-photographed"), r"is the built-in preset"),
        (lambda d: d["lighting"]["presets"][1]["lights"][0].update(type="laser"), r"\"directional\", \"point\""),
    ]
    for change, message in cases:
        d = json.loads(json.dumps(data))
        change(d)
        path = tmp_path / "p.vebuild.json"
        path.write_text(json.dumps(d))
        with pytest.raises(ProjectError, match=message):
            load_project(path, verify_photos=False)


def test_parse_size():
    assert parse_size("1280x720") == (1280, 720) and parse_size("64×48") == (64, 48)


def test_a_renderer_can_draw_its_scene_moved(ctx):
    scene = scene_from_model(box_on_floor_model())
    cam = off_centre_camera([2.3, -1.2, 1.9], [2.1, 1.4, 0.2])
    r = Renderer(ctx, scene)
    before = r.render_rgba(cam)[..., 3]
    model = box_on_floor_model()
    model.node("box").joint.set_values(np.array([-1.0, 0.5, 0.0]))
    r.set_scene(scene.with_model(model))
    after = r.render_rgba(cam)[..., 3]
    r.set_lighting(AS_PHOTOGRAPHED_LIGHTING)
    r.release()
    assert (before != after).mean() > 0.01


def test_load_scene_of_the_example_reads_its_textures(textured_room):
    scene = load_scene(load_project(textured_room))
    assert scene.textured and not scene.warnings and len(scene.pages) == len(scene.page_hashes) >= 1


def test_the_id_buffer_and_picking_agree_with_ray_queries(ctx):
    scene = scene_from_model(box_on_floor_model())
    cam = off_centre_camera([2.3, -1.2, 1.9], [2.1, 1.4, 0.2])
    r = Renderer(ctx, scene, EXACT)
    faces, depth = r.id_buffer(cam)
    mask = r.node_mask(cam, "box")
    tri, points, _ = _trace(scene, cam)
    want = np.where(tri >= 0, scene.mesh.triangle_faces[np.maximum(tri, 0)], 0)
    assert np.mean(faces == want) > 0.995  # all but pixel centres within rounding of an edge
    box_faces = [f.id for f in scene.mesh.faces if f.node == "box"]
    assert np.mean(mask == np.isin(want, box_faces)) > 0.995 and mask.sum() > 1000
    hit = tri >= 0
    z = ((points[hit] - cam.C) @ cam.R.T)[:, 2]
    assert np.median(np.abs(depth[hit] - z)) < 1e-5
    for (u, v) in ((160.25, 120.75), (60.5, 200.5)):
        node, X = r.pick(cam, u, v)
        j, i = int(v), int(u)
        assert node == scene.mesh.faces[want[j, i] - 1].node
        np.testing.assert_allclose(project(cam.K, cam.R, cam.C, X), [u, v], atol=1e-3)
    r.release()
