"""Relations between nodes (flush, aligned, equal) and the flush joint: reading and checking them
(every error names its JSON path), the joint's geometry, and solves of generated scenes where they
hold exactly and sharpen the figures."""

from __future__ import annotations

import copy
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from vebuild.errors import ProjectError
from vebuild.model.joints import FlushJoint, RestsOnJoint
from vebuild.model.relations import Relation, relation_residual, rows_of, world_plane
from vebuild.model.scene import ModelError, model_from_dict
from vebuild.project import decode, load_project

EXAMPLE = Path(__file__).resolve().parents[1] / "scenes" / "room"
MARKERS = {"O": np.zeros(3)}


def _box(name: str, size: tuple[float, float, float], pos: tuple[float, float], yaw: float = 0.0,
         parent: str = "floor", **extra: Any) -> dict[str, Any]:
    return {"name": name, "parent": parent,
            "primitive": {"type": "box", "params": dict(zip(("width", "depth", "height"), size, strict=True))},
            "joint": {"type": "rests_on", "face": "top", "position": list(pos), "yaw_deg": yaw}, **extra}


#: A 6 × 5 m floor, a wall 0.1 m thick along its back (front face at y = 2.4 in the floor's frame),
#: two cabinets 0.6 m deep standing against it, a group.
NODES: list[dict[str, Any]] = [
    {"name": "floor", "primitive": {"type": "quad", "params": {"width": 6.0, "depth": 5.0}},
     "joint": {"type": "marker", "marker": "O", "handle": "v0"}},
    _box("wall", (6.0, 0.1, 2.5), (0.0, 2.45)),
    _box("cab1", (0.8, 0.6, 0.9), (-1.5, 2.1)),
    _box("cab2", (0.8, 0.6, 0.9), (0.5, 2.1)),
    {"name": "group", "parent": "floor", "joint": {"type": "fixed"}},
]


def model(relations: Any, nodes: list[dict[str, Any]] | None = None) -> Any:
    return model_from_dict(copy.deepcopy(NODES if nodes is None else nodes), MARKERS, relations)


def error(relations: Any, nodes: list[dict[str, Any]] | None = None) -> ModelError:
    with pytest.raises(ModelError) as e:
        model(relations, nodes)
    return e.value


FLUSH = {"type": "flush", "a": "cab1:back", "b": "wall:front"}


def test_relations_read_and_round_trip() -> None:
    rels = [FLUSH, {"type": "aligned", "a": "cab1:front", "b": "cab2:front", "name": "row"},
            {"type": "aligned", "a": "cab1:e4", "b": "cab2:e4"},
            {"type": "equal", "params": ["cab1.width", "cab2.width"]},
            {"type": "flush", "a": "cab2:back", "b": "wall:front", "offset": 0.0}]
    m = model(rels)
    assert m.relations[0] == Relation("flush", "cab1:back", "wall:front")
    assert m.relations[1].label() == "row" and m.relations[0].label() == "flush cab1:back – wall:front"
    assert m.relations[3].label() == "equal cab1.width, cab2.width" and m.relations[3].nodes() == ("cab1", "cab2")
    assert [r.to_dict() for r in m.relations] == [{**FLUSH, "offset": 0.0}, rels[1], rels[2], rels[3], rels[4]]
    assert model_from_dict(copy.deepcopy(NODES), MARKERS).relations == []  # absent: none
    # As placed, the cabinets' backs are on the wall and their fronts in one plane.
    for r in m.relations:
        assert relation_residual(r, m) < 1e-12, r.label()


# Each bad relation list, the JSON path its error names, and words the message must contain.
BAD: list[tuple[str, Any, str, list[str]]] = [
    ("not a list", {"type": "flush"}, "$.model.relations", ["expected a list"]),
    ("not an object", ["flush"], "$.model.relations[0]", ["expected an object"]),
    ("unknown type", [{"type": "touching", "a": "cab1:back", "b": "wall:front"}], "$.model.relations[0].type",
     ["'touching'", "flush, aligned, equal"]),
    ("unknown key", [{**FLUSH, "distance": 1}], "$.model.relations[0].distance", ["no key 'distance'"]),
    ("offset on aligned", [{"type": "aligned", "a": "cab1:front", "b": "cab2:front", "offset": 0.1}],
     "$.model.relations[0].offset", ["no key 'offset'"]),
    ("a missing", [{"type": "flush", "b": "wall:front"}], "$.model.relations[0].a", ["node:face"]),
    ("bad offset", [{**FLUSH, "offset": "near"}], "$.model.relations[0].offset", ["metres", "'near'"]),
    ("bad name", [{**FLUSH, "name": ""}], "$.model.relations[0].name", ["non-empty"]),
    ("unknown node", [{"type": "flush", "a": "cabinet:back", "b": "wall:front"}], "$.model.relations[0].a",
     ["no node 'cabinet'", "floor, wall, cab1, cab2, group"]),
    ("no colon", [{"type": "flush", "a": "cab1", "b": "wall:front"}], "$.model.relations[0].a", ["node:face"]),
    ("unknown face", [{"type": "flush", "a": "cab1:side", "b": "wall:front"}], "$.model.relations[0].a",
     ["no face or edge 'side'", "front, right, back, left, top, bottom", "e0, e1"]),
    ("a group", [{"type": "flush", "a": "group:bottom", "b": "wall:front"}], "$.model.relations[0].a",
     ["'group' is a group"]),
    ("itself", [{"type": "flush", "a": "wall:front", "b": "wall:front"}], "$.model.relations[0].b",
     ["with itself"]),
    ("one node", [{"type": "aligned", "a": "cab1:front", "b": "cab1:back"}], "$.model.relations[0].b",
     ["two faces of node 'cab1'"]),
    ("flush edge", [{"type": "flush", "a": "cab1:e0", "b": "wall:front"}], "$.model.relations[0].a",
     ["is an edge"]),
    ("face with edge", [{"type": "aligned", "a": "cab1:front", "b": "cab2:e0"}], "$.model.relations[0].b",
     ["two faces or two edges"]),
    ("equal of one", [{"type": "equal", "params": ["cab1.width"]}], "$.model.relations[0].params",
     ["at least two"]),
    ("equal not names", [{"type": "equal", "params": "cab1.width"}], "$.model.relations[0].params",
     ["list of \"node.param\""]),
    ("equal unknown param", [{"type": "equal", "params": ["cab1.width", "cab2.breadth"]}],
     "$.model.relations[0].params[1]", ["no parameter 'breadth'", "s, t, yaw, width, depth, height"]),
    ("equal unknown node", [{"type": "equal", "params": ["cab1.width", "cab9.width"]}],
     "$.model.relations[0].params[1]", ["names no node"]),
    ("equal twice", [{"type": "equal", "params": ["cab1.width", "cab2.width", "cab1.width"]}],
     "$.model.relations[0].params[2]", ["listed twice"]),
    ("equal kinds", [{"type": "equal", "params": ["cab1.width", "cab2.yaw"]}], "$.model.relations[0].params[1]",
     ["'cab2.yaw' is a angle", "one kind"]),
    ("the same twice", [FLUSH, {"type": "flush", "a": "wall:front", "b": "cab1:back"}], "$.model.relations[1]",
     ["the same relation as $.model.relations[0]"]),
    ("two offsets", [FLUSH, {**FLUSH, "offset": 0.02}], "$.model.relations[1].offset",
     ["conflicts with $.model.relations[0]", "0 m and 0.02 m"]),
]


@pytest.mark.parametrize("relations,where,words", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_relations_name_their_json_path(relations: Any, where: str, words: list[str]) -> None:
    e = error(relations)
    assert e.where == where, str(e)
    assert str(e).startswith("$.model.relations"), str(e)
    for w in words:
        assert w in str(e), str(e)


def test_equal_over_parameters_held_at_different_values_conflicts() -> None:
    nodes = copy.deepcopy(NODES)
    nodes[2]["hold"] = ["width"]
    nodes[3]["hold"] = [{"name": "width", "sigma": 0.0}]
    nodes[3]["primitive"]["params"]["width"] = 0.9
    e = error([{"type": "equal", "params": ["cab2.width", "cab1.width"]}], nodes)
    assert e.where == "$.model.relations[0].params"
    assert "conflicting" in str(e) and "'cab1.width' is held at 0.8" in str(e) and "'cab2.width' at 0.9" in str(e)
    # Merged groups: the conflict shows through a chain of relations, named at the last.
    nodes.append(_box("cab3", (0.7, 0.6, 0.9), (2.0, 2.1)))
    e = error([{"type": "equal", "params": ["cab1.width", "cab3.width"]},
               {"type": "equal", "params": ["cab3.width", "cab2.width"]}], nodes)
    assert e.where == "$.model.relations[1].params"
    nodes[3]["primitive"]["params"]["width"] = 0.8  # held at the same value: fine
    assert len(model([{"type": "equal", "params": ["cab1.width", "cab2.width"]}], nodes).relations) == 1


def test_a_relation_between_nodes_that_are_not_solved_must_already_hold() -> None:
    nodes = copy.deepcopy(NODES)
    nodes[0]["solve"] = False
    for n in nodes[1:4]:
        n["solve"] = False
    assert len(model([FLUSH], nodes).relations) == 1  # it holds as placed
    nodes[2]["joint"]["position"] = [-1.5, 2.05]
    e = error([FLUSH], nodes)
    assert e.where == "$.model.relations[0]"
    assert "cannot hold" in str(e) and "misses by 0.05 m" in str(e) and "'cab1' nor 'wall'" in str(e)
    nodes[0]["solve"] = True  # the floor carries both: a solve could move them, so it is left to the solve
    assert len(model([FLUSH], nodes).relations) == 1


def test_a_flush_relation_that_the_joint_already_makes_is_refused() -> None:
    e = error([{"type": "flush", "a": "floor:top", "b": "cab1:bottom"}])
    assert e.where == "$.model.relations[0]" and "already holds through the rests_on joint of node 'cab1'" in str(e)
    nodes = copy.deepcopy(NODES)
    nodes[2]["parent"] = "wall"
    nodes[2]["joint"] = {"type": "flush", "face": "front", "own_face": "back", "position": [-1.5, -0.8]}
    e = error([{"type": "flush", "a": "cab1:back", "b": "wall:front"}], nodes)
    assert "already holds through the flush joint of node 'cab1' on 'wall:front'" in str(e)
    # With another offset it is no duplicate: it is a cycle that does not add up.
    e = error([{"type": "flush", "a": "cab1:back", "b": "wall:front", "offset": 0.01}], nodes)
    assert e.where == "$.model.relations[0]" and "conflicting: the cycle" in str(e)


def test_cycles_of_flush_faces_must_add_up() -> None:
    nodes = [*copy.deepcopy(NODES), _box("panel", (6.0, 0.02, 2.0), (0.0, 2.39))]
    ok = [{"type": "flush", "a": "cab1:back", "b": "panel:front"},
          {"type": "flush", "a": "cab2:back", "b": "panel:front"},
          {"type": "aligned", "a": "cab1:back", "b": "cab2:back"}]
    assert len(model(ok, nodes).relations) == 3
    bad = [*ok[:2], {"type": "flush", "a": "cab2:back", "b": "panel:front", "offset": 0.01}]
    e = error(bad, nodes)  # the same faces at two offsets
    assert e.where == "$.model.relations[2].offset"
    bad = [ok[0], {"type": "flush", "a": "cab2:back", "b": "panel:front", "offset": 0.05}, ok[2]]
    e = error(bad, nodes)
    assert e.where is not None and e.where.startswith("$.model.relations[")
    for i in range(3):
        assert f"$.model.relations[{i}]" in str(e), str(e)
    assert "0.05 m apart" in str(e)
    # Three faces each flush against the next: two of them would face the same way.
    bad = [{"type": "flush", "a": "cab1:front", "b": "cab2:back"}, {"type": "flush", "a": "cab2:back",
                                                                     "b": "panel:front"},
           {"type": "flush", "a": "panel:front", "b": "cab1:front"}]
    assert "face to face both ways" in str(error(bad, nodes))


def test_the_project_file_names_the_file_and_the_path(tmp_path: Path) -> None:
    shutil.copytree(EXAMPLE, tmp_path / "room")
    path = tmp_path / "room" / "room.vebuild.json"
    data = json.loads(path.read_text())
    assert decode.model(load_project(path), MARKERS).relations == []  # an old project: no relations
    data["model"]["relations"] = [{"type": "flush", "a": "cabinet:rear", "b": "wall_north:front"}]
    path.write_text(json.dumps(data))
    with pytest.raises(ProjectError) as e:
        decode.model(load_project(path), MARKERS)
    assert str(path) in str(e.value) and "$.model.relations[0].a" in str(e.value)
    assert "no face or edge 'rear'" in str(e.value)
    data["model"]["relations"] = [{"type": "aligned", "a": "cabinet:back", "b": "wall_north:front"}]
    path.write_text(json.dumps(data))
    assert decode.model(load_project(path), MARKERS).relations[0].type == "aligned"


# ------------------------------------------------------------------------------------------------
# The flush joint


def test_flush_on_a_bottom_face_at_offset_zero_is_rests_on_bit_for_bit() -> None:
    rng = np.random.default_rng(7)
    m = model([])
    wall, cab = m.node("wall").primitive, m.node("cab1").primitive
    for _ in range(20):
        q = np.r_[rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi)]
        pp, np_ = rng.uniform(0.1, 3, 3), rng.uniform(0.1, 3, 3)
        a = RestsOnJoint(type="rests_on", face="top").transform(q, wall, pp, cab, np_)
        assert np.array_equal(a, FlushJoint(type="flush", face="top").transform(q, wall, pp, cab, np_))
        assert np.array_equal(RestsOnJoint(type="rests_on").transform(q, None, None, cab, np_),
                              FlushJoint(type="flush").transform(q, None, None, cab, np_))  # on the world's floor
    # Through the file: a rests_on node and the same node flush on its bottom, at offset 0.
    nodes = copy.deepcopy(NODES)
    nodes[2]["joint"] = {"type": "flush", "face": "top", "own_face": "bottom", "position": [-1.5, 2.1]}
    a, b = model([]).world_transforms(), model([], nodes).world_transforms()
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert model([], nodes).node("cab1").joint.to_dict() == {"type": "flush", "face": "top", "own_face": "bottom",
                                                              "offset": 0.0, "position": [-1.5, 2.1],
                                                              "yaw_deg": 0.0}


@pytest.mark.parametrize("own,face", [("back", "front"), ("left", "right"), ("top", "bottom"), ("front", "top")])
def test_a_node_flush_on_a_face_stays_flush_under_any_s_t_yaw(own: str, face: str) -> None:
    """A cabinet's face against a wall's face (offset 0 and 0.03 m), whatever its degrees of
    freedom and both primitives' sizes: the faces are parallel, facing each other, the given
    offset apart; a turn is about the wall's normal and (s, t) slides the face in the wall's plane."""
    rng = np.random.default_rng(11)
    for offset in (0.0, 0.03):
        nodes = copy.deepcopy(NODES)
        nodes[2]["parent"] = "wall"
        nodes[2]["joint"] = {"type": "flush", "face": face, "own_face": own, "offset": offset}
        m = model([], nodes)
        rel = Relation("flush", f"cab1:{own}", f"wall:{face}", offset)
        sq, sp = m.slices["cab1"]
        x0 = m.vector()
        for _ in range(20):
            x = x0.copy()
            x[sq] = np.r_[rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi)]
            x[sp] = rng.uniform(0.2, 2, 3)
            x[m.slices["wall"][1]] = rng.uniform(0.05, 6, 3)
            T = m.world_transforms(x)
            assert np.max(np.abs(rows_of(rel, m, T, x))) < 1e-12
            assert relation_residual(rel, m, x) < 1e-12
            # The own face's centre is at (s, t) in the wall face's frame.
            oa = world_plane(m, f"cab1:{own}", T, x)[0]
            ob, xb, yb, nb = world_plane(m, f"wall:{face}", T, x)
            assert [(oa - ob) @ xb, (oa - ob) @ yb, (oa - ob) @ nb] == pytest.approx([*x[sq][:2], offset], abs=1e-12)


def test_flush_joint_errors_name_the_face() -> None:
    nodes = copy.deepcopy(NODES)
    nodes[2]["parent"] = "wall"
    nodes[2]["joint"] = {"type": "flush", "face": "side", "own_face": "back"}
    e = error([], nodes)
    assert e.where == "$.model.nodes[2].joint.face" and "front, right, back, left, top, bottom" in str(e)
    nodes[2]["joint"] = {"type": "flush", "face": "front", "own_face": "rear"}
    assert error([], nodes).where == "$.model.nodes[2].joint.own_face"
    nodes[2]["joint"] = {"type": "flush", "face": "front", "own_face": "back", "offset": "x"}
    assert error([], nodes).where == "$.model.nodes[2].joint.offset"
    nodes[2]["parent"] = None
    nodes[2]["joint"] = {"type": "flush", "face": "front", "own_face": "back"}
    assert error([], nodes).where == "$.model.nodes[2].joint.face"
