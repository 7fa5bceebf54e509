"""The modelling screen's overlay: hidden model edges dashed and dim (checked pixel by pixel against
the model's ID buffer from the photo's camera), lines clipped to the photo, layers and labels,
messages that expire newest first, the refused drag's message, and corners and faces named by
where they are, picked by a click."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from edit_driver import Driver

from vebuild import camera as cam_math
from vebuild.edit.messages import MESSAGE_SECONDS, new_messages
from vebuild.edit.names import corner_directions, face_direction
from vebuild.edit.visibility import clip_segment

#: An ID-buffer sample is "clearly hidden" when all 5 × 5 pixels about it show a face nearer by more
#: than this share of its depth (10 × the screen's own 0.5 % threshold: no doubt at the boundary).
CLEAR_HIDDEN = 0.05
#: Dashes and gaps of 5 px cover half a hidden stretch's pixels; antialiasing adds up to a pixel at
#: each end of a dash (+0.2) and a faint end pixel may fall under the threshold (−0.15): a hidden
#: stretch's centre pixels are drawn 35–75 % of the time, a seen one's (solid) ≥ 95 %.
DASHED_COVER = (0.35, 0.75)
SOLID_COVER = 0.95
#: Hidden parts are drawn at half the opacity: their drawn pixels change the photo less than
#: 0.8 × what the solid ones change it.
DIM_RATIO = 0.8
#: How far past its clipped end a drawn line reaches: half the widest line (4 px) and 1 px of antialiasing.
LINE_REACH_PX = 3


def test_clip_segment_keeps_the_part_inside_the_photo():
    assert clip_segment((-10, 50, 110, 50), 100, 80) == pytest.approx((0, 50, 100, 50))
    assert clip_segment((10, 10, 20, 20), 100, 80) == pytest.approx((10, 10, 20, 20))
    assert clip_segment((-10, -10, -5, 90), 100, 80) is None
    assert clip_segment((50, -40, 50, 200), 100, 80) == pytest.approx((50, 0, 50, 80))


def test_an_edge_behind_a_nearer_face_is_hidden_where_the_face_covers_it():
    from vebuild.camera import ImageCamera, intrinsic_matrix
    from vebuild.edit.visibility import edge_runs

    cam = ImageCamera("c", intrinsic_matrix(100.0, 50.0, 40.0), np.eye(3), np.zeros(3), 100, 80)
    ids = np.ones((80, 100), np.int32)
    depth = np.full((80, 100), 1.0, np.float32)  # a face 1 m away over the left half ...
    ids[:, 50:], depth[:, 50:] = 0, 0.0  # ... nothing over the right half
    a, b = np.array([-1.0, 0.0, 2.0]), np.array([1.0, 0.0, 2.0])  # an edge 2 m away across the image
    runs = edge_runs({"e": (a, b)}, cam, cam, ids, depth)["e"]
    assert [r.visible for r in runs] == [False, True]
    # The change within a pixel or two of the face's side (u = 50: its 3 × 3 pixels reach across).
    assert 48.0 <= runs[0].points[-1, 0] <= 50.0 and np.all(runs[0].points[-1] == runs[1].points[0])
    depth[:, :50] = 2.0 * (1 - 0.004)  # a face nearer by less than the tolerance (0.5 %) hides nothing
    assert [r.visible for r in edge_runs({"e": (a, b)}, cam, cam, ids, depth)["e"]] == [True]


def test_new_messages_follow_what_was_seen():
    assert new_messages(["a", "b"], ["a", "b", "b"]) == ["b"]
    assert new_messages([f"m{i}" for i in range(50)], [f"m{i}" for i in range(1, 51)]) == ["m50"]
    assert new_messages([], ["x"]) == ["x"]


def test_faces_and_corners_are_named_from_the_camera():
    R = cam_math.look_rotation(np.array([0.0, 1.0, 0.0]))  # looking along +y: +x is to the right
    assert face_direction([0, -1, 0], [0, -0.5, 0], R) == "front"  # facing the camera
    assert face_direction([0, 1, 0], [0, -0.5, 0], R) == "front"  # an inward normal, turned outward
    assert face_direction([1, 0, 0], [0.5, 0, 0], R) == "right"
    assert face_direction([0, 0, 1], [0, 0, 0.5], R) == "top"
    box = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    names = corner_directions(box, R)
    assert names[0] == "front-left-bottom" and names[7] == "back-right-top" and len(set(names)) == 8




@pytest.fixture
def driver(solved_room, tmp_path, xdotool, xvfb_display):
    shutil.copytree(solved_room.parent, tmp_path / "room")
    d = Driver(tmp_path / "room" / solved_room.name, xdotool)
    yield d
    d.close()


def _layers(d, want):
    """Set the Layers popup's checkboxes by clicking them (V opens it)."""
    e = d.editor
    if "layer model" not in e.widget_rects:
        d.send("key", "v")
    for layer, on in want.items():
        if e.layer_shown[layer] != on:
            d.click(f"layer {layer}")
        assert e.layer_shown[layer] == on


def test_hidden_edges_are_dashed_where_the_id_buffer_hides_them(driver):
    d = driver
    e, s = d.editor, d.session
    d.send(*d.move_to(5, 5))  # the cursor off the photo: no hover labels
    cam = s.cameras["p1"]
    _layers(d, {k: k == "model" for k in e.layer_shown})
    d.send("key", "v")  # the popup closed, over the photo no more
    with_edges = d.screen().astype(int)
    d.send("key", "v")
    _layers(d, {"model": False})
    d.send("key", "v")
    without = d.screen().astype(int)
    change = np.abs(with_edges - without).sum(axis=2)
    drawn = change > 30  # where the model layer draws
    ids, depth = e._renderer.id_buffer(cam)  # the photo's own size
    handles = np.array([p for _, _, p, _ in s.handles("p1")])
    cover = {"hidden": [], "seen": []}
    strength = {"hidden": [], "seen": []}
    x0, y0, x1, y1 = e.view_rect()
    for a, b in s.edge_world_ends().values():
        n = int(np.linalg.norm(cam_math.project(cam.K, cam.R, cam.C, b) - cam_math.project(cam.K, cam.R, cam.C, a)))
        if n < 4 or cam_math.world_to_camera(cam.R, cam.C, np.stack([a, b]))[:, 2].min() <= 0:
            continue
        X = a + np.linspace(0, 1, 2 * n)[:, None] * (b - a)
        z = cam_math.world_to_camera(cam.R, cam.C, X)[:, 2]
        uv = cam_math.project(cam.K, cam.R, cam.C, X, cam.lens)
        for q, zi in zip(uv, z, strict=True):
            c, r = int(q[0]), int(q[1])
            if not (2 <= c < cam.width - 2 and 2 <= r < cam.height - 2):
                continue
            if np.min(np.hypot(*(handles - q).T)) < 12 / e.zoom:  # the corners' dots are drawn too
                continue
            patch_i, patch_d = ids[r - 2:r + 3, c - 2:c + 3], depth[r - 2:r + 3, c - 2:c + 3]
            if np.all(patch_i > 0) and np.all(patch_d < zi * (1 - CLEAR_HIDDEN)):
                kind = "hidden"
            elif np.any(patch_i[1:4, 1:4] == 0) or np.any(patch_d[1:4, 1:4] >= zi * (1 - 1e-3)):
                kind = "seen"
            else:
                continue
            x, y = e.image_to_window("p1", q)
            if not (x0 + 2 <= x < x1 - 2 and y0 + 2 <= y < y1 - 2):
                continue
            cover[kind].append(bool(drawn[int(y), int(x)]))  # the pixel the line's centre crosses
            if drawn[int(y), int(x)]:
                strength[kind].append(change[int(y), int(x)])
    hidden, seen = np.mean(cover["hidden"]), np.mean(cover["seen"])
    assert len(cover["hidden"]) > 200 and len(cover["seen"]) > 200, {k: len(v) for k, v in cover.items()}
    assert DASHED_COVER[0] <= hidden <= DASHED_COVER[1], hidden
    assert seen >= SOLID_COVER, seen
    assert np.mean(strength["hidden"]) < DIM_RATIO * np.mean(strength["seen"]), \
        (np.mean(strength["hidden"]), np.mean(strength["seen"]))


def test_lines_stay_inside_the_photo(driver):
    d = driver
    e = d.editor
    d.send(*d.move_to(5, 5))
    e.zoom_at(*np.mean(np.reshape(e.view_rect(), (2, 2)), axis=0), 0.6)  # the photo smaller than the view
    _layers(d, {k: True for k in e.layer_shown} | {"vanishing points": False, "markers": False})
    d.send("key", "v")
    d.send("key", "l")  # no labels: their text may reach past the photo's edge, the lines may not
    assert not e.show_labels
    shown = d.screen().astype(int)
    d.send("key", "v")
    _layers(d, {k: False for k in e.layer_shown})
    d.send("key", "v")
    bare = d.screen().astype(int)
    changed = np.abs(shown - bare).sum(axis=2) > 30
    x0, y0, x1, y1 = (int(v) for v in e.view_rect())
    w, h = e.photo_size()
    (px0, py0), (px1, py1) = e.image_to_window(None, (0, 0)), e.image_to_window(None, (w, h))
    view = np.zeros_like(changed)
    view[y0:y1 - 90, x0:x1] = True  # above the message area
    photo = np.zeros_like(changed)
    m = LINE_REACH_PX
    photo[int(py0) - m:int(np.ceil(py1)) + m, int(px0) - m:int(np.ceil(px1)) + m] = True
    inside = (changed & view & photo).sum()
    outside = changed & view & ~photo
    assert inside > 1000 and outside.sum() == 0, (inside, outside.sum())


def test_a_refused_drag_does_not_name_the_dragged_vertex_among_those_that_hold_it(driver):
    d = driver
    e, s = d.editor, d.session
    e.select("cabinet")
    d.frames(2)
    uv0 = next(p for n, h, p, _ in s.handles("p1") if (n, h) == ("cabinet", "v0"))
    x, y = e.image_to_window("p1", uv0)
    d.send(*d.move_to(x, y), "sleep", "0.05", "mousedown", "1", "sleep", "0.05", *d.move_to(x - 30, y + 15),
           "sleep", "0.1", *d.move_to(x - 60, y + 30), "sleep", "0.1")
    text = e.drag_problem
    assert text is not None and "cannot go there" in text
    if "hold it" in text:
        held = text.split("its fixed vertices ", 1)[1].split(" hold it", 1)[0]
        assert "cabinet:v0" not in held.split(", "), text
    assert e.shown_messages()[0][0] == text  # on top of the one message area
    d.send("key", "Escape", "mouseup", "1")


def test_messages_expire_newest_on_top(driver):
    d = driver
    e = d.editor
    now = [1000.0]
    e.message_clock = lambda: now[0]
    e.say("first")
    d.frames(1)
    now[0] += 1.0
    e.say("second")
    d.frames(1)
    texts = [t for t, _ in e.shown_messages()]
    assert texts.index("second") < texts.index("first")
    now[0] += MESSAGE_SECONDS - 0.5
    texts = [t for t, _ in e.shown_messages()]
    assert "first" not in texts and "second" in texts
    now[0] += 1.0
    assert "second" not in [t for t, _ in e.shown_messages()]


def test_a_click_on_a_face_names_it_by_where_it_is(driver):
    d = driver
    e, s = d.editor, d.session
    from vebuild.edit.relating import Pick

    tris = s.pick_outline("p1", Pick("cabinet", "right", "face", (0.0, 0.0, 0.0)))  # the door's face
    centre = np.array(tris, float).reshape(-1, 2).mean(axis=0)
    before = d.screen().astype(int)
    d.send(*d.move_to(*e.image_to_window("p1", centre)), "sleep", "0.05", "click", "1")
    pk = e.picked
    assert pk is not None and (pk["node"], pk["what"], pk["stored"]) == ("cabinet", "face", "right")
    assert pk["shown"] == "front · right"  # p1 looks at the door: its front, whatever the file calls it
    assert any("front · right" in t for t, _ in e.shown_messages())
    after = d.screen().astype(int)
    x, y = e.image_to_window("p1", centre)
    near = np.abs(after - before).sum(axis=2)[int(y) - 20:int(y) + 20, int(x) - 60:int(x) + 60]
    assert (near > 30).sum() > 50  # the face tinted and named where it was clicked


def test_the_preview_is_inside_the_room_and_a_click_in_it_names_a_face(driver):
    d = driver
    e = d.editor
    cam = e.preview_camera()
    lo, hi = e._renderer.scene.bounds()
    assert np.all(cam.C > lo) and np.all(cam.C < hi)  # inside the model's box (the room's walls round it)
    ids, _ = e._renderer.id_buffer(cam)
    faces = e._renderer.scene.mesh.faces
    cabinet = [f.id for f in faces if f.node == "cabinet"]
    rows, cols = np.nonzero(np.isin(ids, cabinet))
    assert len(rows) > 50
    k = len(rows) // 2
    want = faces[ids[rows[k], cols[k]] - 1]
    x0, y0, _, _ = e.widget_rects["preview"]
    d.send(*d.move_to(x0 + cols[k] + 0.5, y0 + rows[k] + 0.5), "sleep", "0.05", "click", "1")
    pk = e.picked
    assert pk is not None and pk["where"] == "preview"
    assert (pk["node"], pk["stored"]) == (want.node, want.name) or pk["what"] == "corner", (pk, want)


def test_the_preview_follows_a_drag_now_and_then(driver):
    d = driver
    e, s = d.editor, d.session
    node = s.add_primitive("box", name="crate", parent="floor", at=("p1", (800.0, 1000.0)))
    e.select(node)
    d.frames(3)
    x0, y0, x1, y1 = (int(v) for v in e.widget_rects["preview"])
    before = d.screen()[y0:y1, x0:x1].astype(int)
    start = e.image_to_window("p1", next(p for n, k, p, _ in s.handles("p1") if (n, k) == (node, "v0")))
    moves = []
    for k in range(1, 5):
        moves += [*d.move_to(start[0] - 25 * k, start[1] + 12 * k), "sleep", "0.6"]  # slower than the preview's period
    d.send(*d.move_to(*start), "sleep", "0.05", "mousedown", "1", "sleep", "0.05", *moves)
    assert s.dragging and e.preview_following()
    during = e.surface.read()[y0:y1, x0:x1].astype(int)  # the drag's frame as shown, not redrawn
    assert (np.abs(during - before).sum(axis=2) > 30).sum() > 20  # the crate moved in the preview too
    d.send("key", "Escape", "mouseup", "1")
    assert not s.dragging


@pytest.mark.parametrize("slow", ["at rest", "in a drag"])
def test_a_slow_preview_does_not_follow_a_drag(driver, slow):
    """The preview's last frame, drawn before the drag, says it is slow (as on a large house), or
    its last frame in a drag took longer than a drag may wait: the drag's moves do not draw it, not
    even once to find that out."""
    from vebuild.edit.preview import PREVIEW_DRAG_FRAME_S, PREVIEW_DRAG_PERIOD_S, PREVIEW_DRAG_SHARE

    d = driver
    e, s = d.editor, d.session
    node = s.add_primitive("box", name="crate", parent="floor", at=("p1", (800.0, 1000.0)))
    e.select(node)
    d.frames(3)
    assert 0.0 < e._preview_frame_s < PREVIEW_DRAG_SHARE * PREVIEW_DRAG_PERIOD_S  # measured, and fast here
    if slow == "at rest":
        e._preview_frame_s = 2 * PREVIEW_DRAG_SHARE * PREVIEW_DRAG_PERIOD_S
    else:  # an earlier drag's preview frame, slower than the drag may wait, fast as it is at rest
        e._preview_follow = (None, 0.0, 2 * PREVIEW_DRAG_FRAME_S)
    follow = e.__dict__.get("_preview_follow")
    start = e.image_to_window("p1", next(p for n, k, p, _ in s.handles("p1") if (n, k) == (node, "v0")))
    moves = []
    for k in range(1, 4):
        moves += [*d.move_to(start[0] - 25 * k, start[1] + 12 * k), "sleep", "0.6"]
    d.send(*d.move_to(*start), "sleep", "0.05", "mousedown", "1", "sleep", "0.05", *moves)
    assert s.dragging and not e.preview_following() and e.__dict__.get("_preview_follow") is follow
    d.send("key", "Escape", "mouseup", "1")
    assert not s.dragging


def test_clip_polyline_keeps_what_clip_segment_keeps_segment_by_segment():
    """The vectorised clip of a polyline (the overlay's edge runs) against the photo: the same
    pieces as clipping each segment on its own, joined where they meet inside the photo."""
    from vebuild.edit.visibility import clip_polyline, clip_segment

    rng = np.random.default_rng(7)
    for _ in range(200):
        P = np.cumsum(rng.normal(0, 40, (rng.integers(2, 30), 2)), axis=0) + rng.uniform(-50, 250, 2)
        parts = clip_polyline(P, 200.0, 150.0)
        expected = [c for a, b in zip(P[:-1], P[1:], strict=True) if (c := clip_segment((*a, *b), 200.0, 150.0))]
        got = [(*p[i], *p[i + 1]) for p in parts for i in range(len(p) - 1)]
        assert np.allclose(np.array(got).reshape(-1, 4), np.array(expected).reshape(-1, 4), atol=1e-9)
        for p in parts:
            assert ((p >= -1e-9) & (p <= (200.0 + 1e-9, 150.0 + 1e-9))).all()


def test_edge_samples_are_each_edges_linspace_bit_for_bit():
    """The hidden-line samples, made for all edges at once, are those of ``np.linspace`` along each
    edge about SAMPLE_PX apart in the photo (at most MAX_SAMPLES, at least both ends); an edge with
    an end behind the camera has none."""
    import math

    from vebuild import camera as cm
    from vebuild.edit.visibility import MAX_SAMPLES, SAMPLE_PX, edge_samples

    rng = np.random.default_rng(11)
    cam = cm.ImageCamera("c", cm.intrinsic_matrix(1500.0, 800.0, 600.0), cm.look_rotation(np.array([0.0, 1.0, 0.0])),
                         np.array([0.0, -8.0, 0.5]), 1600, 1200)
    ends = {("n", i): (rng.normal(0, 3, 3), rng.normal(0, 3, 3)) for i in range(300)}
    ends["behind"] = (np.array([0.0, -9.0, 0.0]), np.array([0.0, 2.0, 0.0]))
    ends["short"] = (np.array([0.0, 0.0, 0.0]), np.array([1e-4, 0.0, 0.0]))
    ends["long"] = (np.array([-400.0, 1.0, 0.0]), np.array([400.0, 1.0, 0.0]))
    got = edge_samples(ends, cam)
    expected = {}
    for key, (a, b) in ends.items():
        z = cm.world_to_camera(cam.R, cam.C, np.stack([a, b]))[:, 2]
        if np.any(z <= 0):
            continue
        pa, pb = cm.project(cam.K, cam.R, cam.C, np.stack([a, b]))
        n = int(min(MAX_SAMPLES, max(2, math.ceil(float(np.linalg.norm(pb - pa)) / SAMPLE_PX) + 1)))
        expected[key] = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
    assert list(got) == list(expected) and "behind" not in got
    assert len(got["short"]) == 2 and len(got["long"]) == MAX_SAMPLES
    assert all(np.array_equal(got[k], expected[k]) for k in expected)
    assert edge_samples({}, cam) == {}
