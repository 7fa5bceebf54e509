"""The walk-through's registered laser scans (K), drawn as points over the view (a part of the
:class:`~vebuild.viewer.app.Viewer`)."""

from __future__ import annotations

from typing import Any

from vebuild.errors import VebuildError


class ViewerScans:
    """Scans shown as points (mixed into the Viewer, which provides ``project``, ``say``,
    ``renderer``, ``eye_camera``, ``viewport``, ``stereo`` and ``ctx``)."""

    show_scans = False
    _scan_layer: Any = None

    def toggle_scans(self) -> None:
        """Show or hide the project's registered laser scans (K)."""
        v: Any = self
        if not v.project.data.get("scans"):
            self.show_scans = False
            v.say("the project has no laser scans (vebuild scan add)")
            return
        v.needs_model("Laser scans (drawn against the model's depth)")
        self.show_scans = not self.show_scans
        v.say(f"laser scans {'shown' if self.show_scans else 'hidden'}")

    def scan_layer(self) -> Any:
        """The scans' points on the GPU (:class:`vebuild.gl.points.PointLayer`), read once; None
        where a scan cannot be read (the message says why, and the scans are hidden)."""
        if self._scan_layer is None:
            import numpy as np

            from vebuild.analysis.scans import DRAW_POINTS, scan_points_world
            from vebuild.gl.points import PointLayer

            v: Any = self
            scans = v.project.data.get("scans") or []
            pts, cols = [], []
            try:
                for i in range(len(scans)):
                    P, C = scan_points_world(v.project, i, max(1, DRAW_POINTS // len(scans)))
                    pts.append(P)
                    cols.append(C)
            except VebuildError as e:
                v.say(f"laser scans not shown: {e}")
                self.show_scans = False
                return None
            self._scan_layer = PointLayer(v.ctx)
            self._scan_layer.set_points(np.concatenate(pts), np.concatenate(cols))
        return self._scan_layer

    def _draw_scans(self) -> None:
        layer = self.scan_layer()
        if layer is None:
            return
        v: Any = self
        cam = v.eye_camera()
        x, y, w, h = v.viewport()
        v.ctx.screen.viewport = (x, y, cam.width, cam.height)
        near, far = v.renderer._near_far(cam)
        # The scene's depth is on the screen only for a mono pinhole view drawn straight into it.
        layer.draw(cam, near, far, flip=True, depth_test=v.stereo is None and cam.lens.is_pinhole)
