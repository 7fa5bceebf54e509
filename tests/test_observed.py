"""Observed versus inferred: the coverage maps as per-texel masks, renders that hatch or tint what
no photo saw (checked pixel by pixel against the ID buffer on the headless EGL context), the
legend and provenance of evidence images, the mask in glTF exports (validated), and the sight-line
and viewshed figures that rest on unobserved surfaces (checked against the blockers' names)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from PIL import Image

from vebuild.actions.render import RenderRequest, render_evidence
from vebuild.analysis.rays import Occluders
from vebuild.analysis.sightline import Eye, target_object, target_point
from vebuild.analysis.sightline import sight_line as cast_sight_line
from vebuild.analysis.viewshed import viewshed
from vebuild.cli import main
from vebuild.errors import ProjectError, VebuildError
from vebuild.gl import headless_context
from vebuild.project import load_project
from vebuild.project.decode import find_view
from vebuild.render.observed import (
    HATCH_DUTY,
    HATCH_PERIOD_M,
    HATCH_STRENGTH,
    LEGEND_BACKGROUND_SRGB,
    LEGEND_TEXT,
    PROVENANCE_KEY,
    TINT_STRENGTH,
    UNOBSERVED_SRGB,
    draw_legend,
    unseen_mask,
)
from vebuild.render.renderer import Renderer, RenderOptions
from vebuild.render.scene import load_scene
from vebuild.texture.layout import GUTTER
from vebuild.texture.merge import COVERAGE_UNSEEN, linear_to_srgb8, srgb8_to_linear

#: One sample per pixel: the scene pass and the ID-buffer pass then rasterise the same triangles
#: onto the same pixel centres, so each pixel's face is the ID buffer's.
EXACT = dict(samples=1, anisotropy=1.0)
#: sRGB levels a marked pixel may differ from its prediction made from the unmarked render: the
#: unmarked pixel is rounded (±0.5 level); mixing keeps (1 − strength) of that error in linear
#: light, which the sRGB curve stretches at most by (1 − strength)^(−1/2.4 + 1) ≈ 1.42 (the power
#: segment's slope ratio between a colour and its darker mix); plus the marked pixel's own rounding
#: (0.5): 0.5 · 0.55 · 1.42 + 0.5 ≈ 0.89 < 1 level.
MARK_TOLERANCE_LEVELS = 1
#: A pixel whose stripe coordinate lies within this many pixel footprints of a stripe's edge may be
#: partly covered (the shader box-filters each edge over one footprint, fwidth).
EDGE_FOOTPRINTS = 1.0
#: Footprints above this are where the hatch starts fading into a tint (scene.frag's smoothstep
#: from 0.125); the stripe test keeps to pixels below it.
SHARP_FOOTPRINT = 0.1
SIZE = (480, 270)
#: The share of a face's sharp pixels the stripes change: the duty, plus the edge pixels partly
#: covered (up to one footprint, < 0.1 of the period, on each side of each stripe).
HATCH_SHARE_TOLERANCE = 2 * SHARP_FOOTPRINT


def _mask_of_nodes(scene, nodes):
    """Masks marking exactly the faces of ``nodes`` unseen (their charts and their half of the gutter)."""
    masks = [np.zeros((h, w), np.uint8) for (w, h) in scene.mesh.pages]
    pad = GUTTER // 2
    for f in scene.mesh.faces:
        if f.node in nodes:
            x0, y0, w, h = f.rect
            masks[f.page][y0 - pad:y0 + h + pad, x0 - pad:x0 + w + pad] = 255
    return masks


@pytest.fixture(scope="module")
def room(textured_room):
    project = load_project(textured_room)
    cam = find_view(project, "overview").resized(*SIZE)
    return project, cam


def _render(scene, cam, mode, **options):
    r = Renderer(headless_context(), scene, RenderOptions(**{**EXACT, **options}, unobserved=mode))
    try:
        return r.render(cam), r.id_buffer(cam), r.marks_unobserved
    finally:
        r.release()


def _mix(off, strength):
    """The marked colour predicted from the unmarked sRGB pixels, mixed in linear light."""
    mark = srgb8_to_linear(np.array(UNOBSERVED_SRGB, np.uint8))
    return linear_to_srgb8(srgb8_to_linear(off) * (1.0 - strength) + mark * strength).astype(int)


def test_the_coverage_maps_give_the_recorded_seen_fraction_of_every_face(room):
    project, _ = room
    scene = load_scene(project)
    record = project.data["textures"]
    assert len(scene.masks) == len(record["pages"]) and scene.mask_hashes == [p["coverage_sha256"]
                                                                            for p in record["pages"]]
    cov = [np.asarray(Image.open(project.folder / p["coverage"]).convert("RGBA")) for p in record["pages"]]
    for k, (m, c) in enumerate(zip(scene.masks, cov, strict=True)):
        on = c[..., 3] > 0
        np.testing.assert_array_equal(m[on] == 255, np.all(c[on] == COVERAGE_UNSEEN, axis=-1), err_msg=f"page {k}")
        assert set(np.unique(m)) <= {0, 255}
    unseen_faces = 0
    for f in record["faces"]:
        x0, y0, w, h = f["rect"]
        c, m = cov[f["page"]][y0:y0 + h, x0:x0 + w], scene.masks[f["page"]][y0:y0 + h, x0:x0 + w]
        on = c[..., 3] > 0
        # the record rounds to 6 decimals
        assert abs((1.0 - (m[on] == 255).mean()) - f["seen_fraction"]) <= 1e-6, (f["node"], f["face"])
        unseen_faces += f["seen_fraction"] == 0.0
    assert unseen_faces > 10  # the example room: many faces no photo saw


def test_unseen_mask_fills_off_face_texels_from_their_chart():
    cov = np.zeros((6, 8, 4), np.uint8)
    cov[1:5, 1:3] = COVERAGE_UNSEEN
    cov[1:5, 5:7] = (26, 152, 80, 255)  # seen by four photos
    m = unseen_mask(cov)
    assert (m[:, :3] == 255).all() and (m[:, 5:] == 0).all() and m[2, 3] == 255 and m[2, 4] == 0
    with pytest.raises(ValueError):
        unseen_mask(cov[..., :3])


@pytest.mark.parametrize("node", ["box", "floor"])
def test_tint_marks_exactly_the_unseen_faces_pixels(room, node):
    project, cam = room
    scene = load_scene(project)
    scene.masks = _mask_of_nodes(scene, {node})
    off, (ids, _), _ = _render(scene, cam, "off")
    tint, (ids2, _), marked = _render(scene, cam, "tint")
    np.testing.assert_array_equal(ids, ids2)
    assert marked
    of_node = np.array([False] + [f.node == node for f in scene.mesh.faces])[ids]
    assert of_node.sum() > 500
    # Every other pixel is the unmarked render's, bit for bit (the same arithmetic).
    np.testing.assert_array_equal(tint[~of_node], off[~of_node])
    diff = np.abs(tint[of_node].astype(int) - _mix(off[of_node], TINT_STRENGTH))
    assert diff.max() <= MARK_TOLERANCE_LEVELS, np.percentile(diff, [50, 99, 100])


def test_hatch_stripes_lie_where_the_world_planes_put_them_on_the_unseen_face_only(room):
    project, _ = room
    cam = find_view(project, "overview")  # full size: the stripes several pixels wide on most of the floor
    scene = load_scene(project)
    scene.masks = _mask_of_nodes(scene, {"floor"})
    off, (ids, depth), _ = _render(scene, cam, "off")
    hatch, _, _ = _render(scene, cam, "hatch")
    of_node = np.array([False] + [f.node == "floor" for f in scene.mesh.faces])[ids]
    np.testing.assert_array_equal(hatch[~of_node], off[~of_node])
    # Each pixel's world point from the ID buffer's depth, and its stripe coordinate.
    j, i = np.mgrid[0:cam.height, 0:cam.width]
    rays = np.linalg.solve(cam.K, np.stack([i + 0.5, j + 0.5, np.ones_like(i, float)], axis=0).reshape(3, -1))
    X = (cam.C[:, None] + cam.R.T @ (rays * depth.reshape(1, -1))).T.reshape(cam.height, cam.width, 3)
    s = X.sum(axis=-1) / (HATCH_PERIOD_M * np.sqrt(2.0))
    foot = np.maximum(np.abs(np.diff(s, axis=1, append=s[:, -1:])), np.abs(np.diff(s, axis=0, append=s[-1:])))
    tri = np.abs(s - np.floor(s) - 0.5)
    inner = of_node & np.roll(of_node, 1, 0) & np.roll(of_node, -1, 0) & np.roll(of_node, 1, 1) \
        & np.roll(of_node, -1, 1) & (foot < SHARP_FOOTPRINT)
    stripe = inner & (tri < HATCH_DUTY / 2 - EDGE_FOOTPRINTS * foot)
    gap = inner & (tri > HATCH_DUTY / 2 + EDGE_FOOTPRINTS * foot)
    assert stripe.sum() > 1000 and gap.sum() > 1000
    np.testing.assert_array_equal(hatch[gap], off[gap])
    diff = np.abs(hatch[stripe].astype(int) - _mix(off[stripe], HATCH_STRENGTH))
    assert diff.max() <= MARK_TOLERANCE_LEVELS, np.percentile(diff, [50, 99, 100])
    # The stripes hold half the face (the duty), give or take the edge pixels.
    changed = np.any(hatch != off, axis=-1)
    share = changed[inner].mean()
    assert abs(share - HATCH_DUTY) < HATCH_SHARE_TOLERANCE, share


def test_off_is_the_unmarked_renderer_and_hatch_is_the_default(room):
    project, cam = room
    scene = load_scene(project)
    assert RenderOptions().unobserved == "hatch" and RenderOptions.interactive().unobserved == "hatch"
    off, _, marked_off = _render(scene, cam, "off", samples=4)
    scene_without = load_scene(project)
    scene_without.masks = []
    plain, _, marked_plain = _render(scene_without, cam, "hatch", samples=4)
    np.testing.assert_array_equal(off, plain)  # --unobserved off: the pixels renders had before masks
    assert not marked_off and not marked_plain
    default, _, marked = _render(scene, cam, RenderOptions().unobserved, samples=4)
    assert marked and (default != off).any()


def test_vebuild_render_hatches_by_default_with_a_legend_and_records_it(room, tmp_path):
    project, _ = room
    outs = {}
    for mode in ("hatch", "off"):
        outs[mode] = tmp_path / f"{mode}.png"
        assert main(["render", str(project.path), "--view", "overview", "--size", "640x360", "--samples", "1",
                     "--unobserved", mode, "--out", str(outs[mode])]) == 0
    default = tmp_path / "default.png"
    assert main(["render", str(project.path), "--view", "overview", "--size", "640x360", "--samples", "1",
                 "--out", str(default)]) == 0
    assert default.read_bytes() == outs["hatch"].read_bytes()
    hatch, off = Image.open(outs["hatch"]), Image.open(outs["off"])
    rec = json.loads(hatch.text[PROVENANCE_KEY])
    assert rec["mode"] == "hatch" and rec["marked"] and rec["legend"]["text"] == LEGEND_TEXT["hatch"]
    assert rec["coverage_sha256"] == [p["coverage_sha256"] for p in project.data["textures"]["pages"]]
    assert json.loads(hatch.text["vebuild:options"])["unobserved"] == "hatch"
    off_rec = json.loads(off.text[PROVENANCE_KEY])
    assert off_rec["mode"] == "off" and off_rec["legend"] is None
    a, b = np.asarray(hatch.convert("RGB")), np.asarray(off.convert("RGB"))
    # The legend: the lower left corner is the key drawn over the off render's pixels.
    np.testing.assert_array_equal(draw_legend(b, "off"), b)
    corner = (slice(320, 358), slice(2, 60))
    assert (a[corner] != b[corner]).any() and (a != b).any()
    assert np.all(a[corner] == LEGEND_BACKGROUND_SRGB, axis=-1).sum() > 200  # the key's box
    assert not np.all(b[corner] == LEGEND_BACKGROUND_SRGB, axis=-1).any()
    thumb = np.full((120, 160, 3), 128, np.uint8)
    np.testing.assert_array_equal(draw_legend(thumb, "hatch"), thumb)  # too small to hold the key
    with pytest.raises(VebuildError, match="--unobserved"):
        RenderRequest(out=tmp_path / "x.png", view="overview", unobserved="stripes")


def test_validation_measures_the_textures_not_the_marks(room, tmp_path):
    project, _ = room
    r = {m: render_evidence(project, RenderRequest(out=tmp_path / f"{m}.png", photo="p1", size=(320, 240), samples=1,
                                                   validate=True, unobserved=m)) for m in ("hatch", "off")}
    assert r["hatch"].rms_colour_difference == r["off"].rms_colour_difference


def test_a_changed_or_missing_coverage_map_is_said(room, tmp_path):
    project, _ = room
    folder = tmp_path / "room"
    shutil.copytree(project.folder, folder)
    path = folder / project.path.name
    cov = folder / project.data["textures"]["pages"][0]["coverage"]
    Image.open(cov).convert("RGBA").rotate(90).save(cov)
    with pytest.raises(ProjectError, match=r"\$\.textures\.pages\[0\]\.coverage_sha256"):
        load_scene(load_project(path))
    cov.unlink()
    scene = load_scene(load_project(path))
    assert scene.textured and scene.masks == [] and any("coverage map is missing" in w for w in scene.warnings)


def test_the_glb_carries_the_coverage_maps_and_the_seen_shares(room, tmp_path):
    from gltf_validation import validate

    from vebuild.render.export import COVERAGE_EXTRAS, SEEN_EXTRAS, export_model, read_glb

    project, _ = room
    res = export_model(project, tmp_path / "room.glb")
    doc, binary = read_glb(res.path.read_bytes())
    pages = project.data["textures"]["pages"]
    faces = {f["id"]: f for f in project.data["textures"]["faces"]}
    for mat, page in zip(doc["materials"], pages, strict=True):
        ex = mat["extras"][COVERAGE_EXTRAS]
        tex = doc["textures"][ex["texture"]["index"]]
        view = doc["bufferViews"][doc["images"][tex["source"]]["bufferView"]]
        assert binary[view["byteOffset"]:view["byteOffset"] + view["byteLength"]] == \
            (project.folder / page["coverage"]).read_bytes()
        assert ex["sha256"] == page["coverage_sha256"] and ex["unseen_rgba"] == list(COVERAGE_UNSEEN)
        assert doc["samplers"][tex["sampler"]]["magFilter"] == 9728  # nearest: the colours are categories
    n = 0
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            seen = prim["extras"][SEEN_EXTRAS]
            area = sum(f["area_m2"] for f in seen["faces"])
            want = sum(f["area_m2"] * faces[f["id"]]["seen_fraction"] for f in seen["faces"]) / area
            assert abs(seen["seen_fraction"] - want) < 1e-5
            assert all(f["seen_fraction"] == faces[f["id"]]["seen_fraction"] for f in seen["faces"])
            n += len(seen["faces"])
    assert n == len(faces)
    report = validate(res.path)
    assert report["issues"]["numErrors"] == 0


# -- sight lines and viewsheds ------------------------------------------------------------------

@pytest.fixture(scope="module")
def box_unseen(room):
    """The room's scene with exactly the box's faces marked as seen by no photo."""
    project, _ = room
    scene = load_scene(project)
    scene.masks = _mask_of_nodes(scene, {"box"})
    return Occluders(scene)


def _box_centre(occ):
    tris = occ.triangles_of("box")
    P = np.concatenate([occ.v0[tris], occ.v0[tris] + occ.e1[tris], occ.v0[tris] + occ.e2[tris]])
    return 0.5 * (P.min(axis=0) + P.max(axis=0)), P.min(axis=0), P.max(axis=0)


def test_a_sight_line_blocked_by_an_unseen_face_says_so(box_unseen):
    occ = box_unseen
    c, lo, hi = _box_centre(occ)
    eye = Eye(np.array([c[0], c[1] + 1.5, 0.5 * (lo[2] + hi[2])]))  # level with the box, beside it
    behind = np.array([c[0], c[1] - 1.0, eye.position[2]])
    res = cast_sight_line(occ, eye, target_point(occ, behind))
    assert not res.visible and res.blocker["node"] == "box" and res.blocker["unobserved"] is True
    assert res.record()["blocker"]["unobserved"] is True
    over = np.array([c[0], c[1] - 1.0, 1.9])  # over the box: nothing in the way, or a wall seen by photos
    res2 = cast_sight_line(occ, Eye(np.array([c[0], c[1] + 1.5, 1.9])), target_point(occ, over))
    assert res2.blocker is None or (res2.blocker["node"] != "box" and res2.blocker["unobserved"] is False)


def test_an_objects_answer_on_unseen_faces_is_its_whole_visible_share(box_unseen):
    occ = box_unseen
    eye = Eye.person(4.2, 3.4)
    res = cast_sight_line(occ, eye, target_object(occ, "box"), samples=2000)
    un = res.unobserved
    assert res.visible_share > 0.1
    # Every sample of the box lies on an unseen face: all it shows rests on unobserved surface.
    assert un["visible_on_unobserved_share"] == pytest.approx(res.visible_share, abs=1e-6)
    table = cast_sight_line(occ, eye, target_object(occ, "table"), samples=2000)
    assert table.unobserved["visible_on_unobserved_share"] == 0.0
    hidden_by_box = table.blocked_by.get("box", 0.0)
    assert table.unobserved["hidden_by_unobserved_share"] == pytest.approx(hidden_by_box, abs=1e-6)


def test_viewshed_figures_count_the_places_hidden_by_the_unseen_box(box_unseen):
    occ = box_unseen
    c, lo, hi = _box_centre(occ)
    target = target_point(occ, np.array([c[0], lo[1] - 0.3, 0.1]))  # low, just in front of the box
    vs = viewshed(occ, target, eye_height=0.3, cell=0.25)
    f = vs.figures()["unobserved"]
    ny, nx = vs.states.shape
    X, Y = np.meshgrid(*[vs.origin[k] + (np.arange(n) + 0.5) * vs.cell for k, n in ((0, nx), (1, ny))])
    places = vs.states == 2
    E = np.stack([X[places], Y[places], np.full(places.sum(), 0.3)], axis=1)
    blocked, _, tri = occ.segments_blocked(E, np.broadcast_to(target.point, E.shape))
    by_box = np.array([b and occ.node_of(t) == "box" for b, t in zip(blocked, tri, strict=True)])
    assert by_box.sum() > 3
    assert f["hidden_area_resting_on_unobserved_m2"] == pytest.approx(by_box.sum() * vs.cell ** 2, abs=1e-6)
    assert f["hidden_share_resting_on_unobserved"] == pytest.approx(by_box.sum() / blocked.sum(), abs=1e-6)
    assert f["seeing_area_resting_on_unobserved_m2"] == 0.0  # a point seen rests on no surface
    obj = viewshed(occ, target_object(occ, "box"), cell=0.5, samples=64).figures()["unobserved"]
    assert obj["seeing_share_resting_on_unobserved"] == pytest.approx(1.0)


def test_without_masks_the_figures_are_unknown_not_zero(room):
    project, _ = room
    scene = load_scene(project)
    scene.masks = []
    occ = Occluders(scene)
    res = cast_sight_line(occ, Eye.person(4.2, 3.4), target_object(occ, "box"), samples=200)
    assert res.unobserved is None
    f = viewshed(occ, target_object(occ, "box"), cell=0.5, samples=16).figures()["unobserved"]
    assert set(f.values()) == {None}


def test_the_walk_through_cycles_the_marks_and_its_screenshots_record_them(room, xvfb_display, tmp_path):
    from vebuild.gl.window import Window
    from vebuild.viewer.app import Viewer
    from vebuild.viewer.keys import VIEWER_KEYS

    project, _ = room
    assert VIEWER_KEYS.key_for("next_unobserved") == "U"
    window = Window(640, 360, "vebuild observed test", visible=False)
    try:
        v = Viewer(load_project(project.path), window, RenderOptions.interactive(), view="overview")
        seen = [v.renderer.unobserved]
        shots = {}
        for _ in range(3):
            shots[v.renderer.unobserved] = Image.open(v.screenshot(tmp_path))
            v.next_unobserved()
            seen.append(v.renderer.unobserved)
        assert seen == ["hatch", "tint", "off", "hatch"] and any("unobserved surfaces: off" in m for m in v.messages)
        for mode, im in shots.items():
            rec = json.loads(im.text[PROVENANCE_KEY])
            assert rec["mode"] == mode and rec["marked"] == (mode != "off")
        a, b = (np.asarray(shots[m].convert("RGB")) for m in ("hatch", "off"))
        assert (a != b).any()
    finally:
        window.close()


def test_the_video_hatches_by_default_with_the_legend_in_every_frame(room, tmp_path):
    import av

    from vebuild.render.video import Timing, VideoRequest, render_video

    project, _ = room
    got = {}
    for mode in ("hatch", "off"):
        out = tmp_path / f"{mode}.mp4"
        render_video(project, VideoRequest(["doorway", "overview"], out, (640, 360), Timing(fps=2, seconds=1.0),
                                           unobserved=mode))
        with av.open(str(out)) as c:
            meta = json.loads(c.metadata.get("comment", ""))
            frames = [f.to_ndarray(format="rgb24") for f in c.decode(c.streams.video[0])]
        got[mode] = (meta, frames)
    assert got["hatch"][0]["unobserved"] == "hatch" and got["hatch"][0]["unobserved_marked"] is True
    assert got["off"][0]["unobserved"] == "off" and got["off"][0]["unobserved_marked"] is False
    corner = (slice(330, 352), slice(12, 40))  # inside the key's box, left of its swatch's right edge
    for a, b in zip(got["hatch"][1], got["off"][1], strict=True):
        # The key's dark box survives H.264 within a few levels; the unmarked frame shows the room there.
        assert np.abs(a[corner].astype(int) - b[corner].astype(int)).mean() > 20
