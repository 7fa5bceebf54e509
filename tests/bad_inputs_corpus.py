"""A corpus of bad, degenerate and hostile inputs for every command (used by test_bad_inputs.py).

A :class:`Case` names a mutation of the example room (of its JSON document, of a photo or of the
folder) or of the command line, the commands it applies to, and what the error message must name.
Every case × command must exit with status 2, print no traceback, name the file and the field
(the JSON path or the option) and a word of what was expected, and leave the project folder (and
the output folder) byte for byte as it was: no file changed, none added, none removed.

Words in a command are formatted with ``{P}`` (the project file), ``{D}`` (the project folder) and
``{OUT}`` (an empty output folder beside the project folder, also watched).
"""

from __future__ import annotations

import copy
import hashlib
import json
import re
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from bad_inputs_scans import SCAN_CASES
from pixel_formats import REFUSED as REFUSED_PIXELS

# -- the commands --------------------------------------------------------------------------------

CMDS: dict[str, list[str]] = {
    "check": ["check", "{P}"],
    "calibrate": ["calibrate", "{P}", "--quiet"],
    "solve": ["solve", "{P}"],
    "solve-recal": ["solve", "{P}", "--recalibrate"],
    "texture": ["texture", "{P}", "--quiet", "--density", "20"],
    "render-view": ["render", "{P}", "--view", "doorway", "--out", "{OUT}/v.png", "--size", "64x36"],
    "render-view-own-size": ["render", "{P}", "--view", "doorway", "--out", "{OUT}/v.png"],
    "render-photo": ["render", "{P}", "--photo", "p1", "--out", "{OUT}/p.png", "--size", "64x48"],
    "render-validate": ["render", "{P}", "--photo", "p1", "--validate", "--out", "{OUT}/p.png", "--size", "64x48"],
    "render-daylight": ["render", "{P}", "--view", "doorway", "--lighting", "daylight", "--out", "{OUT}/v.png",
                        "--size", "64x36"],
    "report": ["report", "{P}", "--out", "{OUT}/report", "--no-pdf", "--quiet"],
    "export": ["export", "{P}", "--out", "{OUT}/m.glb"],
    "export-obj": ["export", "{P}", "--out", "{OUT}/m.obj"],
    "export-html": ["export", "{P}", "--html", "{OUT}/viewer"],
    "scan-check": ["scan", "check", "{P}"],
    "video": ["video", "{P}", "--views", "doorway,overview", "--out", "{OUT}/w.mp4", "--size", "64x36", "--fps", "2",
              "--quiet"],
    "video-own-size": ["video", "{P}", "--views", "doorway,overview", "--out", "{OUT}/w.mp4", "--fps", "2",
                       "--quiet"],
    "analyse": ["analyse", "{P}", "distance", "cabinet:v4", "table.top:v4"],
    "analyse-dims": ["analyse", "{P}", "dimensions", "cabinet"],
    "analyse-lighting": ["analyse", "{P}", "lighting", "--view", "doorway", "--preset", "daylight", "--target",
                         "table.top", "--size", "64x36"],
    "mark": ["mark", "{P}", "Z", "--at", "2,2,0"],
    "mark-photo": ["mark", "{P}", "Z", "--at", "photo:p1@800,900"],
    "register": ["register", "{P}"],
}
#: Every command that loads the project: a document that fails validation fails them all.
LOAD = ["check", "calibrate", "solve", "solve-recal", "texture", "render-view", "render-photo", "report", "export",
        "export-html", "scan-check",
        "video", "analyse", "mark", "register"]
#: A shorter list for the many systematic type errors (each fails in the shared loader).
LOAD_SHORT = ["check", "calibrate", "solve", "render-view", "analyse", "mark"]
RENDERS = ["render-view", "render-photo", "export", "video", "report"]

# The word of "what was expected" that a message must carry (any one of these).
EXPECT_WORD = (r"expected|must|should|at least|at most|greater|less|between|no more|too |only|cannot|not "
               r"|needs?|invalid|unknown|refus|finite|positive|non-zero|nonzero|out of|exceed|limit|range|"
               r"within|contradict|inconsistent|disagree|but |instead|missing|changed|already|no such|not found|no |"
               r"run |first|outside|choose|the \w+ are|its \w+ are|required|which has")

PROJECT = "room.vebuild.json"


@dataclass
class Ctx:
    """What a mutation works on: the copied project folder and its document."""

    folder: Path
    project: Path
    out: Path
    doc: dict[str, Any]
    text: str | None = None   # set to write this exact text instead of the document
    write: bool = True        # False: leave the project file as the mutation left it

    def photo(self, i: int) -> Path:
        return self.folder / self.doc["photos"][i]["file"]

    def rehash(self, i: int) -> None:
        """Record a photo's current bytes as its hash (so that the hash check does not hide the fault)."""
        self.doc["photos"][i]["sha256"] = hashlib.sha256(self.photo(i).read_bytes()).hexdigest()


@dataclass
class Case:
    name: str
    mutate: Callable[[Ctx], None]
    commands: list[Any]                  # names in CMDS or word lists
    expect: list[Any]                    # substrings the message must hold (formatted like the words);
                                         # a tuple: any one of its alternatives
    state: str = "textured"              # raw | solved | textured
    sub: bool = False                    # run in a subprocess (memory-limited; for native crashes)
    any_of: list[str] = field(default_factory=list)  # at least one of these substrings too
    word: str = EXPECT_WORD
    cwd: str = "work"                    # work (an empty folder) | project (the project folder)


CASES: list[Case] = []
_RNG = np.random.default_rng(0)


def case(name: str, mutate: Callable[[Ctx], None], commands: list[Any], expect: list[str], **kw: Any) -> None:
    assert name not in {c.name for c in CASES}, name
    CASES.append(Case(name, mutate, commands, expect, **kw))


# -- helpers -------------------------------------------------------------------------------------

def path_str(parts: tuple[Any, ...]) -> str:
    out = "$"
    for p in parts:
        if isinstance(p, int):
            out += f"[{p}]"
        elif re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", p):
            out += f".{p}"
        else:
            out += f"[{json.dumps(p, ensure_ascii=False)}]"
    return out


def get(doc: Any, parts: tuple[Any, ...]) -> Any:
    for p in parts:
        doc = doc[p]
    return doc


def setter(parts: tuple[Any, ...], value: Any) -> Callable[[Ctx], None]:
    def mutate(ctx: Ctx) -> None:
        get(ctx.doc, parts[:-1])[parts[-1]] = copy.deepcopy(value)
    return mutate


def deleter(parts: tuple[Any, ...]) -> Callable[[Ctx], None]:
    def mutate(ctx: Ctx) -> None:
        del get(ctx.doc, parts[:-1])[parts[-1]]
    return mutate


def doc_fn(fn: Callable[[dict[str, Any]], None]) -> Callable[[Ctx], None]:
    return lambda ctx: fn(ctx.doc)


def nd(i: int, word: str) -> list[Any]:
    """What a message about node i's field must name: the node (its JSON path or its name) and the field."""
    name = list(NODE_INDEX)[i]
    return [(f"$.model.nodes[{i}]", f"node '{name}'"), word]


NODE_INDEX = {n: i for i, n in enumerate(
    ["floor", "cabinet", "box", "table", "table.top", "table.leg1", "table.leg2", "table.leg3", "table.leg4", "door",
     "wall_west", "wall_north", "wall_east", "wall_south", "wall_south.west", "wall_south.east",
     "wall_south.lintel"])}
CAB = ("model", "nodes", 1)
DOOR = ("model", "nodes", 9)


def nothing(ctx: Ctx) -> None:
    pass


def raw(fn: Callable[[str], str]) -> Callable[[Ctx], None]:
    """A mutation of the file's text (for what json.dumps cannot write)."""
    def mutate(ctx: Ctx) -> None:
        ctx.text = fn(json.dumps(ctx.doc, indent=2, ensure_ascii=False))
    return mutate


def replace_once(old: str, new: str) -> Callable[[str], str]:
    def fn(text: str) -> str:
        assert old in text, old
        return text.replace(old, new, 1)
    return fn


def write_bytes(data: bytes) -> Callable[[Ctx], None]:
    def mutate(ctx: Ctx) -> None:
        ctx.project.write_bytes(data)
        ctx.write = False
    return mutate


# -- 1. values out of any sensible range (the audit's list and more) -----------------------------

V = ["check"]  # validation happens at load: check, and the stage that uses the value
P = "{P}"


def _ph(field_: str, value: Any) -> Callable[[Ctx], None]:
    return setter(("photos", 0, field_), value)


case("photo-width-5001-digits", raw(replace_once('"width": 1600', '"width": ' + "9" * 5001)), LOAD,
     [P], any_of=["$.photos[0].width", "line "])
case("photo-height-huge-int", raw(replace_once('"height": 1200', '"height": ' + "1" + "0" * 40)),
     ["check", "calibrate", "render-photo"], [P, "$.photos[0].height"])
case("nested-1000-deep", raw(replace_once('"make": "vebuild"', '"make": ' + "[" * 1000 + "]" * 1000)),
     LOAD, [P, "$.photos[0].exif.make"])
case("nested-100000-deep", raw(replace_once('"make": "vebuild"', '"make": ' + "[" * 100000 + "]" * 100000)),
     ["check", "calibrate", "render-view"], [P], any_of=["$.photos[0].exif.make", "line ", "deep", "nest"])
case("nested-objects-5000-deep", raw(replace_once('"make": "vebuild"', '"make": ' + '{"a":' * 5000 + "1" + "}" * 5000)),
     ["check", "solve"], [P], any_of=["$.photos[0].exif.make", "line ", "deep", "nest"])
# (in a subprocess: printing a lone surrogate to a real stdout is what fails)
case("lone-surrogate-marker-description", raw(replace_once('"description": "floor corner, south-west',
                                                           '"description": "floor\\ud800 corner, south-west')),
     LOAD, [P, "$.markers[0].description"], sub=True)
case("lone-surrogate-project-name", raw(replace_once('"name": "Example room', '"name": "\\udfff Example room')),
     ["check", "calibrate", "report", "export"], [P, "$.name"], sub=True)
case("lone-surrogate-view-name", raw(replace_once('"name": "by the cabinet"', '"name": "by the\\udc80cabinet"')),
     ["check", "render-view", "video"], [P, "$.views[1].name"], sub=True)
case("reference-distance-1e308", setter(("reference_distances", 0, "distance"), 1e308),
     V + ["calibrate", "solve-recal"], [P, "$.reference_distances[0].distance"])
case("reference-sigma-1e-300", setter(("reference_distances", 0, "sigma"), 1e-300),
     V + ["calibrate", "solve-recal"], [P, "$.reference_distances[0].sigma"])
case("click-sigma-1e-300", setter(("settings", "click_sigma_px"), 1e-300),
     V + ["calibrate", "solve", "solve-recal"], [P, "$.settings.click_sigma_px"])
case("click-sigma-1e308", setter(("settings", "click_sigma_px"), 1e308),
     V + ["calibrate", "solve"], [P, "$.settings.click_sigma_px"])
case("principal-point-sigma-rel-1e-300", setter(("settings", "principal_point_sigma_rel"), 1e-300),
     V + ["calibrate"], [P, "$.settings.principal_point_sigma_rel"])
case("exif-focal-sigma-rel-zero", setter(("settings", "exif_focal_sigma_rel"), 0.0),
     V + ["calibrate"], [P, "$.settings.exif_focal_sigma_rel"])
case("focal-prior-1e308", _ph("focal_px", {"value": 1e308, "sigma": 1.0}),
     V + ["calibrate"], [P, "$.photos[0].focal_px"])
case("focal-prior-sigma-1e-300", _ph("focal_px", {"value": 1350.0, "sigma": 1e-300}),
     V + ["calibrate"], [P, "$.photos[0].focal_px"])
case("exif-focal-px-1e308", setter(("photos", 0, "exif", "focal_length_px"), 1e308),
     V + ["calibrate"], [P, "$.photos[0].exif.focal_length_px"])
case("marker-O-at-1e308", setter(("markers", 0, "position"), [1e308, 0.0, 0.0]),
     V + ["calibrate", "solve-recal"], [P, "$.markers[0].position"])
case("marker-at-1e6", setter(("markers", 1, "position"), [1e6, 0.0, 0.0]),
     V + ["calibrate", "solve-recal"], [P, "$.markers[1].position"])
case("principal-point-1e9", _ph("principal_point", {"value": [1e9, 600.0], "sigma": 5.0}),
     V + ["calibrate"], [P, "$.photos[0].principal_point"])
case("x-axis-unresolved-number", _ph("x_axis_unresolved", 5),
     V + ["calibrate"], [P, "$.photos[0].x_axis_unresolved"])
case("x-axis-unresolved-empty", _ph("x_axis_unresolved", ""),
     V + ["calibrate"], [P, "$.photos[0].x_axis_unresolved"])
case("marker-observation-1e308", setter(("photos", 0, "marker_observations", "O"), [1e308, 592.6]),
     V + ["calibrate", "solve-recal"], [P, "$.photos[0].marker_observations.O"])
case("vanishing-segment-1e308", setter(("photos", 0, "vanishing_segments", "x", 0), [1e308, 610.2, 82.1, 937.4]),
     V + ["calibrate"], [P, "$.photos[0].vanishing_segments.x[0]"])
case("pin-at-1e308", setter(("model", "pins", 0, "uv"), [1e308, 592.4]),
     V + ["solve", "solve-recal"], [P, "$.model.pins[0].uv"])
case("edge-point-1e308", setter(("model", "edge_observations", 0, "points", 0), [1e308, 621.0]),
     V + ["solve"], [P, "$.model.edge_observations[0].points"])
case("box-1e308-wide", setter(CAB + ("primitive", "params", "width"), 1e308),
     V + ["solve", "texture", "render-view", "export"], [P, *nd(1, "width")])
case("rests-on-position-1e308", setter(CAB + ("joint", "position"), [1e308, 0.0]),
     V + ["solve", "render-view", "export"], [P, *nd(1, "position")])
case("fixed-translation-1e308", setter(("model", "nodes", 4, "joint", "translation"), [0.0, 0.0, 1e308]),
     V + ["solve", "render-view", "export"], [P, *nd(4, "translation")])
case("evidence-marker-1e308", doc_fn(lambda d: d.__setitem__("evidence_markers", [
        {"label": "A", "node": "floor", "position": [1e308, 1.0, 0.0]}])),
     V + ["render-view", "report", "export"], [P, "$.evidence_markers[0].position"])
case("view-position-1e308", setter(("views", 0, "position"), [1e308, 0.3, 1.6]),
     V + ["render-view", "video"], [P, "$.views[0].position"])
case("view-fov-1e-300", setter(("views", 0, "fov_deg"), 1e-300),
     V + ["render-view", "video", "analyse-lighting"], [P, "$.views[0].fov_deg"])
case("view-fov-180", setter(("views", 0, "fov_deg"), 180.0),
     V + ["render-view", "video"], [P, "$.views[0].fov_deg"])
case("view-focal-mm-zero", doc_fn(lambda d: d["views"][2].__setitem__("focal_length_mm", 0.0)),
     ["check", ["render", P, "--view", "overview", "--out", "{OUT}/v.png", "--size", "64x36"]],
     [P, "$.views[2].focal_length_mm"])
case("light-position-1e308", setter(("lighting", "presets", 1, "lights", 0, "position"), [1e308, 2.0, 2.5]),
     V + [["render", P, "--view", "doorway", "--lighting", "ceiling lamp", "--out", "{OUT}/v.png", "--size",
           "64x36"]], [P, "$.lighting.presets[1].lights[0].position"])
case("light-intensity-1e308", setter(("lighting", "presets", 0, "lights", 0, "intensity"), 1e308),
     V + ["render-daylight"], [P, "$.lighting.presets[0].lights[0].intensity"])
case("calibration-camera-position-1e308", setter(("calibration", "cameras", "p1", "position", "value"),
                                                 [1e308, 3.6, 1.6]),
     V + ["render-photo", "texture", "export"], [P, "$.calibration.cameras.p1"])

# -- 2. degenerate geometry ------------------------------------------------------------------------

case("zero-hinge-axis", setter(DOOR + ("joint", "axis"), [0.0, 0.0, 0.0]),
     V + ["solve", "render-view", "export"], [P, *nd(9, "axis")])
case("reversed-hinge-limits", setter(DOOR + ("joint", "limits_deg"), [150.0, 0.0]),
     V + ["solve", "render-view"], [P, *nd(9, "limits_deg")])
case("hinge-angle-outside-limits", setter(DOOR + ("joint", "angle_deg"), 400.0),
     V + ["solve", "render-view"], [P, *nd(9, "angle_deg")])
case("hinge-solve-axis-not-a-boolean", setter(DOOR + ("joint", "solve_axis"), "yes"),
     V + ["solve"], [P, *nd(9, "solve_axis")])
case("slider-zero-axis", setter(DOOR + ("joint",), {"type": "slider", "axis": [0, 0, 0],
                                                    "translation": [1.25, -1.98, 0], "rotation_deg": [0, 0, 0],
                                                    "offset": 0.0, "limits": [0.0, 1.0]}),
     V + ["solve", "render-view"], [P, *nd(9, "axis")])
case("slider-reversed-limits", setter(DOOR + ("joint",), {"type": "slider", "axis": [1, 0, 0],
                                                          "translation": [1.25, -1.98, 0], "rotation_deg": [0, 0, 0],
                                                          "offset": 0.0, "limits": [1.0, -1.0]}),
     V + ["solve", "render-view"], [P, *nd(9, "limits")])
case("calibration-all-zero-rotation", setter(("calibration", "cameras", "p1", "R"), [[0.0] * 3] * 3),
     V + ["render-photo", "texture", "export", "mark-photo"], [P, "$.calibration.cameras.p1.R"])
case("calibration-rotation-not-orthonormal", setter(("calibration", "cameras", "p1", "R"),
                                                    [[2.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]),
     V + ["render-photo", "texture", "render-view", "analyse", "report", "export-html", "video"],
     [P, "$.calibration.cameras.p1.R"])
case("calibration-K-zero-focal", setter(("calibration", "cameras", "p1", "K"),
                                        [[0.0, 0, 800], [0, 0.0, 600], [0, 0, 1]]),
     V + ["render-photo", "texture", "export"], [P, "$.calibration.cameras.p1.K"])


def _left_out_p1(ctx: Ctx) -> None:
    """p1 as `vebuild calibrate` leaves out a photo whose marks determine no camera."""
    cal = ctx.doc["calibration"]
    cal["cameras"].pop("p1")
    cal["left_out"] = {"p1": {"reason": "the focal length is not determined: give its focal length"}}


case("calibration-photo-left-out", _left_out_p1, ["render-photo", "mark-photo"],
     [P, "$.calibration.left_out.p1", "the calibration left it out (the focal length is not determined"])
case("box-zero-height", setter(CAB + ("primitive", "params", "height"), 0.0),
     V + ["solve", "render-view", "texture"], [P, *nd(1, "height")])
case("box-negative-width", setter(CAB + ("primitive", "params", "width"), -0.5),
     V + ["solve", "render-view", "export"], [P, *nd(1, "width")])
case("quad-zero-depth", setter(("model", "nodes", 0, "primitive", "params", "depth"), 0.0),
     V + ["solve", "texture"], [P, *nd(0, "depth")])
case("cylinder-negative-radius", setter(CAB + ("primitive",), {"type": "cylinder",
                                                              "params": {"radius": -0.2, "height": 1.0}}),
     V + ["solve", "render-view"], [P, *nd(1, "radius")])
case("sphere-zero-radius", setter(CAB + ("primitive",), {"type": "sphere", "params": {"radius": 0.0}}),
     V + ["solve", "render-view"], [P, *nd(1, "radius")])
case("missing-parameter", deleter(CAB + ("primitive", "params", "height")),
     V + ["solve", "render-view", "export"], [P, *nd(1, "height")])
case("unknown-parameter", setter(CAB + ("primitive", "params", "radius"), 1.0),
     V + ["solve"], [P, *nd(1, "radius")])
case("unknown-primitive-type", setter(CAB + ("primitive", "type"), "torus"),
     V + ["solve"], [P, *nd(1, "torus")])
case("unknown-joint-type", setter(CAB + ("joint", "type"), "weld"),
     V + ["solve"], [P, *nd(1, "weld")])
case("scene-graph-cycle", doc_fn(lambda d: (d["model"]["nodes"][1].__setitem__("parent", "box"),
                                            d["model"]["nodes"][2].__setitem__("parent", "cabinet"))),
     V + ["solve", "render-view", "export", "texture"], [P, "$.model.nodes"],
     any_of=["cycle", "circular", "loop", "ancestor", "itself"])
case("scene-graph-self-parent", setter(CAB + ("parent",), "cabinet"),
     V + ["solve", "render-view"], [P, *nd(1, "parent")])
case("missing-parent", setter(CAB + ("parent",), "sofa"),
     V + ["solve", "render-view", "export"], [P, *nd(1, "sofa")])
case("unknown-face", setter(CAB + ("joint", "face"), "roof"),
     V + ["solve", "render-view"], [P, *nd(1, "roof")])
case("unknown-pin-handle", setter(("model", "pins", 0, "handle"), "v99"),
     V + ["solve", "solve-recal"], [P, "$.model.pins[0].handle", "v99"])
case("unknown-marker-joint-handle", setter(("model", "nodes", 0, "joint", "handle"), "v9"),
     V + ["solve", "render-view"], [P, *nd(0, "v9")])
case("unknown-marker-joint-marker", setter(("model", "nodes", 0, "joint", "marker"), "Q"),
     V + ["solve"], [P, *nd(0, "'Q'")])
case("unknown-edge", setter(("model", "edge_observations", 0, "edge"), "e99"),
     V + ["solve"], [P, "$.model.edge_observations[0].edge", "e99"])
case("unknown-hold", setter(("model", "nodes", 5, "hold"), ["heigth"]),
     V + ["solve"], [P, *nd(5, "heigth")])
case("entered-unknown-name", setter(("model", "nodes", 5, "hold"), [{"name": "heigth", "sigma": 0.002}]),
     V + ["solve"], [P, "$.model.nodes[5].hold[0].name", "heigth", "it has"])
case("entered-negative-sigma", setter(("model", "nodes", 5, "hold"), [{"name": "height", "sigma": -0.002}]),
     V + ["solve"], [P, "$.model.nodes[5].hold[0].sigma", "at least 0"])
case("entered-text-sigma", setter(("model", "nodes", 5, "hold"), [{"name": "height", "sigma": "2 mm"}]),
     V + ["solve"], [P, "$.model.nodes[5].hold[0].sigma", "expected a number"])
case("entered-held-twice", setter(("model", "nodes", 5, "hold"), ["height", {"name": "height", "sigma": 0.002}]),
     V + ["solve"], [P, "$.model.nodes[5].hold[1].name", "held twice"])
case("pin-unknown-photo", setter(("model", "pins", 0, "photo"), "p9"),
     V + ["solve"], [P, "$.model.pins[0].photo", "p9"])
case("pin-unknown-node", setter(("model", "pins", 0, "node"), "sofa"),
     V + ["solve"], [P, "$.model.pins[0].node", "sofa"])
case("duplicate-node-name", setter(("model", "nodes", 2, "name"), "cabinet"),
     V + ["solve", "render-view"], [P, *nd(2, "cabinet")])
case("group-rests-on-group-face", setter(("model", "nodes", 4, "joint"),
                                         {"type": "rests_on", "face": "top", "position": [0, 0], "yaw_deg": 0}),
     V + ["solve", "render-view"], [P, *nd(4, "face")])
case("reference-distance-zero", setter(("reference_distances", 0, "distance"), 0.0),
     V + ["calibrate"], [P, "$.reference_distances[0].distance"])
case("reference-distance-to-itself", setter(("reference_distances", 0, "b"), "O"),
     V + ["calibrate"], [P, "$.reference_distances[0]"])
case("reference-distance-unknown-marker", setter(("reference_distances", 0, "b"), "X9"),
     V + ["calibrate"], [P, "$.reference_distances[0].b", "X9"])
case("reference-distance-unknown-handle", setter(("reference_distances", 2, "b"), "cabinet:v99"),
     V + ["calibrate", "solve"], [P, "$.reference_distances[2].b", "v99"])
case("two-scale-distances-contradict", doc_fn(lambda d: d["reference_distances"].append(
        {"a": "O", "b": "Y4", "distance": 400.0, "sigma": 0.002, "role": "scale"})),
     ["calibrate", "solve-recal"], [P, ("$.reference_distances[", "the scale distances")])
case("scale-distances-contradict-by-100", setter(("reference_distances", 1, "distance"), 400.0),
     ["calibrate", "solve-recal"], [P, ("$.reference_distances[", "the scale distances")])
case("no-scale-distance", setter(("reference_distances",), []),
     ["calibrate"], [P, ("$.reference_distances", "reference distance")], state="raw")
case("no-photos", setter(("photos",), []), ["calibrate", "register"], [P, "$.photos"], state="raw")
case("origin-marker-unknown", setter(("origin_marker",), "Q"), V + ["calibrate"], [P, "$.origin_marker", "Q"])
case("marker-observation-unknown-marker", setter(("photos", 0, "marker_observations", "Q"), [10.0, 10.0]),
     V + ["calibrate"], [P, "$.photos[0].marker_observations", "Q"])
case("vanishing-segment-zero-length", setter(("photos", 0, "vanishing_segments", "x", 0), [597.6, 610.2, 597.6, 610.2]),
     V + ["calibrate"], [P, ("$.photos[0].vanishing_segments.x[0]", "$.photos[0] photo 'p1': axis x, segment 0")])
case("vanishing-segments-unknown-axis", setter(("photos", 0, "vanishing_segments", "w"), [[1, 2, 3, 4]]),
     V + ["calibrate"], [P, "$.photos[0].vanishing_segments", "w"])


# -- camera groups: photos of one camera, named, one size, in one group, not released -------------------
def _groups(*groups: list[str]) -> Callable[[Ctx], None]:
    return setter(("camera_groups",), [{"id": f"g{k}", "photos": g} for k, g in enumerate(groups)])


def _group_of_two_sizes(d: dict[str, Any]) -> None:
    d["camera_groups"] = [{"id": "body", "photos": ["p1", "p2"]}]
    d["photos"][1]["width"] = 1601


def _group_with_released(d: dict[str, Any]) -> None:
    d["camera_groups"] = [{"id": "body", "photos": ["p1", "p2"]}]
    d["photos"][1]["own_camera"] = True


case("camera-group-unknown-photo", _groups(["p1", "p9"]), V + ["calibrate"],
     [P, "$.camera_groups[0].photos[1]", "'p9'"])
case("camera-group-photo-in-two-groups", _groups(["p1", "p2"], ["p2", "p3"]), V + ["calibrate"],
     [P, "$.camera_groups[1].photos[0]", "already in $.camera_groups[0]"])
case("camera-group-of-one-photo", _groups(["p1"]), V + ["calibrate"], [P, "$.camera_groups[0].photos"])
case("camera-group-sizes-differ", doc_fn(_group_of_two_sizes), V + ["calibrate"],
     [P, "$.camera_groups[0].photos[1]", "1601×1200"])
case("camera-group-released-photo", doc_fn(_group_with_released), V + ["calibrate"],
     [P, "$.camera_groups[0].photos[1]", "own_camera"])
case("calibration-camera-group-without-covariance",
     setter(("calibration", "camera_groups"), [{"id": "body", "shared": True, "calibrated": ["p1", "p2"]}]),
     ["solve-recal"], [P, "$.calibration.camera_groups[0]", "covariance"])
case("calibrate-group-unknown-photo", nothing, [["calibrate", P, "--group", "body=p1,p9"]], [P, "--group", "'p9'"])
case("calibrate-release-unknown-photo", nothing, [["calibrate", P, "--release", "p9"]], [P, "--release", "'p9'"])
# A photo's own scale (a photo placed alone): bad values are refused at load, naming the field.
_KNOWN = {"photo": "p1", "axis": "z", "ends": [[800.0, 900.0], [800.0, 300.0]], "length": 2.0, "sigma": 0.002}


case("known-length-unknown-photo", setter(("known_lengths",), [{**_KNOWN, "photo": "p9"}]),
     V + ["calibrate"], [P, "$.known_lengths[0].photo", "p9"])
case("known-length-ends-coincide", setter(("known_lengths",), [{**_KNOWN, "ends": [[800.0, 900.0], [800.5, 900.0]]}]),
     V + ["calibrate"], [P, "$.known_lengths[0].ends"])
case("known-length-off-the-photo", setter(("known_lengths",), [{**_KNOWN, "ends": [[800.0, 900.0], [9e5, 900.0]]}]),
     V + ["calibrate"], [P, "$.known_lengths[0].ends[1]"])
case("known-length-floor-end-2", setter(("known_lengths",), [{**_KNOWN, "floor_end": 2}]),
     V + ["calibrate"], [P, "$.known_lengths[0].floor_end"])
case("known-length-zero", setter(("known_lengths",), [{**_KNOWN, "length": 0.0}]),
     V + ["calibrate"], [P, "$.known_lengths[0].length"])
case("camera-height-negative", setter(("photos", 0, "camera_height"), {"value": -1.6, "sigma": 0.05}),
     V + ["calibrate"], [P, "$.photos[0].camera_height.value"])
case("camera-height-no-sigma", setter(("photos", 0, "camera_height"), {"value": 1.6}),
     V + ["calibrate"], [P, "$.photos[0].camera_height", "sigma"])
case("marker-on-floor-not-boolean", setter(("markers", 0, "on_floor"), "yes"),
     V + ["calibrate"], [P, "$.markers[0].on_floor"])
case("duplicate-photo-id", setter(("photos", 1, "id"), "p1"), V + ["calibrate", "render-photo"], [P, "$.photos[1].id"])
case("duplicate-marker-name", setter(("markers", 1, "name"), "O"), V + ["calibrate"], [P, "$.markers[1].name"])
case("photo-id-unsafe", setter(("photos", 0, "id"), "p 1/../x"), V + ["calibrate", "render-photo"],
     [P, "$.photos[0].id"])
case("photo-file-absolute", setter(("photos", 0, "file"), "/etc/hostname"), LOAD, [P, "$.photos[0].file"])
case("photo-file-dotdot", setter(("photos", 0, "file"), "../room/photos/p1.jpg"), LOAD, [P, "$.photos[0].file"])
case("photo-width-mismatch", setter(("photos", 0, "width"), 1601), LOAD, [P, "$.photos[0].width"])
case("photo-width-zero", setter(("photos", 0, "width"), 0), LOAD_SHORT, [P, "$.photos[0].width"])
case("photo-height-negative", setter(("photos", 0, "height"), -1200), LOAD_SHORT, [P, "$.photos[0].height"])
case("photo-sha-uppercase", doc_fn(lambda d: d["photos"][0].__setitem__("sha256", d["photos"][0]["sha256"].upper())),
     LOAD_SHORT, [P, "$.photos[0].sha256"])

# -- 3. views and lighting -------------------------------------------------------------------------

RV = ["render", P, "--view", "big", "--out", "{OUT}/v.png"]


def _big_view(w: int, h: int) -> Callable[[Ctx], None]:
    return doc_fn(lambda d: d["views"].append({"name": "big", "position": [3.7, 0.3, 1.6], "look_at": [2.2, 2.7, 0.74],
                                               "width": w, "height": h}))


for _w, _h in ((1, 100000), (20000, 1), (40000, 40000)):
    case(f"view-too-large-{_w}x{_h}", _big_view(_w, _h),
         ["check", RV, ["video", P, "--views", "big,doorway", "--out", "{OUT}/w.mp4", "--fps", "2", "--quiet"]],
         [P, "$.views[3]"], sub=True)
case("view-too-large-sightline-recorded", doc_fn(lambda d: (
        d["views"].append({"name": "big", "position": [3.7, 0.3, 1.6], "look_at": [2.2, 2.7, 0.74],
                           "width": 40000, "height": 40000}),
        d.__setitem__("analyses", [{"name": "witness", "command": ["sightline", "--standing", "3.7,0.4", "--object",
                                                                   "box", "--size", "40000x40000", "--out",
                                                                   "witness.png"]}]))),
     ["check", "report"], [P], any_of=["$.analyses[0]", "$.views[3]"], sub=True)
case("view-20000x1", doc_fn(lambda d: d["views"][0].update(width=20000, height=1)),
     V + ["report", "render-view", "export", "analyse"], [P, "$.views[0]"])
case("view-zero-width", setter(("views", 0, "width"), 0), V + ["render-view-own-size"], [P, "$.views[0].width"])
case("view-both-aims", setter(("views", 0, "direction"), [1.0, 0.0, 0.0]), V + ["render-view"], [P, "$.views[0]"])
case("view-look-at-itself", setter(("views", 0, "look_at"), [3.7, 0.3, 1.6]), V + ["render-view"],
     [P, "$.views[0].look_at"])
case("view-zero-direction", doc_fn(lambda d: (d["views"][0].pop("look_at"),
                                              d["views"][0].__setitem__("direction", [0, 0, 0]))),
     V + ["render-view"], [P, "$.views[0].direction"])
case("view-duplicate-name", setter(("views", 1, "name"), "doorway"), V + ["render-view", "video"],
     [P, "$.views[1].name"])
case("more-lights-than-renderer-draws", doc_fn(lambda d: d["lighting"]["presets"][0]["lights"].extend(
        [{"type": "point", "position": [1.0 + 0.3 * k, 2.0, 2.4]} for k in range(8)])),
     V + ["render-daylight", "analyse-lighting",
          ["video", P, "--views", "doorway,overview", "--lighting", "daylight", "--out", "{OUT}/w.mp4", "--size",
           "64x36", "--fps", "2", "--quiet"]],
     [P, "$.lighting.presets[0].lights"])
case("light-zero-direction", setter(("lighting", "presets", 0, "lights", 0, "direction"), [0.0, 0.0, 0.0]),
     V + ["render-daylight"], [P, "$.lighting.presets[0].lights[0].direction"])
case("spot-inner-wider-than-outer", setter(("lighting", "presets", 2, "lights", 0, "inner_cone_deg"), 40.0),
     V, [P, "$.lighting.presets[2].lights[0].inner_cone_deg"])
case("spot-outer-cone-180", setter(("lighting", "presets", 2, "lights", 0, "outer_cone_deg"), 180.0),
     V + [["render", P, "--view", "doorway", "--lighting", "night, torch", "--out", "{OUT}/v.png", "--size", "64x36"]],
     [P, "$.lighting.presets[2].lights[0].outer_cone_deg"])
case("point-light-without-position", deleter(("lighting", "presets", 1, "lights", 0, "position")), V,
     [P, "$.lighting.presets[1].lights[0]", "position"])
case("preset-named-as-photographed", setter(("lighting", "presets", 0, "name"), "as-photographed"),
     V + ["render-view"], [P, "$.lighting.presets[0].name"])
case("light-negative-colour", setter(("lighting", "presets", 0, "lights", 0, "colour"), [-1.0, 0.5, 0.5]),
     V + ["render-daylight"], [P, "$.lighting.presets[0].lights[0].colour"])

# -- 4. hypotheses, evidence markers, analyses ------------------------------------------------------

case("hypothesis-changes-joint-type", doc_fn(lambda d: d.__setitem__("hypotheses", [
        {"name": "h", "joints": {"cabinet": {"type": "fixed", "translation": [0, 0, 0], "rotation_deg": [0, 0, 0]}}}])),
     V + [["render", P, "--view", "doorway", "--hypothesis", "h", "--out", "{OUT}/v.png", "--size", "64x36"]],
     [P, "$.hypotheses[0].joints.cabinet.type"])
case("hypothesis-unknown-node", doc_fn(lambda d: d.__setitem__("hypotheses", [
        {"name": "h", "joints": {"sofa": {"type": "rests_on", "face": "top", "position": [0, 0], "yaw_deg": 0}}}])),
     V + ["report"], [P, "$.hypotheses[0].joints.sofa"])
case("hypothesis-hinge-beyond-limits", doc_fn(lambda d: d.__setitem__("hypotheses", [
        {"name": "h", "joints": {"door": {**d["model"]["nodes"][9]["joint"], "angle_deg": 720.0}}}])),
     V + [["render", P, "--view", "doorway", "--hypothesis", "h", "--out", "{OUT}/v.png", "--size", "64x36"]],
     [P, "$.hypotheses[0].joints.door"])
case("evidence-marker-unknown-node", doc_fn(lambda d: d.__setitem__("evidence_markers", [
        {"label": "A", "node": "sofa", "position": [1.0, 1.0, 0.0]}])),
     V + ["render-view", "report"], [P, "$.evidence_markers[0].node", "sofa"])
case("evidence-marker-duplicate-label", doc_fn(lambda d: d.__setitem__("evidence_markers", [
        {"label": "A", "node": "floor", "position": [1.0, 1.0, 0.0]},
        {"label": "A", "node": "floor", "position": [2.0, 1.0, 0.0]}])),
     V + ["render-view"], [P, "$.evidence_markers[1].label"])


def _analysis(command: list[str]) -> Callable[[Ctx], None]:
    return doc_fn(lambda d: d.__setitem__("analyses", [{"name": "a", "command": command}]))


case("unknown-recorded-analysis", _analysis(["frobnicate", "cabinet"]), V + ["report"], [P, "$.analyses[0].command"])
case("recorded-analysis-help", _analysis(["distance", "--help"]), V + ["report"], [P, "$.analyses[0].command"])
case("recorded-analysis-h", _analysis(["-h"]), V + ["report"], [P, "$.analyses[0].command"])
case("recorded-analysis-empty", _analysis([]), V + ["report"], [P, "$.analyses[0].command"])
case("recorded-sightline-unknown-object", _analysis(["sightline", "--standing", "3.7,0.4", "--object", "sofa"]),
     V + ["report"], [P, "$.analyses[0]", "sofa"])
case("recorded-lighting-unknown-target", _analysis(["lighting", "--view", "doorway", "--preset", "daylight",
                                                    "--target", "sofa", "--size", "64x36"]),
     V + ["report"], [P, "$.analyses[0]", "sofa"])
case("recorded-lighting-unknown-preset", _analysis(["lighting", "--view", "doorway", "--preset", "dusk",
                                                    "--target", "table.top", "--size", "64x36"]),
     V + ["report"], [P, "$.analyses[0]", "dusk"])
case("recorded-trajectory-unknown-view", _analysis(["trajectory", "--from", "1,1,1", "--to", "2,2,1", "--view",
                                                    "hall"]), V + ["report"], [P, "$.analyses[0]", "hall"])
case("recorded-sightline-unknown-hypothesis", _analysis(["sightline", "--standing", "3.7,0.4", "--object", "cabinet",
                                                         "--hypothesis", "h9"]), V + ["report"],
     [P, "$.analyses[0]", "h9"])
case("recorded-trajectory-unknown-node", _analysis(["trajectory", "--from", "sofa:v1", "--to", "2,2,1"]),
     V + ["report", "export-html"], [P, "$.analyses[0]", "sofa"])
case("recorded-sightline-one-number-spot", _analysis(["sightline", "--standing", "3.7", "--object", "cabinet"]),
     V + ["report"], [P, "$.analyses[0]", "--standing"])
case("recorded-viewshed-unknown-object", _analysis(["viewshed", "--object", "sofa", "--out", "x.png"]),
     V + ["report"], [P, "$.analyses[0]", "sofa"])
case("recorded-analysis-unknown-node", _analysis(["distance", "sofa:v1", "cabinet:v4"]), V + ["report", "render-view"],
     [P, "$.analyses[0]", "sofa"])

# The case details (FORMAT.md "case"): set by `vebuild case`, shown on the report's title page.
CASE_CMD = ["case", P, "--examiner", "A. Examiner"]
case("case-not-an-object", setter(("case",), "2026/17"), V + ["report", CASE_CMD], [P, "$.case"], state="raw")
case("case-unknown-field", setter(("case",), {"numbr": "2026/17"}), V + ["report", CASE_CMD],
     [P, "$.case", "numbr"], state="raw")
case("case-number-not-text", setter(("case",), {"number": 17}), V + ["report", CASE_CMD], [P, "$.case.number"],
     state="raw")
case("case-examiner-empty", setter(("case",), {"examiner": ""}), V + [CASE_CMD], [P, "$.case.examiner"],
     state="raw")
case("case-declaration-too-long", setter(("case",), {"declaration": "I declare. " * 1000}), V + [CASE_CMD],
     [P, "$.case.declaration"], state="raw")


# -- 5. results: calibration, model_solution, textures ---------------------------------------------


def _orphan_camera(d: dict[str, Any]) -> None:
    d["calibration"]["cameras"]["p9"] = copy.deepcopy(d["calibration"]["cameras"]["p1"])


case("orphan-camera-in-calibration", doc_fn(_orphan_camera),
     V + ["render-photo", "texture", "export", "report", "solve-recal"], [P, "$.calibration.cameras", "p9"])
case("text-where-model-solution-number", setter(("model_solution", "nodes", "floor", "params", "width", "value"),
                                                "5.0"),
     V + ["analyse-dims", "report", "analyse"], [P, "$.model_solution.nodes.floor.params.width.value"])
case("model-solution-rms-text", setter(("model_solution", "rms_px"), "small"), V + ["report"],
     [P, "$.model_solution.rms_px"])
case("model-solution-covariance-not-square", doc_fn(lambda d: d["model_solution"]["covariance"]["matrix"].pop()),
     V + ["analyse", "report"], [P, "$.model_solution.covariance"])
case("model-solution-orphan-node", doc_fn(lambda d: d["model_solution"]["nodes"].__setitem__(
        "sofa", copy.deepcopy(d["model_solution"]["nodes"]["cabinet"]))),
     V + ["analyse", "report"], [P, "$.model_solution.nodes", "sofa"])
case("calibration-overwritten-by-an-older-recalibration",
     setter(("calibration", "cameras", "p2", "recalibrated"), True),
     V + ["solve", "solve-recal", "render-photo", "texture", "export", "report"],
     [P, "$.calibration.cameras.p2.recalibrated", "vebuild calibrate"])


def _recalibrated_not_a_rotation(d: dict[str, Any]) -> None:
    rec = copy.deepcopy(d["calibration"]["cameras"]["p1"])
    rec.update(R=[[2, 0, 0], [0, 1, 0], [0, 0, 1]], recalibrated=True)
    d["model_solution"]["cameras"] = {"p1": rec}


case("recalibrated-camera-not-a-rotation", doc_fn(_recalibrated_not_a_rotation),
     V + ["render-photo", "texture", "export"], [P, "$.model_solution.cameras.p1.R", "rotation"])
case("calibration-marker-1e308", setter(("calibration", "markers", "O", "position"), [1e308, 0.0, 0.0]),
     V + ["solve-recal", "report"], [P, "$.calibration.markers.O"])
case("atlas-page-50000x50000", doc_fn(lambda d: d["textures"]["pages"][0].update(width=50000, height=50000)),
     V + ["render-view", "export", "video", "report"], [(P, "textures/atlas_"), "$.textures.pages[0]"], sub=True)
case("atlas-page-path-absolute", setter(("textures", "pages", 0, "atlas"), "/etc/hostname"),
     V + ["render-view", "export", "export-obj"], [P, "$.textures.pages[0].atlas"])
case("atlas-page-path-dotdot", setter(("textures", "pages", 0, "atlas"), "../outside/atlas_0.png"),
     V + ["render-view", "export", "export-obj"], [P, "$.textures.pages[0].atlas"])
case("coverage-page-path-dotdot", setter(("textures", "pages", 0, "coverage"), "../../coverage_0.png"),
     V + ["render-view", "export"], [P, "$.textures.pages[0].coverage"])
case("atlas-page-path-backslash", setter(("textures", "pages", 0, "atlas"), "textures\\atlas_0.png"),
     V + ["render-view", "export"], [P, "$.textures.pages[0].atlas"])

# The audit trail (FORMAT.md, "Audit trail"): every entry as the schema gives it, else refused at load.
case("audit-not-a-list", setter(("audit",), {"command": "solve"}), LOAD_SHORT, [P, "$.audit"])
case("audit-entry-without-after-hash", doc_fn(lambda d: d["audit"][0].pop("after_sha256")), LOAD_SHORT,
     [P, "$.audit[0]", "after_sha256"])
case("audit-before-hash-not-hex", setter(("audit", 0, "before_sha256"), "not a hash"), V + ["solve"],
     [P, "$.audit[0].before_sha256"])
case("audit-time-not-iso", setter(("audit", 0, "time"), "yesterday"), V + ["solve"], [P, "$.audit[0].time"])
case("audit-arguments-not-words", setter(("audit", 0, "arguments"), [1, 2]), V + ["solve"],
     [P, "$.audit[0].arguments[0]"])
case("audit-entry-unknown-key", doc_fn(lambda d: d["audit"][0].update(comment="edited")), V + ["solve"],
     [P, "$.audit[0]", "comment"])
case("computed-from-not-a-hash", setter(("model_solution", "computed_from", "settings"), 42), V + ["solve"],
     [P, "$.model_solution.computed_from.settings"])


def _atlas_file(ctx: Ctx) -> Path:
    return ctx.folder / ctx.doc["textures"]["pages"][0]["atlas"]


def _atlas_changed(ctx: Ctx) -> None:
    f = _atlas_file(ctx)
    b = bytearray(f.read_bytes())
    b[-20] ^= 0xFF
    f.write_bytes(bytes(b))


def _atlas_not_image(ctx: Ctx) -> None:
    f = _atlas_file(ctx)
    f.write_bytes(b"not a PNG at all\n")
    ctx.doc["textures"]["pages"][0]["atlas_sha256"] = hashlib.sha256(f.read_bytes()).hexdigest()


def _textures_symlink(ctx: Ctx) -> None:
    # The textures folder replaced by a link to a folder outside the project (which is watched too).
    outside = ctx.folder.parent / "outside"
    shutil.move(str(ctx.folder / "textures"), str(outside))
    (ctx.folder / "textures").symlink_to(outside, target_is_directory=True)


case("atlas-file-changed", _atlas_changed, ["check", "render-view", "export"],
     [(P, "textures/atlas_"), "$.textures.pages[0]"],
     any_of=["sha256", "changed"])
case("atlas-not-an-image", _atlas_not_image, ["check", "render-view", "export"],
     [(P, "textures/atlas_"), "$.textures.pages[0].atlas"])
case("textures-folder-symlink", _textures_symlink, ["check", "render-view", "export", "texture"],
     [(P, "{D}/textures"), "textures"])
case("texture-face-rect-outside-page", setter(("textures", "faces", 0, "rect"), [0, 0, 1000000, 1000000]),
     V + ["render-view", "export"], [P, "$.textures.faces[0].rect"])
case("texture-face-unknown-page", setter(("textures", "faces", 0, "page"), 7),
     V + ["render-view", "export"], [P, "$.textures.faces[0].page"])

# -- 6. photos ----------------------------------------------------------------------------------------


def _truncate_photo(ctx: Ctx) -> None:
    f = ctx.photo(0)
    f.write_bytes(f.read_bytes()[: f.stat().st_size // 2])
    ctx.rehash(0)


def _change_photo(ctx: Ctx) -> None:
    f = ctx.photo(0)
    b = bytearray(f.read_bytes())
    b[len(b) // 2] ^= 0x55
    f.write_bytes(bytes(b))


def _missing_photo(ctx: Ctx) -> None:
    ctx.photo(1).unlink()


def _photo_not_image(ctx: Ctx) -> None:
    ctx.photo(0).write_text("these are my notes, not a photograph\n")
    ctx.rehash(0)


def _photo_empty(ctx: Ctx) -> None:
    ctx.photo(0).write_bytes(b"")
    ctx.rehash(0)


def _photo_is_folder(ctx: Ctx) -> None:
    ctx.photo(0).unlink()
    ctx.photo(0).mkdir()


def _photo_png_bomb(ctx: Ctx) -> None:
    # A valid PNG header that claims 60000 × 60000 pixels (a decompression bomb of 3.6 gigapixels; each
    # side within the schema's 65535, so that it is the image reader that must refuse it).
    import struct
    import zlib
    ihdr = struct.pack(">IIBBBBB", 60000, 60000, 8, 2, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    data = (b"\x89PNG\r\n\x1a\n" + struct.pack(">I", len(ihdr)) + chunk
            + struct.pack(">I", zlib.crc32(chunk) & 0xFFFFFFFF))
    ctx.photo(0).write_bytes(data)
    ctx.rehash(0)
    ctx.doc["photos"][0].update(width=60000, height=60000)


case("truncated-jpeg-photo", _truncate_photo, ["check", "calibrate", "texture", "render-validate", "report"],
     [P, "$.photos[0]", "p1.jpg"])
case("photo-changed-hash", _change_photo, LOAD, [P, "$.photos[0].sha256", "p1.jpg"])
case("photo-missing", _missing_photo, LOAD, [P, "$.photos[1].file", "p2.jpg"])
case("photo-replaced-by-non-image", _photo_not_image, LOAD, [P, "$.photos[0].file", "p1.jpg"])
case("photo-empty-file", _photo_empty, ["check", "texture", "render-validate"], [P, "$.photos[0].file", "p1.jpg"])
case("photo-is-a-folder", _photo_is_folder, ["check", "calibrate"], [P, "$.photos[0].file", "p1.jpg"])
case("photo-decompression-bomb", _photo_png_bomb, ["check", "texture", "render-validate"], [P, "$.photos[0]"],
     sub=True)


# A photo whose pixel format vebuild refuses (tests/pixel_formats.py: floating point, 32-bit or signed
# integers, pixels not opaque), at the photo's own size, so that the pixels are the only fault.
def _photo_pixels(make: Callable[..., Any]) -> Callable[[Ctx], None]:
    def mutate(ctx: Ctx) -> None:
        entry = ctx.doc["photos"][0]
        sample = make(np.random.default_rng(0), entry["height"], entry["width"])
        ctx.photo(0).write_bytes(sample.data)
        ctx.rehash(0)
    return mutate


for _make in REFUSED_PIXELS:
    case(f"photo-pixels-{_make.__name__.replace('_', '-')}", _photo_pixels(_make),
         ["check", "calibrate", "texture", "render-validate"],
         [P, "$.photos[0].file", "p1.jpg", f"Pillow mode {_make(_RNG, 1, 1).mode!r}"])

# -- 7. the file itself ---------------------------------------------------------------------------------

case("duplicate-keys", raw(replace_once('"origin_marker": "O"', '"origin_marker": "O",\n  "origin_marker": "X5"')),
     LOAD, [P, "origin_marker"], any_of=["$", "line "])
case("duplicate-keys-nested", raw(replace_once('"width": 1600', '"width": 1600, "width": 1601')),
     ["check", "calibrate"], [P, "width"], any_of=["$.photos[0]", "line "])
case("nan-literal", raw(replace_once('"click_sigma_px": 0.7', '"click_sigma_px": NaN')), LOAD,
     [P, "NaN"], any_of=["$.settings.click_sigma_px", "line "])
case("infinity-literal", raw(replace_once('"distance": 5.0', '"distance": Infinity')), ["check", "calibrate"],
     [P, "Infinity"], any_of=["$.reference_distances[0].distance", "line "])
case("number-overflowing-to-inf", raw(replace_once('"distance": 5.0', '"distance": 1e999')), ["check", "calibrate"],
     [P, "$.reference_distances[0].distance"])
case("wrong-format", setter(("format",), "blender-project"), LOAD_SHORT, [P, "$.format", "vebuild-project"])
case("wrong-version", setter(("version",), 2), LOAD_SHORT, [P, "$.version"])
case("version-as-text", setter(("version",), "1"), ["check"], [P, "$.version"])
case("version-as-float", setter(("version",), 1.0), ["check"], [P, "$.version"])
case("version-huge-int", raw(replace_once('"version": 1', '"version": ' + "1" * 5000)), ["check", "calibrate"],
     [P], any_of=["$.version", "line "])
case("top-level-array", write_bytes(b"[]\n"), LOAD_SHORT, [P, "$"])
case("top-level-string", write_bytes(b'"vebuild-project"\n'), ["check"], [P, "$"])
case("not-utf8", raw(replace_once('"name": "Example room', '"name": "Exampl\udcc9 room')), LOAD_SHORT,
     [P], any_of=["UTF-8", "utf-8", "utf8"])
case("utf16-file", lambda ctx: (ctx.project.write_text(json.dumps(ctx.doc), encoding="utf-16"),
                                setattr(ctx, "write", False)),
     ["check", "calibrate"], [P], any_of=["UTF-8", "utf-8"])
case("empty-file", write_bytes(b""), LOAD, [P], any_of=["empty", "JSON"])
case("only-whitespace", write_bytes(b"   \n\n"), ["check"], [P], any_of=["empty", "JSON"])
case("truncated-json", raw(lambda t: t[: len(t) // 2]), LOAD_SHORT, [P], any_of=["JSON", "line "])
case("binary-garbage", write_bytes(bytes(range(256)) * 4), ["check", "render-view"], [P], any_of=["UTF-8", "JSON"])
case("unknown-top-level-key", setter(("photoes",), []), LOAD_SHORT, [P, "photoes"])
case("missing-required-key", deleter(("markers",)), LOAD_SHORT, [P, "markers"])


def _dir_as_project(ctx: Ctx) -> None:
    ctx.project.unlink()
    ctx.project.mkdir()
    ctx.write = False


case("directory-as-project", _dir_as_project, LOAD, [P])
case("folder-given-as-project", nothing, [[c[0], "{D}", *c[2:]] for c in (CMDS["check"], CMDS["calibrate"],
                                                                           CMDS["render-view"], CMDS["report"])],
     ["{D}"])
case("project-missing", lambda ctx: (ctx.project.unlink(), setattr(ctx, "write", False)), LOAD_SHORT, [P],
     any_of=["not found", "no such", "does not exist"])
case("project-symlink-loop", lambda ctx: (ctx.project.unlink(), ctx.project.symlink_to(ctx.project),
                                          setattr(ctx, "write", False)), ["check", "calibrate"], [P])

# -- 8. type errors at every level of the document ------------------------------------------------------

TYPE_ERRORS: list[tuple[tuple[Any, ...], Any]] = [
    (("name",), 5),
    (("settings",), []),
    (("settings", "click_sigma_px"), "0.7"),
    (("photos",), {}),
    (("photos", 0), "p1"),
    (("photos", 0, "id"), 1),
    (("photos", 0, "file"), ["photos/p1.jpg"]),
    (("photos", 0, "width"), "1600"),
    (("photos", 0, "height"), 1200.5),
    (("photos", 0, "sha256"), 0),
    (("photos", 0, "exif"), "canon"),
    (("photos", 0, "exif", "focal_length_mm"), "2 mm"),
    (("photos", 0, "vanishing_segments"), []),
    (("photos", 0, "vanishing_segments", "x"), {}),
    (("photos", 0, "vanishing_segments", "x", 0), "597,610,82,937"),
    (("photos", 0, "vanishing_segments", "x", 0, 0), "597.6"),
    (("photos", 0, "marker_observations"), []),
    (("photos", 0, "marker_observations", "O"), {"u": 1, "v": 2}),
    (("photos", 0, "marker_observations", "O", 1), None),
    (("markers",), "O"),
    (("markers", 0, "name"), ["O"]),
    (("markers", 0, "description"), 3),
    (("origin_marker",), 0),
    (("reference_distances",), {}),
    (("reference_distances", 0, "distance"), "5 m"),
    (("reference_distances", 0, "role"), True),
    (("reference_distances", 0, "sigma"), [0.002]),
    (("model",), []),
    (("model", "nodes"), {}),
    (("model", "nodes", 1, "name"), 7),
    (("model", "nodes", 1, "parent"), ["floor"]),
    (("model", "nodes", 1, "primitive"), "box"),
    (("model", "nodes", 1, "primitive", "params"), [0.4, 0.8, 2.0]),
    (("model", "nodes", 1, "primitive", "params", "width"), "0.445"),
    (("model", "nodes", 1, "joint"), "rests_on"),
    (("model", "nodes", 1, "joint", "position"), "1,2"),
    (("model", "nodes", 1, "joint", "yaw_deg"), "-9.8"),
    (("model", "nodes", 1, "solve"), "yes"),
    (("model", "nodes", 5, "hold"), "height"),
    (("model", "nodes", 9, "joint", "limits_deg"), 150),
    (("model", "pins"), {}),
    (("model", "pins", 0, "uv"), "388,592"),
    (("model", "pins", 0, "fixed"), "true"),
    (("model", "edge_observations", 0, "points"), [1, 2, 3, 4]),
    (("views",), {}),
    (("views", 0, "position"), {"x": 1}),
    (("views", 0, "width"), "1280"),
    (("views", 0, "fov_deg"), "65"),
    (("lighting",), []),
    (("lighting", "presets", 0, "lights", 0, "intensity"), "bright"),
    (("lighting", "presets", 0, "ambient"), 0.3),
    (("settings", "principal_point_sigma_rel"), None),
    (("photos", 0, "focal_px"), 1350.0),
    (("photos", 0, "principal_point"), [800.0, 600.0]),
    (("markers", 0, "position"), "0,0,0"),
    (("reference_distances", 0, "a"), 1),
    (("model", "nodes", 1, "primitive", "type"), 3),
    (("model", "nodes", 9, "joint", "axis"), "z"),
    (("model", "nodes", 9, "joint", "angle_deg"), None),
    (("views", 0, "look_at"), 5),
    (("views", 0, "roll_deg"), "0"),
    (("lighting", "presets", 0, "name"), 1),
    (("lighting", "presets", 0, "lights"), {}),
    (("lighting", "presets", 0, "lights", 0, "type"), 1),
    (("evidence_markers",), {}),
    (("hypotheses",), "h"),
    (("analyses",), {"name": "a"}),
]
for _parts, _value in TYPE_ERRORS:
    case(f"type-{path_str(_parts)}-as-{type(_value).__name__}", setter(_parts, _value), LOAD_SHORT,
         [P, path_str(_parts)])

RESULT_TYPE_ERRORS: list[tuple[tuple[Any, ...], Any, list[str]]] = [
    (("calibration",), [], ["render-photo", "report"]),
    (("calibration", "cameras"), [], ["render-photo", "texture"]),
    (("calibration", "cameras", "p1", "K"), "K", ["render-photo", "texture", "export"]),
    (("calibration", "cameras", "p1", "R"), [[1, 0, 0], [0, 1, 0]], ["render-photo", "texture"]),
    (("calibration", "cameras", "p1", "position", "value"), "here", ["render-photo", "export"]),
    (("calibration", "markers", "O", "position"), "origin", ["solve-recal", "report"]),
    (("model_solution",), "solved", ["analyse", "report"]),
    (("model_solution", "rms_px"), [1.0], ["report"]),
    (("model_solution", "nodes", "cabinet", "handles", "v4", "value"), "up there", ["analyse"]),
    (("model_solution", "covariance", "matrix"), "identity", ["analyse"]),
    (("textures",), [], ["render-view", "export"]),
    (("textures", "pages", 0, "width"), "674", ["render-view", "export"]),
    (("textures", "pages", 0, "atlas"), 0, ["render-view", "export"]),
    (("textures", "faces", 0, "rect"), "0,0,1,1", ["render-view", "export"]),
    (("textures", "faces"), {}, ["render-view", "export"]),
]
for _parts, _value, _cmds in RESULT_TYPE_ERRORS:
    case(f"type-{path_str(_parts)}-as-{type(_value).__name__}", setter(_parts, _value), ["check", *_cmds],
         [P, path_str(_parts)])

# -- 9. command lines: outputs that would overwrite or delete something, bad options, unknown names -----

case("report-out-project-folder", nothing, [["report", P, "--out", "{D}", "--no-pdf", "--quiet"]], [("--out", "{D}:")])
case("report-out-photos", nothing, [["report", P, "--out", "{D}/photos", "--no-pdf", "--quiet"]],
     [("--out", "{D}/photos")])
case("report-out-dot-in-project-folder", nothing, [["report", P, "--out", ".", "--no-pdf", "--quiet"]],
     [("--out", ".:")], cwd="project")
case("report-out-folder-with-unrelated-file", lambda ctx: (ctx.out / "mine").mkdir() or
     (ctx.out / "mine" / "notes.txt").write_text("the examiner's own notes\n"),
     [["report", P, "--out", "{OUT}/mine", "--no-pdf", "--quiet"]], [("--out", "{OUT}/mine")])
case("report-out-project-file", nothing, [["report", P, "--out", P, "--no-pdf", "--quiet"]], [P])
case("report-out-parent-of-project", nothing, [["report", P, "--out", "{D}/..", "--no-pdf", "--quiet"]],
     [("--out", "{D}/..")])


def _photo_as_png(ctx: Ctx) -> None:
    from PIL import Image
    src = ctx.photo(0)
    dst = src.with_suffix(".png")
    with Image.open(src) as im:
        im.save(dst)
    src.unlink()
    ctx.doc["photos"][0]["file"] = "photos/p1.png"
    ctx.rehash(0)


case("render-out-over-photo-png", _photo_as_png,
     [["render", P, "--view", "doorway", "--out", "{D}/photos/p1.png", "--size", "64x36"],
      ["analyse", P, "lighting", "--view", "doorway", "--preset", "daylight", "--target", "table.top", "--size",
       "64x36", "--out", "{D}/photos/p1.png"],
      ["analyse", P, "sightline", "--standing", "3.7,0.4", "--object", "box", "--size", "64x36", "--out",
       "{D}/photos/p1.png"]],
     [("--out", "{D}/photos/p1.png")])
case("render-out-project-file", nothing, [["render", P, "--view", "doorway", "--out", P, "--size", "64x36"]], [P])
case("export-out-project-file", nothing, [["export", P, "--out", P]], [P])
case("export-out-photo", nothing, [["export", P, "--out", "{D}/photos/p1.jpg"]], ["p1.jpg"])
case("video-out-over-photo", nothing, [["video", P, "--views", "doorway,overview", "--out", "{D}/photos/p1.jpg",
                                        "--size", "64x36", "--fps", "2", "--quiet"]], ["p1.jpg"])
case("analyse-json-over-project", nothing, [["analyse", P, "dimensions", "cabinet", "--json", P]], [P])
case("analyse-json-over-photo", nothing, [["analyse", P, "checks", "--json", "{D}/photos/p2.jpg"]], ["p2.jpg"])

case("render-out-over-atlas-page", nothing,
     [["render", P, "--view", "doorway", "--out", "{D}/{ATLAS}", "--size", "64x36"],
      ["analyse", P, "viewshed", "--target", "1,1,1", "--out", "{D}/{ATLAS}"]],
     [("--out", "{D}/{ATLAS}", "{ATLAS}")])
case("report-out-textures", nothing, [["report", P, "--out", "{D}/textures", "--no-pdf", "--quiet"],
                                      ["report", P, "--out", "{D}/textures/report", "--no-pdf", "--quiet"]],
     [("--out", "{D}/textures")])
case("analyse-json-missing-folder", nothing, [["analyse", P, "checks", "--json", "{OUT}/nofolder/c.json"]],
     [("--json", "{OUT}/nofolder")])
case("mark-lone-surrogate-label", nothing, [["mark", P, "A\udc80", "--at", "2,2,0"]],
     [P, ("--label", "$.evidence_markers", "label")])
case("mark-lone-surrogate-description", nothing, [["mark", P, "A", "--at", "2,2,0", "--description", "x\ud800y"]],
     [P, ("--description", "$.evidence_markers", "description")])

BAD_SIZES = ["abc", "0x10", "10x0", "-5x5", "10x", "1e3x5", "99999999999999999999x1", "100000x1", "64x36x2", "",
             "64 36", "6.5x4"]
for _i, _s in enumerate(BAD_SIZES):
    cmds: list[Any] = [["render", P, "--view", "doorway", "--out", "{OUT}/v.png", "--size", _s]]
    if _i % 3 == 0:
        cmds.append(["video", P, "--views", "doorway,overview", "--out", "{OUT}/w.mp4", "--size", _s, "--fps", "2",
                     "--quiet"])
    if _i % 3 == 1:
        cmds.append(["analyse", P, "lighting", "--view", "doorway", "--preset", "daylight", "--target", "table.top",
                     "--size", _s])
    if _i % 3 == 2:
        cmds.append(["render", P, "--photo", "p1", "--out", "{OUT}/p.png", "--size", _s])
    case(f"bad-size-{_s or 'empty'}", nothing, cmds, ["--size"], sub=_s in ("100000x1", "99999999999999999999x1"))

R = ["render", P, "--out", "{OUT}/v.png", "--size", "64x36"]
case("unknown-view", nothing, [[*R, "--view", "nope"], ["video", P, "--views", "doorway,nope", "--out", "{OUT}/w.mp4",
                                                        "--quiet"],
                               ["analyse", P, "lighting", "--view", "nope", "--preset", "daylight", "--target",
                                "table.top"], ["mark", P, "Z", "--at", "view:nope@10,10"]], ["nope"])
case("unknown-photo", nothing, [[*R, "--photo", "p9"], [*R, "--photo", "0"], [*R, "--photo", "99"],
                                ["mark", P, "Z", "--at", "photo:p9@10,10"], ["register", P, "p9"]], ["p"])
case("unknown-hypothesis", nothing, [[*R, "--view", "doorway", "--hypothesis", "nope"],
                                     ["analyse", P, "trajectory", "--from", "1,3,1.2", "--to", "2,2.8,1",
                                      "--hypothesis", "nope"]], ["nope"])
case("unknown-lighting-preset", nothing, [[*R, "--view", "doorway", "--lighting", "nope"],
                                          ["analyse", P, "lighting", "--view", "doorway", "--preset", "nope",
                                           "--target", "table.top", "--size", "64x36"]], ["nope"])
case("unknown-analysis-target", nothing, [["analyse", P, "lighting", "--view", "doorway", "--preset", "daylight",
                                           "--target", "sofa", "--size", "64x36"],
                                          ["analyse", P, "dimensions", "sofa"],
                                          ["analyse", P, "distance", "sofa:v1", "cabinet:v4"],
                                          ["analyse", P, "distance", "cabinet:v99", "cabinet:v4"],
                                          ["analyse", P, "height", "cabinet:v4", "--above", "table.top@roof"]],
     [], any_of=["sofa", "v99", "roof"])
case("video-one-view", nothing, [["video", P, "--views", "doorway", "--out", "{OUT}/w.mp4", "--quiet"]], ["--views"])
case("video-empty-view-name", nothing, [["video", P, "--views", "doorway,,overview", "--out", "{OUT}/w.mp4",
                                         "--quiet"]], ["--views"])
V2 = ["video", P, "--views", "doorway,overview", "--out", "{OUT}/w.mp4", "--size", "64x36", "--quiet"]
case("video-bad-numbers", nothing, [[*V2, "--fps", "0"], [*V2, "--fps", "nan"], [*V2, "--fps", "-30"],
                                    [*V2, "--fps", "1e308"], [*V2, "--crf", "99"], [*V2, "--speed", "-1"],
                                    [*V2, "--seconds", "0"], [*V2, "--hold", "-1"], [*V2, "--turn-rate", "0"]],
     [], any_of=["--fps", "--crf", "--speed", "--seconds", "--hold", "--turn-rate"])
T = ["texture", P, "--quiet"]
case("texture-bad-numbers", nothing, [[*T, "--density", "0"], [*T, "--density", "-1"], [*T, "--density", "nan"],
                                      [*T, "--density", "1e308"], [*T, "--max-face-texels", "0"],
                                      [*T, "--erode-px", "-1"],
                                      [*T, "--drop-ratio", "2"], [*T, "--drop-ratio", "nan"]],
     [], any_of=["--density", "--max-face-texels", "--erode-px", "--drop-ratio", "texels_per_metre",
                 "max_face_texels", "erode_px", "drop_ratio"], sub=True)
RP = ["render", P, "--view", "doorway", "--out", "{OUT}/v.png", "--size", "64x36"]
case("render-bad-numbers", nothing, [[*RP, "--samples", "0"], [*RP, "--samples", "-4"],
                                     [*RP, "--stereo", "sbs", "--eye-separation", "nan"],
                                     [*RP, "--stereo", "sbs", "--eye-separation", "-1"],
                                     [*RP, "--stereo", "sbs", "--convergence", "0"],
                                     [*RP, "--stereo", "sbs", "--convergence", "nan"]],
     [], any_of=["--samples", "--eye-separation", "--convergence"], sub=True)
case("render-bad-out", nothing, [["render", P, "--view", "doorway", "--out", "{OUT}/v.jpg"],
                                 ["render", P, "--view", "doorway", "--out", "{OUT}/nofolder/v.png"],
                                 ["render", P, "--view", "doorway", "--out", "{OUT}"],
                                 ["render", P, "--view", "doorway"]], [("--out", "{OUT}")])
M = ["mark", P, "Z"]
case("mark-bad-at", nothing, [[*M, "--at", "1,2"], [*M, "--at", "nan,0,0"], [*M, "--at", "1e308,0,0"],
                              [*M, "--at", "photo:p1@1e9,1"], [*M, "--at", "view:doorway@-5,-5"],
                              [*M, "--at", "photo:p1@"], [*M, "--at", "50,50,50"]],
     [("--at", "evidence marker 'Z'")])
case("mark-remove-unknown", nothing, [["mark", P, "nope", "--remove"]], [P, "$.evidence_markers", "nope"])
case("mark-empty-label", nothing, [["mark", P, "", "--at", "2,2,0"]], [], any_of=["label", "$.evidence_markers"])
case("mark-unsolved", nothing, [CMDS["mark"]], [P], any_of=["solve", "model"], state="raw")
case("analyse-unsolved", nothing, [CMDS["analyse"], CMDS["analyse-dims"]], [P], any_of=["solve"], state="raw")
case("render-uncalibrated", nothing, [CMDS["render-photo"], CMDS["texture"], CMDS["report"]], [P],
     any_of=["calibrat"], state="raw")
case("analyse-bad-points", nothing, [["analyse", P, "distance", "1,2", "cabinet:v4"],
                                     ["analyse", P, "distance", "nan,0,0", "cabinet:v4"],
                                     ["analyse", P, "sightline", "--standing", "a,b", "--object", "box"],
                                     ["analyse", P, "trajectory", "--from", "1,2", "--to", "2,2.8,1"],
                                     ["analyse", P, "viewshed", "--cell", "0", "--out", "{OUT}/m.png",
                                      "--target", "1,1,1"]],
     [], any_of=["1,2", "nan", "a,b", "--cell", "--standing", "--from", "point"])


# -- 9b. vebuild import: fSpy project files (tests/fspy_writer.py writes them as fSpy does) ------------

FSPY = "{D}/scene.fspy"
FSPY_IMPORT = [["import", FSPY, "--out", "{OUT}/imported"]]


def _fspy(change: Callable[[dict[str, Any]], Any], mode: str = "TwoVanishingPoints",
          raw_: Callable[[bytes], bytes] | None = None) -> Callable[[Ctx], None]:
    """A mutation that writes scene.fspy beside the project: an fSpy 1.0.2 state changed by ``change``
    (or its file's bytes by ``raw_``)."""
    def mutate(ctx: Ctx) -> None:
        import numpy as np
        from fspy_writer import KnownCamera, StateBuilder, fspy_bytes, make_image

        state = StateBuilder(KnownCamera.looking_at_corner(), np.random.default_rng(0), noise_px=0.0,
                             mode=mode).build()
        change(state)
        data = fspy_bytes(state, make_image(640, 480))
        (ctx.folder / "scene.fspy").write_bytes(raw_(data) if raw_ else data)
    return mutate


def _fspy_set(path: str, value: Any, mode: str = "TwoVanishingPoints") -> Callable[[Ctx], None]:
    def change(state: dict[str, Any]) -> None:
        *head, last = path.split(".")
        get(state, tuple(head))[last] = copy.deepcopy(value)
    return _fspy(change, mode)


def _fspy_case(name: str, mutate: Callable[[Ctx], None], where: str) -> None:
    case(f"fspy-{name}", mutate, FSPY_IMPORT, [FSPY, where], state="raw")


_1VP = "OneVanishingPoint"
_fspy_case("huge-integer-coordinate", _fspy(lambda s: None, raw_=lambda d: d.replace(
    b'"origin":{"x":', b'"origin":{"x":' + b"9" * 400 + b',"was":', 1).replace(
    d[8:12], (int.from_bytes(d[8:12], "little") + 407).to_bytes(4, "little"), 1)), "$.controlPointsStateBase.origin.x")
_fspy_case("axis-list", _fspy_set("calibrationSettingsBase.firstVanishingPointAxis", ["xPositive"]),
           "$.calibrationSettingsBase.firstVanishingPointAxis")
_fspy_case("axis-object", _fspy_set("calibrationSettingsBase.secondVanishingPointAxis", {"axis": "y"}),
           "$.calibrationSettingsBase.secondVanishingPointAxis")
_fspy_case("reference-axis-list", _fspy_set("calibrationSettingsBase.referenceDistanceAxis", ["z"]),
           "$.calibrationSettingsBase.referenceDistanceAxis")
_fspy_case("unit-object", _fspy_set("calibrationSettingsBase.referenceDistanceUnit", {"unit": "Meters"}),
           "$.calibrationSettingsBase.referenceDistanceUnit")
_fspy_case("unit-list", _fspy_set("calibrationSettingsBase.referenceDistanceUnit", ["Meters"]),
           "$.calibrationSettingsBase.referenceDistanceUnit")
_fspy_case("saved-axes-lists", _fspy_set("cameraParameters.vanishingPointAxes", [["x"], ["y"], ["z"]]),
           "$.cameraParameters.vanishingPointAxes")
_fspy_case("lens-no-camera-has", _fspy(lambda s: (
    s["calibrationSettings1VP"].update(absoluteFocalLength=100000),
    s["calibrationSettingsBase"]["cameraData"].update(customSensorWidth=0.001, customSensorHeight=0.001)), _1VP),
    "$.calibrationSettings1VP.absoluteFocalLength")
_fspy_case("quad-mode-number", _fspy_set("calibrationSettings2VP.quadModeEnabled", 0),
           "$.calibrationSettings2VP.quadModeEnabled")
_fspy_case("preset-id-list", _fspy_set("calibrationSettingsBase.cameraData.presetId", ["canon_5d"], _1VP),
           "$.calibrationSettingsBase.cameraData.presetId")
_fspy_case("horizon-object-bad-point", _fspy_set("controlPointsState1VP.horizon", {
    "0": {"x": 0.2, "y": 0.5}, "1": {"x": [0.8], "y": 0.5}}, _1VP), '$.controlPointsState1VP.horizon["1"].x')
_fspy_case("horizon-object-other-keys", _fspy_set("controlPointsState1VP.horizon", {
    "0": {"x": 0.2, "y": 0.5}, "2": {"x": 0.8, "y": 0.5}}, _1VP), "$.controlPointsState1VP.horizon")
_fspy_case("segment-of-three", _fspy(lambda s: s["controlPointsStateBase"]["firstVanishingPoint"]["lineSegments"][0]
                                     .append({"x": 0.5, "y": 0.5})),
           "$.controlPointsStateBase.firstVanishingPoint.lineSegments[0]")
_fspy_case("header-state-size-huge", _fspy(lambda s: None, raw_=lambda d: d[:8] + b"\xff\xff\xff\xff" + d[12:]),
           "header.state_size")
_fspy_case("header-image-size-past-end", _fspy(lambda s: None, raw_=lambda d: d[:12] + b"\xff\xff\xff\x00" + d[16:]),
           "header.image_size")


# -- 10. vebuild new ----------------------------------------------------------------------------------

def _outside_photo(ctx: Ctx) -> None:
    shutil.copy(ctx.folder / "photos" / "p1.jpg", ctx.out / "elsewhere.jpg")


def _float_photo(ctx: Ctx) -> None:
    from pixel_formats import float_tiff
    (ctx.folder / "photos" / "float.tif").write_bytes(float_tiff(_RNG, 48, 64).data or b"")


def _notes(ctx: Ctx) -> None:
    (ctx.folder / "notes.txt").write_text("not an image\n")


case("new-photo-outside-folder", _outside_photo, [["new", "{D}/n.vebuild.json", "{OUT}/elsewhere.jpg"]],
     ["elsewhere.jpg"], any_of=["outside", "inside"])
case("new-photo-not-image", _notes, [["new", "{D}/n.vebuild.json", "{D}/notes.txt"]], ["notes.txt"])
case("new-photo-float-pixels", _float_photo, [["new", "{D}/n.vebuild.json", "{D}/photos/float.tif"]],
     ["float.tif", "Pillow mode 'F'"])
case("new-photo-missing", nothing, [["new", "{D}/n.vebuild.json", "{D}/photos/p9.jpg"]], ["p9.jpg"])
case("new-photo-is-folder", nothing, [["new", "{D}/n.vebuild.json", "{D}/photos"]], ["photos"])
case("new-over-existing-project", nothing, [["new", P, "{D}/photos/p1.jpg"]], [P, "--force"])
case("new-over-photo", nothing, [["new", "{D}/photos/p1.jpg", "{D}/photos/p2.jpg"],
                                 ["new", "{D}/photos/p1.jpg", "{D}/photos/p2.jpg", "--force"]], ["p1.jpg"])
case("new-in-missing-folder", nothing, [["new", "{D}/nofolder/n.vebuild.json"]], ["nofolder"])
case("new-duplicate-photo-id", lambda ctx: shutil.copy(ctx.folder / "photos" / "p1.jpg",
                                                       ctx.folder / "photos" / "p1.jpeg"),
     [["new", "{D}/n.vebuild.json", "{D}/photos/p1.jpg", "{D}/photos/p1.jpeg"]], ["p1"])
case("new-same-photo-twice", nothing, [["new", "{D}/n.vebuild.json", "{D}/photos/p1.jpg", "{D}/photos/p1.jpg"]],
     ["p1"])
case("new-lone-surrogate-name", nothing, [["new", "{D}/n.vebuild.json", "--name", "bad\udc80name"]],
     [("--name", "$.name")], any_of=["n.vebuild.json"])


# -- 11. links below an output folder: tests/bad_inputs_links.py registers its cases here ----------------
import bad_inputs_links  # noqa: E402, F401

# -- 12. laser scans whose header disagrees with their body (tests/bad_inputs_scans.py) -----------

for _name, _mutate, _commands, _expect in SCAN_CASES:
    case(_name, _mutate, _commands, _expect)


# -- cases that still fail with the fixes in flight merged (h-a, h-b, h-c): real findings, kept strict ----
# Test id (case|command) → what happens and which area it belongs to. Strict: a fix makes the test XPASS,
# which fails the suite until the entry is removed here.

#: The cases whose fault is not one of the project as it reads (each with why): a command's options
#: (every case that leaves the project as it is), what it would write, or what a stage finds only by
#: computing (``check`` decodes, it never calibrates or solves). Every other case a command that
#: reads a project refuses, ``vebuild check`` refuses with the very same message (one decoder, one
#: answer: test_bad_inputs.py checks it beside each refusal).
NOT_THE_PROJECTS: dict[str, str] = {
    **{c.name: "the command line" for c in CASES if c.mutate is nothing},
    "two-scale-distances-contradict": "found by calibrating (the two scales the cameras give disagree)",
    "scale-distances-contradict-by-100": "found by calibrating (the two scales the cameras give disagree)",
    "no-scale-distance": "calibrating needs a scale; an uncalibrated project without one is valid",
    "textures-folder-symlink": "texture writes its pages anew: it refuses the folder it would write to",
    "render-out-over-photo-png": "the output would overwrite a photo",
    "report-out-folder-with-unrelated-file": "the output folder holds a file vebuild did not write",
    "calibration-photo-left-out": "the command names a photo the calibration left out (check lists it: the "
                                  "project is valid)",
    **{c.name: "what it would write: a link below its output folder, or the file it replaces has other names"
       for c in CASES if c.name.startswith("output-")},  # section 11 (tests/bad_inputs_links.py)
    **{name: "the scan file is the command line's (`scan add`), not yet the project's"
       for name, _, commands, _ in SCAN_CASES if commands[0][:2] == ["scan", "add"]},  # section 12
}
#: The commands that read no project file (they make one, or read another kind of file).
READ_NO_PROJECT = ("new", "import", "demo", "bench")

KNOWN_FAILURES: dict[str, str] = {
}
