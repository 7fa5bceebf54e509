"""Rooms as occluders (vebuild.model.occlusion): from inside a room, blocks behind its walls are not
drawn, and leaving them out changes no pixel of a view or of its ID buffer."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from vebuild.camera import ImageCamera, intrinsic_matrix, look_rotation, near_reach
from vebuild.gl import headless_context
from vebuild.model.occlusion import Rooms, rooms_of
from vebuild.model.scene import model_from_dict
from vebuild.render import draworder
from vebuild.render.renderer import Renderer, RenderOptions
from vebuild.render.scene import scene_from_model
from vebuild.synthetic.house_layout import furnished_house

W, H = 320, 180
#: Views of the generated house compared with and without the rooms occluding.
N_VIEWS = 40


@pytest.fixture(scope="module")
def ctx():
    return headless_context()


def _camera(C: Any, target: Any, f: float = 260.0) -> ImageCamera:
    C = np.asarray(C, float)
    return ImageCamera("test", intrinsic_matrix(f, W / 2, H / 2), look_rotation(np.asarray(target, float) - C), C, W,
                       H)


def _views(renderer: Renderer, cams: list[ImageCamera], occlude: bool) -> list[tuple[np.ndarray, np.ndarray]]:
    renderer.rooms_occlude = occlude
    try:
        return [(renderer.render(c), renderer.id_buffer(c)[0]) for c in cams]
    finally:
        renderer.rooms_occlude = True


def _drawn_blocks(renderer: Renderer, cam: ImageCamera, rooms: Rooms | None = None) -> set[int]:
    """Which blocks of the draw order a view draws: with the model's rooms occluding, with
    ``rooms`` instead, or (``Rooms([])``) with none."""
    order = renderer._order
    kept = order.rooms
    if rooms is not None:
        order.rooms = rooms
    try:
        order._last = None
        index, _ = order.plan(np.asarray(cam.C, float), near_reach(cam.K, W, H, 0.05),
                              draworder.side_planes(cam.K, cam.R, W, H))
    finally:
        order.rooms = kept
        order._last = None
    assert index is not None
    starts = {tuple(order.index[s]): b for b, s in enumerate(order.starts)}
    return {starts[tuple(t)] for t in index if tuple(t) in starts}


def test_the_house_looks_the_same_with_the_rooms_occluding(ctx) -> None:
    """Random views from inside the rooms of a generated house (doorways between them, one room
    open above): every pixel and every face id is the same as when everything in the frustum is
    drawn, and most blocks are left out."""
    house = furnished_house(np.random.default_rng(11), 2, 2)
    scene = scene_from_model(house.model())
    rng = np.random.default_rng(5)
    lo, hi = scene.bounds()
    rooms = rooms_of(scene.model)
    assert len(rooms.shells) == 4 and len(rooms.links) == 6  # three doorways, each seen from both sides
    cams = []
    while len(cams) < N_VIEWS:
        C = lo + rng.uniform(0, 1, 3) * (hi - lo)
        C[2] = rng.uniform(0.4, 2.3)
        if not any(s.holds(C, 0.2) for s in rooms.shells):
            continue
        target = lo + rng.uniform(0, 1, 3) * (hi - lo)
        cams.append(_camera(C, target, rng.uniform(150, 600)))
    r = Renderer(ctx, scene, RenderOptions(samples=1, anisotropy=1.0))
    try:
        with_rooms, without = _views(r, cams, True), _views(r, cams, False)
        drawn = [len(_drawn_blocks(r, c)) for c in cams]
        everything = [len(_drawn_blocks(r, c, Rooms([]))) for c in cams]
    finally:
        r.release()
    for (a, ids_a), (b, ids_b) in zip(with_rooms, without, strict=True):
        np.testing.assert_array_equal(ids_a, ids_b)
        np.testing.assert_array_equal(a, b)
    assert sum(drawn) < 0.6 * sum(everything)


def _three_rooms(window: bool = False) -> list[dict[str, Any]]:
    """Rooms A, B, C in a row along x (4 × 4 m, walls 0.1 m), doorways 1 m wide in line at y 1.5–2.5;
    in C a box on the line of the doorways and one off it, near C's north wall."""
    def room(name: str, openings: dict[str, tuple[int, float]]) -> dict[str, Any]:
        params = {"c1_x": 4.0, "c2_y": 4.0, "height": 2.5, "thickness": 0.1}
        for o, (_, off) in openings.items():
            params.update({f"{o}_offset": off, f"{o}_width": 1.0, f"{o}_height": 2.0 if o != "win" else 1.0,
                           f"{o}_sill": 0.0 if o != "win" else 1.0})
        return {"name": name, "primitive": {"type": "room", "corners": 4, "rectilinear": True, "ceiling": True,
                                            "params": params, "openings": [
                                                {"name": o, "wall": w, "kind": "window" if o == "win" else "door"}
                                                for o, (w, _) in openings.items()]}}

    a = room("A", {"east": (1, 1.5), **({"win": (0, 1.5)} if window else {})})
    a["joint"] = {"type": "marker", "marker": "O", "handle": "f0", "yaw_deg": 0.0}
    b = room("B", {"west": (3, 1.5), "east": (1, 1.5)})
    b.update(parent="A", joint={"type": "through", "opening": "east", "own_opening": "west"})
    c = room("C", {"west": (3, 1.5)})
    c.update(parent="B", joint={"type": "through", "opening": "east", "own_opening": "west"})

    def box(name: str, pos: tuple[float, float]) -> dict[str, Any]:
        return {"name": name, "parent": "C", "primitive": {"type": "box", "params": {
            "width": 0.3, "depth": 0.3, "height": 1.2}}, "joint": {"type": "rests_on", "face": "floor",
                                                                   "position": list(pos), "yaw_deg": 0.0}}

    return [a, b, c, box("in_line", (2.0, 2.0)), box("off_line", (2.0, 3.5))]


def test_a_box_is_drawn_through_two_doorways_only_where_both_let_it_be_seen(ctx) -> None:
    model = model_from_dict(_three_rooms(), {"O": np.zeros(3)})
    scene = scene_from_model(model)
    rooms = rooms_of(model)
    assert sorted(rooms.links) == [(0, 0), (1, 0), (1, 1), (2, 0)]  # A-B and B-C, both ways
    cam = _camera([1.0, 2.0, 1.2], [20.0, 2.0, 1.0])  # in A, looking along the row
    r = Renderer(ctx, scene, RenderOptions(samples=1, anisotropy=1.0))
    try:
        node_of_block = {b: scene.node_names[n] for b, n in enumerate(r._order.block_node)}
        drawn = {node_of_block[b] for b in _drawn_blocks(r, cam)}
        one_room = {node_of_block[b] for b in _drawn_blocks(r, cam, Rooms(rooms.shells))}  # no doorway followed
        everything = {node_of_block[b] for b in _drawn_blocks(r, cam, Rooms([]))}
        (image, ids), (image_all, ids_all) = _views(r, [cam], True)[0], _views(r, [cam], False)[0]
    finally:
        r.release()
    assert {"off_line", "in_line"} <= everything  # both in the frustum
    assert "off_line" in one_room  # in the cone through A's doorway, hidden by B's wall
    assert "in_line" in drawn and "off_line" not in drawn
    seen_nodes = {scene.mesh.faces[i - 1].node for i in np.unique(ids) if i > 0}
    assert "in_line" in seen_nodes
    np.testing.assert_array_equal(ids, ids_all)
    np.testing.assert_array_equal(image, image_all)


def test_a_window_to_the_outside_leads_nowhere_and_keeps_its_whole_cone() -> None:
    model = model_from_dict(_three_rooms(window=True), {"O": np.zeros(3)})
    rooms = rooms_of(model)
    a = rooms.shells[0]
    win = next(k for k, o in enumerate(a.openings) if o.outward[1] < -0.5)  # on A's south wall
    assert (0, win) not in rooms.links
    lo, hi = np.array([[1.8, -3.0, 1.2], [1.8, 3.0, 0.0]]), np.array([[2.2, -2.6, 1.6], [2.2, 3.4, 0.3]])
    seen = rooms.seen(np.array([2.0, 1.0, 1.5]), 0.05, lo, hi)  # a box outside, in front of the window
    assert seen is not None and seen.tolist() == [True, True]  # the second box is inside A


def test_nothing_is_culled_from_outside_the_rooms_or_with_the_near_plane_through_a_wall() -> None:
    model = model_from_dict(_three_rooms(), {"O": np.zeros(3)})
    rooms = rooms_of(model)
    lo, hi = np.array([[9.0, 3.4, 0.0]]), np.array([[9.3, 3.7, 1.2]])
    assert rooms.seen(np.array([-3.0, 2.0, 1.2]), 0.05, lo, hi) is None  # outside the house
    assert rooms.seen(np.array([2.0, 2.0, 2.47]), 0.05, lo, hi) is None  # the near plane reaches the ceiling
    assert rooms.seen(np.array([0.03, 2.0, 1.2]), 0.05, lo, hi) is None  # ... or the west wall
    assert rooms.seen(np.array([2.0, 0.5, 1.2]), 0.05, lo, hi).tolist() == [False]  # from inside A: hidden


def test_walls_not_back_to_back_are_not_a_passage() -> None:
    """With a gap between B and C, a ray through B's doorway may travel between the walls: C's
    contents in that cone are kept."""
    nodes = _three_rooms()
    nodes[2]["joint"] = {"type": "marker", "marker": "P", "handle": "f0", "yaw_deg": 0.0}
    nodes[2].pop("parent")
    model = model_from_dict(nodes, {"O": np.zeros(3), "P": np.array([8.6, 0.0, 0.0])})  # C 0.2 m east
    rooms = rooms_of(model)
    assert sorted(rooms.links) == [(0, 0), (1, 0)]


def test_bench_house_measures_the_frame_with_and_without_the_rooms_occluding(ctx) -> None:
    from vebuild.bench.house import rooms_occluding
    from vebuild.bench.render import Timing

    model = model_from_dict(_three_rooms(), {"O": np.zeros(3)})
    fig = rooms_occluding(ctx, scene_from_model(model), _camera([1.0, 2.0, 1.2], [20.0, 2.0, 1.0]), Timing(0.0, 2, 2))
    assert fig["house_frame_fps_unlit_rooms_occluding"] > 0 and fig["house_frame_fps_unlit_rooms_not_occluding"] > 0
    # The box off the line of the doorways (12 triangles) is left out, and the parts of B's and
    # C's walls out of the cones are not (a room's walls are one block).
    assert fig["house_frame_triangles_in_view"] - fig["house_frame_triangles_drawn"] == 12


def _cameras_in_rooms(rooms: Rooms, lo: np.ndarray, hi: np.ndarray, n: int, seed: int) -> list[ImageCamera]:
    rng = np.random.default_rng(seed)
    cams: list[ImageCamera] = []
    while len(cams) < n:
        C = lo + rng.uniform(0, 1, 3) * (hi - lo)
        C[2] = rng.uniform(0.4, 2.3)
        if any(s.holds(C, 0.2) for s in rooms.shells):
            cams.append(_camera(C, lo + rng.uniform(0, 1, 3) * (hi - lo), rng.uniform(150, 600)))
    return cams


def test_the_texture_passes_id_buffers_and_seen_faces_are_the_same_with_the_rooms_occluding(ctx) -> None:
    """Pass 1 and the token-chart test draw and query only what the walls of the camera's room do
    not hide: every ID buffer, the faces each holds and the faces any camera sees are the same."""
    from vebuild.texture import layout as lay
    from vebuild.texture.gpu import Extractor
    from vebuild.texture.options import Options
    from vebuild.texture.visibility import face_points, faces_in_view, faces_not_hidden, seen_faces

    model = furnished_house(np.random.default_rng(11), 2, 2).model()
    mesh = lay.scene_mesh(model, lay.layout(model, 20.0, 4096, 2048))
    rooms = rooms_of(model)
    cams = _cameras_in_rooms(rooms, mesh.vertices.min(axis=0), mesh.vertices.max(axis=0), 12, 8)
    buffers = {}
    for occluding in (True, False):
        ex = Extractor(ctx, mesh, Options(), rooms=rooms if occluding else None)
        try:
            got = []
            for cam in cams:
                tex = ex.id_pass(cam, 1.5)
                got.append((np.frombuffer(tex.read(), "f4").copy(), set(ex.id_faces)))
            buffers[occluding] = got
        finally:
            ex.release()
    for (ids_a, faces_a), (ids_b, faces_b) in zip(buffers[True], buffers[False], strict=True):
        np.testing.assert_array_equal(ids_a, ids_b)
        assert faces_a == faces_b
    assert seen_faces(ctx, mesh, cams, rooms=rooms) == seen_faces(ctx, mesh, cams)
    points = face_points(mesh)
    left_out = []
    for cam in cams:
        unhidden = faces_not_hidden(points, rooms, cam, 0.05)
        assert unhidden is not None
        left_out.append(len(faces_in_view(points, cam) - unhidden) / len(faces_in_view(points, cam)))
    assert np.mean(left_out) > 0.3  # most of what is in view lies behind the walls
