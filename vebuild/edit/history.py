"""The modelling screen's history: each edit one transaction (the document restored if the edit
fails or leaves it invalid), undo and redo, and the autosave side file written after every edit so
that a crash loses nothing (:class:`~vebuild.edit.session.EditSession` is made of this and the
marks, modelling and overlay parts)."""

from __future__ import annotations

import contextlib
import copy
import gc
import pickle
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from vebuild.errors import VebuildError
from vebuild.model.undo import UndoStack
from vebuild.project import RESULT_KEYS, Project, autosave_path, load_project, save_project, validate

if TYPE_CHECKING:
    from vebuild.camera import ImageCamera
    from vebuild.model.scene import Model

#: Undo steps kept; older ones are dropped (the autosave and the project file hold the work).
UNDO_DEPTH = 200

_IMMUTABLE = (str, int, float, bool, type(None))


def document_copy(value: Any) -> Any:
    """A deep copy of a project document: its objects and lists copied, its text, numbers, true,
    false and null shared (they cannot change); anything else by :func:`copy.deepcopy`. Half
    of deepcopy's time on a house's document (measured: 65 → 35 ms), copied before every edit."""
    if isinstance(value, dict):
        return {k: v if type(v) in _IMMUTABLE else document_copy(v) for k, v in value.items()}
    if isinstance(value, list):
        return [v if type(v) in _IMMUTABLE else document_copy(v) for v in value]
    return value if type(value) in _IMMUTABLE else copy.deepcopy(value)


#: Paths (keys from the document's root) of what no edit changes in place: a solve replaces each
#: whole. An undo step shares them with the document instead of copying them. The solution's
#: covariance matrix is most of a solved house's document (1,523² numbers): copied, it made an undo
#: step 29 MB (5.8 GB at :data:`UNDO_DEPTH` steps); shared, the rest of the document is 10.6 MB
#: as objects and 2.9 MB packed (:class:`PackedDocument`).
SHARED_IN_SNAPSHOTS: tuple[tuple[str, ...], ...] = (("model_solution", "covariance", "matrix"),)


def document_snapshot(data: Any, shared: tuple[tuple[str, ...], ...] = SHARED_IN_SNAPSHOTS) -> Any:
    """:func:`document_copy` of ``data``, but for the values at the ``shared`` paths: those are the
    document's own (the same objects), so they must only ever be replaced, never changed in place.

    The cyclic garbage collector is held off while it copies: the copy makes no cycles, and on a
    solved house the collections its hundred thousand new objects set off (each going over the
    whole document) had doubled its time (measured: 100 → 45 ms)."""
    was = gc.isenabled()
    gc.disable()
    try:
        return _snapshot(data, shared)
    finally:
        if was:
            gc.enable()


def _snapshot(data: Any, shared: tuple[tuple[str, ...], ...]) -> Any:
    if not shared or not isinstance(data, dict):
        return document_copy(data)
    out = {}
    for k, v in data.items():
        below = tuple(p[1:] for p in shared if p[0] == k)
        if () in below:
            out[k] = v
        elif below:
            out[k] = _snapshot(v, below)
        else:
            out[k] = v if type(v) in _IMMUTABLE else document_copy(v)
    return out


class PackedDocument:
    """An undo step's document, kept as one pickled string (the values at the shared paths beside
    it, by reference): not a hundred thousand objects. On a solved house a step as objects held
    10.6 MB, and every step's objects were gone over by each of the cyclic garbage collector's full
    collections (0.1 s after loading, 0.2 s after five edits, growing with the history); packed,
    2.9 MB and nothing for the collector. Packing takes 15 ms, unpacking (an undo) 0.1 s."""

    __slots__ = ("_blob", "_shared")

    def __init__(self, data: dict[str, Any], shared: tuple[tuple[str, ...], ...] = SHARED_IN_SNAPSHOTS):
        held: list[tuple[tuple[str, ...], Any]] = []
        for path in shared:
            parent = _parent(data, path)
            if parent is not None:
                held.append((path, parent[path[-1]]))
        try:  # the shared values out of the pickle (None in their places, so the keys keep their order)
            for path, _ in held:
                _parent(data, path)[path[-1]] = None  # type: ignore[index]
            self._blob = pickle.dumps(data, protocol=pickle.HIGHEST_PROTOCOL)
        finally:
            for path, value in held:
                _parent(data, path)[path[-1]] = value  # type: ignore[index]
        self._shared = held

    def unpack(self) -> dict[str, Any]:
        """A document of its own, equal to the one packed (the shared values the same objects)."""
        data = pickle.loads(self._blob)
        for path, value in self._shared:
            _parent(data, path)[path[-1]] = value  # type: ignore[index]
        return data

    @property
    def nbytes(self) -> int:
        """The packed string's size (the shared values are the document's own)."""
        return len(self._blob)


def _parent(data: Any, path: tuple[str, ...]) -> dict[str, Any] | None:
    """The object holding ``path``'s last key, where the whole path is there; else None."""
    for key in path[:-1]:
        data = data.get(key) if isinstance(data, dict) else None
    return data if isinstance(data, dict) and path[-1] in data else None


class EditError(VebuildError):
    """A user's edit that cannot be done; the text says why and what to do instead."""


class SessionState:
    """What the parts of an edit session share: the project and the session's state, and the few
    calls each part makes of another (the session provides them)."""

    # Set by EditSession; declared here for the type checker.
    project: Project
    messages: list[str]
    revision: int
    dirty: bool
    autosave: bool
    recovery_available: bool
    _cache: dict[Any, Any]
    _drag: Any
    history: UndoStack[PackedDocument]

    @property
    def data(self) -> dict[str, Any]:
        return self.project.data

    @property
    def autosave_path(self) -> Path:
        return autosave_path(self.project.path)

    def say(self, text: str) -> None:
        self.messages = (self.messages + [text])[-50:]

    def photo(self, photo_id: str) -> dict[str, Any]:
        try:
            return self.project.photo(photo_id)
        except VebuildError as e:
            raise EditError(str(e)) from None

    @property
    def settings(self) -> dict[str, float]:
        return self.project.settings

    if TYPE_CHECKING:
        @property
        def cameras(self) -> dict[str, ImageCamera]: ...

        @property
        def model(self) -> Model | None: ...

        def _camera(self, photo: str) -> ImageCamera: ...


class History(SessionState):
    """Undoable edits and the autosave (mixed into the session)."""

    @contextlib.contextmanager
    def _edit(self, label: str) -> Iterator[None]:
        """One undoable change: the document is restored if the change fails or leaves it invalid."""
        if self._drag is not None and label != "drag":
            raise EditError("finish the drag first (release the mouse button, or Esc to cancel it)")
        before = document_snapshot(self.data)
        try:
            yield
            # Results (calibration, solution, textures) the edit left as they were were valid before
            # it: only the inputs, and results it changed, are validated again (the covariance
            # matrices make a whole validation most of an edit's time).
            kept = [k for k in RESULT_KEYS if k in self.data and self.data[k] == before.get(k)]
            validate({k: v for k, v in self.data.items() if k not in kept}, self.project.path, valid_before=before)
        except VebuildError as e:
            self.project.data = before
            self._cache.clear()
            raise e if isinstance(e, EditError) else EditError(str(e)) from None
        except BaseException:
            self.project.data = before
            self._cache.clear()
            raise
        self.history.push(PackedDocument(before), label)
        rebuilt = self._cache.get("rebuilt-model")  # the edited document's model, its last step
        self._changed()
        if rebuilt is not None:
            self._cache["model"] = rebuilt

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
        return self.history.undo_label

    @property
    def redo_label(self) -> str | None:
        return self.history.redo_label

    def undo(self) -> bool:
        step = None if self._drag is not None else self.history.undo(PackedDocument(self.data))
        if step is None:
            return False
        label, self.project.data = step[0], step[1].unpack()
        self._changed()
        self.say(f"undone: {label}")
        return True

    def redo(self) -> bool:
        step = None if self._drag is not None else self.history.redo(PackedDocument(self.data))
        if step is None:
            return False
        label, self.project.data = step[0], step[1].unpack()
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
