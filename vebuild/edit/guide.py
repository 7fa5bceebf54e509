"""First steps: the modelling screen's guided sequence for a new or empty project.

The steps run from adding a photo to a first object on the floor: what the three axes mean (the
floor's two directions x and y, and z up: docs DESIGN.md's world frame), marking two or more
directed segments per axis in the photo shown, placing markers, entering a measured distance,
calibrating and adding the floor. Each step states what to do, how it is known to be done and what
comes next; whether it is done is read from the session's state alone (the photo shown, its marks,
the project's distances, cameras and model), so a step done by any means (keys, the panels, an
undo that takes it back) is ticked or unticked at once. What the guide itself holds (shown or
hidden, the axes read, steps skipped) lives in the window only: nothing of it is saved.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

#: Segments per axis in the photo shown that make its vanishing point (two lines meet in a point).
SEGMENTS_PER_AXIS = 2
#: Markers seen in the photo shown before a distance between two of them can be entered.
MARKERS_PER_PHOTO = 2
#: Primitives a floor can be: a quad at the root of the model, or a room (which has a floor).
FLOOR_TYPES = ("quad", "room")


def _photo(session: Any, photo: str | None) -> dict[str, Any]:
    if photo is None or photo not in session.photo_ids:
        return {}
    return dict(session.photo(photo))


def segments_in(session: Any, photo: str | None, axis: str) -> int:
    """How many vanishing segments of ``axis`` the photo has."""
    return len((_photo(session, photo).get("vanishing_segments") or {}).get(axis) or [])


def _marked(session: Any, photo: str | None, axis: str) -> bool:
    return segments_in(session, photo, axis) >= SEGMENTS_PER_AXIS


def markers_in(session: Any, photo: str | None) -> int:
    """How many markers are placed in the photo."""
    return len(_photo(session, photo).get("marker_observations") or {})


def has_scale(session: Any, photo: str | None) -> bool:
    """A measured distance between markers, or this photo's own scale (a known length, its camera's height)."""
    data = session.data
    if data.get("reference_distances"):
        return True
    if photo is not None and any(k.get("photo") == photo for k in data.get("known_lengths") or []):
        return True
    return bool(_photo(session, photo).get("camera_height"))


def _nodes(session: Any) -> list[dict[str, Any]]:
    return list((session.data.get("model") or {}).get("nodes") or [])


def floor_node(session: Any) -> str | None:
    """The model's floor: the first node at its root that is a quad or a room; None if none."""
    for n in _nodes(session):
        prim = n.get("primitive") or {}
        if not n.get("parent") and prim.get("type") in FLOOR_TYPES:
            return str(n["name"])
    return None


def has_object(session: Any) -> bool:
    """A primitive besides the floor."""
    floor = floor_node(session)
    return any(n.get("primitive") and n["name"] != floor for n in _nodes(session))


def is_calibrated(session: Any, photo: str | None) -> bool:
    return photo is not None and photo in session.cameras


@dataclass(frozen=True)
class Step:
    """One step: its key, its title, what to do, what makes it done (in words), and the test of
    it over (session, photo shown); None: the user says it is read (the axes)."""

    key: str
    title: str
    todo: str
    done_when: str
    check: Callable[[Any, str | None], bool] | None


STEPS: tuple[Step, ...] = (
    Step("photo", "Add a photo",
         "Ctrl+O (or the Photos… button) opens a file browser: pick one or more photos of the scene in the "
         "project's folder and press Add. Image files dropped onto the window are added too.",
         "the project has a photo", lambda s, p: bool(s.photo_ids)),
    Step("axes", "The three axes",
         "The room's directions are named once for every photo: x and y run along the floor at a right angle "
         "to each other, z points straight up. Choose x along one set of floor edges (a wall's foot, a table's "
         "long side), y along the other; turning from x to y is anticlockwise seen from above.",
         "you have read it (Next)", None),
    Step("x", "Mark x lines",
         "Key 1 (Segment X): press on an edge that runs along x, drag along it toward +x, release. Mark two or "
         "more such edges, far apart; the arrow shows the direction.",
         f"{SEGMENTS_PER_AXIS} or more x segments in this photo", lambda s, p: _marked(s, p, "x")),
    Step("y", "Mark y lines",
         "Key 2 (Segment Y): the same along edges that run along y, dragged toward +y.",
         f"{SEGMENTS_PER_AXIS} or more y segments in this photo", lambda s, p: _marked(s, p, "y")),
    Step("z", "Mark up lines",
         "Key 3 (Segment Z): the same along vertical edges (a door's jamb, a room's corner), dragged upward.",
         f"{SEGMENTS_PER_AXIS} or more z segments in this photo", lambda s, p: _marked(s, p, "z")),
    Step("markers", "Place markers",
         "Key M (Marker): click a point on the floor (the first marker is the world's origin), then the other "
         "end of a distance you measured at the scene; the toolbar's field names the next marker. A project of "
         "one photo needs none: its origin is then the floor below the camera.",
         f"{MARKERS_PER_PHOTO} or more markers in this photo (none in a project of one photo)",
         lambda s, p: markers_in(s, p) >= MARKERS_PER_PHOTO or len(s.photo_ids) == 1),
    Step("distance", "Enter a distance",
         "Calibration tab, reference distances: type the two markers' names and the metres measured between "
         "them, then add (or Ctrl+D, Tab between the fields, Ctrl+Enter). (A photo placed alone can take a "
         "known length or its camera's height, Scale tab.)",
         "a reference distance (or this photo's own scale) is given", has_scale),
    Step("calibrate", "Calibrate",
         "Press Calibrate (Calibration tab): each photo's focal length, orientation and position are found "
         "from its lines and markers. Then T measures on the photo alone: a height (its foot on the floor, then "
         "its top), a distance on the floor, a length on a wall.",
         "this photo is calibrated", is_calibrated),
    Step("floor", "Click the floor's corners",
         "Key H (Room): click the floor's corners in the photo in turn, where the walls meet it, then the first "
         "corner again (or Enter); then click a wall's top straight above a corner, or type the height. The room "
         "appears on the corners you clicked; in the Model tab, untick each wall the photos do not show. (No "
         "corners in sight: A floor quad, then click where it lies.)",
         "the model has a floor (a quad or a room at its root)", lambda s, p: floor_node(s) is not None),
    Step("object", "Add a first object",
         "Key B (Box): click three corners of its footprint on the floor in turn round it, then its top straight "
         "above a corner (or type the height); then Solve (Model tab). Or Add a box, then click where it stands.",
         "the model has a primitive besides the floor", lambda s, p: has_object(s)),
)

STEP_KEYS = tuple(s.key for s in STEPS)


def is_new(session: Any) -> bool:
    """Whether the project is new or empty: no vanishing segment in any photo and no model."""
    if _nodes(session):
        return False
    return not any(any((p.get("vanishing_segments") or {}).values()) for p in session.data.get("photos", []))


@dataclass
class Guide:
    """The guide's state in the window (never saved): shown or not, the steps the user has read
    or skipped, and the progress as last computed (cached on the session's revision and photo)."""

    shown: bool = False
    read: set[str] = field(default_factory=set)
    tab_for: str | None = None  # the step whose panel tab was last brought forward
    _key: Any = None
    _done: tuple[bool, ...] = ()

    def done(self, session: Any, photo: str | None) -> tuple[bool, ...]:
        """Each step's state now: done (its test passes, or the user read or skipped it)."""
        key = (session.revision, photo, len(session.photo_ids), frozenset(self.read))
        if key != self._key:
            self._done = tuple(s.key in self.read or (s.check is not None and bool(s.check(session, photo)))
                               for s in STEPS)
            self._key = key
        return self._done

    def current(self, session: Any, photo: str | None) -> Step | None:
        """The first step not done; None when all are."""
        for step, ok in zip(STEPS, self.done(session, photo), strict=True):
            if not ok:
                return step
        return None

    def next_after(self, step: Step, session: Any, photo: str | None) -> Step | None:
        """The step that comes after ``step`` (the next one not done), or None."""
        done = self.done(session, photo)
        i = STEPS.index(step)
        return next((s for s, ok in zip(STEPS[i + 1:], done[i + 1:], strict=True) if not ok), None)

    def skip(self, key: str) -> None:
        """Mark a step read (the axes) or skipped (a step done another way)."""
        if key not in STEP_KEYS:
            raise ValueError(f"no first step '{key}'")
        self.read.add(key)
