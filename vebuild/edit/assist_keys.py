"""The modelling screen's proposal keys over every photo at once: Shift+D detects on every photo
(x chosen from the markers the photos share), W suggests markers in every calibrated photo, Q
accepts every photo's proposals (one undoable edit). The session does the work
(:class:`vebuild.edit.assist.Assist`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from collections.abc import Callable


class AssistKeys:
    """Mixed into the screen (:class:`vebuild.edit.screen.Editor`)."""

    if TYPE_CHECKING:
        session: Any

        photo: str | None

        def alt_held(self) -> bool: ...

        def say(self, text: str) -> None: ...

        def _long(self, title: str, fn: Callable[[Callable[[float, str], None]], Any]) -> tuple[Any, str | None]: ...

    def detect_everywhere(self) -> None:
        """Shift+D: every photo's detected segments proposed, each photo's x from the markers."""
        self._long("detecting lines on every photo", lambda progress: self.session.detect_everywhere())

    def suggest_markers_everywhere(self) -> None:
        """W: the markers placed elsewhere suggested in every calibrated photo."""
        self._long("suggesting markers", lambda progress: self.session.suggest_markers_everywhere())

    def snap_release(self, uv: tuple[float, float]) -> tuple[float, float]:
        """A dragged vertex's release point: snapped to the image corner near it unless Alt is held
        (the status line says how far it moved)."""
        if self.photo is None:
            return uv
        at, snap = self.session.snap_vertex(self.photo, uv, exact=self.alt_held())
        if snap is not None:
            self.say(f"released at the image corner {snap.moved_px:.1f} px away (σ {snap.sigma_px:.2f} px; hold "
                     "Alt to release exactly)")
        return at

    def draw_rename_field(self, panels: Any) -> None:
        """The Calibration tab's marker rename field (:mod:`vebuild.edit.rename_field`)."""
        from .rename_field import rename_field

        rename_field(panels)

    def accept_everywhere(self) -> None:
        """Q: every photo's proposals accepted (one undoable edit)."""
        self._long("accepting every proposal", lambda progress: self.session.accept_everywhere())
