"""The modelling screen's 3-D preview: the model drawn with the renderer from an orbiting camera
(textured once textures are extracted), redrawn when the model or the view changes."""

from __future__ import annotations

import copy
import math
import time
from typing import Any

import numpy as np
from imgui_bundle import imgui

from vebuild.camera import ImageCamera, fov_to_focal, intrinsic_matrix, look_rotation
from vebuild.errors import VebuildError

from .layout import CLICK_SLOP_PX, PANEL_W, PREVIEW_FOV_DEG, PREVIEW_H, EditorPart, u32

#: Without a photo's camera inside the model, the first view is this share of the way from the
#: model's centre to its box's side (inside a room).
INSIDE_SHARE = 0.7
#: During a drag the preview is drawn again at most this often (seconds), and only when its last
#: frame at all (drawn at rest, its scene made afresh) took under this share of that period: a
#: model whose preview is slow to draw does not pay for one slow frame in its first drag to learn it.
PREVIEW_DRAG_PERIOD_S = 0.5
PREVIEW_DRAG_SHARE = 0.3
#: ... and only when its last frame in a drag took under this (seconds): a preview frame is drawn
#: between two of the drag's moves, and a longer one stalls the drag (on the house of 522
#: primitives, 110 ms every half second, where a move takes 8 ms), so it waits for the release.
PREVIEW_DRAG_FRAME_S = 0.05


class Preview(EditorPart):
    """The 3-D preview (a part of the Editor)."""

    def preview_camera(self) -> ImageCamera | None:
        r = self._renderer
        if r is None:
            return None
        lo, hi = r.scene.bounds()
        if self.preview_distance is None:
            self._preview_target = self._preview_inside(lo, hi, 0.5 * (lo + hi))
        target = self.__dict__.get("_preview_target")
        target = 0.5 * (lo + hi) if target is None else target
        cp, sp = math.cos(self.preview_pitch), math.sin(self.preview_pitch)
        C = target + self.preview_distance * np.array([cp * math.cos(self.preview_yaw),
                                                       cp * math.sin(self.preview_yaw), sp])
        w, h = self.preview_size
        f = fov_to_focal(math.radians(PREVIEW_FOV_DEG), w)
        return ImageCamera("preview", intrinsic_matrix(f, w / 2, h / 2), look_rotation(target - C), C, w, h)

    def _preview_inside(self, lo: Any, hi: Any, target: Any) -> Any:
        """The first view, from inside the model's box; returns the point it orbits. From the shown
        photo's camera where that is inside the box, looking as the photo does (the room as the
        photo shows it, orbiting the point of its view axis as deep as the box's centre), else
        from :data:`INSIDE_SHARE` of the way from the centre to the box's side, looking at the
        centre."""
        cam = self.session.cameras.get(self.photo) if self.photo is not None else None
        d = None
        if cam is not None and np.all(np.asarray(cam.C) > lo) and np.all(np.asarray(cam.C) < hi):
            C, forward = np.asarray(cam.C, float), np.asarray(cam.R, float)[2]
            target = C + max(float((target - C) @ forward), 0.5) * forward
            d = C - target
        if d is None or float(np.linalg.norm(d)) < 1e-3:
            half = 0.5 * (np.asarray(hi, float) - np.asarray(lo, float))
            cp, sp = math.cos(self.preview_pitch), math.sin(self.preview_pitch)
            u = np.array([cp * math.cos(self.preview_yaw), cp * math.sin(self.preview_yaw), sp])
            reach = min(half[k] / abs(u[k]) for k in range(3) if abs(u[k]) > 1e-9)  # to the box's side
            d = INSIDE_SHARE * max(reach, 0.5) * u
        n = float(np.linalg.norm(d))
        self.preview_distance = n
        self.preview_yaw = math.atan2(d[1], d[0])
        self.preview_pitch = math.asin(float(np.clip(d[2] / n, -1.0, 1.0)))
        return target

    def preview_from_outside(self) -> None:
        """The preview's camera outside the model's box (the whole model in view)."""
        r = self._renderer
        if r is not None:
            lo, hi = r.scene.bounds()
            self._preview_target = 0.5 * (lo + hi)
            self.preview_distance = max(1.0, 1.2 * float(np.linalg.norm(hi - lo)))

    def _preview_scene(self, model: Any) -> Any:
        """The model as a render scene: the last one's faces and pages when only the sizes and
        joints changed (half the time), else laid out anew (with the textures, if any)."""
        from vebuild.render.scene import load_scene, scene_from_model

        record = self.session.data.get("textures")
        pages_key = tuple(p.get("atlas_sha256") for p in record.get("pages", [])) if record else ()
        shape = (tuple((n.name, n.primitive.TYPE if n.primitive is not None else None) for n in model.nodes),
                 pages_key)
        r = self._renderer
        if r is not None and shape == self._preview_shape:
            try:
                return r.scene.with_model(model)
            except (ValueError, KeyError):
                pass
        self._preview_shape = shape
        if record is None:
            return scene_from_model(model)
        if self._preview_pages is None or self._preview_pages[0] != pages_key:
            try:
                pages = load_scene(self.session.project).pages
            except VebuildError as e:
                self.say(f"3-D preview untextured: {e}")
                pages = []
            self._preview_pages = (pages_key, pages)
        return scene_from_model(model, record if self._preview_pages[1] else None, self._preview_pages[1])

    def _update_preview(self) -> None:
        s = self.session
        key = (s.revision, self.preview_yaw, self.preview_pitch, self.preview_distance, self.selected)
        if s.dragging:  # the photo view follows the drag on every move; the preview, every so often
            self._preview_follow_drag()
            return
        if key == self._preview_key:
            return
        model = s.model
        if model is None or not any(n.primitive is not None for n in model.nodes):
            self.preview_note = "no model yet"
            self._preview_key = key
            return
        from vebuild.render.renderer import Renderer, RenderOptions

        try:
            t0 = time.perf_counter()
            scene = self._preview_scene(model)
            pages = self._preview_shape[1]
            if self._renderer is not None and self._renderer_pages != pages:  # new textures: new pages
                self._renderer.release()
                self._renderer = None
            if self._renderer is None:
                self._renderer = Renderer(self.ctx, scene, RenderOptions(samples=1, anisotropy=1.0,
                                                                         trilinear=False, shadows=False))
                self._renderer_pages = pages
            else:
                self._renderer.set_scene(scene)
            self._renderer.highlight = self.selected
            cam = self.preview_camera()
            self._preview_tex = self._renderer.frame(cam)
            self._preview_frame_s = time.perf_counter() - t0  # the scene made and drawn
            self._preview_scans(cam)
            self.preview_note = ""
        except VebuildError as e:
            self.preview_note = str(e)
        self._preview_key = (s.revision, self.preview_yaw, self.preview_pitch, self.preview_distance, self.selected)

    def _preview_follow_drag(self) -> None:
        """During a drag, the preview drawn again with the drag's model at most every
        :data:`PREVIEW_DRAG_PERIOD_S`, and only where its last frame at all took less than
        :data:`PREVIEW_DRAG_SHARE` of that and its last frame in a drag less than
        :data:`PREVIEW_DRAG_FRAME_S` (a slow renderer or a large model leaves it for the release)."""
        d, r = self.session._drag, self._renderer
        now = time.perf_counter()
        follow = self.__dict__.get("_preview_follow")  # (the drag, when last drawn, its seconds)
        if follow is not None and follow[0] is d and now - follow[1] < PREVIEW_DRAG_PERIOD_S:
            return
        if follow is not None and follow[2] > PREVIEW_DRAG_FRAME_S:
            return
        at_rest = self.__dict__.get("_preview_frame_s", 0.0)
        if r is None or d is None or at_rest > PREVIEW_DRAG_SHARE * PREVIEW_DRAG_PERIOD_S:
            return
        try:
            model = copy.deepcopy(d.model)  # the session's model stays as it was until the drag is kept
            model.set_vector(d.x_good)
            r.set_scene(r.scene.with_model(model))
            cam = self.preview_camera()
            self._preview_tex = r.frame(cam)
        except (VebuildError, ValueError, KeyError):
            return
        self._preview_follow = (d, now, time.perf_counter() - now)
        self._preview_key = None  # drawn again from the project's model after the drag

    def _draw_preview_image(self) -> None:
        """The preview's image alone, where the last whole frame drew it (a drag's frames copy the
        rest of the panels from the frame of the press)."""
        r = self.widget_rects.get("preview")
        if r is not None and self._preview_tex is not None and not self.preview_note:
            imgui.get_background_draw_list().add_image(self.gui.texture_ref(self._preview_tex), r[:2], r[2:])

    def preview_following(self) -> bool:
        """Whether the preview has been drawn during this drag (then every frame of the drag shows it)."""
        follow = self.__dict__.get("_preview_follow")
        return follow is not None and self.session.dragging and follow[0] is self.session._drag

    def toggle_preview_scans(self) -> None:
        """Show or hide the project's laser scans in the 3-D preview (Ctrl+L)."""
        if not self.session.project.data.get("scans"):
            self.session.say("the project has no laser scans (vebuild scan add)")
            return
        self.preview_scans = getattr(self, "preview_scans", True) is False
        self._preview_key = None  # drawn again
        self.session.say(f"laser scans {'shown' if self.preview_scans else 'hidden'} in the 3-D preview")

    def _preview_scans(self, cam: ImageCamera | None) -> None:
        """The project's registered laser scans as points over the preview (where it has any and
        ``preview_scans`` is not False); a scan that cannot be read is named in the note instead."""
        scans = self.session.project.data.get("scans") or []
        if cam is None or not scans or getattr(self, "preview_scans", True) is False:
            return
        from vebuild.analysis.scans import DRAW_POINTS, scan_points_world
        from vebuild.gl.points import PointLayer

        key = tuple((e["file"], e["sha256"], repr(e["registration"]["similarity"])) for e in scans)
        layer = getattr(self, "_scan_layer", None)
        if layer is None or getattr(self, "_scan_key", None) != key:
            pts, cols = [], []
            try:
                for i in range(len(scans)):
                    P, C = scan_points_world(self.session.project, i, max(1, DRAW_POINTS // len(scans)))
                    pts.append(P)
                    cols.append(C)
            except VebuildError as e:
                self.preview_scans = False
                self.session.say(f"laser scans not shown: {e}")
                return
            if layer is None:
                layer = self._scan_layer = PointLayer(self.ctx)
            layer.set_points(np.concatenate(pts), np.concatenate(cols))
            self._scan_key = key
        draw_points_over_frame(self._renderer, cam, layer)

    def _draw_preview(self) -> None:
        W, H = self.size()
        self.fixed_window("3-D preview", (W - PANEL_W, H - PREVIEW_H, W, H), 0)
        w, h = self.preview_size
        if self._preview_tex is not None and not self.preview_note:
            imgui.image(self.gui.texture_ref(self._preview_tex), (w, h))
        else:
            imgui.dummy((w, h))
            mn = imgui.get_item_rect_min()
            imgui.get_window_draw_list().add_text((mn.x + 10, mn.y + 10), u32((0.8, 0.8, 0.8, 1)),
                                                  self.preview_note or "no model yet")
        self.rect("preview")
        if imgui.is_item_hovered():
            io = imgui.get_io()
            moved = imgui.get_mouse_drag_delta(imgui.MouseButton_.left, 0.0)
            if imgui.is_mouse_released(imgui.MouseButton_.left) and math.hypot(moved.x, moved.y) <= CLICK_SLOP_PX:
                mn = imgui.get_item_rect_min()  # a click, not an orbit: name the corner or face there
                self.guard(self.pick_in_preview, io.mouse_pos.x - mn.x, io.mouse_pos.y - mn.y)
            if imgui.is_mouse_dragging(imgui.MouseButton_.left):
                d = io.mouse_delta
                self.preview_yaw -= 0.01 * d.x
                self.preview_pitch = float(np.clip(self.preview_pitch + 0.01 * d.y, -1.5, 1.5))
            if io.mouse_wheel and self.preview_distance is not None:
                self.preview_distance *= 0.9 ** io.mouse_wheel
        imgui.end()


def draw_points_over_frame(renderer: Any, cam: ImageCamera, layer: Any) -> None:
    """Draw ``layer`` (a :class:`vebuild.gl.points.PointLayer`) over the frame ``renderer.frame(cam)``
    just drew, depth-tested against it, into the texture it returned."""
    near, far = renderer._near_far(cam)
    draw, resolve, _ = renderer._target(cam.width, cam.height, "output")  # the frame's own targets (cached)
    draw.use()
    draw.viewport = (0, 0, cam.width, cam.height)
    layer.draw(cam, near, far, flip=False, depth_test=cam.lens.is_pinhole)
    if draw is not resolve:
        renderer.ctx.copy_framebuffer(resolve, draw)
