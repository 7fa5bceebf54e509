"""Evidence markers and lighting comparisons (paper §5.1) on the headless GL context."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image
from viewer_scene import write_project

from vebuild.actions.render import RenderRequest, render_evidence
from vebuild.analysis.lighting import compare_lighting, relative_luminance, side_by_side
from vebuild.analysis.markers import (
    MARKER_COLOUR,
    add_marker,
    draw_markers,
    marker_at_pixel,
    marker_at_point,
    visible_markers,
)
from vebuild.camera import project as project_points
from vebuild.errors import ProjectError, VebuildError
from vebuild.gl import headless_context
from vebuild.project import load_project, save_project
from vebuild.project.decode import find_view
from vebuild.render.renderer import Renderer, RenderOptions
from vebuild.render.scene import load_scene


@pytest.fixture
def room(tmp_path):
    path = write_project(tmp_path)
    data = json.loads(path.read_text())
    data["lighting"]["presets"].append({"name": "dim lamp", "ambient": [0.02] * 3, "lights": [
        {"type": "point", "position": [3.0, 2.5, 2.3], "intensity": 0.8}]})
    path.write_text(json.dumps(data))
    return load_project(path)


@pytest.fixture
def renderer(room):
    r = Renderer(headless_context(), load_scene(room), RenderOptions(samples=1))
    yield r
    r.release()


def test_a_marker_placed_from_a_pixel_lies_on_the_surface_seen_there(room, renderer):
    cam = find_view(room, "at the box")
    box_top = np.array([2.0, 2.0, 0.5])
    u, v = project_points(cam.K, cam.R, cam.C, box_top)
    m = marker_at_pixel(renderer, cam, "A", (u, v), "blood stain")
    assert m["node"] == "box" and m["description"] == "blood stain"
    np.testing.assert_allclose(m["position"], box_top, atol=2e-3)
    with pytest.raises(VebuildError, match="shows no surface of the model"):
        marker_at_pixel(renderer, find_view(room, "entrance"), "B", (320, 2))  # the sky above the walls


def test_a_marker_off_every_surface_is_refused(room, renderer):
    m = marker_at_point(renderer.scene, "C", [2.0, 1.0, 0.0005])  # on the floor
    assert m["node"] == "floor"
    with pytest.raises(VebuildError, match=r"the point \[4.5, 1.5, 1.2\] is 1.200 m from the nearest surface"):
        marker_at_point(renderer.scene, "D", [4.5, 1.5, 1.2])  # in mid-air, 1.2 m above the floor


def test_markers_are_drawn_where_they_are_and_hollow_when_hidden(room, renderer):
    cam = find_view(room, "at the box")
    on_top = marker_at_point(renderer.scene, "on the box", [2.0, 2.0, 0.5])
    behind = marker_at_point(renderer.scene, "behind the box", [1.6, 2.25, 0.0])  # hidden by the box here
    placed = visible_markers(renderer, cam, [on_top, behind])
    seen = {m["label"]: vis for m, _, vis in placed}
    assert seen == {"on the box": True, "behind the box": False}
    img = draw_markers(renderer.render(cam), placed)
    u, v = (int(round(c)) for c in placed[0][1])
    assert tuple(img[v, u]) == MARKER_COLOUR


def test_render_draws_the_projects_markers_and_names_them(room, renderer, tmp_path):
    add_marker(room, marker_at_point(renderer.scene, "A", [2.0, 2.0, 0.5]))
    save_project(room)
    out = tmp_path / "m.png"
    render_evidence(load_project(room.path), RenderRequest(out=out, view="at the box", samples=1))
    im = Image.open(out)
    assert json.loads(im.text["vebuild:evidence_markers"]) == ["A"]
    cam = find_view(room, "at the box")
    u, v = (int(round(c)) for c in project_points(cam.K, cam.R, cam.C, np.array([2.0, 2.0, 0.5])))
    assert tuple(np.asarray(im)[v, u]) == MARKER_COLOUR
    # A marker on a node the model does not have is refused when the project loads.
    data = json.loads(room.path.read_text())
    data["evidence_markers"][0]["node"] = "sofa"
    room.path.write_text(json.dumps(data))
    with pytest.raises(ProjectError, match=r"\$.evidence_markers\[0\].node: names the node 'sofa'"):
        load_project(room.path)


def test_a_darker_preset_gives_a_lower_target_luminance(room, renderer):
    cam = find_view(room, "at the box")
    results = compare_lighting(room, renderer.scene, renderer, cam, ["as-photographed", "lamp", "dim lamp"], "box")
    lum = {r.preset: r.luminance for r in results}
    assert lum["dim lamp"] < lum["lamp"]
    # The box's top is 1.8 m below the lamp: irradiance 3/1.8² ≈ 0.93 under "lamp" plus 0.1 ambient,
    # so its luminance is about that times the untextured grey's (0.51 linear), on the top at least.
    assert 0.2 < lum["lamp"] < 0.6
    for r in results:
        assert r.luminance_p10 <= r.luminance <= r.luminance_p90
    strip = side_by_side(results, renderer.node_mask(cam, "box"))
    assert strip.shape[1] == 3 * cam.width and strip.shape[0] > cam.height
    assert relative_luminance(np.array([255, 255, 255], np.uint8)) == pytest.approx(1.0)


def test_lighting_comparison_errors(room, renderer):
    cam = find_view(room, "at the box")
    with pytest.raises(VebuildError, match="the target 'sofa' is no node of the model"):
        compare_lighting(room, renderer.scene, renderer, cam, ["lamp"], "sofa")
    with pytest.raises(VebuildError, match="is not seen from this view"):
        compare_lighting(room, renderer.scene, renderer, find_view(room, "facing the west wall"), ["lamp"], "door")
    with pytest.raises(ProjectError, match="no lighting preset is called 'moon'"):
        compare_lighting(room, renderer.scene, renderer, cam, ["moon"], "box")


def test_vebuild_mark_places_and_removes_markers(room, capsys):
    from vebuild.cli import main

    cam = find_view(room, "at the box")
    u, v = project_points(cam.K, cam.R, cam.C, np.array([2.0, 2.0, 0.5]))
    assert main(["mark", str(room.path), "A", "--at", f"view:at the box@{u:.2f},{v:.2f}",
                 "--description", "a knife"]) == 0
    assert "on 'box'" in capsys.readouterr().out
    assert main(["mark", str(room.path), "B", "--at", "2.0,1.0,0.0"]) == 0
    data = json.loads(room.path.read_text())
    assert [m["label"] for m in data["evidence_markers"]] == ["A", "B"]
    assert data["evidence_markers"][0]["description"] == "a knife"
    for args, message in ((["C", "--at", "3,2.5,1.2"], "from the nearest surface"),
                          (["C", "--at", "view:entrance@320,2"], "a point off every surface"),
                          (["C", "--at", "here"], "expected X,Y,Z in metres"),
                          (["Z", "--remove"], "no marker is labelled 'Z'")):
        assert main(["mark", str(room.path), *args]) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err
    assert main(["mark", str(room.path), "A", "--remove"]) == 0
    assert [m["label"] for m in json.loads(room.path.read_text())["evidence_markers"]] == ["B"]
