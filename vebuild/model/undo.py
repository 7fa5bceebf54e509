"""Undo and redo over snapshots of a state, each step labelled: the one history the walk-through's
arrangements (:class:`vebuild.model.arrange.ObjectMover`) and the modelling screen's edits
(:mod:`vebuild.edit.history`) both keep."""

from __future__ import annotations

from typing import Generic, TypeVar

T = TypeVar("T")


class UndoStack(Generic[T]):
    """Steps as (label, the state before them); ``depth`` keeps only the latest steps."""

    def __init__(self, depth: int | None = None):
        self.depth = depth
        self._undo: list[tuple[str, T]] = []
        self._redo: list[tuple[str, T]] = []

    def push(self, before: T, label: str = "") -> None:
        """A new step, from state ``before``: what was undone can no longer be redone."""
        self._undo.append((label, before))
        if self.depth is not None and len(self._undo) > self.depth:
            del self._undo[: len(self._undo) - self.depth]
        self._redo.clear()

    def undo(self, now: T) -> tuple[str, T] | None:
        """The last step's label and the state before it (``now`` kept for redo), or None."""
        if not self._undo:
            return None
        label, before = self._undo.pop()
        self._redo.append((label, now))
        return label, before

    def redo(self, now: T) -> tuple[str, T] | None:
        """The last undone step's label and the state after it (``now`` kept for undo), or None."""
        if not self._redo:
            return None
        label, after = self._redo.pop()
        self._undo.append((label, now))
        return label, after

    @property
    def undo_label(self) -> str | None:
        return self._undo[-1][0] if self._undo else None

    @property
    def redo_label(self) -> str | None:
        return self._redo[-1][0] if self._redo else None
