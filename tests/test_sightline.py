"""Sight lines and viewsheds on the viewer's test room (walls with a doorway in the east wall
x = 6 from y = 2 to 3, a door on a hinge, a box, a cabinet, a table), checked against an
independent ray caster: trimesh's ray queries (rtree-accelerated triangle tests)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh
from PIL import Image
from viewer_scene import nodes, write_project

from vebuild.analysis import sightline as sl
from vebuild.analysis import viewshed as vsh
from vebuild.analysis.rays import END_EPS_M, Occluders
from vebuild.camera import Lens
from vebuild.cli import main
from vebuild.errors import VebuildError
from vebuild.model.scene import model_from_dict
from vebuild.render.scene import scene_from_model

#: Allowed difference between our object share and trimesh's, each from 4000 independent samples:
#: the difference's standard error is at most √(2 · 0.25 / 4000) = 0.011, so 0.04 is 3.5 σ.
SHARE_TOLERANCE = 0.04
#: Agreement of the viewshed with trimesh, cell by cell, over every cell (boundaries included).
VIEWSHED_AGREEMENT = 0.99


def _scene(door_deg: float = 10.0):
    ns = nodes()
    for n in ns:
        if n["name"] == "door":
            n["joint"]["angle_deg"] = door_deg
    return scene_from_model(model_from_dict(ns))


@pytest.fixture(scope="module")
def open_room():
    """The room with its door opened to 90° (lying along the south side of the doorway, inside)."""
    return Occluders(_scene(90.0))


@pytest.fixture(scope="module")
def closed_room():
    return Occluders(_scene(0.0))


def _tm(occ: Occluders) -> trimesh.Trimesh:
    m = occ.scene.mesh
    return trimesh.Trimesh(m.vertices, m.triangles, process=False)


def _tm_blocked(tm: trimesh.Trimesh, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Segments blocked by a surface more than END_EPS_M from either end, by trimesh (first hit)."""
    starts = np.broadcast_to(starts, ends.shape)
    d = ends - starts
    L = np.linalg.norm(d, axis=1)
    d = d / L[:, None]
    o = starts + END_EPS_M * d
    loc, ray, _ = tm.ray.intersects_location(o, d, multiple_hits=True)
    blocked = np.zeros(len(ends), bool)
    t = np.linalg.norm(loc - o[ray], axis=1)
    hit = t < L[ray] - 2 * END_EPS_M
    blocked[ray[hit]] = True
    return blocked


def test_through_the_doorway_visible_and_through_a_wall_not(open_room, closed_room):
    eye = sl.Eye(np.array([7.0, 2.6, 1.6]))  # outside the room, east of the doorway
    seen = sl.sight_line(open_room, eye, sl.target_point(open_room, (3.0, 2.6, 1.0)))
    assert seen.visible and seen.blocker is None
    assert seen.distance_m == pytest.approx(np.linalg.norm([4.0, 0.0, 0.6]))
    wall = sl.sight_line(open_room, sl.Eye(np.array([7.0, 1.0, 1.6])), sl.target_point(open_room, (3.0, 1.0, 1.0)))
    assert not wall.visible
    assert wall.blocker["node"] == "wall.east.1" and wall.blocker["face"] == "right"
    # The wall's outer face x = 6.1 is met 0.9 m from the eye, along a line of slope 0.6 / 4.
    assert wall.blocker["distance_from_eye_m"] == pytest.approx(0.9 * np.hypot(1.0, 0.15), abs=1e-6)
    # The same doorway line with the door shut is blocked by the door.
    shut = sl.sight_line(closed_room, eye, sl.target_point(closed_room, (3.0, 2.6, 1.0)))
    assert not shut.visible and shut.blocker["node"] == "door"
    # A standing person outside the doorway sees the point too (eyes 1.6 m up).
    person = sl.sight_line(open_room, sl.Eye.person(7.0, 2.6), sl.target_point(open_room, (3.0, 2.6, 1.0)))
    assert person.visible and person.eye.position[2] == sl.STANDING_EYE_M


def test_object_share_from_straight_above_is_its_top_face(open_room):
    # From above the box's centre only its top face is seen: 0.6 × 0.4 of its 1.48 m².
    res = sl.sight_line(open_room, sl.Eye(np.array([2.0, 2.0, 2.4])), sl.target_object(open_room, "box"))
    truth = 0.24 / 1.48
    lo, hi = res.share_ci95
    assert lo <= truth <= hi
    assert res.visible_share == pytest.approx(truth, abs=0.02)


def test_object_share_agrees_with_trimesh(open_room):
    # A sitting witness whose view of the box grazes the table top: partly hidden.
    eye = sl.Eye.person(5.5, 4.5, "sitting")
    res = sl.sight_line(open_room, eye, sl.target_object(open_room, "box"))
    assert 0.05 < res.visible_share < res.facing_share
    assert "table.top" in res.blocked_by
    # Independent: trimesh samples the box's surface and casts its own rays.
    tris = open_room.triangles_of("box")
    box = trimesh.Trimesh(open_room.scene.mesh.vertices, open_room.scene.mesh.triangles[tris], process=False)
    P, fi = trimesh.sample.sample_surface(box, 4000, seed=1)
    facing = np.einsum("ij,ij->i", eye.position - P, box.face_normals[fi]) > 0
    hidden = _tm_blocked(_tm(open_room), eye.position[None], P[facing])
    share = (~hidden).sum() / len(P)
    assert res.visible_share == pytest.approx(share, abs=SHARE_TOLERANCE)


def test_viewshed_of_a_point_matches_trimesh_cell_by_cell():
    occ = Occluders(_scene(10.0))
    target = sl.target_point(occ, (3.0, 3.3, 0.4))  # under the table's edge: the table top shades much
    vs = vsh.viewshed(occ, target, eye_height=1.6, cell=0.1)
    places = vs.states == vsh.PLACE
    assert vs.states.shape == (50, 60) and places.sum() > 2500
    # Occupied: the box, the cabinet, the table top and its leg, the door (all below eye height).
    assert 0.5 < (vs.states == vsh.OCCUPIED).sum() * 0.01 < 3.0
    xs, ys = vs.centres()
    X, Y = np.meshgrid(xs, ys)
    E = np.stack([X[places], Y[places], np.full(places.sum(), 1.6)], axis=1)
    theirs = ~_tm_blocked(_tm(occ), E, np.broadcast_to(target.point, E.shape).copy())
    ours = vs.share[places] > 0
    agreement = float((ours == theirs).mean())
    assert agreement >= VIEWSHED_AGREEMENT, agreement
    fig = vs.figures()
    assert 0.2 < fig["seeing_share_of_place_area"] < 0.9
    assert fig["seeing_area_m2"] == pytest.approx(ours.sum() * 0.01)


def test_viewshed_of_an_object_matches_trimesh_on_the_same_samples(open_room):
    target = sl.target_object(open_room, "box")
    vs = vsh.viewshed(open_room, target, eye_height=1.2, cell=0.5, samples=128)
    P, N = sl.sample_surface(open_room, target.nodes, 128)
    tm = _tm(open_room)
    xs, ys = vs.centres()
    worst = 0.0
    for j, i in zip(*np.nonzero(vs.states == vsh.PLACE), strict=True):
        e = np.array([xs[i], ys[j], 1.2])
        facing = np.einsum("ij,ij->i", e - P, N) > 0
        share = (~_tm_blocked(tm, e[None], P[facing])).sum() / len(P) if facing.any() else 0.0
        worst = max(worst, abs(share - vs.share[j, i]))
    assert worst <= 2 / 128  # at most two grazing samples differ in any cell


def test_bad_input_is_a_clear_error(open_room):
    with pytest.raises(VebuildError, match="no node called 'sofa'.*box"):
        sl.target_object(open_room, "sofa")
    with pytest.raises(VebuildError, match="eye point .* is inside the object 'box'"):
        sl.sight_line(open_room, sl.Eye(np.array([2.0, 2.0, 0.3])), sl.target_point(open_room, (3, 3, 1)))
    with pytest.raises(VebuildError, match=r"standing at \(-0.05, 2.5\).*inside the object 'wall.west'"):
        sl.sight_line(open_room, sl.Eye.person(-0.05, 2.5), sl.target_point(open_room, (3, 3, 1)))
    with pytest.raises(VebuildError, match="target point .* is off the scene"):
        sl.target_point(open_room, (100.0, 0.0, 1.0))
    with pytest.raises(VebuildError, match="below the floor"):
        sl.sight_line(open_room, sl.Eye(np.array([3.0, 3.0, -0.5])), sl.target_point(open_room, (3, 3, 1)))
    with pytest.raises(VebuildError, match="target point .* is inside the object 'cabinet'.*--object cabinet"):
        sl.target_point(open_room, (1.0, 4.7, 0.3))
    with pytest.raises(VebuildError, match="--eye: expected X,Y,Z"):
        sl.parse_floats("1,2", 3, "--eye")


def test_cli_sightline_and_viewshed_with_json(tmp_path, capsys):
    proj = write_project(tmp_path)
    view, js = tmp_path / "view.png", tmp_path / "s.json"
    assert main(["analyse", str(proj), "sightline", "--standing", "4.5,1", "--object", "box", "--out", str(view),
                 "--size", "320x180", "--json", str(js)]) == 0
    out = capsys.readouterr().out
    assert "visible" in out and "of its surface" in out
    doc = json.loads(js.read_text())
    assert doc["analysis"] == "sightline" and doc["sightline"]["visible"] is True
    assert 0 < doc["sightline"]["visible_share"] < 1 and doc["sightline"]["distance_m"] > 0
    with Image.open(view) as im:
        text = dict(im.text)
        img = np.asarray(im.convert("RGB")).astype(int)
    assert json.loads(text["vebuild:camera"])["kind"] == "witness" and "vebuild:inputs_sha256" in text
    assert json.loads(text["vebuild:sightline"])["target"]["object"] == "box"
    # The box is highlighted: pixels mixed half-way toward the highlight colour (255, 190, 0).
    assert ((img[..., 0] - img[..., 2]) > 60).sum() > 200

    vmap, vj = tmp_path / "map.png", tmp_path / "v.json"
    assert main(["analyse", str(proj), "viewshed", "--target", "3.0,3.3,0.4", "--cell", "0.2", "--out", str(vmap),
                 "--json", str(vj)]) == 0
    doc = json.loads(vj.read_text())["viewshed"]
    assert doc["grid"]["nx"] == 30 and 0.2 < doc["seeing_share_of_place_area"] < 0.9
    assert len(doc["share_rows_top_to_bottom"]) == 25
    with Image.open(vmap) as im:
        assert json.loads(im.text["vebuild:viewshed"])["cell_m"] == 0.2

    assert main(["analyse", str(proj), "sightline", "--eye", "2,2,0.3", "--target", "3,3,1"]) == 2
    assert "inside the object 'box'" in capsys.readouterr().err
    assert main(["analyse", str(proj), "sightline", "--sitting", "3,1", "--object", "sofa"]) == 2
    assert "no node called 'sofa'" in capsys.readouterr().err


def test_a_point_marker_is_drawn_where_the_photos_lens_puts_it():
    """Over a photo taken through a barrel lens the cross-hair sits on the distorted pixel of the
    point (its ring's centre within a pixel), not where a pinhole would put it (some 20 px away)."""
    from vebuild.camera import ImageCamera, intrinsic_matrix, look_rotation, project

    C = np.array([0.0, 0.0, 1.5])
    cam = ImageCamera("p", intrinsic_matrix(1000.0, 800.0, 600.0), look_rotation([1.0, 0.0, 0.0]), C, 1600, 1200,
                      lens=Lens(-0.03))
    X = C + np.array([4.0, -2.8, -2.0])  # toward the lower right corner
    lens, pinhole = project(cam.K, cam.R, cam.C, X, cam.lens), project(cam.K, cam.R, cam.C, X)
    assert np.linalg.norm(lens - pinhole) > 15.0
    img = sl.draw_point_marker(np.zeros((1200, 1600, 3), np.uint8), cam, X, visible=True)
    v, u = np.nonzero(img.any(axis=2))
    centre = np.array([0.5 * (u.min() + u.max() + 1), 0.5 * (v.min() + v.max() + 1)])  # the cross-hair's box
    assert np.linalg.norm(centre - lens) < 1.0
