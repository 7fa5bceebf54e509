"""The renderer's speed work changes no pixel it should not: the scene program's per-preset
variants draw exactly what the generic program draws; culling closed primitives' back faces
changes only pixels on silhouettes (where a back face used to win the tie with the front face it
shares an edge with); a camera inside a closed primitive culls nothing; blocks are drawn nearest
first. On the headless EGL context (llvmpipe), at a small size."""

from __future__ import annotations

import numpy as np
import pytest

from vebuild.bench.render import primitives_model
from vebuild.camera import ImageCamera, intrinsic_matrix, look_rotation, near_reach
from vebuild.gl import headless_context
from vebuild.project.decode import preset_from_record
from vebuild.render import draworder, renderer, variants
from vebuild.render.renderer import Renderer, RenderOptions, Stereo
from vebuild.render.scene import RenderScene, scene_from_model
from vebuild.texture import layout as lay

W, H = 320, 180
#: Culling may change a pixel only where a back face met its front face at a shared edge: a share
#: of the image bounded by the silhouettes' length (measured 0.1 %; 1 % leaves room, no more).
MAX_CULL_CHANGED_SHARE = 0.01
MULTI = {"name": "multi", "ambient": [0.1, 0.1, 0.1], "lights": [
    {"type": "point", "position": [1.0, 1.0, 2.2], "intensity": 2.0, "shadows": True},
    {"type": "spot", "position": [0.0, -1.0, 2.4], "direction": [0.2, 0.5, -1.0], "intensity": 3.0},
    {"type": "directional", "direction": [-0.3, 0.2, -1.0], "intensity": 0.5, "shadows": False},
    {"type": "directional", "direction": [0.5, 0.3, -1.0], "intensity": 0.8}]}


@pytest.fixture(scope="module")
def ctx():
    return headless_context()


@pytest.fixture(scope="module")
def scene() -> RenderScene:
    """Fourteen primitives of every closed kind on a quad floor, a checker atlas, and a mask
    marking a third of the texels as unseen (so that hatching is drawn)."""
    model = primitives_model(14, seed=4)
    faces = lay.layout(model, 40.0, 512, 1024)
    rng = np.random.default_rng(1)
    pages = [rng.integers(40, 230, (h, w, 3)).astype(np.uint8) for w, h in lay.page_sizes(faces)]
    record = {"faces": [{"id": f.id, "node": f.node, "face": f.name, "size_m": list(f.size_m), "page": f.page,
                         "rect": list(f.rect)} for f in faces]}
    s = scene_from_model(model, record, pages)
    s.masks = [np.where(np.arange(p.shape[1])[None, :] % 3 == 0, 255, 0).astype(np.uint8).repeat(p.shape[0], 0)
               for p in pages]
    return s


def _camera(C, target) -> ImageCamera:
    C = np.asarray(C, float)
    return ImageCamera("test", intrinsic_matrix(260.0, W / 2, H / 2), look_rotation(np.asarray(target) - C), C, W, H)


OUTSIDE = _camera([-2.5, -2.5, 2.4], [2.0, 1.5, 0.3])


def _render(ctx, scene, cam, lighting=None, unobserved="hatch", stereo=None):
    r = Renderer(ctx, scene, RenderOptions(samples=1, anisotropy=1.0))
    try:
        if lighting:
            r.set_lighting(preset_from_record(lighting))
        r.unobserved = unobserved
        return r.render(cam, stereo), r.id_buffer(cam)[0]
    finally:
        r.release()


@pytest.mark.parametrize("lighting,unobserved", [(None, "hatch"), (None, "tint"), (None, "off"),
                                                 (MULTI, "hatch")])
def test_a_variant_draws_what_the_generic_program_draws(ctx, scene, monkeypatch, lighting, unobserved):
    fast, _ = _render(ctx, scene, OUTSIDE, lighting, unobserved)

    def generic(lighting, shadows, textured, mode):  # the loop over n_lights, the modes as uniforms
        return {"LIT": int(lighting.lit), "MAX_LIGHTS": variants.MAX_LIGHTS, "MAX_TILES": variants.MAX_TILES}
    monkeypatch.setattr(renderer, "scene_defines", generic)
    slow, _ = _render(ctx, scene, OUTSIDE, lighting, unobserved)
    np.testing.assert_array_equal(fast, slow)
    assert fast.std() > 10  # a picture, not a blank


def test_culling_changes_only_silhouette_pixels(ctx, scene, monkeypatch):
    culled, ids = _render(ctx, scene, OUTSIDE, MULTI)
    monkeypatch.setattr(draworder, "CLOSED_TYPES", frozenset())
    whole, whole_ids = _render(ctx, scene, OUTSIDE, MULTI)
    changed = (culled != whole).any(axis=-1)
    assert changed.mean() <= MAX_CULL_CHANGED_SHARE
    # Each changed pixel has, within one pixel, another face in the unculled ID buffer (an edge).
    pad = np.pad(whole_ids, 1, mode="edge")
    near = np.stack([pad[1 + dy:1 + dy + H, 1 + dx:1 + dx + W] for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    on_edge = (near != whole_ids[None]).any(axis=0)
    assert on_edge[changed].all()
    # The ID buffer is culled alike: a pixel's face is one the colour pass drew there.
    assert ((ids != whole_ids) <= on_edge).all()


def test_a_camera_inside_a_closed_primitive_culls_nothing(ctx, scene, monkeypatch):
    box = next(n for n in scene.model.nodes if n.primitive is not None and n.primitive.TYPE == "box")
    fids = [i + 1 for i, f in enumerate(scene.mesh.faces) if f.node == box.name]
    v = scene.mesh.vertices[np.isin(scene.mesh.face_of_vertex, fids)]
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    cam = _camera(centre, centre + [1.0, 0.3, -0.2])
    order = draworder.DrawOrder(scene, np.zeros(len(scene.mesh.triangles), np.int32))
    assert order.may_be_inside(cam.C, 0.01)
    assert not any(r.cull for r in order.plan(cam.C, 0.01)[1])
    inside, _ = _render(ctx, scene, cam)
    monkeypatch.setattr(draworder, "CLOSED_TYPES", frozenset())
    whole, _ = _render(ctx, scene, cam)
    np.testing.assert_array_equal(inside, whole)
    assert (inside != np.array(RenderOptions().background_srgb, np.uint8)).any(axis=-1).mean() > 0.5


def test_blocks_are_drawn_nearest_first_closed_ones_culled(scene):
    order = draworder.DrawOrder(scene, np.zeros(len(scene.mesh.triangles), np.int32))
    C = np.asarray(OUTSIDE.C, float)
    assert not order.may_be_inside(C, 0.01)
    index, ranges = order.plan(C, 0.01)
    assert index is not None and len(index) == len(scene.mesh.triangles)
    assert sorted(map(tuple, index.tolist())) == sorted(map(tuple, scene.mesh.triangles.tolist()))
    assert [r.cull for r in ranges] == [True, False]  # the closed primitives, then the floor
    tri_node = scene.node_of_face[scene.mesh.face_of_vertex[index[:, 0]] - 1]
    names = scene.node_names
    assert names[tri_node[-1]] == "floor" and "floor" not in {names[n] for n in tri_node[: ranges[0].count // 3]}
    # Along the culled range, the blocks' distances from the camera never decrease.
    lo = np.minimum.reduceat(scene.mesh.vertices[index].min(axis=1), np.r_[0, np.flatnonzero(np.diff(tri_node)) + 1])
    hi = np.maximum.reduceat(scene.mesh.vertices[index].max(axis=1), np.r_[0, np.flatnonzero(np.diff(tri_node)) + 1])
    dist = np.linalg.norm(np.maximum(np.maximum(lo - C, C - hi), 0.0), axis=1)
    assert np.all(np.diff(dist[:-1]) >= 0)
    assert order.plan(C, 0.01)[0] is None  # the same view again: the index buffer is kept


def test_stereo_and_flipped_views_cull_the_right_side(ctx, scene, monkeypatch):
    """Side-by-side eyes (and, through them, the window's flipped framebuffer's winding rule,
    which is the same rule mirrored) lose only silhouette pixels too."""
    a, _ = _render(ctx, scene, OUTSIDE, stereo=Stereo("sbs"))
    monkeypatch.setattr(draworder, "CLOSED_TYPES", frozenset())
    b, _ = _render(ctx, scene, OUTSIDE, stereo=Stereo("sbs"))
    assert (a != b).any(axis=-1).mean() <= MAX_CULL_CHANGED_SHARE


def _flipped(ctx, scene):
    r = Renderer(ctx, scene, RenderOptions(samples=1, anisotropy=1.0))
    tex = ctx.texture((W, H), 4)
    fbo = ctx.framebuffer([tex], ctx.depth_renderbuffer((W, H)))
    try:
        r.draw(fbo, OUTSIDE, flip=True)  # as into a window: image row 0 at the top of the screen
        return np.frombuffer(tex.read(alignment=1), np.uint8).reshape(H, W, 4)[::-1, :, :3]
    finally:
        fbo.release()
        tex.release()
        r.release()


def test_a_window_culls_the_back_faces_too(ctx, scene, monkeypatch):
    """A flipped target (a window's framebuffer) mirrors the winding: the culled side must follow,
    so that it loses only silhouette pixels as well (the wrong side would lose whole primitives)."""
    image, _ = _render(ctx, scene, OUTSIDE)
    culled = _flipped(ctx, scene)
    monkeypatch.setattr(draworder, "CLOSED_TYPES", frozenset())
    whole = _flipped(ctx, scene)
    assert (culled != whole).any(axis=-1).mean() <= MAX_CULL_CHANGED_SHARE
    # and it is the same picture as off-screen, up to the rasteriser's edge rules
    assert (culled != image).any(axis=-1).mean() <= MAX_CULL_CHANGED_SHARE


def test_near_reach_is_the_near_rectangles_far_corner():
    K = intrinsic_matrix(100.0, 50.0, 25.0)
    reach = near_reach(K, 100, 50, 0.01)
    assert reach == pytest.approx(0.01 * np.sqrt(1 + 0.5 ** 2 + 0.25 ** 2), rel=0.02)


def test_blocks_out_of_view_are_not_drawn(ctx, scene):
    """A camera looking away from most of the scene draws only the blocks in its view, and the
    picture (and ID buffer) is the one drawing everything gives."""
    cam = _camera([1.5, 1.5, 1.0], [-1.0, -1.0, -2.0])  # near a corner of the floor, looking out and down
    order = draworder.DrawOrder(scene, np.zeros(len(scene.mesh.triangles), np.int32))
    planes = draworder.side_planes(cam.K, cam.R, W, H)
    index, _ = order.plan(np.asarray(cam.C, float), 0.01, planes)
    assert index is not None and 0 < len(index) < len(scene.mesh.triangles) // 4
    seen, ids = _render(ctx, scene, cam)
    r = Renderer(ctx, scene, RenderOptions(samples=1, anisotropy=1.0))
    try:
        r._order.plan = lambda C, reach, planes=None, rooms=True, plan=r._order.plan: plan(C, reach, None)  # type: ignore
        everything, all_ids = r.render(cam), r.id_buffer(cam)[0]
    finally:
        r.release()
    np.testing.assert_array_equal(seen, everything)
    np.testing.assert_array_equal(ids, all_ids)
    assert (ids > 0).mean() > 0.2  # the floor is in view
