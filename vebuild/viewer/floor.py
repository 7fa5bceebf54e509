"""The walk-through over a project with no model (a part of the :class:`~vebuild.viewer.app.Viewer`):
its calibrated photos, each at its camera (P), with the floor (z = 0) drawn over the photo as a grid
and the world's axes at the origin, through the photo's own lens; off a photo's camera, the grid,
the axes and every calibrated photo's camera as its frustum (the pyramid of its view, the photo's
name at its apex), so that where the photos were taken from can be seen from anywhere.

The grid and the axes are drawn in the photo's pixels by the same projection the calibration
fitted (K, R, C and the lens's k1), so that they lie on the photo where the floor is: a floor
marker's grid point on its click. G shows or hides them (with a model too, where they are hidden
at first).

What needs a model (its textures, lighting presets, objects and their doors, evidence markers on
its surfaces, trajectories and sight lines, laser scans drawn against its depth, screenshots of
it) says so in words (:meth:`FloorOverlay.needs_model`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera, project, undistort_pixels, world_to_camera
from vebuild.errors import VebuildError
from vebuild.project import Project

Array = NDArray[np.float64]

#: Grid lines are 1 m (or, with no scale given, 1 relative unit) apart.
GRID_SPACING = 1.0
#: The grid reaches this many camera heights beyond the farthest camera's foot (and at least
#: GRID_MIN_HALF_SIZE units from the origin).
GRID_REACH_HEIGHTS = 10.0
GRID_MIN_HALF_SIZE = 5
#: The grid fades from this many camera heights from the foot of the view's camera.
GRID_FADE_HEIGHTS = 3.0
#: At most this many lines each way (a camera far from the origin: the grid stays drawable).
GRID_MAX_HALF_SIZE = 100
#: Pieces each grid line is cut into, so that a lens's distortion bends it as it bends the floor.
GRID_PIECES = 96
#: Through a distorting lens, a piece is cut again into pieces at most this long in the image
#: (pixels), at most MAX_CUTS of them: a 16 px chord of a bent line strays well under a pixel.
MAX_PIECE_PX = 16.0
MAX_CUTS = 64
#: Nothing nearer the eye than this (m) is drawn: a line is cut where it passes behind the camera.
NEAR_M = 0.02
GRID_RGBA = (1.0, 1.0, 1.0, 0.75)
AXIS_RGBA = {"x": (1.0, 0.2, 0.2, 1.0), "y": (0.25, 0.95, 0.3, 1.0), "z": (0.3, 0.55, 1.0, 1.0)}
FRUSTUM_RGBA = (1.0, 0.55, 0.1, 1.0)
#: A frustum's depth, as a share of its camera's height above the floor.
FRUSTUM_DEPTH_SHARE = 0.5


def needs_model_error(what: str) -> VebuildError:
    """The sentence a command that needs a model says on a project with none."""
    return VebuildError(f"{what}: this needs a model, and the project has none yet; the walk-through shows its "
                        "calibrated photos (P), the floor grid and the axes, and measures on a photo alone (T). "
                        "Build the model in the modelling screen (`vebuild edit`) and solve it (`vebuild solve`)")


def project_has_model(project: Project) -> bool:
    """Whether the project has a model to draw (nodes; solved or not)."""
    return bool((project.data.get("model") or {}).get("nodes"))


def check_viewable(project: Project) -> None:
    """A project the walk-through can show: a model, or at least one calibrated photo."""
    from vebuild.project.decode import camera_records

    if project_has_model(project) or camera_records(project.data):
        return
    raise VebuildError(f"{project.path}: the project has no model yet and no calibrated photo to show; calibrate "
                       "its photos (`vebuild calibrate`, or Calibrate in the modelling screen, `vebuild edit`) to "
                       "see each at its camera with the floor drawn over it, or build and solve a model")


def clip_to_front(cam: ImageCamera, a: Array, b: Array, near: float = NEAR_M) -> tuple[Array, Array] | None:
    """The part of the segment a–b in front of ``cam`` (depth ≥ ``near``), or None."""
    za, zb = (float(world_to_camera(cam.R, cam.C, p[None, :])[0, 2]) for p in (a, b))
    if za < near and zb < near:
        return None
    if za < near:
        a = a + (b - a) * (near - za) / (zb - za)
    elif zb < near:
        b = b + (a - b) * (near - zb) / (za - zb)
    return a, b


def polyline(cam: ImageCamera, a: Array, b: Array, pieces: int = 1) -> Array | None:
    """The pixels (n, 2) of the world segment a–b seen by ``cam`` (through its lens), cut into
    ``pieces`` so that a distorting lens bends it; None where it lies wholly behind the camera."""
    both = polyline_points(cam, a, b, pieces)
    return None if both is None else both[1]


def polyline_points(cam: ImageCamera, a: Array, b: Array, pieces: int = 1) -> tuple[Array, Array] | None:
    """:func:`polyline`'s world points (n, 3) and their pixels (n, 2): ``pieces`` even steps along
    the segment, each cut again, through a distorting lens, into pieces of at most MAX_PIECE_PX."""
    front = clip_to_front(cam, np.asarray(a, float), np.asarray(b, float))
    if front is None:
        return None
    a, b = front
    t = np.linspace(0.0, 1.0, pieces + 1)
    uv: Array = project(cam.K, cam.R, cam.C, a[None, :] + t[:, None] * (b - a)[None, :], cam.lens)
    if not cam.lens.is_pinhole:
        with np.errstate(invalid="ignore"):
            cuts = np.clip(np.ceil(np.linalg.norm(np.diff(uv, axis=0), axis=1) / MAX_PIECE_PX), 1, MAX_CUTS)
        cuts = np.where(np.isfinite(cuts), cuts, 1).astype(int)
        t = np.concatenate([np.linspace(t[k], t[k + 1], n, endpoint=False) for k, n in enumerate(cuts)] + [t[-1:]])
        uv = project(cam.K, cam.R, cam.C, a[None, :] + t[:, None] * (b - a)[None, :], cam.lens)
    pts = a[None, :] + t[:, None] * (b - a)[None, :]
    return pts, uv


def grid_fade(cam: ImageCamera, P: Array) -> Array:
    """How much of the grid's colour floor points keep (1 near, 0 far): full to GRID_FADE_HEIGHTS
    camera heights from the foot of the view's camera, none at GRID_REACH_HEIGHTS, so that the
    lines crowding at the horizon (the floor goes on behind the walls) fade away."""
    h = max(abs(float(cam.C[2])), 0.1)
    d = np.hypot(P[:, 0] - float(cam.C[0]), P[:, 1] - float(cam.C[1]))
    near, far = GRID_FADE_HEIGHTS * h, GRID_REACH_HEIGHTS * h
    out: Array = np.clip((far - d) / (far - near), 0.0, 1.0)
    return out


def grid_half_size(cameras: list[ImageCamera]) -> int:
    """How many grid lines each way from the origin: the cameras' feet and the floor they see."""
    if not cameras:
        return GRID_MIN_HALF_SIZE
    reach = max(math.hypot(float(c.C[0]), float(c.C[1])) + GRID_REACH_HEIGHTS * abs(float(c.C[2])) for c in cameras)
    return int(min(GRID_MAX_HALF_SIZE, max(GRID_MIN_HALF_SIZE, math.ceil(reach / GRID_SPACING))))


def grid_segments(half: int, spacing: float = GRID_SPACING) -> list[tuple[Array, Array]]:
    """The floor grid's lines, x = const then y = const, from −half to +half spacings."""
    L = half * spacing
    out = [(np.array([i * spacing, -L, 0.0]), np.array([i * spacing, L, 0.0])) for i in range(-half, half + 1)]
    out += [(np.array([-L, i * spacing, 0.0]), np.array([L, i * spacing, 0.0])) for i in range(-half, half + 1)]
    return out


def frustum_segments(cam: ImageCamera) -> list[tuple[Array, Array]]:
    """A photo's camera as lines: apex to the photo's corners at a depth, the corners' rectangle
    (the photo's frame through its lens), and the plumb line from the camera to the floor."""
    depth = max(0.05, FRUSTUM_DEPTH_SHARE * abs(float(cam.C[2])))
    w, h = float(cam.width), float(cam.height)
    corners_px = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
    pin = undistort_pixels(cam.K, corners_px, cam.lens)
    x = np.linalg.solve(cam.K, np.c_[pin, np.ones(4)].T).T  # camera coordinates at depth 1
    corners = cam.C[None, :] + depth * x @ cam.R  # Rᵀ x for each row
    C = np.asarray(cam.C, float)
    out = [(C, c) for c in corners] + [(corners[k], corners[(k + 1) % 4]) for k in range(4)]
    out.append((C, np.array([C[0], C[1], 0.0])))
    return out


class FloorOverlay:
    """The floor grid, the axes and the photos' frustums over the view (mixed into the Viewer,
    which provides ``project``, ``photo``, ``camera``, ``viewport``, ``window``, ``say`` and
    ``has_model``)."""

    show_floor: bool = False

    def needs_model(self, what: str) -> None:
        """Refuse ``what`` in words where the project has no model."""
        v: Any = self
        if not v.has_model:
            raise needs_model_error(what)

    def toggle_floor(self) -> None:
        """G: the floor grid and the axes shown or hidden."""
        v: Any = self
        self.show_floor = not self.show_floor
        v.say(f"floor grid (1 {self.grid_unit()} apart) and axes at the origin "
              f"{'shown' if self.show_floor else 'hidden'}")

    def grid_unit(self) -> str:
        """'m', or where no length was given (the camera's height above the floor is 1), 'unit'."""
        v: Any = self
        lengths = (v.project.data.get("calibration") or {}).get("lengths")
        return "unit" if lengths == "relative" else "m"

    def photo_cameras(self) -> list[ImageCamera]:
        """The calibrated photos' cameras (those that cannot be read are left out)."""
        from vebuild.project.decode import camera_records, photo_camera

        v: Any = self
        key = id(v.project.data.get("calibration"))
        if self.__dict__.get("_cams_key") != key:
            cams = []
            for pid in camera_records(v.project.data):
                try:
                    cams.append(photo_camera(v.project, pid))
                except VebuildError:
                    continue
            self.__dict__["_cams"], self.__dict__["_cams_key"] = cams, key
        out: list[ImageCamera] = self.__dict__["_cams"]
        return out

    def _window(self, uv: Array) -> list[tuple[float, float]]:
        """Window points (ImGui's) of pixels of the view's camera."""
        v: Any = self
        import glfw

        W, H = v.window.framebuffer_size()
        ww, wh = glfw.get_window_size(v.window.handle)
        sx, sy = W / max(ww, 1), H / max(wh, 1)
        vx, vy, _, vh = v.viewport()
        return [((vx + float(u)) / sx, (H - vy - vh + float(w)) / sy) for u, w in uv]

    def _line(self, imgui: Any, dl: Any, cam: ImageCamera, a: Array, b: Array, rgba: tuple[float, ...],
              width: float, pieces: int, fade: bool = False) -> None:
        """A world segment drawn in ``rgba``, faded with distance where ``fade`` (the grid)."""
        both = polyline_points(cam, a, b, pieces)
        if both is None or not np.isfinite(both[1]).all():
            return
        P, uv = both
        alpha = grid_fade(cam, 0.5 * (P[:-1] + P[1:])) if fade else np.ones(len(P) - 1)
        pts = [imgui.ImVec2(x, y) for x, y in self._window(uv)]
        for p, q, f in zip(pts[:-1], pts[1:], alpha, strict=True):
            if f > 0.02:
                dl.add_line(p, q, imgui.get_color_u32(imgui.ImVec4(rgba[0], rgba[1], rgba[2], rgba[3] * float(f))),
                            width)

    def draw_floor(self, imgui: Any) -> None:
        """The grid, the axes and (off a photo's camera) the photos' frustums, clipped to the view;
        called by the panel between its frame's start and end (under its windows)."""
        v: Any = self
        if not self.show_floor or v.stereo is not None:
            return
        cam = v.camera()
        dl = imgui.get_background_draw_list()  # over the photo, under the panel
        x0, y0 = self._window(np.array([[0.0, 0.0]]))[0]
        x1, y1 = self._window(np.array([[float(cam.width), float(cam.height)]]))[0]
        dl.push_clip_rect(imgui.ImVec2(x0, y0), imgui.ImVec2(x1, y1), True)
        for a, b in grid_segments(grid_half_size(self.photo_cameras())):
            self._line(imgui, dl, cam, a, b, GRID_RGBA, 1.5, GRID_PIECES, fade=True)
        if v.photo is None:
            orange = imgui.get_color_u32(imgui.ImVec4(*FRUSTUM_RGBA))
            for pc in self.photo_cameras():
                for a, b in frustum_segments(pc):
                    self._line(imgui, dl, cam, a, b, FRUSTUM_RGBA, 1.5, 8)
                if world_to_camera(cam.R, cam.C, pc.C[None, :])[0, 2] > NEAR_M:
                    (p,) = self._window(project(cam.K, cam.R, cam.C, pc.C[None, :], cam.lens))
                    dl.add_text(imgui.ImVec2(p[0] + 6, p[1] - 16), orange, f"photo {pc.id}")
        for k, axis in enumerate("xyz"):
            colour = imgui.get_color_u32(imgui.ImVec4(*AXIS_RGBA[axis]))
            end = np.zeros(3)
            end[k] = GRID_SPACING
            self._line(imgui, dl, cam, np.zeros(3), end, AXIS_RGBA[axis], 2.5, 16)
            tip = polyline(cam, end, end + 0.15 * GRID_SPACING * np.eye(3)[k])
            if tip is not None:
                (p,) = self._window(tip[-1:])
                dl.add_text(imgui.ImVec2(p[0] + 3, p[1] - 8), colour, axis)
        dl.pop_clip_rect()
