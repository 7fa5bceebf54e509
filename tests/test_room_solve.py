"""Rooms in the scene graph and the solver: a door leaf hinged at a jamb, a window pane in its
opening and a room joined to another through a doorway follow the room's solved parameters; a
room's corners are solved from what known cameras see of its walls, a corner no photo shows
included, with honest uncertainties."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from vebuild.camera import ImageCamera
from vebuild.model.residuals import EdgeObservation, Pin
from vebuild.model.scene import ModelError, model_from_dict
from vebuild.model.solution import solution_at
from vebuild.model.solver import Problem, ProblemOptions
from vebuild.synthetic import CLICK_NOISE_PX

MARKERS = {"O": np.zeros(3)}
#: Poses composed of exact frames: agreement to rounding.
EXACT = 1e-9

#: An L-shaped room (as tests/test_room.py) with its door in wall 2, which runs from corner 2
#: (5, 2.5) toward corner 3 (2.5, 2.5), so the door moves with c1_x and c2_y.
ROOM = {"type": "room", "corners": 6,
        "params": {"c1_x": 5.0, "c2_y": 2.5, "c3_x": 2.5, "c4_y": 4.0, "height": 2.6, "thickness": 0.1,
                   "door_offset": 0.6, "door_width": 0.9, "door_height": 2.05, "door_sill": 0.0,
                   "win_offset": 0.8, "win_width": 1.2, "win_height": 1.1, "win_sill": 0.9},
        "openings": [{"name": "door", "wall": 2, "kind": "door"}, {"name": "win", "wall": 4, "kind": "window"}]}
LEAF_DEPTH = 0.04


def room_node(prim: dict = ROOM, name: str = "room") -> dict:
    return {"name": name, "primitive": prim, "joint": {"type": "marker", "marker": "O", "handle": "f0"}}


def leaf_node(angle_deg: float, side: str = "start", parent: str = "room") -> dict:
    """A door leaf (a box as wide as the doorway) hung on the doorway's start jamb: shut at angle
    0, its hinge edge on the jamb's axis, its face in the wall's inner plane."""
    w, h = ROOM["params"]["door_width"], ROOM["params"]["door_height"]
    return {"name": "leaf", "parent": parent,
            "primitive": {"type": "box", "params": {"width": w, "depth": LEAF_DEPTH, "height": h}},
            "joint": {"type": "hinge", "jamb": {"opening": "door", "side": side}, "axis_point": [0, 0, 0],
                      "axis": [0, 0, 1], "translation": [w / 2, LEAF_DEPTH / 2, 0], "angle_deg": angle_deg,
                      "limits_deg": [-100, 100]}}


def world(model, node: str, handle: str) -> np.ndarray:
    return model.handle_world(node, handle)


def with_params(**changes: float) -> dict:
    return {**ROOM, "params": {**ROOM["params"], **changes}}


@pytest.mark.parametrize("changes", [{}, {"c1_x": 5.7, "c2_y": 2.1}, {"door_offset": 1.1, "thickness": 0.25}])
@pytest.mark.parametrize("angle", [0.0, 35.0, -80.0])
def test_a_door_leaf_on_a_jamb_follows_the_room(changes: dict, angle: float) -> None:
    model = model_from_dict([room_node(with_params(**changes)), leaf_node(angle)], MARKERS)
    p = {**ROOM["params"], **changes}
    # The hinge edge (leaf corner v0 at the jamb) stays on the jamb's foot, whatever the angle.
    jamb = world(model, "room", "door_sb")
    np.testing.assert_allclose(world(model, "leaf", "v0"), jamb, atol=EXACT)
    np.testing.assert_allclose(world(model, "leaf", "v4"), world(model, "room", "door_sb") + [0, 0, p["door_height"]],
                               atol=EXACT)
    # The free edge swings about the jamb's vertical through the angle, into the room for > 0.
    along = world(model, "room", "door_eb") - jamb  # the wall's direction through the doorway
    free = world(model, "leaf", "v1") - world(model, "leaf", "v0")
    assert np.linalg.norm(free) == pytest.approx(p["door_width"], abs=EXACT)
    turn = np.degrees(np.arctan2(np.cross(along, free)[2], along @ free))
    assert turn == pytest.approx(angle, abs=1e-7)
    # Shut, the leaf fills the doorway: its free corner on the end jamb.
    if angle == 0.0:
        np.testing.assert_allclose(world(model, "leaf", "v1"), world(model, "room", "door_eb"), atol=EXACT)


def test_a_window_pane_sits_in_its_opening_as_the_room_changes() -> None:
    pane = {"name": "pane", "parent": "room",
            "primitive": {"type": "box", "params": {"width": 1.2, "depth": 0.01, "height": 1.1}},
            "joint": {"type": "opening", "opening": "win", "translation": [0, -0.05, 0]}}
    for changes in ({}, {"c4_y": 4.6, "c3_x": 2.9, "win_offset": 1.0, "thickness": 0.2}):
        model = model_from_dict([room_node(with_params(**changes)), pane], MARKERS)
        t = {**ROOM["params"], **changes}["thickness"]
        # Its bottom face centred on the sill, 5 cm out from the wall's inner face; as wide as the window.
        sb, eb = world(model, "room", "win_sb"), world(model, "room", "win_eb")
        out = (world(model, "room", "win_osb") - sb) / t
        bottom = np.mean([world(model, "pane", f"v{k}") for k in range(4)], axis=0)
        np.testing.assert_allclose(bottom, (sb + eb) / 2 + 0.05 * out, atol=EXACT)
        np.testing.assert_allclose(world(model, "pane", "v1") - world(model, "pane", "v0"), eb - sb, atol=EXACT)
        np.testing.assert_allclose(world(model, "pane", "v4") - world(model, "pane", "v0"), [0, 0, 1.1], atol=EXACT)
        assert model.to_dict()[1]["joint"] == {"type": "opening", "opening": "win",
                                                "translation": [0.0, -0.05, 0.0], "rotation_deg": [0.0, 0.0, 0.0]}


def test_two_rooms_joined_through_a_doorway_share_its_plane() -> None:
    """The hall's doorway is the room's doorway seen from the other side: the outer faces of the
    two walls lie in one plane, facing each other, the two doorways' outlines coincide (the
    room's start jamb is the hall's end jamb), both floors at z = 0."""
    hall = {"type": "room", "corners": 4, "params": {"c1_x": 2.0, "c2_y": 3.0, "height": 2.4, "thickness": 0.12,
                                                     "d_offset": 1.5, "d_width": 0.9, "d_height": 2.05, "d_sill": 0.0},
            "openings": [{"name": "d", "wall": 3, "kind": "door"}]}
    node = {"name": "hall", "parent": "room", "primitive": hall,
            "joint": {"type": "through", "opening": "door", "own_opening": "d"}}
    for changes in ({}, {"c1_x": 5.5, "c2_y": 2.2, "door_offset": 1.0}):
        model = model_from_dict([room_node(with_params(**changes)), node], MARKERS)
        for mine, theirs in (("osb", "oeb"), ("ost", "oet"), ("oeb", "osb"), ("oet", "ost")):
            np.testing.assert_allclose(world(model, "hall", f"d_{mine}"), world(model, "room", f"door_{theirs}"),
                                       atol=EXACT)
        T = model.world_transforms()
        o1, _, _, n1 = model.node("room").primitive.plane_frame("outer2")
        o2, _, _, n2 = model.node("hall").primitive.plane_frame("outer3")
        n1, n2 = T["room"][:3, :3] @ n1, T["hall"][:3, :3] @ n2
        o1, o2 = T["room"][:3, :3] @ o1 + T["room"][:3, 3], T["hall"][:3, :3] @ o2 + T["hall"][:3, 3]
        np.testing.assert_allclose(n2, -n1, atol=EXACT)
        assert (o2 - o1) @ n1 == pytest.approx(0.0, abs=EXACT)
        assert world(model, "hall", "f0")[2] == pytest.approx(0.0, abs=EXACT)
        # The hall's inner face is the party wall's far side: both thicknesses from the room's.
        assert (world(model, "hall", "d_sb") - world(model, "room", "door_eb")) @ (-n1) == pytest.approx(
            -(0.1 + 0.12), abs=EXACT)
    assert model.to_dict()[1]["joint"] == {"type": "through", "opening": "door", "own_opening": "d"}


@pytest.mark.parametrize(("nodes", "where", "message"), [
    ([room_node(), {**leaf_node(10), "joint": {**leaf_node(10)["joint"], "jamb": {"opening": "hatch"}}}],
     "$.model.nodes[1].joint.jamb.opening", "names opening 'hatch', which parent 'room' lacks"),
    ([room_node(), {**leaf_node(10), "joint": {**leaf_node(10)["joint"], "jamb": {"opening": "door", "side": "top"}}}],
     "$.model.nodes[1].joint.jamb.side", "a jamb's side is 'start'"),
    ([room_node(), {**leaf_node(10), "joint": {**leaf_node(10)["joint"], "jamb": "door"}}],
     "$.model.nodes[1].joint.jamb", "a hinge's jamb must be an object"),
    ([room_node(), {**leaf_node(10, parent="box")},
      {"name": "box", "parent": "room", "primitive": {"type": "box", "params": {"width": 1, "depth": 1, "height": 1}},
       "joint": {"type": "rests_on", "face": "floor"}}],
     "$.model.nodes[1].parent", "parent 'box' is a box, not a room"),
    ([room_node(), {"name": "pane", "parent": "room", "primitive": {"type": "box", "params": {
        "width": 1, "depth": 0.01, "height": 1}}, "joint": {"type": "opening", "opening": "skylight"}}],
     "$.model.nodes[1].joint.opening", "names opening 'skylight'"),
    ([room_node(), {"name": "pane", "primitive": {"type": "box", "params": {"width": 1, "depth": 0.01, "height": 1}},
                    "joint": {"type": "opening", "opening": "win"}}],
     "$.model.nodes[1].parent", "its parent is the world (no parent), not a room"),
    ([room_node(), {"name": "hall", "parent": "room", "primitive": ROOM,
                    "joint": {"type": "through", "opening": "door"}}],
     "$.model.nodes[1].joint.own_opening", "own_opening must name an opening"),
    ([room_node(), {"name": "hall", "parent": "room", "primitive": ROOM,
                    "joint": {"type": "through", "opening": "door", "own_opening": "back"}}],
     "$.model.nodes[1].joint.own_opening", "which this node lacks"),
    ([room_node(), {"name": "hall", "parent": "room",
                    "primitive": {"type": "box", "params": {"width": 1, "depth": 1, "height": 1}},
                    "joint": {"type": "through", "opening": "door", "own_opening": "door"}}],
     "$.model.nodes[1].primitive", "this node is a box, not a room"),
])
def test_joints_tied_to_a_room_refuse_what_the_room_lacks(nodes: list, where: str, message: str) -> None:
    with pytest.raises(ModelError) as e:
        model_from_dict(nodes, MARKERS)
    assert e.value.where == where, str(e.value)
    assert message in str(e.value)


def test_furniture_rests_on_the_room_floor_in_room_coordinates() -> None:
    chest = {"name": "chest", "parent": "room",
             "primitive": {"type": "box", "params": {"width": 1.0, "depth": 0.5, "height": 0.8}},
             "joint": {"type": "rests_on", "face": "floor", "position": [1.0, 2.0], "yaw_deg": 0.0}}
    model = model_from_dict([room_node(), chest], MARKERS)
    np.testing.assert_allclose(world(model, "chest", "v0"), [0.5, 1.75, 0.0], atol=EXACT)
    moved = model_from_dict([room_node(with_params(c1_x=6.0, c3_x=3.0)), chest], MARKERS)
    np.testing.assert_allclose(world(moved, "chest", "v0"), [0.5, 1.75, 0.0], atol=EXACT)


# ------------------------------------------------------------------------------------------------
# Solving a room's corners from its walls

#: The L-shaped room to recover (no openings: the test is about its corners).
TRUE = {"c1_x": 5.0, "c2_y": 2.5, "c3_x": 2.5, "c4_y": 4.0, "height": 2.6}
#: Where each wall's floor and top lines are clicked, as fractions along the wall from its start
#: corner: walls 2 and 3 meet at the reflex corner 3 (2.5, 2.5), which no photo shows: their
#: clicks stay at least 40 % of the wall away from it.
CLICKED_AT = {0: (0.2, 0.8), 1: (0.2, 0.8), 2: (0.1, 0.6), 3: (0.4, 0.9), 4: (0.2, 0.8), 5: (0.2, 0.8)}
#: Cameras standing in the room at eye height: (position, looking at).
CAMERAS = [((0.6, 0.5, 1.6), (4.5, 2.5, 1.0)), ((4.6, 0.4, 1.5), (0.5, 3.5, 1.1)), ((0.5, 3.6, 1.7), (4.0, 0.8, 1.0)),
           ((4.5, 2.1, 1.5), (0.3, 0.3, 1.2)), ((2.0, 1.2, 1.4), (2.0, 4.0, 1.3))]
WIDTH, HEIGHT, FOCAL = 1600, 1200, 900.0


def look_at(C: np.ndarray, target: np.ndarray) -> np.ndarray:
    """World→camera rotation: camera z toward the target, image x level (right), image y down."""
    z = (target - C) / np.linalg.norm(target - C)
    x = np.cross(z, [0, 0, 1.0])
    x /= np.linalg.norm(x)
    return np.vstack([x, np.cross(z, x), z])


def cameras() -> dict[str, ImageCamera]:
    K = np.array([[FOCAL, 0, WIDTH / 2], [0, FOCAL, HEIGHT / 2], [0, 0, 1.0]])
    return {f"p{k}": ImageCamera(f"p{k}", K, look_at(np.array(C, float), np.array(T, float)), np.array(C, float),
                                 WIDTH, HEIGHT) for k, (C, T) in enumerate(CAMERAS)}


def observations(rng: np.random.Generator, cams: dict[str, ImageCamera]) -> list[EdgeObservation]:
    """Each wall's floor and top lines, clicked at two points with the click noise where the
    camera sees them (in front, inside the photo); corner 3 is never clicked."""
    truth = model_from_dict([room_node({"type": "room", "corners": 6, "params": {**TRUE, "thickness": 0.1}})], MARKERS)
    out = []
    for cid, cam in cams.items():
        for i, (a, b) in CLICKED_AT.items():
            for kind, z in (("floor", 0.0), ("top", TRUE["height"])):
                ends = [world(truth, "room", f"f{i}"), world(truth, "room", f"f{(i + 1) % 6}")]
                pts = []
                for s in (a, b):
                    X = ends[0] + s * (ends[1] - ends[0]) + [0, 0, z]
                    xc = cam.R @ (X - cam.C)
                    uv = cam.K[:2] @ xc / xc[2]
                    if xc[2] > 0.3 and 0 <= uv[0] <= WIDTH and 0 <= uv[1] <= HEIGHT:
                        pts.append(uv + rng.normal(0, CLICK_NOISE_PX, 2))
                if len(pts) == 2:
                    out.append(EdgeObservation(cid, "room", f"{kind}{i}", np.array(pts)))
    return out


def solve_room(seed: int, start_off: float):
    """The room solved from the edge observations of seed ``seed``, from first guesses ``start_off``
    (relative) off the truth, alternately long and short; the thickness (no photo shows it) held."""
    rng = np.random.default_rng(seed)
    cams = cameras()
    edges = observations(rng, cams)
    guess = {k: v * (1 + start_off * (-1) ** j) for j, (k, v) in enumerate(TRUE.items())}
    node = {**room_node({"type": "room", "corners": 6, "params": {**guess, "thickness": 0.1}}), "hold": ["thickness"]}
    node["joint"] = {**node["joint"], "yaw_deg": 4.0}
    model = model_from_dict([node], MARKERS)
    problem = Problem(model, cams, [], edges, options=ProblemOptions(click_sigma_px=CLICK_NOISE_PX, prior_scale=1e5))
    r = problem.solve()
    sol = solution_at(problem, r.x, r.iterations)
    sigma = np.sqrt(np.diag(sol.covariance))[problem.layout.model.slice]
    return problem, r.x[problem.layout.model.slice], sigma, sol, len(edges)


def test_a_corner_no_photo_shows_is_solved_from_its_walls() -> None:
    """The reflex corner 3 = (c3_x, c2_y) is clicked nowhere, yet its two walls' floor and top
    lines fix it; over 12 seeds every corner coordinate and the height lie within 1 cm per metre
    (≥ 1 cm) of the truth, their error / σ has an honest RMS (two-sided χ² band) and at least 90 %
    of the truths fall inside the 95 % intervals. From first guesses 10 % and 25 % off the
    figures agree within 0.1 σ."""
    truth = {**TRUE, "yaw": 0.0}
    z = []
    for seed in range(12):
        problem, x, sigma, sol, n_edges = solve_room(seed, 0.10)
        assert n_edges >= 20 and not sol.undetermined  # every wall's two lines, most in two photos
        names = [n.split(".", 1)[1] for n in problem.names]
        assert set(names) == set(truth), names
        for name, v, s in zip(names, x, sigma, strict=True):
            err = v - truth[name]
            if name != "yaw":
                assert abs(err) < max(0.01, 0.01 * truth[name]), f"seed {seed}: {name} off by {err:.4f} m"
            # A σ both honest and useful: the corner is measured to millimetres, not "undetermined".
            assert 1e-5 < s < 0.01, f"seed {seed}: {name} σ {s}"
            z.append(err / s)
        if seed < 3:
            _, x2, _, _, _ = solve_room(seed, 0.25)
            assert np.all(np.abs(x2 - x) < 0.1 * sigma), f"seed {seed}: the start changed the answer"
    z = np.array(z)
    lo, hi = (float(np.sqrt(chi2.ppf(q, len(z)) / len(z))) for q in (0.0005, 0.9995))
    assert lo < np.sqrt(np.mean(z**2)) < hi, f"RMS of error/σ over {len(z)} values"
    assert np.mean(np.abs(z) < 1.96) >= 0.90


def test_a_room_pinned_at_its_corners_moves_its_jamb_hinged_door_with_it() -> None:
    """Pins on the room's top corners and a door leaf's free corners: solving the room and the
    leaf's angle together, the leaf stays on its jamb (exactly) and its angle is recovered."""
    rng = np.random.default_rng(5)
    cams = cameras()
    truth = model_from_dict([room_node(), leaf_node(30.0)], MARKERS)
    pins = []
    for cid, cam in cams.items():
        for node, handles in (("room", [f"t{i}" for i in range(6) if i != 3]), ("leaf", ["v1", "v2", "v5", "v6"])):
            for h in handles:
                xc = cam.R @ (world(truth, node, h) - cam.C)
                uv = cam.K[:2] @ xc / xc[2]
                if xc[2] > 0.3 and 0 <= uv[0] <= WIDTH and 0 <= uv[1] <= HEIGHT:
                    pins.append(Pin(cid, node, h, uv + rng.normal(0, CLICK_NOISE_PX, 2)))
    start_room = {"name": "room", **room_node(with_params(c1_x=5.4, c2_y=2.3, c3_x=2.7, c4_y=3.8, height=2.5)),
                  "hold": ["thickness", "door_offset", "door_width", "door_height", "door_sill", "win_offset",
                           "win_width", "win_height", "win_sill"]}
    start_leaf = {**leaf_node(10.0), "hold": ["width", "depth", "height"]}
    model = model_from_dict([start_room, start_leaf], MARKERS)
    problem = Problem(model, cams, pins, [], options=ProblemOptions(click_sigma_px=CLICK_NOISE_PX, prior_scale=1e5))
    r = problem.solve()
    sol = solution_at(problem, r.x, r.iterations)
    sigma = dict(zip(problem.names, np.sqrt(np.diag(sol.covariance)), strict=True))
    model.set_vector(problem.model_vector(r.x))
    got = dict(zip(problem.names, r.x, strict=True))
    assert abs(np.degrees(got["leaf.angle"]) - 30.0) < 4 * np.degrees(sigma["leaf.angle"]) + 1e-6
    for k in ("c1_x", "c2_y", "c4_y"):
        assert abs(got[f"room.{k}"] - ROOM["params"][k]) < 4 * sigma[f"room.{k}"]
    np.testing.assert_allclose(world(model, "leaf", "v0"), world(model, "room", "door_sb"), atol=EXACT)


def test_solved_values_that_make_an_impossible_room_are_a_clear_error() -> None:
    from vebuild.errors import VebuildError

    model = model_from_dict([room_node(), leaf_node(20.0)], MARKERS)
    x = model.vector()
    x[model.slices["room"][1].start + model.node("room").primitive.PARAMS.index("door_width")] = 4.0
    x[model.slices["leaf"][0]] = 0.5
    with pytest.raises(VebuildError, match=r"node 'room': the solved values make an impossible room .*door"):
        model.set_vector(x)
    assert model.node("room").primitive.param("door_width") == 0.9  # nothing half-changed
    assert model.node("leaf").joint.angle == pytest.approx(np.radians(20.0))


def test_the_room_joints_load_from_a_project_file_and_round_trip(tmp_path) -> None:
    import json

    from vebuild.project import load_project
    from vebuild.project.decode import model as decode_model

    pane = {"name": "pane", "parent": "room",
            "primitive": {"type": "box", "params": {"width": 1.2, "depth": 0.01, "height": 1.1}},
            "joint": {"type": "opening", "opening": "win", "translation": [0, -0.05, 0], "rotation_deg": [0, 0, 0]}}
    hall = {"name": "hall", "parent": "room", "primitive": ROOM,
            "joint": {"type": "through", "opening": "door", "own_opening": "door"}}
    nodes = [room_node(), leaf_node(20.0), pane, hall]
    path = tmp_path / "r.vebuild.json"
    path.write_text(json.dumps({"format": "vebuild-project", "version": 1, "name": "r",
                                "settings": {"click_sigma_px": 0.7}, "reference_distances": [], "photos": [],
                                "markers": [{"name": "O"}], "origin_marker": "O", "model": {"nodes": nodes}}))
    model = decode_model(load_project(path), MARKERS)
    assert [n.joint.type for n in model.nodes] == ["marker", "hinge", "opening", "through"]
    again = model_from_dict(model.to_dict(), MARKERS)
    assert again.to_dict() == model.to_dict()
    assert model.to_dict()[1]["joint"]["jamb"] == {"opening": "door", "side": "start"}
    np.testing.assert_allclose(world(again, "leaf", "v1"), world(model, "leaf", "v1"), atol=EXACT)
