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

import json
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild import camera as cam_math
from vebuild.camera import ImageCamera
from vebuild.console.tables import camera_group_lines, exif_check_words
from vebuild.errors import VebuildError
from vebuild.model.undo import UndoStack
from vebuild.project import Project, load_project, new_photo_entry
from vebuild.project.images import RAW_SUFFIXES
from vebuild.project.provenance import Stale, stale
from vebuild.project.stills import fixed_camera_groups, prepare_photos, split_word, write_stills
from vebuild.project.video import is_video

from .assist import Assist, Proposal
from .history import UNDO_DEPTH, EditError, PackedDocument
from .marks import AXES, VanishingState
from .modelling import ANCHOR_HANDLE, DEFAULT_PARAMS, FOLLOW_TOL_PX, DragFeedback
from .photo_overlay import SessionOverlays
from .room_clicks import ClickBuild

#: The file name endings of the images "Add all photos" adds (what vebuild reads: camera RAW too).
PHOTO_SUFFIXES = frozenset({".jpg", ".jpeg", ".png", ".tif", ".tiff"}) | RAW_SUFFIXES

Progress = Callable[[float, str], None]

__all__ = ["ANCHOR_HANDLE", "AXES", "DEFAULT_PARAMS", "FOLLOW_TOL_PX", "UNDO_DEPTH", "DragFeedback", "EditError",
           "EditSession", "Proposal", "VanishingState"]


class EditSession(Assist, ClickBuild, SessionOverlays):
    """One project being edited; see the module's docstring. Its parts, by concern: the history
    (:mod:`.history`: edits, undo, autosave), the marks (:mod:`.marks`), the modelling
    (:mod:`.modelling`: primitives, drags, fixes, joints), the relations between faces and sizes
    (:mod:`.relating`), room shells (:mod:`.rooms`) and the overlays (:mod:`.photo_overlay`)."""

    def __init__(self, project: Project, autosave: bool = True):
        self.project = project
        self.autosave = autosave
        self.messages: list[str] = []
        self.revision = 0
        self.dirty = False
        self.history: UndoStack[PackedDocument] = UndoStack(UNDO_DEPTH)
        self._cache: dict[Any, Any] = {}
        self._drag = None  # the drag under way (modelling._Drag)
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

    @property
    def stale(self) -> list[Stale]:
        """The stale results of the project as edited (the toolbar's stale line), once per change."""
        if "stale" not in self._cache:
            self._cache["stale"] = stale(self.data, str(self.project.path))
        return list(self._cache["stale"])

    # -- photos -----------------------------------------------------------------------------------

    @property
    def photo_ids(self) -> list[str]:
        return [p["id"] for p in self.data["photos"]]

    def add_photo(self, path: str | Path, photo_id: str | None = None) -> str:
        """Add an image from the project's folder, its size, SHA-256 and EXIF recorded; a video
        file named with its frame (``clip.mp4@frame=N`` or ``@time=T``) adds that frame as a still."""
        file, key, value = split_word(str(path))
        if key is not None or is_video(file):
            video = Path(file) if Path(file).is_absolute() or Path(file).exists() else self.project.folder / file
            return self._add_still(video, {key: value} if key is not None and value is not None else {})
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

    def add_video_still(self, video: str | Path, frame: int, field: str | None = None) -> str:
        """Add frame ``frame`` (from 0) of a video from the project's folder as a still: a lossless
        PNG beside it, its origin recorded, in the video's camera group (docs/video-stills.md)."""
        return self._add_still(Path(video), {"frame": str(frame)}, field)

    def _add_still(self, video: Path, which: dict[str, str], field: str | None = None) -> str:
        """Add the frame of ``video`` that ``which`` names ({"frame": N} or {"time": T}, as typed)."""
        words = [f"{video}@{k}={v}" for k, v in which.items()] or [str(video)]
        try:
            (prepared,) = prepare_photos(self.project.folder, words, field=field, taken=self.photo_ids)
            write_stills([prepared])
        except VebuildError as e:
            raise EditError(str(e)) from None
        entry = prepared.entry
        with self._edit(f"add photo {entry['id']}"):
            self.data["photos"].append(entry)
            fixed_camera_groups(self.data)
        o = entry["origin"]
        self.say(f"added photo '{entry['id']}': frame {o['frame']} at {o['time']:g} s of {o['video']} "
                 f"({entry['width']}×{entry['height']}, SHA-256 {entry['sha256'][:12]}…)")
        return str(entry["id"])

    def folder_photos(self) -> list[Path]:
        """The image files (:data:`PHOTO_SUFFIXES`) in the project's folder and the folders inside it
        that no photo of the project is made from yet, sorted by their path; hidden ones left out."""
        folder = Path(self.project.folder)
        have = {Path(self.project.photo_path(p)).resolve() for p in self.data["photos"]}
        out = []
        for f in sorted(folder.rglob("*")):
            rel = f.relative_to(folder)
            if any(part.startswith(".") for part in rel.parts) or not f.is_file():
                continue
            if f.suffix.lower() in PHOTO_SUFFIXES and f.resolve() not in have:
                out.append(f)
        return out

    def add_folder_photos(self) -> list[str]:
        """Add every image of :meth:`folder_photos` (one undoable edit); returns their ids. A file
        that is not an image after all is left out and named in the status line."""
        entries, bad = [], []
        taken = set(self.photo_ids)
        for f in self.folder_photos():
            try:
                entry = new_photo_entry(self.project.folder, f, None)
            except VebuildError as e:
                bad.append(f"{f.relative_to(self.project.folder).as_posix()} ({e})")
                continue
            base, k = entry["id"], 2
            while entry["id"] in taken:
                entry["id"] = f"{base}-{k}"
                k += 1
            taken.add(entry["id"])
            entries.append(entry)
        if not entries:
            self.say("no photos in the project's folder that the project lacks"
                     + (f"; not images: {', '.join(bad)}" if bad else ""))
            return []
        with self._edit(f"add {len(entries)} photos"):
            self.data["photos"].extend(entries)
        self.say(f"added {len(entries)} photos from the project's folder: " + ", ".join(e["id"] for e in entries)
                 + (f"; left out, not images: {', '.join(bad)}" if bad else ""))
        return [e["id"] for e in entries]

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

    # -- calibration, solving, re-calibration, registration, textures (paper §2, §3.1, §3.2, §4) -----

    def calibrate(self, progress: Progress | None = None) -> dict[str, Any]:
        """Calibrate every photo with segments and place the cameras (``vebuild calibrate``)."""
        from vebuild.actions.calibrate import calibrate_project

        with self._edit("calibrate"):
            result = calibrate_project(self.project, progress=_iterating(progress, "calibrating photos"))
        lines = [f"{pid}: {c['mode']}, f {c['focal_px']['value']:.1f} ± {c['focal_px']['sigma']:.1f} px, "
                 f"rms {c['rms_px']:.2f} px{exif_text(c)}{placement_text(c)}" for pid, c in result["cameras"].items()]
        self.say("calibrated " + "; ".join(lines))
        for line in camera_group_lines(result.get("camera_groups") or [])[:-1]:
            self.say(line.strip())
        for w in result.get("warnings", []):
            self.say(w)
        return result

    def group_cameras(self, group: str, photos: list[str]) -> None:
        """Say that these photos were taken with one camera (FORMAT.md "Camera groups"): the next
        calibration gives them one focal length, principal point and lens distortion."""
        from vebuild.actions.camera_group_records import apply_group_options

        with self._edit(f"group {', '.join(photos)} as camera '{group}'"):
            apply_group_options(self.data, self.project.path, [f"{group}={','.join(photos)}"], [])
        self.say(f"photos {', '.join(photos)} share camera '{group}': calibrate to solve them together")

    def release_camera(self, photo: str) -> None:
        """Release a photo from its camera group (EXIF's or the user's): its intrinsics become its own."""
        from vebuild.actions.camera_group_records import apply_group_options

        with self._edit(f"release {photo} from its camera group"):
            apply_group_options(self.data, self.project.path, [], [photo])
        self.say(f"photo '{photo}' released from camera groups: calibrate to give it intrinsics of its own")

    @property
    def cameras(self) -> dict[str, ImageCamera]:
        if "cameras" not in self._cache:
            from vebuild.project.decode import cameras

            try:  # the final cameras: re-calibrated where the solution has them
                self._cache["cameras"] = cameras(self.project)
            except VebuildError:
                self._cache["cameras"] = {}
        return self._cache["cameras"]

    def _camera(self, photo: str) -> ImageCamera:
        cam = self.cameras.get(photo)
        if cam is None:
            raise EditError(f"photo '{photo}' has no calibrated camera yet: mark its vanishing segments and "
                            "calibrate, or register it from known points")
        return cam

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
        for w in result.get("warnings", []):
            self.say(w)
        for c in result.get("check_distances", []):
            if c.get("within_ci95") is not None:
                self.say(f"check distance {c['a']}–{c['b']}: {1000 * c['difference_m']:+.1f} ± "
                         f"{1000 * c['difference_sigma_m']:.1f} mm from the tape, "
                         f"{'within' if c['within_ci95'] else 'OUTSIDE'} its 95 % interval")
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
        from vebuild.texture.options import Options

        opts = Options() if texels_per_metre is None else Options(texels_per_metre=texels_per_metre)

        def step(done: int, total: int, text: str) -> None:
            if progress:
                progress(done / max(total, 1), text)

        with self._edit("extract textures"):
            record, _ = texture_project(self.project, opts, progress=step, save=False)
        self.say(f"textures extracted: {len(record['pages'])} page(s)")
        return record


def photo_cameras(data: dict[str, Any]) -> dict[str, str]:
    """Each photo's camera, in words, for the screen's photo list (FORMAT.md "Camera groups"): the
    camera group it shares intrinsics with (the user's or EXIF's), or that it has a camera of its own
    (released from groups where ``own_camera``)."""
    from vebuild.calibration.camera_groups import camera_groups

    out = {p["id"]: "own camera, released from its group" if p.get("own_camera") else "own camera"
           for p in data["photos"]}
    for g in camera_groups(data["photos"], data.get("camera_groups") or []):
        for pid in g.photos:
            out[pid] = f"camera '{g.id}' ({'grouped by you' if g.source == 'user' else 'same EXIF camera'})"
    return out


def exif_text(camera: dict[str, Any]) -> str:
    """What the screen adds to a calibrated photo's line about its EXIF focal length: EXIF relative
    to the vanishing points' estimate, as the console and the report say it, and whether it was
    combined (none where EXIF gives no focal length or the vanishing points alone fix none)."""
    check = camera.get("exif_focal_check")
    if not isinstance(check, dict):
        return ""
    used = "" if "combined" not in check else ", combined" if check["combined"] else ", not combined"
    return f"; {exif_check_words(check)}{used}"


def placement_text(camera: dict[str, Any]) -> str:
    """What the screen adds to a calibrated photo's line: its lens distortion where it has one (k1
    and how far it moves the corners, each with its 1σ, and where k1 came from), and, placed alone,
    its camera's height and where its scale came from, or that its lengths are relative."""
    out = ""
    lens = camera.get("distortion")
    if lens:
        k1, corner = lens["k1"], lens["corner_displacement_px"]
        k2 = lens.get("k2") or {}
        second = (f", k2 {k2['value']:+.4f} ± {k2.get('sigma') or 0.0:.4f}"
                  if k2 and (k2.get("value") or k2.get("sigma")) else "")
        out += (f"; lens k1 {k1['value']:+.4f} ± {k1['sigma'] or 0.0:.4f}{second} ({lens['source']}), corners moved "
                f"{corner['value']:.1f} ± {corner['sigma'] or 0.0:.1f} px")
    where = camera.get("placement") or {}
    if where.get("how") != "alone":
        return out
    if where.get("lengths") == "relative":
        return out + "; placed alone, no scale: lengths are relative (in units of the camera's height)"
    h = where.get("camera_height_m") or {}
    return out + (f"; placed alone, camera {h.get('value', float('nan')):.3f} ± {h.get('sigma') or 0.0:.3f} m above "
                  f"the floor (scale: {where.get('scale', '?')})")


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
