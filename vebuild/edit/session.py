"""The edit logic of the modelling screen (paper §2–3.2, Figures 1–3, 5 and 7), without a window.

An :class:`EditSession` holds one project and changes it the way the screen's tools do: vanishing
segments, markers, the origin and reference distances for calibration; primitives, joints, drags,
fixed vertices and edge observations for modelling; calibration, solving (with re-calibration),
registration and texture extraction on demand. Every change is one undoable edit, and after every
edit the whole document is written atomically to a side file beside the project
(``NAME.vebuild.json.autosave``), so a crash loses nothing: opening the project again offers to
recover it. :meth:`EditSession.save` writes the project file itself and removes the side file.

What the screen draws over a photo comes from :meth:`EditSession.overlay`. Errors a user can cause
raise :class:`EditError`, whose text is a sentence for the screen.
"""

from __future__ import annotations

import contextlib
import copy
import json
import math
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild import camera as cam_math
from vebuild.calibration.vanishing import MIN_SEGMENT_LENGTH_PX
from vebuild.camera import ImageCamera
from vebuild.errors import CalibrationError, VebuildError
from vebuild.model.edit import DragSession, drag_nodes, project_edges
from vebuild.model.scene import Model, ModelError, model_from_dict
from vebuild.model.solver import EdgeObservation, Pin
from vebuild.project import (
    RESULT_KEYS,
    Project,
    autosave_path,
    load_project,
    new_photo_entry,
    save_project,
    validate,
)

from .overlay import (
    AXIS_COLOURS,
    CYAN,
    GREY,
    MAGENTA,
    ORANGE,
    RED,
    WHITE,
    YELLOW,
    Line,
    Overlay,
    Point,
    horizon_and_axes,
    vanishing_rays,
)

Array = NDArray[np.float64]
Progress = Callable[[float, str], None]

AXES = ("x", "y", "z")
#: Undo steps kept; older ones are dropped (the autosave and the project file hold the work).
UNDO_DEPTH = 200
#: A segment whose residual exceeds this many click σ is shown as an outlier.
OUTLIER_SIGMAS = 3.0
#: During a drag, the grabbed vertex must end within this many pixels of the mouse, and the fixed
#: vertices within this many pixels of where they were, or the constraints "cannot follow": the
#: primitive stays where it was. Four click σ (1 px each): the least-squares compromise among
#: consistent clicks stays well inside it, a joint or fixed vertex that blocks the move does not.
FOLLOW_TOL_PX = 4.0
#: Default sizes (metres) of a new primitive: something of furniture scale to drag into place.
DEFAULT_PARAMS: dict[str, dict[str, float]] = {
    "quad": {"width": 2.0, "depth": 2.0},
    "box": {"width": 0.5, "depth": 0.5, "height": 0.5},
    "wedge": {"width": 0.5, "depth": 0.5, "height": 0.5},
    "cylinder": {"radius": 0.25, "height": 0.5},
    "frustum": {"radius_bottom": 0.25, "radius_top": 0.15, "height": 0.5},
    "cone": {"radius_bottom": 0.25, "radius_top": 0.0, "height": 0.5},
    "sphere": {"radius": 0.25},
}
#: The handle a first primitive puts on the origin marker (paper §3.1: the floor's corner).
ANCHOR_HANDLE = {"quad": "v0", "box": "v0", "wedge": "v0", "cylinder": "bc", "frustum": "bc", "sphere": "bottom"}


class EditError(VebuildError):
    """A user's edit that cannot be done; the text says why and what to do instead."""


@dataclass
class VanishingState:
    """One axis of one photo: its segments and, once they allow it, the fitted vanishing point.

    point : (3,) homogeneous pixel coordinates (w = 0 at infinity), or None.
    residuals_px : (n,) each segment's residual, or None.
    problem : why there is no vanishing point yet, or None.
    """

    axis: str
    segments: Array
    point: Array | None = None
    residuals_px: Array | None = None
    problem: str | None = None


@dataclass
class DragFeedback:
    """After one mouse move of a drag: whether the model followed, and if not, why."""

    ok: bool
    reason: str | None
    handle_px: tuple[float, float]
    ms: float


class _Drag:
    def __init__(self, session: DragSession, model: Model):
        self.session = session
        self.model = model
        self.x_good = model.vector()  # the model vector last shown
        self.xp_good = session.x.copy()  # the drag problem's vector that gives it
        self.uv_good = session.pin.uv.copy()
        self.baseline_fixed = 0.0
        self.moved = False
        self.revision = 0  # counts the moves the model followed
        self.T = session.problem.transforms(self.x_good)
        self.T_key = 0


class EditSession:
    """One project being edited; see the module's docstring."""

    def __init__(self, project: Project, autosave: bool = True):
        self.project = project
        self.autosave = autosave
        self.messages: list[str] = []
        self.revision = 0
        self.dirty = False
        self._undo: list[tuple[str, dict[str, Any]]] = []
        self._redo: list[tuple[str, dict[str, Any]]] = []
        self._cache: dict[Any, Any] = {}
        self._drag: _Drag | None = None
        self.recovery_available = False
        if autosave:
            from vebuild.project.outputs import begin_stage

            begin_stage(project)  # temporaries of a session (or a stage) that was killed
        side = self.autosave_path
        if side.exists():
            try:
                saved = json.loads(side.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                saved = None
            self.recovery_available = saved is not None and saved != project.data
            if self.recovery_available:
                self.say(f"unsaved edits from an earlier session are in {side.name}: recover or discard them")

    @classmethod
    def open(cls, path: str | Path, recover: bool | None = None, autosave: bool = True) -> EditSession:
        """Open a project; ``recover`` True takes an autosave side file's edits, False discards
        them, None leaves the choice to the user (:attr:`recovery_available`)."""
        project = load_project(path, verify_photos=False)
        s = cls(project, autosave=autosave)
        if s.recovery_available and recover is not None:
            s.recover() if recover else s.discard_recovery()
        return s

    # -- state ------------------------------------------------------------------------------------

    @property
    def data(self) -> dict[str, Any]:
        return self.project.data

    @property
    def autosave_path(self) -> Path:
        return autosave_path(self.project.path)

    @property
    def photo_ids(self) -> list[str]:
        return [p["id"] for p in self.data["photos"]]

    def photo(self, photo_id: str) -> dict[str, Any]:
        try:
            return self.project.photo(photo_id)
        except VebuildError as e:
            raise EditError(str(e)) from None

    def say(self, text: str) -> None:
        self.messages = (self.messages + [text])[-50:]

    @property
    def settings(self) -> dict[str, float]:
        return self.project.settings

    # -- edits, undo, autosave ----------------------------------------------------------------------

    @contextlib.contextmanager
    def _edit(self, label: str) -> Iterator[None]:
        """One undoable change: the document is restored if the change fails or leaves it invalid."""
        if self._drag is not None and label != "drag":
            raise EditError("finish the drag first (release the mouse button, or Esc to cancel it)")
        before = copy.deepcopy(self.data)
        try:
            yield
            # Results (calibration, solution, textures) the edit left as they were were valid before
            # it: only the inputs, and results it changed, are validated again (the covariance
            # matrices make a whole validation most of an edit's time).
            kept = [k for k in RESULT_KEYS if k in self.data and self.data[k] == before.get(k)]
            validate({k: v for k, v in self.data.items() if k not in kept}, self.project.path)
        except VebuildError as e:
            self.project.data = before
            self._cache.clear()
            raise e if isinstance(e, EditError) else EditError(str(e)) from None
        except BaseException:
            self.project.data = before
            self._cache.clear()
            raise
        self._undo = (self._undo + [(label, before)])[-UNDO_DEPTH:]
        self._redo.clear()
        self._changed()

    def _changed(self) -> None:
        self.revision += 1
        self.dirty = True
        self._cache.clear()
        if self.autosave:
            self._write_autosave()

    def _write_autosave(self) -> None:
        try:
            save_project(self.autosave_path, self.data, validated=True)  # every edit is validated in _edit
        except VebuildError as e:
            self.say(f"could not autosave: {e}")

    @property
    def undo_label(self) -> str | None:
        return self._undo[-1][0] if self._undo else None

    @property
    def redo_label(self) -> str | None:
        return self._redo[-1][0] if self._redo else None

    def undo(self) -> bool:
        if self._drag is not None or not self._undo:
            return False
        label, before = self._undo.pop()
        self._redo.append((label, self.data))
        self.project.data = before
        self._changed()
        self.say(f"undone: {label}")
        return True

    def redo(self) -> bool:
        if self._drag is not None or not self._redo:
            return False
        label, after = self._redo.pop()
        self._undo.append((label, self.data))
        self.project.data = after
        self._changed()
        self.say(f"redone: {label}")
        return True

    def save(self) -> Path:
        try:
            path = save_project(self.project)
        except VebuildError as e:
            raise EditError(str(e)) from None
        self.dirty = False
        with contextlib.suppress(FileNotFoundError):
            self.autosave_path.unlink()
        self.say(f"saved {path.name}")
        return path

    def recover(self) -> None:
        """Take the edits kept in the autosave side file (one undoable step)."""
        try:
            saved = load_project(self.autosave_path, verify_photos=False).data
        except VebuildError as e:
            self.recovery_available = False
            raise EditError(f"the autosave cannot be recovered: {e}") from None
        with self._edit("recover autosaved edits"):
            self.project.data = saved
        self.recovery_available = False
        self.say(f"recovered the edits kept in {self.autosave_path.name}; save to keep them in the project")

    def discard_recovery(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            self.autosave_path.unlink()
        self.recovery_available = False
        self.say("discarded the autosaved edits")

    # -- photos -----------------------------------------------------------------------------------

    def add_photo(self, path: str | Path, photo_id: str | None = None) -> str:
        """Add an image from the project's folder, its size, SHA-256 and EXIF recorded."""
        path = Path(path)
        if not path.is_absolute() and not path.exists():
            path = self.project.folder / path
        try:
            entry = new_photo_entry(self.project.folder, path, photo_id)
        except VebuildError as e:
            raise EditError(str(e)) from None
        base, k = entry["id"], 2
        while entry["id"] in self.photo_ids:
            entry["id"] = f"{base}-{k}"
            k += 1
        with self._edit(f"add photo {entry['id']}"):
            self.data["photos"].append(entry)
        self.say(f"added photo '{entry['id']}' ({entry['width']}×{entry['height']}, "
                 f"SHA-256 {entry['sha256'][:12]}…)")
        return entry["id"]

    def photo_pixels(self, photo_id: str) -> NDArray[np.uint8]:
        """The photo's pixels (h, w, 3); EditError naming the file if it is missing, changed or unreadable."""
        from vebuild.texture.extract import PhotoSource, read_photo

        p = self.photo(photo_id)
        i = self.photo_ids.index(photo_id)
        src = PhotoSource(photo_id, self.project.photo_path(p), p["sha256"], f"$.photos[{i}]", str(self.project.path))
        try:
            size_only = cam_math.ImageCamera(photo_id, np.eye(3), np.eye(3), np.zeros(3), p["width"], p["height"])
            return read_photo(src, size_only)
        except VebuildError as e:
            raise EditError(f"photo '{photo_id}' fails to load: {e}") from None

    # -- calibration marks (paper §2) ---------------------------------------------------------------

    def _segments(self, photo: str, axis: str) -> list[list[float]]:
        if axis not in AXES:
            raise EditError(f"a vanishing segment runs along world axis x, y or z, not {axis!r}")
        p = self.photo(photo)
        return p.setdefault("vanishing_segments", {}).setdefault(axis, [])

    def add_segment(self, photo: str, axis: str, p1: Sequence[float], p2: Sequence[float]) -> int:
        """Add a directed segment (p1 toward +axis at p2); EditError for one shorter than 2 px."""
        seg = [float(p1[0]), float(p1[1]), float(p2[0]), float(p2[1])]
        self._check_segment(seg, axis)
        with self._edit(f"add {axis} segment in {photo}"):
            segs = self._segments(photo, axis)
            segs.append(seg)
        return len(segs) - 1

    def _check_segment(self, seg: Sequence[float], axis: str) -> None:
        if not all(math.isfinite(v) for v in seg):
            raise EditError("a segment's end point is not a number")
        length = math.hypot(seg[2] - seg[0], seg[3] - seg[1])
        if length < MIN_SEGMENT_LENGTH_PX:
            raise EditError(f"that {axis} segment is {length:.1f} px long: a vanishing segment needs two distinct "
                            f"end points at least {MIN_SEGMENT_LENGTH_PX:g} px apart along an edge; press, drag "
                            "along the edge, release")

    def move_segment(self, photo: str, axis: str, index: int, seg: Sequence[float]) -> None:
        seg = [float(v) for v in seg]
        self._check_segment(seg, axis)
        with self._edit(f"move {axis} segment {index} in {photo}"):
            self._segments(photo, axis)[index] = seg

    def delete_segment(self, photo: str, axis: str, index: int) -> None:
        with self._edit(f"delete {axis} segment {index} in {photo}"):
            segs = self._segments(photo, axis)
            del segs[index]
            if not segs:
                del self.photo(photo)["vanishing_segments"][axis]

    def segment_at(self, photo: str, uv: Sequence[float], radius_px: float) -> tuple[str, int, int | None] | None:
        """The segment near uv: (axis, index, 0/1 for an end point or None for its body)."""
        best, q = None, np.asarray(uv, float)
        for axis, segs in (self.photo(photo).get("vanishing_segments") or {}).items():
            for i, s in enumerate(segs):
                a, b = np.asarray(s[:2]), np.asarray(s[2:])
                for end, p in ((0, a), (1, b)):
                    d = float(np.linalg.norm(q - p))
                    if d <= radius_px and (best is None or d < best[0] - 1e-9 or best[2] is None):
                        best = (d, (axis, i, end), end)
                t = np.clip(np.dot(q - a, b - a) / max(np.dot(b - a, b - a), 1e-12), 0, 1)
                d = float(np.linalg.norm(q - (a + t * (b - a))))
                if d <= radius_px and best is None:
                    best = (d, (axis, i, None), None)
        return best[1] if best else None

    def vanishing(self, photo: str, axis: str) -> VanishingState:
        """The segments of one axis and their best-fit vanishing point (or why there is none yet)."""
        key = ("vp", photo, axis)
        if key not in self._cache:
            from vebuild.calibration.vanishing import fit_vanishing_point

            p = self.photo(photo)
            segs = np.asarray((p.get("vanishing_segments") or {}).get(axis, []), float).reshape(-1, 4)
            state = VanishingState(axis, segs)
            if len(segs) < 2:
                state.problem = (f"{axis}: {len(segs)} segment{'s' if len(segs) != 1 else ''}; a vanishing point needs "
                                 "two or more, along different parallel edges")
            else:
                try:
                    fit = fit_vanishing_point(segs, p["width"], p["height"], axis=axis, photo=photo)
                    state.point, state.residuals_px = fit.point, fit.residuals_px
                except CalibrationError as e:
                    state.problem = f"{axis}: cannot fit a vanishing point yet: {e.detail}"
            self._cache[key] = state
        return self._cache[key]

    def next_marker_name(self) -> str:
        names = set(self.project.marker_names())
        k = 1
        while f"M{k}" in names:
            k += 1
        return f"M{k}"

    def place_marker(self, photo: str, name: str, uv: Sequence[float]) -> None:
        """Mark marker ``name`` at uv in the photo (a new name makes a new marker)."""
        name = name.strip()
        if not name or ":" in name:
            raise EditError("a marker needs a name (without ':', which names model vertices)")
        uv = [float(uv[0]), float(uv[1])]
        with self._edit(f"place marker {name} in {photo}"):
            if name not in self.project.marker_names():
                self.data["markers"].append({"name": name})
            self.photo(photo).setdefault("marker_observations", {})[name] = uv
            if not self.data.get("origin_marker") and len(self.data["markers"]) == 1:
                self.data["origin_marker"] = name

    def remove_marker(self, photo: str, name: str) -> None:
        """Remove the marker's observation in this photo (and the marker, once nothing refers to it)."""
        obs = self.photo(photo).get("marker_observations") or {}
        if name not in obs:
            raise EditError(f"marker '{name}' is not marked in photo '{photo}'")
        with self._edit(f"remove marker {name} from {photo}"):
            del obs[name]
            used = any(name in (p.get("marker_observations") or {}) for p in self.data["photos"])
            used |= any(name in (d["a"], d["b"]) for d in self.data["reference_distances"])
            nodes = (self.data.get("model") or {}).get("nodes", [])
            used |= any(n.get("joint", {}).get("marker") == name for n in nodes)
            if not used:
                self.data["markers"] = [m for m in self.data["markers"] if m["name"] != name]
                if self.data.get("origin_marker") == name:
                    del self.data["origin_marker"]

    def marker_at(self, photo: str, uv: Sequence[float], radius_px: float) -> str | None:
        obs = self.photo(photo).get("marker_observations") or {}
        best = min(obs.items(), key=lambda kv: math.dist(kv[1], uv), default=None)
        return best[0] if best and math.dist(best[1], uv) <= radius_px else None

    def set_origin(self, name: str) -> None:
        if name not in self.project.marker_names():
            raise EditError(f"no marker is called '{name}'; place it in a photo first")
        with self._edit(f"origin at {name}"):
            self.data["origin_marker"] = name

    def add_distance(self, a: str, b: str, distance_m: float, sigma_m: float = 0.002, role: str = "scale") -> None:
        """A measured distance between two markers (or model vertices ``node:handle``)."""
        a, b = a.strip(), b.strip()
        if role not in ("scale", "check"):
            raise EditError(f"a reference distance's role is 'scale' or 'check', not {role!r}")
        if not (math.isfinite(distance_m) and distance_m > 0):
            raise EditError(f"a reference distance must be a positive number of metres, not {distance_m!r}")
        if not (math.isfinite(sigma_m) and sigma_m > 0):
            raise EditError(f"a reference distance's σ must be a positive number of metres, not {sigma_m!r}")
        if a == b:
            raise EditError("a reference distance needs two different ends")
        with self._edit(f"distance {a}–{b}"):
            self.data["reference_distances"].append({"a": a, "b": b, "distance": float(distance_m),
                                                     "sigma": float(sigma_m), "role": role})

    def remove_distance(self, index: int) -> None:
        with self._edit("remove distance"):
            del self.data["reference_distances"][index]

    def calibrate(self, progress: Progress | None = None) -> dict[str, Any]:
        """Calibrate every photo with segments and place the cameras (``vebuild calibrate``)."""
        from vebuild.actions.calibrate import calibrate_project

        with self._edit("calibrate"):
            result = calibrate_project(self.project, progress=_iterating(progress, "calibrating photos"))
        lines = [f"{pid}: {c['mode']}, f {c['focal_px']['value']:.1f} ± {c['focal_px']['sigma']:.1f} px, "
                 f"rms {c['rms_px']:.2f} px" for pid, c in result["cameras"].items()]
        self.say("calibrated " + "; ".join(lines))
        for w in result.get("warnings", []):
            self.say(w)
        return result

    @property
    def cameras(self) -> dict[str, ImageCamera]:
        if "cameras" not in self._cache:
            from vebuild.project.decode import cameras_from_calibration

            try:
                self._cache["cameras"] = cameras_from_calibration(self.project)
            except VebuildError:
                self._cache["cameras"] = {}
        return self._cache["cameras"]

    def _camera(self, photo: str) -> ImageCamera:
        cam = self.cameras.get(photo)
        if cam is None:
            raise EditError(f"photo '{photo}' has no calibrated camera yet: mark its vanishing segments and "
                            "calibrate, or register it from known points")
        return cam

    # -- the model (paper §3) -----------------------------------------------------------------------

    def _markers_placed(self) -> dict[str, Array]:
        cal = (self.data.get("calibration") or {}).get("markers", {})
        return {n: np.asarray(m["position"], float) for n, m in cal.items()}

    @property
    def model(self) -> Model | None:
        if "model" not in self._cache:
            nodes = (self.data.get("model") or {}).get("nodes") or []
            try:
                self._cache["model"] = model_from_dict(nodes, self._markers_placed()) if nodes else None
            except ModelError as e:
                self.say(str(e))
                self._cache["model"] = None
        return self._cache["model"]

    def _model_doc(self) -> dict[str, Any]:
        return self.data.setdefault("model", {"nodes": [], "pins": [], "edge_observations": []})

    def _nodes(self) -> list[dict[str, Any]]:
        return self._model_doc().setdefault("nodes", [])

    def _node_doc(self, name: str) -> dict[str, Any]:
        for n in self._nodes():
            if n["name"] == name:
                return n
        raise EditError(f"the model has no node called '{name}'")

    def _pins(self) -> list[dict[str, Any]]:
        return self._model_doc().setdefault("pins", [])

    def _edge_docs(self) -> list[dict[str, Any]]:
        return self._model_doc().setdefault("edge_observations", [])

    def _rebuild_check(self) -> None:
        """The model as edited must still be a model (ModelError → EditError, the edit undone)."""
        nodes = self._nodes()
        try:
            model_from_dict(nodes, self._markers_placed())
        except ModelError as e:
            raise EditError(str(e)) from None

    def add_primitive(self, kind: str, *, name: str | None = None, parent: str | None = None,
                      at: tuple[str, Sequence[float]] | None = None,
                      params: dict[str, float] | None = None, marker: str | None = None) -> str:
        """Add a primitive, attached to ``parent`` (resting on its top), to a calibrated ``marker``
        (its first handle on the marker; the first primitive goes on the origin marker, paper §3.1),
        or else resting on the floor; ``at`` = (photo, (u, v)) puts it where that pixel's ray meets
        the surface it rests on."""
        if kind not in DEFAULT_PARAMS:
            raise EditError(f"a primitive is one of {', '.join(DEFAULT_PARAMS)}, not {kind!r}")
        ptype = "frustum" if kind == "cone" else kind
        existing = {n["name"] for n in self._nodes()}
        if name is None or not name.strip():
            k = 1
            while f"{kind}{k}" in existing:
                k += 1
            name = f"{kind}{k}"
        name = name.strip()
        if name in existing:
            raise EditError(f"the model already has a node called '{name}'")
        if parent is not None and parent not in existing:
            raise EditError(f"the model has no node called '{parent}' to attach '{name}' to")
        values = dict(DEFAULT_PARAMS[kind]) | (params or {})
        joint: dict[str, Any]
        origin = self.data.get("origin_marker") or (self.data.get("calibration") or {}).get("origin_marker")
        if marker is not None and parent is not None:
            raise EditError(f"'{name}' can hang on a parent or on a marker, not both")
        if parent is None and (marker is not None or not existing):
            if not self.cameras:
                raise EditError("calibrate first: the first primitive is placed on the origin marker, which the "
                                "calibration locates")
            anchor = marker if marker is not None else origin
            if anchor not in self._markers_placed():
                raise EditError(f"marker '{anchor}' has no calibrated position yet: mark it in two photos and "
                                "calibrate" if marker is not None else
                                "the first primitive sits on the origin marker; mark the origin and calibrate")
            joint = {"type": "marker", "marker": anchor, "handle": ANCHOR_HANDLE[ptype], "yaw_deg": 0.0}
        else:
            joint = {"type": "rests_on", "position": [0.0, 0.0], "yaw_deg": 0.0}
            if parent is not None:
                prim = self.model.node(parent).primitive if self.model else None
                if prim is None or "top" not in prim.faces():
                    faces = ", ".join(prim.faces()) if prim else "none (a group)"
                    raise EditError(f"'{parent}' has no top face for '{name}' to rest on (its faces: {faces}); "
                                    "attach it to another node")
                joint["face"] = "top"
            if at is not None:
                joint["position"] = self._surface_point(parent, at, values, ptype)
        node = {"name": name, "primitive": {"type": ptype, "params": values}, "joint": joint}
        if parent is not None:
            node["parent"] = parent
        with self._edit(f"add {kind} {name}"):
            self._nodes().append(node)
            self._model_doc().setdefault("pins", [])
            self._model_doc().setdefault("edge_observations", [])
            self._rebuild_check()
        self.say(f"added {kind} '{name}'" + (f" on '{parent}'" if parent else "") +
                 ": drag its corners onto the photo")
        return name

    def _surface_point(self, parent: str | None, at: tuple[str, Sequence[float]], values: dict[str, float],
                       ptype: str) -> list[float]:
        """(s, t) on the parent's top face (or the floor) under the pixel ``at``."""
        photo, uv = at
        cam = self._camera(photo)
        C = np.asarray(cam.C, float)
        d = cam_math.pixel_rays_world(cam.K, cam.R, np.asarray(uv, float))
        o, x, y, n = np.zeros(3), np.eye(3)[0], np.eye(3)[1], np.eye(3)[2]
        if parent is not None:
            model = self.model
            T = model.world_transforms()[parent]
            node = model.node(parent)
            fo, fx, fy, fn = node.primitive.face_frame("top")
            o, x, y, n = T[:3, :3] @ fo + T[:3, 3], T[:3, :3] @ fx, T[:3, :3] @ fy, T[:3, :3] @ fn
        denom = float(d @ n)
        lam = float((o - C) @ n) / denom if abs(denom) > 1e-9 else -1.0
        if lam <= 0:
            raise EditError("that pixel does not look at the surface the new primitive rests on; click on it")
        P = C + lam * d
        return [float((P - o) @ x), float((P - o) @ y)]

    def remove_node(self, name: str) -> None:
        """Remove a node with its children, their observations and any hypothesis joints of them."""
        model = self.model
        if model is None or name not in model.index:
            raise EditError(f"the model has no node called '{name}'")
        gone = set(model.subtree(name))
        with self._edit(f"remove {name}"):
            doc = self._model_doc()
            doc["nodes"] = [n for n in doc["nodes"] if n["name"] not in gone]
            doc["pins"] = [p for p in doc.get("pins", []) if p["node"] not in gone]
            doc["edge_observations"] = [e for e in doc.get("edge_observations", []) if e["node"] not in gone]
            self.data["reference_distances"] = [d for d in self.data["reference_distances"]
                                                if not any(e.split(":", 1)[0] in gone for e in (d["a"], d["b"])
                                                           if ":" in e)]
            for h in self.data.get("hypotheses", []):
                h["joints"] = {k: v for k, v in h["joints"].items() if k not in gone}
            if not doc["nodes"]:
                del self.data["model"]
            self.data.pop("model_solution", None)

    def set_params(self, node: str, params: dict[str, float]) -> None:
        with self._edit(f"sizes of {node}"):
            doc = self._node_doc(node)
            if "primitive" not in doc:
                raise EditError(f"'{node}' is a group: it has no sizes")
            for k, v in params.items():
                if k not in doc["primitive"]["params"]:
                    raise EditError(f"'{node}' has no size '{k}' (it has {', '.join(doc['primitive']['params'])})")
                if not (math.isfinite(v) and v >= 0):
                    raise EditError(f"{node}.{k} must be a length ≥ 0 m, not {v!r}")
                doc["primitive"]["params"][k] = float(v)
            self._rebuild_check()

    def set_joint(self, node: str, joint: dict[str, Any]) -> None:
        """Replace the node's joint (the project file's form, degrees)."""
        with self._edit(f"joint of {node}"):
            self._node_doc(node)["joint"] = copy.deepcopy(joint)
            self._rebuild_check()

    def set_limits(self, node: str, lo: float, hi: float) -> None:
        """Limits of a hinge (degrees) or slider (metres)."""
        doc = self._node_doc(node)
        kind = doc.get("joint", {}).get("type")
        if kind not in ("hinge", "slider"):
            raise EditError(f"'{node}' moves on a {kind} joint, which has no limits (a hinge or a slider has)")
        if not lo <= hi:
            raise EditError(f"limits must run from low to high, not [{lo}, {hi}]")
        with self._edit(f"limits of {node}"):
            j = self._node_doc(node)["joint"]
            if kind == "hinge":
                j["limits_deg"] = [float(lo), float(hi)]
                j["angle_deg"] = float(np.clip(j.get("angle_deg", 0.0), lo, hi))
            else:
                j["limits"] = [float(lo), float(hi)]
                j["offset"] = float(np.clip(j.get("offset", 0.0), lo, hi))
            self._rebuild_check()

    def set_solve(self, node: str, solve: bool) -> None:
        with self._edit(f"{'solve' if solve else 'hold'} {node}"):
            doc = self._node_doc(node)
            if solve:
                doc.pop("solve", None)
            else:
                doc["solve"] = False

    def group(self, nodes: Sequence[str], name: str) -> str:
        """Make the nodes the parts of one object: a group node under their common parent, resting
        where the first of them rests, and each part fixed to it where it is now (paper §3)."""
        model = self.model
        if model is None or len(nodes) < 1:
            raise EditError("select the primitives to group first")
        name = name.strip()
        if not name or name in model.index:
            raise EditError(f"a group needs a new name; '{name}' is taken" if name else "a group needs a name")
        for n in nodes:
            if n not in model.index:
                raise EditError(f"the model has no node called '{n}'")
        parents = {model.node(n).parent for n in nodes}
        if len(parents) != 1:
            raise EditError("only nodes attached to the same parent can be grouped: "
                            + ", ".join(f"{n} on {model.node(n).parent or 'the world'}" for n in nodes))
        parent = parents.pop()
        first = model.node(nodes[0])
        if first.joint.type == "marker":
            raise EditError(f"'{nodes[0]}' is tied to a marker; group the objects standing on it instead")
        T = model.world_transforms()
        group_joint = first.joint.to_dict()
        T_group = T[nodes[0]]
        with self._edit(f"group {name}"):
            docs = self._nodes()
            at = min(i for i, d in enumerate(docs) if d["name"] in nodes)
            g: dict[str, Any] = {"name": name, "joint": group_joint}
            if parent is not None:
                g["parent"] = parent
            docs.insert(at, g)
            from vebuild.model.scene import pose_to_dict

            for n in nodes:
                rel = np.linalg.inv(T_group) @ T[n]
                d = self._node_doc(n)
                d["parent"] = name
                d["joint"] = {"type": "fixed", **pose_to_dict(rel)}
            self._rebuild_check()
        self.say(f"grouped {', '.join(nodes)} as '{name}': they move together")
        return name

    # -- handles, drags, pins (paper §3.1, Figure 7) ------------------------------------------------

    def _model_now(self) -> tuple[Model | None, Array | None]:
        """The model and its vector as shown: during a drag, the drag's live state."""
        if self._drag is not None:
            return self._drag.model, self._drag.x_good
        m = self.model
        return m, (m.vector() if m is not None else None)

    def handles(self, photo: str,
                nodes: Sequence[str] | None = None) -> list[tuple[str, str, tuple[float, float], bool]]:
        """Every primitive's handles (or those of ``nodes``) projected into the photo: (node,
        handle, (u, v), fixed)."""
        cam = self.cameras.get(photo)
        model, x = self._model_now()
        if cam is None or model is None:
            return []
        T = self._transforms()
        fixed = {(p["node"], p["handle"]) for p in self._pins() if p["photo"] == photo and p.get("fixed", True)}
        out = []
        for node in model.nodes if nodes is None else [model.node(n) for n in nodes]:
            if node.primitive is None:
                continue
            hs = node.primitive.handles(x[model.slices[node.name][1]])
            W = hs @ T[node.name][:3, :3].T + T[node.name][:3, 3]
            front = cam_math.world_to_camera(cam.R, cam.C, W)[:, 2] > 0
            uv = cam_math.project(cam.K, cam.R, cam.C, W)
            for h, ok, p in zip(node.primitive.handle_names(), front, uv, strict=True):
                if ok:
                    out.append((node.name, h, (float(p[0]), float(p[1])), (node.name, h) in fixed))
        return out

    def _transforms(self) -> dict[str, Array]:
        """World transforms of every node as shown; during a drag only the moving subtree is
        recomputed (the rest cannot move)."""
        d = self._drag
        if d is None:
            if "transforms" not in self._cache:
                self._cache["transforms"] = self.model.world_transforms()
            return self._cache["transforms"]
        if d.T_key != d.revision:
            d.T = d.session.problem.transforms(d.x_good)
            d.T_key = d.revision
        return d.T

    def handle_at(self, photo: str, uv: Sequence[float], radius_px: float,
                  prefer: str | None = None) -> tuple[str, str] | None:
        """The handle nearest uv within radius_px (those of node ``prefer`` first)."""
        near = [(math.dist(p, uv) - (radius_px if n == prefer else 0.0), n, h)
                for n, h, p, _ in self.handles(photo) if math.dist(p, uv) <= radius_px]
        return min(near)[1:] if near else None

    @property
    def dragging(self) -> bool:
        return self._drag is not None

    def _observations(self) -> tuple[list[Pin], list[EdgeObservation]]:
        pins = [Pin(p["photo"], p["node"], p["handle"], np.asarray(p["uv"], float), bool(p.get("fixed", True)))
                for p in self._pins() if p["photo"] in self.cameras]
        edges = [EdgeObservation(e["photo"], e["node"], e["edge"], np.asarray(e["points"], float))
                 for e in self._edge_docs() if e["photo"] in self.cameras]
        return pins, edges

    def begin_drag(self, photo: str, node: str, handle: str) -> None:
        """Grab a handle in a photo (paper Figure 7): until one of its vertices is fixed the node moves
        as a whole along its joint; then its sizes change too."""
        if self._drag is not None:
            self.cancel_drag()
        self._camera(photo)
        model = self.model
        if model is None or node not in model.index:
            raise EditError(f"the model has no node called '{node}'")
        free = drag_nodes(model, node)
        movable = [n for n in free if model.node(n).solve]
        if not movable:
            raise EditError(f"'{node}' cannot be dragged: it is held (solve: false); untick 'hold' in its properties")
        pins, edges = self._observations()
        try:
            ds = DragSession(model, self.cameras, pins, edges, photo, node, handle,
                             click_sigma_px=self.settings["click_sigma_px"], edges_into=())
        except (KeyError, ValueError) as e:
            raise EditError(f"cannot drag {node}:{handle}: {e}") from None
        if ds.x.size == 0:
            raise EditError(f"'{node}' cannot move: its joint ({model.node(free[-1]).joint.type}) has no freedom "
                            "and its sizes are held")
        self._drag = _Drag(ds, model)
        self._drag.baseline_fixed = self._fixed_error(ds)

    def _fixed_error(self, ds: DragSession) -> float:
        """The largest distance of the drag's other fixed vertices from their pins, now."""
        p = ds.problem
        r = p.residuals(ds.x) * p.sigma
        return max((float(np.linalg.norm(r[p.rows_pin[i]])) for i, q in enumerate(p.pins) if q is not ds.pin),
                   default=0.0)

    def drag_to(self, uv: Sequence[float]) -> DragFeedback:
        """The mouse is at uv: solve; if the constraints cannot follow, stay and say why."""
        d = self._drag
        if d is None:
            raise EditError("no drag in progress")
        t0 = time.perf_counter()
        ds = d.session
        x_prev = ds.x.copy()
        uv = np.asarray(uv, float)
        try:
            res = ds.move(uv)
            reach = float(np.linalg.norm(res.handle_px - uv))
            ok = bool(np.all(np.isfinite(res.x))) and reach <= FOLLOW_TOL_PX and \
                res.fixed_error_px <= d.baseline_fixed + FOLLOW_TOL_PX
        except (np.linalg.LinAlgError, FloatingPointError, ValueError):
            ok, reach, res = False, float("inf"), None
        if ok:
            d.x_good, d.xp_good, d.uv_good, d.moved = res.x.copy(), ds.x.copy(), uv.copy(), True
            d.revision += 1
            self.revision += 1
            return DragFeedback(True, None, (float(res.handle_px[0]), float(res.handle_px[1])),
                                1e3 * (time.perf_counter() - t0))
        ds.x = x_prev
        ds.problem.set_pin_pixel(ds._pin_index, d.uv_good)
        reason = self._why_stuck(d, res.fixed_error_px - d.baseline_fixed if res is not None else None)
        cam = self.cameras[ds.photo]
        hp = cam_math.project(cam.K, cam.R, cam.C, d.model.handle_world(ds.node, ds.handle, d.x_good))
        return DragFeedback(False, reason, (float(hp[0]), float(hp[1])), 1e3 * (time.perf_counter() - t0))

    def _why_stuck(self, d: _Drag, fixed_shift: float | None) -> str:
        ds = d.session
        model = d.model
        root = model.node(ds.free[-1])
        what = f"{ds.node}:{ds.handle}"
        j = root.joint
        how = {"rests_on": f"it rests on {('the ' + repr(root.parent) + ' top') if root.parent else 'the floor'} "
                           "(it slides and turns on it only)",
               "hinge": "it turns on its hinge only" + (" and is at its limit" if _at_limit(j) else ""),
               "slider": "it slides along its runner only" + (" and is at its limit" if _at_limit(j) else ""),
               "marker": f"it is tied to marker '{getattr(j, 'marker', '?')}' (it turns about it only)",
               "fixed": "it is fixed to its parent", "free": "it moves freely"}.get(j.type, f"its {j.type} joint")
        fixed = sorted({f"{p.node}:{p.handle}" for p in ds.other_pins
                        if p.fixed and p.node in set(ds.moved) and p.photo in self.cameras})
        held = f"; its fixed vertices {', '.join(fixed[:4])} hold it" if fixed else ""
        shift = (f" (they would move {fixed_shift:.1f} px)"
                 if fixed and fixed_shift and fixed_shift > FOLLOW_TOL_PX else "")
        return (f"{what} cannot go there: {how}{held}{shift}; it stays where it was. Unfix a vertex (F), "
                "or change the joint")

    def end_drag(self) -> None:
        """Keep the dragged result; the grabbed vertex becomes fixed in that photo."""
        d = self._drag
        if d is None:
            return
        ds = d.session
        if not d.moved:
            self._drag = None
            self.revision += 1
            return
        ds.x = d.xp_good
        pin = ds.release()
        pin.uv = d.uv_good
        self._drag = None
        with self._edit(f"drag {pin.node}:{pin.handle} in {pin.photo}"):
            self._model_doc()["nodes"] = _merge_nodes(self._nodes(), d.model.to_dict())
            key = (pin.photo, pin.node, pin.handle)
            pins = [p for p in self._pins() if (p["photo"], p["node"], p["handle"]) != key]
            pins.append({"photo": pin.photo, "node": pin.node, "handle": pin.handle,
                         "uv": [float(pin.uv[0]), float(pin.uv[1])], "fixed": True})
            self._model_doc()["pins"] = pins
            self._rebuild_check()

    def cancel_drag(self) -> None:
        if self._drag is not None:
            self._drag.session.cancel()
            self._drag = None
            self.revision += 1

    def fix(self, photo: str, node: str, handle: str, uv: Sequence[float] | None = None) -> None:
        """Fix a vertex where it is seen in the photo (or at uv)."""
        if uv is None:
            found = [p for n, h, p, _ in self.handles(photo) if (n, h) == (node, handle)]
            if not found:
                raise EditError(f"{node}:{handle} is not in view in photo '{photo}'")
            uv = found[0]
        with self._edit(f"fix {node}:{handle} in {photo}"):
            pins = [p for p in self._pins() if (p["photo"], p["node"], p["handle"]) != (photo, node, handle)]
            pins.append({"photo": photo, "node": node, "handle": handle, "uv": [float(uv[0]), float(uv[1])],
                         "fixed": True})
            self._model_doc()["pins"] = pins

    def unfix(self, photo: str, node: str, handle: str) -> None:
        pins = self._pins()
        if not any((p["photo"], p["node"], p["handle"]) == (photo, node, handle) for p in pins):
            raise EditError(f"{node}:{handle} is not fixed in photo '{photo}'")
        with self._edit(f"unfix {node}:{handle} in {photo}"):
            key = (photo, node, handle)
            self._model_doc()["pins"] = [p for p in pins if (p["photo"], p["node"], p["handle"]) != key]

    def nearest_edge(self, photo: str, p1: Sequence[float], p2: Sequence[float],
                     node: str | None = None) -> tuple[str, str] | None:
        """The projected model edge that the stroke p1–p2 follows best (of ``node``, or any)."""
        cam = self._camera(photo)
        model, x = self._model_now()
        if model is None:
            return None
        names = [node] if node else [n.name for n in model.nodes if n.primitive is not None]
        a, b = np.asarray(p1, float), np.asarray(p2, float)
        best = None
        for n, edges in project_edges(model, cam, names, x).items():
            for e, (u1, v1, u2, v2) in edges:
                q1, q2 = np.array([u1, v1]), np.array([u2, v2])
                d = q2 - q1
                L = float(np.linalg.norm(d))
                if L < 1e-6:
                    continue
                nrm = np.array([-d[1], d[0]]) / L
                dist = abs(float((a - q1) @ nrm)) + abs(float((b - q1) @ nrm))
                mid = 0.5 * (a + b)
                t = float((mid - q1) @ d) / L**2
                dist += max(0.0, -t, t - 1.0) * L  # beyond the edge's ends
                if best is None or dist < best[0]:
                    best = (dist, n, e)
        return (best[1], best[2]) if best else None

    def add_edge_observation(self, photo: str, node: str, edge: str, p1: Sequence[float], p2: Sequence[float]) -> None:
        """The user's (red) edge: the model edge must pass through p1 and p2 (paper §3)."""
        self._camera(photo)
        if math.dist(p1, p2) < MIN_SEGMENT_LENGTH_PX:
            raise EditError(f"an edge needs two end points at least {MIN_SEGMENT_LENGTH_PX:g} px apart")
        model = self.model
        prim = model.node(node).primitive if model and node in model.index else None
        if prim is None or edge not in [e for e, _, _ in prim.edges()]:
            raise EditError(f"'{node}' has no edge '{edge}'")
        with self._edit(f"edge {node}:{edge} in {photo}"):
            self._edge_docs().append({"photo": photo, "node": node, "edge": edge,
                                      "points": [[float(p1[0]), float(p1[1])], [float(p2[0]), float(p2[1])]]})

    def remove_edge_observation(self, index: int) -> None:
        with self._edit("remove edge"):
            del self._edge_docs()[index]

    # -- solving, re-calibration, registration, textures (paper §3.1, §3.2, §4) ---------------------

    def solve(self, recalibrate: bool = False, progress: Progress | None = None) -> dict[str, Any]:
        """Solve the model from its fixed vertices and edges; ``recalibrate`` refines the cameras and
        markers with it (paper §3.2). Returns the solution: residuals per observation, outliers."""
        from vebuild.actions.solve import solve_project

        if progress:
            progress(0.0, "re-calibrating and solving" if recalibrate else "solving")
        with self._edit("re-calibrate" if recalibrate else "solve"):
            result = solve_project(self.project, recalibrate=recalibrate)
        if progress:
            progress(1.0, "done")
        self.say(f"{'re-calibrated and solved' if recalibrate else 'solved'}: rms {result['rms_px']:.2f} px over "
                 f"{len(result['pins'])} vertices and {len(result['edge_observations'])} edges"
                 + (f"; outliers: {'; '.join(result['outliers'])}" if result["outliers"] else "; no outliers"))
        return result

    def register(self, photo: str) -> None:
        """Place this photo from the known points marked in it (paper §3.2)."""
        from vebuild.actions.register import register_photos

        with self._edit(f"register {photo}"):
            reg = register_photos(self.project, [photo])[photo]
        self.say(f"registered '{photo}' from {len(reg.residuals_px)} known points, rms "
                 f"{float(np.sqrt(np.mean(np.asarray(reg.residuals_px) ** 2))):.2f} px")

    def texture(self, progress: Progress | None = None, texels_per_metre: float | None = None) -> dict[str, Any]:
        """Extract the textures now (``vebuild texture``): atlas pages beside the project."""
        from vebuild.actions.texture import texture_project
        from vebuild.texture.gpu import Options

        opts = Options() if texels_per_metre is None else Options(texels_per_metre=texels_per_metre)

        def step(done: int, total: int, text: str) -> None:
            if progress:
                progress(done / max(total, 1), text)

        with self._edit("extract textures"):
            record, _ = texture_project(self.project, opts, progress=step, save=False)
        self.say(f"textures extracted: {len(record['pages'])} page(s)")
        return record

    # -- what to draw -------------------------------------------------------------------------------

    def overlay(self, photo: str, selected: str | None = None) -> Overlay:
        """Everything drawn over one photo (see :mod:`vebuild.edit.overlay`)."""
        key = ("overlay", photo, selected, self.revision)
        if key not in self._cache:
            if self._drag is None:
                self._cache[key] = self._overlay(photo, selected)
            else:
                still, moving = self.overlay_layers(photo, selected)
                self._cache[key] = Overlay(photo, still.lines + moving.lines, still.points + moving.points,
                                           still.notes + moving.notes)
        return self._cache[key]

    def overlay_layers(self, photo: str, selected: str | None = None) -> tuple[Overlay, Overlay]:
        """The overlay as what stays put and what moves: during a drag, everything but the moving
        primitives (kept from the drag's first frame) and their edges and handles now; otherwise
        the whole overlay and nothing."""
        d = self._drag
        if d is None:
            return self.overlay(photo, selected), Overlay(photo)
        still = ("overlay-still", photo, selected, id(d))
        if still not in self._cache:
            self._cache[still] = self._overlay(photo, selected, skip=set(d.session.moved))
        key = ("overlay-moving", photo, selected, self.revision)
        if key not in self._cache:
            moving = Overlay(photo)
            cam = self.cameras.get(photo)
            if cam is not None:
                self._primitives_overlay(moving, photo, cam, selected, d.session.moved)
            self._cache[key] = moving
        return self._cache[still], self._cache[key]

    def _overlay(self, photo: str, selected: str | None, skip: set[str] | frozenset[str] = frozenset()) -> Overlay:
        ov = Overlay(photo)
        p = self.photo(photo)
        sigma = self.settings["click_sigma_px"]
        for axis in AXES:
            vs = self.vanishing(photo, axis)
            colour = AXIS_COLOURS[axis]
            for i, s in enumerate(vs.segments):
                r = None if vs.residuals_px is None else float(vs.residuals_px[i])
                outlier = r is not None and abs(r) > OUTLIER_SIGMAS * sigma
                ov.lines.append(Line(tuple(map(float, s)), YELLOW if outlier else colour, 3.0 if outlier else 2.0,
                                     "segment", (axis, i), None if r is None else
                                     (f"{axis}{i}: {r:+.2f} px" + (" outlier" if outlier else "")), arrow=True))
            if vs.point is not None:
                vanishing_rays(ov, vs, p["width"], p["height"])
            elif vs.problem and len(vs.segments):
                ov.notes.append(vs.problem)
        cam = self.cameras.get(photo)
        if cam is not None:
            horizon_and_axes(ov, cam, p["width"], p["height"])
        self._markers_overlay(ov, photo, cam)
        self._model_overlay(ov, photo, cam, selected, skip)
        return ov

    def _markers_overlay(self, ov: Overlay, photo: str, cam: ImageCamera | None) -> None:
        placed = self._markers_placed()
        origin = self.data.get("origin_marker")
        res = ((self.data.get("calibration") or {}).get("cameras", {}).get(photo) or {}).get("marker_residuals_px", {})
        for name, uv in (self.photo(photo).get("marker_observations") or {}).items():
            label = name + (" (origin)" if name == origin else "")
            if name in res:
                label += f"  {np.linalg.norm(res[name]):.2f} px"
            ov.points.append(Point((float(uv[0]), float(uv[1])), ORANGE, 5.0, False, "marker", name, label))
            if cam is not None and name in placed:
                X = placed[name]
                if cam_math.world_to_camera(cam.R, cam.C, X)[2] > 0:
                    q = cam_math.project(cam.K, cam.R, cam.C, X)
                    ov.points.append(Point((float(q[0]), float(q[1])), GREY, 2.5, True, "marker-projected", name))
                    ov.lines.append(Line((float(uv[0]), float(uv[1]), float(q[0]), float(q[1])), MAGENTA, 1.0,
                                         "residual", ("marker", name)))

    def _model_overlay(self, ov: Overlay, photo: str, cam: ImageCamera | None, selected: str | None,
                       skip: set[str] | frozenset[str] = frozenset()) -> None:
        model, x = self._model_now()
        if model is None:
            return
        if cam is None:
            ov.notes.append("this photo has no camera yet: the model is drawn in calibrated photos only")
            return
        self._primitives_overlay(ov, photo, cam, selected, [n.name for n in model.nodes if n.name not in skip])
        self._observations_overlay(ov, photo)

    def _primitives_overlay(self, ov: Overlay, photo: str, cam: ImageCamera, selected: str | None,
                            nodes: Sequence[str]) -> None:
        """The projected edges (white; the selected node's yellow) and handles (fixed: red) of nodes."""
        model, x = self._model_now()
        names = [n for n in nodes if model.node(n).primitive is not None]
        for node, edges in project_edges(model, cam, names, x, self._transforms()).items():
            colour = YELLOW if node == selected else WHITE
            for e, uv4 in edges:
                ov.lines.append(Line(tuple(map(float, uv4)), colour, 2.0 if node == selected else 1.5, "edge",
                                     (node, e)))
        for n, h, uv, fixed in self.handles(photo, names):
            ov.points.append(Point(uv, RED if fixed else (YELLOW if n == selected else WHITE),
                                   5.0 if fixed or n == selected else 3.0, fixed or n == selected,
                                   "pin" if fixed else "handle", (n, h), h if n == selected else None))

    def _observations_overlay(self, ov: Overlay, photo: str) -> None:
        """The user's edges (red) and, after a solve, each fixed vertex's residual (outliers magenta)."""
        for i, e in enumerate(self._edge_docs()):
            if e["photo"] == photo:
                (u1, v1), (u2, v2) = e["points"]
                ov.lines.append(Line((u1, v1, u2, v2), RED, 2.0, "user-edge", i, f"{e['node']}:{e['edge']}"))
        sol = self.data.get("model_solution") or {}
        outliers = " ".join(sol.get("outliers", []))
        if self._drag is None:
            for pin, r in zip(self._pins(), sol.get("pins", []), strict=False):
                if pin["photo"] != photo or (pin["node"], pin["handle"]) != (r["node"], r["handle"]):
                    continue
                u, v = pin["uv"]
                bad = f"pin {r['node']}:{r['handle']} in photo '{photo}'" in outliers
                scale = 10.0  # residuals are a pixel or two: drawn ten times longer to be seen
                ov.lines.append(Line((u, v, u + scale * r["residual_px"][0], v + scale * r["residual_px"][1]),
                                     MAGENTA if bad else CYAN, 3.0 if bad else 1.0, "residual",
                                     (r["node"], r["handle"]),
                                     f"{np.hypot(*r['residual_px']):.2f} px" + (" outlier" if bad else "")))


def _at_limit(j: Any) -> bool:
    lims = getattr(j, "limits", None)
    if lims is None:
        return False
    v = j.values()[0]
    return bool(min(abs(v - lims[0]), abs(v - lims[1])) < 1e-6)


def _merge_nodes(docs: list[dict[str, Any]], solved: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The nodes' documents with joints and sizes from the solved model (other keys kept)."""
    by = {d["name"]: d for d in solved}
    out = []
    for d in docs:
        s = by.get(d["name"], {})
        d = copy.deepcopy(d)
        if "joint" in s:
            d["joint"] = s["joint"]
        if "primitive" in s:
            d["primitive"] = s["primitive"]
        out.append(d)
    return out


def _iterating(progress: Progress | None, text: str) -> Callable[[Iterable[Any]], Iterable[Any]]:
    """An iterator wrapper that reports the share done (the calibration's progress interface)."""
    def wrap(items: Iterable[Any]) -> Iterable[Any]:
        items = list(items)
        for i, item in enumerate(items):
            if progress:
                progress(i / max(len(items), 1), text)
            yield item
        if progress:
            progress(1.0, text)
    return wrap
