"""Trajectories on the viewer's test room: known paths hit known surfaces at known distances."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from PIL import Image
from viewer_scene import nodes, write_project

from vebuild.analysis import trajectory as tj
from vebuild.analysis.rays import Occluders
from vebuild.cli import main
from vebuild.errors import VebuildError
from vebuild.gl import headless_context
from vebuild.model.scene import model_from_dict
from vebuild.project.decode import view_camera
from vebuild.render.renderer import Renderer, RenderOptions
from vebuild.render.scene import scene_from_model


@pytest.fixture(scope="module")
def room():
    return Occluders(scene_from_model(model_from_dict(nodes())))


def test_through_two_holes_in_the_east_wall_to_the_north_wall(room):
    # Entry on the wall's outer face x = 6.1, exit on its inner face x = 6.0, heading north-west
    # level at 1.2 m: the next surface met is the north wall's inner face y = 5 at x = 1.6.
    A, B = np.array([6.1, 0.5, 1.2]), np.array([6.0, 0.6, 1.2])
    tr = tj.trajectory(room, A, B, sigma=(0.002, 0.002))
    assert tr.stop is not None and (tr.stop.node, tr.stop.face) == ("wall.north", "front")
    assert tr.stop.t == pytest.approx(4.5 * math.sqrt(2), abs=1e-9)
    np.testing.assert_allclose(tr.stop.point, [1.6, 5.0, 1.2], atol=1e-9)
    rec = tr.record()
    assert rec["stops_at"]["angle_to_surface_deg"] == pytest.approx(45.0)
    assert rec["azimuth_deg"] == pytest.approx(135.0) and rec["elevation_deg"] == pytest.approx(0.0)
    where = [(s["node"], s["where"]) for s in rec["surfaces"]]
    assert where[:3] == [("wall.east.1", "at entry"), ("wall.east.1", "at exit"), ("wall.north", "beyond exit")]
    # Toward the shooter: nothing (outside the model).
    assert tr.source is None and rec["behind_leaves_scene_at_m"] is not None
    # The 95 % cone: half-angle atan(2.448 √(σa² + σb²) / L), and its radius at the stop.
    L = math.hypot(0.1, 0.1)
    assert tr.cone_deg == pytest.approx(math.degrees(math.atan(tj.K95_2D * math.hypot(0.002, 0.002) / L)))
    u = tr.stop.t / L
    assert rec["stops_at"]["cone_radius_95_m"] == pytest.approx(
        tj.K95_2D * 0.002 * math.hypot(1 - u, u), abs=1e-6)
    assert sum(rec["cone_stops_at_share_by_node"].values()) == pytest.approx(1.0)


def test_azimuth_and_elevation_hit_the_table_leg(room):
    # Heading +Y, 30° down from (3.2, 1.0, 1.5): under the table top, into the leg's face y = 3.475.
    tr = tj.trajectory(room, np.array([3.2, 1.0, 1.5]), direction=tj.direction_from_angles(90.0, -30.0),
                       cone_deg=1.0)
    assert (tr.stop.node, tr.stop.face) == ("table.leg", "front")
    assert tr.stop.t == pytest.approx(2.475 / math.cos(math.radians(30.0)), abs=1e-9)
    r = tr.record()["stops_at"]["cone_radius_95_m"]
    assert r == pytest.approx(tr.stop.t * math.tan(math.radians(1.0)), abs=1e-6)
    # Behind the point, toward the shooter, the line rises to the south wall's inner face y = 0.
    assert (tr.source.node, tr.source.face) == ("wall.south", "back")
    assert tr.source.t == pytest.approx(-1.0 / math.cos(math.radians(30.0)), abs=1e-9)


def test_a_path_that_leaves_the_scene_is_reported(room, tmp_path, capsys):
    tr = tj.trajectory(room, np.array([3.0, 2.5, 1.5]), direction=tj.direction_from_angles(0.0, 45.0))
    assert tr.stop is None and tr.record()["leaves_scene"] is True
    np.testing.assert_allclose(tr.leaves_at, [4.0, 2.5, 2.5], atol=1e-9)  # the room has no ceiling
    assert tr.source.node == "floor"  # backward, the line meets the floor at (1.5, 2.5, 0)
    np.testing.assert_allclose(tr.source.point, [1.5, 2.5, 0.0], atol=1e-9)
    proj = write_project(tmp_path)
    assert main(["analyse", str(proj), "trajectory", "--from", "3,2.5,1.5", "--azimuth", "0", "--elevation",
                 "45"]) == 0
    assert "leaves the scene at (4.000, 2.500, 2.500)" in capsys.readouterr().out


def test_bad_input_is_a_clear_error(room):
    A = np.array([3.0, 2.5, 1.0])
    with pytest.raises(VebuildError, match="mm apart"):
        tj.trajectory(room, A, A + 1e-4)
    with pytest.raises(VebuildError, match="exit point .* is off the scene"):
        tj.trajectory(room, A, np.array([300.0, 2.5, 1.0]))
    with pytest.raises(VebuildError, match="no node called 'sofa'"):
        tj.parse_point(room, "sofa:v0", "--from")
    with pytest.raises(VebuildError, match="has no handle 'v9'; its handles are: v0"):
        tj.parse_point(room, "box:v9", "--to")
    with pytest.raises(VebuildError, match="--sigma: .* needs two points"):
        tj.trajectory(room, A, direction=np.array([1.0, 0, 0]), sigma=(0.01, 0.01))
    with pytest.raises(VebuildError, match="--elevation"):
        tj.direction_from_angles(0.0, 95.0)
    np.testing.assert_allclose(tj.parse_point(room, "box:v4", "--from"), [1.7, 1.8, 0.5], atol=1e-12)


def test_drawn_over_a_headless_view(room):
    scene = room.scene
    cam = view_camera({"name": "t", "position": [3.0, 0.8, 1.6], "look_at": [3.0, 4.0, 0.8], "fov_deg": 75.0,
                       "width": 320, "height": 180})
    r = Renderer(headless_context(), scene, RenderOptions(samples=1))
    try:
        base = r.render(cam)
    finally:
        r.release()
    tr = tj.trajectory(room, np.array([3.2, 1.0, 1.5]), direction=tj.direction_from_angles(90.0, -30.0),
                       cone_deg=2.0)
    img = tj.draw_trajectory(base, cam, tr, room).astype(int)
    red = (img[..., 0] > 180) & (img[..., 1] < 80) & (img[..., 2] < 80)
    assert red.sum() > 50
    # The path's end at the leg is drawn where the leg's face projects.
    lines = tj.path_polylines(tr)
    assert lines["path"][0][-1] == pytest.approx(tr.stop.point)
    assert len(lines["cone"]) == 8 + 6


def test_cli_with_a_view_and_json(tmp_path, capsys):
    proj = write_project(tmp_path)
    out, js = tmp_path / "t.png", tmp_path / "t.json"
    assert main(["analyse", str(proj), "trajectory", "--from", "6.1,0.5,1.2", "--to", "6.0,0.6,1.2",
                 "--sigma", "0.002", "--view", "entrance", "--out", str(out), "--json", str(js)]) == 0
    text = capsys.readouterr().out
    assert "stops at: wall.north (front) 6.364 m from the entry" in text
    doc = json.loads(js.read_text())
    assert doc["analysis"] == "trajectory"
    assert doc["trajectory"]["stops_at"]["distance_m"] == pytest.approx(6.363961, abs=1e-6)
    assert doc["trajectory"]["sigma_m"] == [0.002, 0.002]
    with Image.open(out) as im:
        assert json.loads(im.text["vebuild:trajectory"])["stops_at"]["node"] == "wall.north"
    assert main(["analyse", str(proj), "trajectory", "--from", "door:v9", "--to", "1,1,1"]) == 2
    assert "has no handle 'v9'" in capsys.readouterr().err
    assert main(["analyse", str(proj), "trajectory", "--from", "1,1,1", "--to", "2,2,2", "--out", str(out)]) == 2
    assert "--view NAME and --out" in capsys.readouterr().err
