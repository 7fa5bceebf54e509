"""Renaming a marker: in every photo, reference distance, joint, scan target and calibration
result that names it, in one undoable edit; a name in use, an empty one or one with ':' is
refused, saying why. Then the Calibration tab's rename field, by real input in a window."""

from __future__ import annotations

import shutil

import pytest
from edit_driver import Driver

from vebuild.edit.history import EditError
from vebuild.edit.session import EditSession
from vebuild.resources import example_project_dir


@pytest.fixture
def room(tmp_path):
    folder = tmp_path / "room"
    shutil.copytree(example_project_dir(), folder)
    return folder / "room.vebuild.json"


def _mentions(data, name: str) -> list[str]:
    """Where the document still names marker ``name`` (as a name, a key or a joint's marker)."""
    out = []
    out += ["markers"] * any(m["name"] == name for m in data["markers"])
    out += ["origin_marker"] * (data.get("origin_marker") == name)
    out += [f"photo {p['id']}" for p in data["photos"] if name in (p.get("marker_observations") or {})]
    out += ["distance"] * any(name in (r["a"], r["b"]) for r in data["reference_distances"])
    out += ["joint"] * any((n.get("joint") or {}).get("marker") == name for n in data["model"]["nodes"])
    cal = data.get("calibration") or {}
    out += ["calibration.markers"] * (name in (cal.get("markers") or {}))
    out += [f"residuals {c}" for c, cam in (cal.get("cameras") or {}).items()
            if name in (cam.get("marker_residuals_px") or {})]
    return out


def test_a_rename_reaches_every_reference_and_undoes_in_one_step(room):
    s = EditSession.open(room, autosave=False)
    before = _mentions(s.data, "O")
    assert {"markers", "origin_marker", "distance", "joint"} <= set(before)
    assert sum(m.startswith("photo") for m in before) >= 3
    sightings = {p["id"]: p["marker_observations"]["O"] for p in s.data["photos"]
                 if "O" in (p.get("marker_observations") or {})}
    s.rename_marker("O", "corner")
    assert _mentions(s.data, "O") == []
    assert [m.replace("corner", "O") for m in _mentions(s.data, "corner")] == before
    assert {p["id"]: p["marker_observations"]["corner"] for p in s.data["photos"]
            if "corner" in (p.get("marker_observations") or {})} == sightings  # where it is, unchanged
    assert "corner" in s.messages[-1]
    s.undo()
    assert _mentions(s.data, "O") == before and _mentions(s.data, "corner") == []
    s.redo()
    assert _mentions(s.data, "O") == []
    s.save()
    again = EditSession.open(room, autosave=False)  # the renamed project is valid and loads
    assert _mentions(again.data, "corner") == _mentions(s.data, "corner")
    # A marker the calibration placed: its position and residuals are listed under the new name.
    s.calibrate()
    t2 = _mentions(s.data, "T2")
    assert "calibration.markers" in t2 and any(m.startswith("residuals") for m in t2)
    pos = s.data["calibration"]["markers"]["T2"]
    s.rename_marker("T2", "tee")
    assert _mentions(s.data, "T2") == [] and len(_mentions(s.data, "tee")) == len(t2)
    assert s.data["calibration"]["markers"]["tee"] == pos


@pytest.mark.parametrize(("old", "new", "says"), [
    ("T1", "T2", "a marker is called 'T2' already"),
    ("T1", "  ", "new name must be given"),
    ("T1", "box:v0", "without ':'"),
    ("T1", "T1", "is called that already"),
    ("nobody", "X", "no marker is called 'nobody'"),
])
def test_a_rename_is_refused_with_its_reason_and_nothing_changes(room, old, new, says):
    s = EditSession.open(room, autosave=False)
    data = repr(s.data)
    with pytest.raises(EditError, match=says.replace("(", r"\(")):
        s.rename_marker(old, new)
    assert repr(s.data) == data and not s.dirty


@pytest.mark.usefixtures("xvfb_display")
def test_the_rename_field_in_the_calibration_tab(room, xdotool):
    d = Driver(room, xdotool)
    try:
        e, s = d.editor, d.session
        d.click("tab:Calibration")
        d.frames(2)
        x0, y0, x1, y1 = e.widget_rects["Calibrate"]  # the wheel over the panel scrolls it to the field
        for _ in range(30):
            if all(k in e.widget_rects for k in ("rename from", "rename to", "rename##marker")):
                break
            d.send("mousemove", f"{int((x0 + x1) / 2)}", f"{int((y0 + y1) / 2)}", "click", "5")
            d.frames(2)
        for label, text in (("rename from", "T1"), ("rename to", "T2")):
            d.send(*d.at(label), "click", "1", "key", "ctrl+a", "type", text)
        d.click("rename##marker")
        d.frames(2)
        assert "a marker is called 'T2' already" in s.messages[-1] and "T1" in s.project.marker_names()
        d.send(*d.at("rename to"), "click", "1", "key", "ctrl+a", "type", "tripod")
        d.click("rename##marker")
        d.frames(2)
        assert "tripod" in s.project.marker_names() and "T1" not in s.project.marker_names()
        d.send("key", "ctrl+z")
        d.frames(2)
        assert "T1" in s.project.marker_names()
    finally:
        d.close()
