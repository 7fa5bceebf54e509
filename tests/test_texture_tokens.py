"""Token charts: a face no photo can see gets a few texels, not its full chart.

The visibility test (:mod:`vebuild.texture.visibility`) must never give a token chart to a face a
photo sees (its texels would be lost): checked against the full extraction, where every such face
has no seen texel. The atlas shrinks; what the renders show of those faces (marked unseen, their
node's average colour) does not change.
"""

from __future__ import annotations

import numpy as np
import pytest

from vebuild.actions.example_truth import photo_path, true_cameras, true_model
from vebuild.camera import ImageCamera
from vebuild.gl import headless_context
from vebuild.model.scene import model_from_dict
from vebuild.render.observed import unseen_mask
from vebuild.texture import layout as lay
from vebuild.texture.extract import PhotoSource, extract
from vebuild.texture.merge import COVERAGE_UNSEEN
from vebuild.texture.options import Options
from vebuild.texture.visibility import seen_faces

#: A low density keeps the two extractions quick; the test is the same at any density.
DENSITY = 60.0


@pytest.fixture(scope="module")
def both():
    model, cams = true_model(), true_cameras()
    sources = {c.id: PhotoSource(c.id, photo_path(c.id)) for c in cams}
    full = extract(model, cams, sources, Options(texels_per_metre=DENSITY, token_charts=False))
    token = extract(model, cams, sources, Options(texels_per_metre=DENSITY))
    return model, full, token


def _by_key(res):
    return {(f.node, f.name): f for f in res.faces}


def test_only_faces_no_photo_sees_get_token_charts(both):
    _, full, token = both
    f_full, f_tok = _by_key(full), _by_key(token)
    keys = {(f.node, f.name) for f in token.token_faces}
    assert len(keys) >= 20  # the example: walls' backs, tops and ends, undersides
    assert {("cabinet", "bottom"), ("box", "bottom")} <= keys  # resting on the floor
    for key in keys:  # seen by no photo in the full extraction: nothing is lost
        assert full.face_stats[f_full[key].id].seen_fraction == 0.0, key
        assert f_tok[key].rect[2:] == (lay.TOKEN_TEXELS, lay.TOKEN_TEXELS), key
    seen_by_some = [k for k, f in f_full.items() if full.face_stats[f.id].seen_fraction > 0]
    assert ("floor", "top") in seen_by_some and len(seen_by_some) >= 30
    for key in seen_by_some:  # a face some photo sees keeps its full chart, and its seen share
        assert key not in keys
        assert f_tok[key].rect[2:] == f_full[key].rect[2:], key
        st_full, st_tok = full.face_stats[f_full[key].id], token.face_stats[f_tok[key].id]
        # the same texels seen, but for one where a texel centre lies on a chart's seam
        assert abs(st_full.seen_fraction - st_tok.seen_fraction) * st_full.texels <= 1.0, key


def test_the_atlas_shrinks_and_the_full_size_is_what_the_layout_alone_says(both):
    model, full, token = both
    assert token.atlas_texels < 0.7 * full.atlas_texels  # measured 0.47 at 200 texels per metre
    pages = lay.page_sizes(lay.layout(model, DENSITY, Options.max_face_texels, full.page_size))
    assert sum(w * h for w, h in pages) == full.atlas_texels  # the benchmark's "before" figure
    assert token.atlas_texels == sum(a.shape[0] * a.shape[1] for a in token.atlases)
    assert not full.token_faces


def test_a_token_chart_is_marked_unseen_and_painted_its_nodes_colour(both):
    _, full, token = both
    f_full = _by_key(full)
    masks = [unseen_mask(c) for c in token.coverage]
    for f in token.token_faces:
        x0, y0, w, h = f.rect
        cov = token.coverage[f.page][y0:y0 + h, x0:x0 + w]
        on = cov[..., 3] > 0
        assert on.sum() >= 4 and np.all(cov[on] == COVERAGE_UNSEEN), (f.node, f.name)
        pad = lay.GUTTER // 2  # the mask covers the chart and its half of the gutter along each side
        m = masks[f.page]
        assert (m[y0 - pad:y0 + h + pad, x0:x0 + w] == 255).all(), (f.node, f.name)
        assert (m[y0:y0 + h, x0 - pad:x0 + w + pad] == 255).all(), (f.node, f.name)
        chart = token.atlases[f.page][y0:y0 + h, x0:x0 + w].reshape(-1, 3)
        g = f_full[(f.node, f.name)]
        big = full.atlases[g.page][g.rect[1]:g.rect[1] + g.rect[3], g.rect[0]:g.rect[0] + g.rect[2]].reshape(-1, 3)
        assert (chart == chart[0]).all() and (big == big[0]).all()
        # the node's average of its seen faces (its exposure gains differ a little: a level or two)
        assert np.abs(chart[0].astype(int) - big[0].astype(int)).max() <= 3, (f.node, f.name)


def _two_boxes():
    """A box hidden behind a larger one from a camera looking along +y."""
    nodes = [
        {"name": "near", "primitive": {"type": "box", "params": {"width": 1.0, "depth": 0.4, "height": 1.0}},
         "joint": {"type": "fixed", "translation": [0.0, 2.0, 0.0], "rotation_deg": [0.0, 0.0, 0.0]}},
        {"name": "far", "primitive": {"type": "box", "params": {"width": 0.3, "depth": 0.3, "height": 0.3}},
         "joint": {"type": "fixed", "translation": [0.0, 3.0, 0.3], "rotation_deg": [0.0, 0.0, 0.0]}},
    ]
    model = model_from_dict(nodes, {})
    K = np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    ahead = ImageCamera("ahead", K, np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]), np.array([0.0, -1.0, 0.45]),
                        640, 480)
    return model, ahead, K


def _mesh(model):
    plan = lay.plan_faces(model, 100.0, 2048, 4096)
    return lay.scene_mesh(model, [lay.Face(i + 1, n, f, s, 0, (0, 0, 1, 1)) for i, (n, f, s, _) in enumerate(plan)])


def test_a_face_hidden_behind_another_is_seen_by_no_camera_one_beside_it_sees_it():
    model, ahead, K = _two_boxes()
    mesh = _mesh(model)
    name = {f.id: (f.node, f.name) for f in mesh.faces}
    got = {name[i] for i in seen_faces(headless_context(), mesh, [ahead])}
    assert ("near", "front") in got and ("near", "top") not in got  # the top is above the eye
    assert not any(node == "far" for node, _ in got), got  # in view, facing the camera, hidden
    # From the side (looking along −x from x = 3), the far box's side shows past the near one.
    side = ImageCamera("side", K, np.array([[0.0, 1, 0], [0, 0, -1], [-1, 0, 0]]), np.array([3.0, 3.0, 0.45]),
                       640, 480)
    got2 = {name[i] for i in seen_faces(headless_context(), mesh, [ahead, side])}
    assert any(node == "far" for node, _ in got2) and got <= got2
    # A camera turned away sees nothing.
    away = ImageCamera("away", K, np.array([[-1.0, 0, 0], [0, 0, -1], [0, -1, 0]]), np.array([0.0, -1.0, 0.45]),
                       640, 480)
    assert seen_faces(headless_context(), mesh, [away]) == set()


def test_token_charts_can_be_switched_off_and_the_option_is_checked():
    from vebuild.errors import VebuildError

    assert Options().token_charts and not Options(token_charts=False).token_charts
    with pytest.raises(VebuildError, match="token_charts: expected true or false"):
        Options(token_charts="yes")  # type: ignore[arg-type]


def test_a_render_marks_the_token_charts_faces_as_unseen(textured_room):
    """A camera above the example room looks down on the walls' and the cabinet's tops: no photo
    saw them, so they have token charts, and the render marks every pixel of them (tint), leaving
    fully seen faces unmarked."""
    from vebuild.project import load_project
    from vebuild.render.renderer import Renderer, RenderOptions
    from vebuild.render.scene import load_scene

    project = load_project(textured_room)
    scene = load_scene(project)
    V = scene.mesh.vertices
    centre = np.array([*(V.min(0) + V.max(0))[:2] / 2, V.max(0)[2] + 8.0])
    K = np.array([[300.0, 0, 240], [0, 300.0, 135], [0, 0, 1]])
    cam = ImageCamera("above", K, np.array([[1.0, 0, 0], [0, -1, 0], [0, 0, -1]]), centre, 480, 270)
    faces = {f["id"]: f for f in project.data["textures"]["faces"]}
    token = {i for i, f in faces.items() if f["rect"][2:] == [lay.TOKEN_TEXELS] * 2}
    assert token and all(faces[i]["seen_fraction"] == 0.0 for i in token)
    out = {}
    for mode in ("off", "tint"):
        r = Renderer(headless_context(), scene, RenderOptions(samples=1, anisotropy=1.0, unobserved=mode))
        try:
            out[mode], (ids, _) = r.render(cam), r.id_buffer(cam)
        finally:
            r.release()
    on_token = np.isin(ids, list(token))
    fully_seen = np.isin(ids, [i for i, f in faces.items() if f["seen_fraction"] == 1.0])
    assert on_token.sum() > 200  # the test means something: the tops show
    changed = np.any(out["tint"] != out["off"], axis=-1)
    assert changed[on_token].mean() > 0.99
    assert not changed[fully_seen].any()


def _id_buffer_faces(tex) -> set[int]:
    a = np.frombuffer(tex.read(), "f4").reshape(tex.height, tex.width, 2)
    return set(np.unique(a[..., 0]).astype(int).tolist()) - {0}


def test_each_photos_passes_draw_only_the_faces_its_id_buffer_holds():
    """The ID pass's occlusion queries name the faces in view that hold a pixel of its ID buffer
    (a face tied with the nearest at a pixel too), and not a face that is in the photo's frustum
    but hidden. A back face the buffer holds on a silhouette's pixels is not in view: pass 2
    discards its texels (they face away)."""
    from vebuild.texture.gpu import Extractor

    model, ahead, _ = _two_boxes()
    mesh = _mesh(model)
    name = {f.id: (f.node, f.name) for f in mesh.faces}
    ex = Extractor(headless_context(), mesh, Options())
    try:
        in_view = ex._visible_faces(ahead)
        assert any(name[i][0] == "far" for i in in_view)  # in the frustum, facing the camera
        tex = ex.id_pass(ahead, 0.0)
        assert ex.id_faces == _id_buffer_faces(tex) & in_view and ex.id_faces
        assert not any(name[i][0] == "far" for i in ex.id_faces)
    finally:
        ex.release()
    mesh2 = _mesh(true_model())
    ex2 = Extractor(headless_context(), mesh2, Options())
    try:
        fewer = 0
        for cam in true_cameras():
            in_view = ex2._visible_faces(cam)
            tex = ex2.id_pass(cam, 0.0)
            assert _id_buffer_faces(tex) & in_view <= ex2.id_faces <= in_view, cam.id
            fewer += len(in_view) - len(ex2.id_faces)
            tex = ex2.id_pass(cam, Options().erode_px)
            assert _id_buffer_faces(tex) & in_view <= ex2.id_faces, cam.id
        assert fewer >= 10  # the example's photos have faces in view that are hidden
    finally:
        ex2.release()


def test_drawing_only_the_faces_an_id_buffer_holds_clipped_to_the_frame_changes_no_texel(monkeypatch):
    """The textures are bit for bit those of pass 2 drawn over every face in the frustum, each
    chart whole (not clipped to the photo's frame)."""
    from vebuild.texture import gpu
    from vebuild.texture.gpu import Extractor

    model, cams = true_model(), true_cameras()
    sources = {c.id: PhotoSource(c.id, photo_path(c.id)) for c in cams}
    opts = Options(texels_per_metre=30.0, token_charts=False)
    culled = extract(model, cams, sources, opts)
    id_pass = Extractor.id_pass

    def whole_frustum(self, cam, erode_px):
        tex = id_pass(self, cam, erode_px)
        self.id_faces = self._visible_faces(cam)
        return tex

    monkeypatch.setattr(Extractor, "id_pass", whole_frustum)
    monkeypatch.setattr(gpu, "CLIP_PLANES", 0)
    every = extract(model, cams, sources, opts)
    assert len(culled.atlases) == len(every.atlases)
    for a, b in zip(culled.atlases + culled.coverage, every.atlases + every.coverage, strict=True):
        assert np.array_equal(a, b)
