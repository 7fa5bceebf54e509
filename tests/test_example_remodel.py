"""The example room (scenes/room) remodelled with a room shell and a flush relation, against the
example as shipped, both calibrated and solved (re-calibrating) as a user would, and compared with
scenes/room/ground_truth.json.

The shipped model has a floor quad and seven wall nodes (four walls, the south wall in three pieces
around the doorway), all but the floor held; the door leaf on a hinge whose axis is typed in. The
remodel replaces the floor and the walls by one room (four corners, the doorway an opening of its
south wall), hangs the leaf on the doorway's east jamb with its axis solved (``solve_axis``), and
puts the cabinet's side flush against the room's west wall. The pins move with their handles (the
floor's corners are the room's); the pins that the remodel makes redundant are left out: those on
floor corner 0 (the room's corner 0 sits on the origin marker by its joint) and the one on the
cabinet's corner against the wall (the flush relation places that face).

What the walls held before the room holds too: its height and thickness, and the doorway's place
and size (no photo pins a wall's top or the doorway's head), so the two models rest on the same
information about them.
"""

from __future__ import annotations

import copy
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from vebuild.actions.calibrate import calibrate_project
from vebuild.actions.solve import solve_project
from vebuild.project import load_project, save_project

EXAMPLE = Path(__file__).resolve().parents[1] / "scenes" / "room"
WALLS = ("wall_west", "wall_north", "wall_east", "wall_south", "wall_south.west", "wall_south.east",
         "wall_south.lintel")
#: A figure is "the same or better" when its error is no larger than before plus this many of
#: its σ (the two solves rest on the same clicks; a remodel may move a figure within its σ).
SAME_WITHIN_SIGMA = 1.0
#: Every figure within this many σ of the truth, in both models.
Z_BOUND = 4.5


def remodel(model: dict) -> dict:
    """The shipped model with the floor and walls replaced by a room, the door on its jamb, the
    cabinet flush against the west wall, the redundant pins left out."""
    m = copy.deepcopy(model)
    nodes = {n["name"]: n for n in m["nodes"]}
    floor = nodes["floor"]
    w, d = floor["primitive"]["params"]["width"], floor["primitive"]["params"]["depth"]
    thickness = nodes["wall_west"]["primitive"]["params"]["depth"]
    # The held walls stand about the floor's centre; their inner faces are the room's corners.
    half = np.array([nodes["wall_east"]["joint"]["position"][0] - nodes["wall_west"]["joint"]["position"][0],
                     nodes["wall_north"]["joint"]["position"][1] - nodes["wall_south"]["joint"]["position"][1]])
    half = (half - thickness) / 2
    walls_h = nodes["wall_south.west"]["primitive"]["params"]["height"]
    lintel = nodes["wall_south.lintel"]
    door_w = lintel["primitive"]["params"]["width"]
    door_h = lintel["joint"]["translation"][2]
    # The lintel's centre along the south wall (its group turned 180° about the floor's centre).
    door_x = half[0] + nodes["wall_south"]["joint"]["position"][0] - lintel["joint"]["translation"][0]
    room = {"name": "room",
            "primitive": {"type": "room", "corners": 4, "rectilinear": True, "ceiling": False,
                          "params": {"c1_x": w, "c2_y": d, "height": walls_h,
                                     "thickness": thickness,
                                     "door_offset": door_x - door_w / 2, "door_width": door_w, "door_height": door_h,
                                     "door_sill": 0.0},
                          "openings": [{"name": "door", "wall": 0, "kind": "door"}]},
            "joint": {"type": "marker", "marker": floor["joint"]["marker"], "handle": "f0",
                      "yaw_deg": floor["joint"]["yaw_deg"]},
            # As the walls were held (solve: false): no photo pins their tops or the doorway's head.
            "hold": ["height", "thickness", "door_offset", "door_width", "door_height", "door_sill"]}
    out = [room]
    for n in m["nodes"]:
        if n["name"] in ("floor", *WALLS):
            continue
        if n.get("parent") == "floor":
            n["parent"] = "room"
            if n["joint"]["type"] == "rests_on":
                # From the floor quad's centre to the room's corner 0, the room's floor face.
                s, t = n["joint"]["position"]
                n["joint"].update(face="floor", position=[s + half[0], t + half[1]])
        out.append(n)
    door = next(n for n in out if n["name"] == "door")
    j = door["joint"]
    # The pose at angle 0 and the axis, from the floor's frame into the doorway's east jamb's
    # (origin at the jamb's foot, axes the room's).
    jamb = np.array([door_x + door_w / 2 - half[0], -half[1], 0.0])
    door["joint"] = {"type": "hinge", "jamb": {"opening": "door", "side": "end"},
                     "axis_point": [float(v) for v in np.asarray(j["axis_point"]) - jamb], "axis": j["axis"],
                     "translation": [float(v) for v in np.asarray(j["translation"]) - jamb],
                     "rotation_deg": j["rotation_deg"], "angle_deg": j["angle_deg"], "limits_deg": j["limits_deg"],
                     "solve_axis": True}
    m["nodes"] = out
    m["relations"] = [{"type": "flush", "a": "cabinet:left", "b": "room:wall3", "name": "cabinet on the west wall"}]
    handle = {f"v{i}": f"f{i}" for i in range(4)}
    m["pins"] = [{**p, "node": "room", "handle": handle[p["handle"]]} if p["node"] == "floor" else p
                 for p in m["pins"]
                 if not (p["node"] == "floor" and p["handle"] == "v0")
                 and not (p["node"] == "cabinet" and p["handle"] in ("v0", "v3", "v4", "v7"))]
    m["edge_observations"] = [{**e, "node": "room", "edge": f"floor{e['edge'][1:]}"} if e["node"] == "floor" else e
                              for e in m["edge_observations"]]
    return m


def _solve(folder: Path, model: dict | None) -> dict:
    shutil.copytree(EXAMPLE, folder)
    path = folder / "room.vebuild.json"
    data = json.loads(path.read_text())
    if model is not None:
        data["model"] = model
    path.write_text(json.dumps(data, indent=1))
    project = load_project(path)
    calibrate_project(project)
    save_project(path, project.data)
    project = load_project(path)
    return solve_project(project, recalibrate=True)


def _figures(sol: dict, room: bool) -> dict[str, tuple[float, float, float]]:
    """(value, σ, true) of the figures compared: the room's size, the door leaf's, the hinge's
    axis (its distance from the true one: 0 when exact), the cabinet's, the check distance."""
    n = sol["nodes"]
    out = {}
    if room:
        p = n["room"]["params"]
        out["room width"] = (p["c1_x"]["value"], p["c1_x"]["sigma"], 5.0)
        out["room depth"] = (p["c2_y"]["value"], p["c2_y"]["sigma"], 4.0)
    else:
        p = n["floor"]["params"]
        out["room width"] = (p["width"]["value"], p["width"]["sigma"], 5.0)
        out["room depth"] = (p["depth"]["value"], p["depth"]["sigma"], 4.0)
    for k, true in (("width", 0.89), ("height", 2.035)):
        out[f"door {k}"] = (n["door"]["params"][k]["value"], n["door"]["params"][k]["sigma"], true)
    for k, true in (("width", 0.5), ("depth", 1.0), ("height", 1.9)):
        out[f"cabinet {k}"] = (n["cabinet"]["params"][k]["value"], n["cabinet"]["params"][k]["sigma"], true)
    if room:
        a = n["door"]["axis"]["point"]
        err = float(np.hypot(a["value"][0] - 4.2, a["value"][1] - 0.0))
        out["hinge axis off (m)"] = (err, float(np.hypot(*a["sigma"][:2])), 0.0)
    else:
        out["hinge axis off (m)"] = (0.0, 0.0, 0.0)  # typed in at the truth
    for c in sol.get("check_distances", []):
        out[f"check {c['a']}-{c['b']}"] = (c["measured_m"], c["measured_sigma_m"], c["known_m"])
    return out


@pytest.fixture(scope="module")
def both(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, dict, dict, dict]:
    before_model = json.loads((EXAMPLE / "room.vebuild.json").read_text())["model"]
    after_model = remodel(before_model)
    before = _solve(tmp_path_factory.mktemp("before") / "room", None)
    after = _solve(tmp_path_factory.mktemp("after") / "room", after_model)
    return before_model, after_model, before, after


def test_the_remodelled_example_has_fewer_nodes_and_pins_and_the_same_or_better_figures(both) -> None:
    before_model, after_model, before, after = both
    fb, fa = _figures(before, room=False), _figures(after, room=True)
    lines = [f"{'':24s} {'before':>22s} {'after':>22s} {'true':>8s}",
             f"{'nodes':24s} {len(before_model['nodes']):>22d} {len(after_model['nodes']):>22d}",
             f"{'pins':24s} {len(before_model['pins']):>22d} {len(after_model['pins']):>22d}"]
    for k in fb:
        (vb, sb, t), (va, sa, _) = fb[k], fa[k]
        lines.append(f"{k:24s} {vb:>12.4f} ± {sb:<7.4f} {va:>12.4f} ± {sa:<7.4f} {t:>8.3f}")
    print("\n".join(lines))
    assert len(after_model["nodes"]) < len(before_model["nodes"])
    assert len(after_model["pins"]) < len(before_model["pins"])
    for k in fb:
        (vb, sb, t), (va, sa, _) = fb[k], fa[k]
        if k.startswith("hinge"):
            # Before, the axis was typed in at the truth (no measurement: σ 0); now it is solved
            # from the leaf seen open in the photos: it must hold the truth within its σ.
            assert va <= Z_BOUND * sa, (k, fa[k])
            continue
        assert abs(va - t) <= abs(vb - t) + SAME_WITHIN_SIGMA * max(sa, sb), (k, fb[k], fa[k])
        assert abs(va - t) <= Z_BOUND * sa, (k, fa[k])
    assert after["relations"][0]["residual_m"] < 1e-4
