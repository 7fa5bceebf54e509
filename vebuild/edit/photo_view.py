"""The modelling screen's photo view: the photos as textures (full resolution, a few kept; the
strip's thumbnails), the overlay drawn over the photo, the stroke being drawn, the magnifier, and
the cached frame that keeps a drag's redraw to what moves."""

from __future__ import annotations

import math
import time
from typing import Any

import glfw
import moderngl
import numpy as np
from imgui_bundle import imgui

from vebuild.errors import VebuildError

from .layout import (
    MAGNIFIER_PX,
    MAGNIFIER_ZOOM,
    NEAREST_ABOVE_ZOOM,
    PANEL_W,
    PHOTO_CACHE,
    STRIP_H,
    THUMB_H,
    EditorPart,
    u32,
)
from .overlay import AXIS_COLOURS, RED, WHITE, Overlay
from .visibility import clip_polyline, clip_segment

#: A model edge's hidden parts: dashes and gaps this long (window pixels), this opaque and wide.
HIDDEN_DASH_PX = 5.0
HIDDEN_ALPHA = 0.5
HIDDEN_WIDTH = 1.0
#: A vanishing segment the calibration left out: half the arms of the cross at its middle, window pixels.
CROSS_HALF_PX = 6.0


class PhotoView(EditorPart):
    """The photo and what is drawn over it (a part of the Editor)."""

    def _photo_texture(self, photo: str) -> moderngl.Texture | None:
        tex = self._photo_tex.get(photo)
        if tex is not None:
            self._photo_tex[photo] = self._photo_tex.pop(photo)  # most recently used last
            return tex
        try:
            pixels = self.session.photo_pixels(photo)
        except VebuildError as e:
            self._photo_errors[photo] = str(e)
            return None
        self._photo_errors.pop(photo, None)
        h, w = pixels.shape[:2]
        tex = self.ctx.texture((w, h), 3, np.ascontiguousarray(pixels, np.uint8).tobytes(), alignment=1)
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_NEAREST, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = False
        self._photo_tex[photo] = tex
        if photo not in self._thumbs:
            self._thumbs[photo] = self._make_thumb(pixels)
        while len(self._photo_tex) > PHOTO_CACHE:
            old = next(iter(self._photo_tex))
            self.gui.forget_texture(self._photo_tex[old])
            self._photo_tex.pop(old).release()
        return tex

    def _make_thumb(self, pixels: np.ndarray) -> moderngl.Texture:
        from PIL import Image

        h, w = pixels.shape[:2]
        im = Image.fromarray(pixels).resize((max(1, round(w * THUMB_H / h)), THUMB_H), Image.Resampling.BOX)
        t = self.ctx.texture(im.size, 3, im.tobytes(), alignment=1)
        t.filter = (moderngl.LINEAR, moderngl.LINEAR)
        return t

    def _load_next_thumbnail(self) -> None:
        """One missing thumbnail per frame (each photo is read once)."""
        for pid in self.session.photo_ids:
            if pid not in self._thumbs:
                try:
                    self._thumbs[pid] = self._make_thumb(self.session.photo_pixels(pid))
                except VebuildError as e:
                    self._photo_errors[pid] = str(e)
                    self._thumbs[pid] = None
                return

    def _view_pixels(self, fb_size: tuple[int, int]) -> tuple[int, int, int, int]:
        """The photo view in framebuffer pixels (x0, y0, x1, y1), rows from the top."""
        W, H = self.size()
        sx, sy = fb_size[0] / max(W, 1), fb_size[1] / max(H, 1)
        x0, y0, x1, y1 = self.view_rect()
        return (int(math.floor(x0 * sx)), int(math.floor(y0 * sy)), int(math.ceil(x1 * sx)),
                int(math.ceil(y1 * sy)))

    def _view_uncovered(self, fb_size: tuple[int, int]) -> list[tuple[int, int, int, int]]:
        """The parts of the photo view (framebuffer pixels, rows from the top) that the photo does
        not cover: at most four bands (a software renderer clears a small band much faster than the
        whole view)."""
        vx0, vy0, vx1, vy1 = self._view_pixels(fb_size)
        if self.photo is None or self._photo_tex.get(self.photo) is None:
            return [(vx0, vy0, vx1, vy1)]
        W, H = self.size()
        sx, sy = fb_size[0] / max(W, 1), fb_size[1] / max(H, 1)
        w, h = self.photo_size()
        px0, py0 = self.image_to_window(None, (0, 0))
        px1, py1 = self.image_to_window(None, (w, h))
        # The photo's inner whole pixels: a band of one pixel overlaps its edge rather than a gap.
        cx0 = min(max(int(math.ceil(px0 * sx)), vx0), vx1)
        cy0 = min(max(int(math.ceil(py0 * sy)), vy0), vy1)
        cx1 = max(min(int(math.floor(px1 * sx)), vx1), cx0)
        cy1 = max(min(int(math.floor(py1 * sy)), vy1), cy0)
        bands = [(vx0, vy0, vx1, cy0), (vx0, cy1, vx1, vy1), (vx0, cy0, cx0, cy1), (cx1, cy0, vx1, cy1)]
        return [b for b in bands if b[2] > b[0] and b[3] > b[1]]

    def _cache_frame(self, fb_size: tuple[int, int]) -> None:
        """Keep the frame just drawn, for the drag that this press may begin."""
        if self._frame_cache is None or self._frame_cache.size != fb_size:
            self._release_frame_cache()
            self._frame_cache_rb = self.ctx.renderbuffer(fb_size, 4)
            self._frame_cache = self.ctx.framebuffer(color_attachments=[self._frame_cache_rb])
        self.ctx.copy_framebuffer(self._frame_cache, self.surface.fbo)
        self._frame_cache_press = self._press  # the press itself (an id could be reused by the next)
        self._frame_cache_serial += 1

    def _cache_still_view(self, fbo: moderngl.Framebuffer, fb_size: tuple[int, int]) -> None:
        """The frame of the press with the photo view redrawn without the moving primitives, kept
        for the moves of this drag (drawn anew if the view is zoomed or panned meanwhile)."""
        key = (self._frame_cache_serial, self.photo, self.zoom, self.pan, self.selected, fb_size)
        if key == self._view_cache_key and self._view_cache is not None:
            return
        assert self._frame_cache is not None  # a drag's first frame is cached (_drag_frame_cached)
        self.ctx.copy_framebuffer(fbo, self._frame_cache)
        for x0, y0, x1, y1 in self._view_uncovered(fb_size):  # the photo covers the rest
            fbo.clear(0.11, 0.11, 0.12, 1.0, viewport=(x0, fb_size[1] - y1, x1 - x0, y1 - y0))
        self.gui.new_frame()
        self._draw_photo_view("still")
        self.gui.render()
        if self._view_cache is None or self._view_cache.size != fb_size:
            if self._view_cache is not None and self._view_cache_rb is not None:
                self._view_cache.release()
                self._view_cache_rb.release()
            self._view_cache_rb = self.ctx.renderbuffer(fb_size, 4)
            self._view_cache = self.ctx.framebuffer(color_attachments=[self._view_cache_rb])
        self.ctx.copy_framebuffer(self._view_cache, fbo)
        self._view_cache_key = key

    def _drag_frame_cached(self, fb_size: tuple[int, int]) -> bool:
        return (self.session.dragging and self._busy is None and self._frame_cache is not None
                and self._frame_cache.size == fb_size and self._press is not None
                and self._frame_cache_press is self._press)

    def _release_frame_cache(self) -> None:
        for fb, rb in ((self._frame_cache, self._frame_cache_rb), (self._view_cache, self._view_cache_rb)):
            if fb is not None and rb is not None:
                fb.release()
                rb.release()
        self._frame_cache = self._view_cache = None
        self._view_cache_key = None

    def _draw_photo_view(self, layer: str = "all") -> None:
        """The photo and what is drawn over it; during a drag, ``still`` (the photo and what does
        not move) or ``moving`` (the moving primitives and the stroke), drawn over the other."""
        dl = imgui.get_background_draw_list()
        x0, y0, x1, y1 = self.view_rect()
        dl.push_clip_rect((x0, y0), (x1, y1), False)
        if layer == "moving":
            t0 = time.perf_counter()
            layers = self.guard(self.session.overlay_layers, self.photo, self.selected)
            self.timings["overlay_ms"] = 1e3 * (time.perf_counter() - t0)
            if layers is not None:
                self._draw_overlay(dl, layers[1])
            self._draw_stroke(dl)
            dl.pop_clip_rect()
            return
        if self.photo is None:
            dl.add_text((x0 + 20, y0 + 20), u32((1, 1, 1, 1)),
                        "no photos yet: Add all photos below (or type a file name and Add photo)")
            dl.pop_clip_rect()
            return
        w, h = self.photo_size()
        a = self.image_to_window(None, (0, 0))
        b = self.image_to_window(None, (w, h))
        tex = self._photo_texture(self.photo)
        if tex is not None:
            mag = moderngl.NEAREST if self.zoom >= NEAREST_ABOVE_ZOOM else moderngl.LINEAR
            tex.filter = (moderngl.LINEAR_MIPMAP_NEAREST, mag)  # trilinear costs 20 % of a frame on llvmpipe
            dl.add_image(self.gui.texture_ref(tex, opaque=True), a, b)
        else:
            grey, red = u32((0.25, 0.25, 0.27, 1.0)), u32((0.8, 0.2, 0.2, 1.0))
            dl.add_rect_filled(a, b, grey)
            dl.add_line(a, b, red, 2.0)
            dl.add_line((a[0], b[1]), (b[0], a[1]), red, 2.0)
            text = self._photo_errors.get(self.photo, "photo not loaded")
            dl.add_text((max(a[0], x0) + 12, max(a[1], y0) + 12), u32((1, 0.6, 0.6, 1)),
                        f"photo '{self.photo}' cannot be shown: {text}")
        if layer == "still":
            layers = self.guard(self.session.overlay_layers, self.photo, self.selected)
            if layers is not None:
                self._draw_overlay(dl, layers[0])
            dl.pop_clip_rect()
            return
        ov = self.overlay()
        if ov is not None:
            self._draw_overlay(dl, ov)
        self._draw_proposals(dl)
        self._draw_relate(dl)
        self._draw_stroke(dl)
        self._draw_snap_preview(dl)
        dl.pop_clip_rect()

    def _draw_proposals(self, dl: Any) -> None:
        """The shown photo's proposals, thinner than accepted marks and dashed: segments in their
        axis' colour, markers as circles, pins as squares."""
        items = self.session.proposals.get(self.photo) or []
        for p in items:
            if p.kind == "segment":
                col = u32((*AXIS_COLOURS[p.axis][:3], 0.9))
                a, b = self.image_to_window(None, p.segment[:2]), self.image_to_window(None, p.segment[2:])
                _dashed(dl, a, b, col, 1.2)
                self._arrow_head(dl, a, b, col, 6.0)
            else:
                c = self.image_to_window(None, p.uv)
                col = u32((1.0, 0.6, 0.1, 0.95) if p.kind == "marker" else (0.2, 0.95, 0.95, 0.95))
                r = 7.0
                if p.kind == "marker":
                    for k in range(0, 12, 2):
                        dl.path_arc_to(c, r, k * math.pi / 6, (k + 1) * math.pi / 6)
                        dl.path_stroke(col, 0, 1.5)
                    dl.add_text((c[0] + r + 3, c[1] - 7), col, f"{p.name}?")
                else:
                    q = [(c[0] - r, c[1] - r), (c[0] + r, c[1] - r), (c[0] + r, c[1] + r), (c[0] - r, c[1] + r)]
                    for a, b in zip(q, q[1:] + q[:1], strict=True):
                        _dashed(dl, a, b, col, 1.5, dash=3.0)
                    dl.add_text((c[0] + r + 3, c[1] - 7), col, f"{p.node}:{p.handle}?")

    def snap_preview(self) -> Any:
        """Where the mark being placed will land (shown before release): ("point", uv, snap) for a
        marker or a segment's end, ("segment", (a, b), fit) for a segment stroke, or None."""
        if self.photo is None:
            return None
        x, y = self._cursor
        if not self._photo_takes(x, y):
            return None
        p = self._press
        uv = self.window_to_image(x, y)
        alt = self.alt_held()
        key = (self.photo, uv, alt, None if p is None else (p["kind"], p["uv"], p.get("moved")), self.session.revision)
        if key == getattr(self, "_snap_key", None):
            return getattr(self, "_snap_shown", None)
        shown: Any = None
        try:
            if p is None and self.tool == "marker":
                at, snapped = self.session.snap(self.photo, uv, exact=alt)
                shown = ("point", at, snapped)
            elif p is not None and p["kind"] in ("marker-move", "segment-end") and p.get("moved"):
                at, snapped = self.session.snap(self.photo, uv, exact=alt)
                shown = ("point", at, snapped)
            elif p is not None and p["kind"] in ("x", "y", "z") and p.get("moved") and self.open_polyline is None \
                    and not self.shift_held():
                a, b, fit = self.session.snap_segment(self.photo, p["uv"], uv, exact=alt)
                shown = ("segment", (a, b), fit)
        except VebuildError:
            shown = None
        self._snap_key, self._snap_shown = key, shown
        return shown

    def _draw_snap_preview(self, dl: Any) -> None:
        shown = self.snap_preview()
        if shown is None or shown[2] is None:
            return
        col = u32((1.0, 1.0, 0.3, 1.0))
        if shown[0] == "point":
            c = self.image_to_window(None, shown[1])
            dl.add_line((c[0] - 6, c[1]), (c[0] + 6, c[1]), col, 1.5)
            dl.add_line((c[0], c[1] - 6), (c[0], c[1] + 6), col, 1.5)
            dl.add_text((c[0] + 8, c[1] + 4), col, f"snaps to the {shown[2].kind}")
        else:
            a, b = (self.image_to_window(None, q) for q in shown[1])
            dl.add_line(a, b, col, 1.5)
            dl.add_text((b[0] + 8, b[1] + 4), col, f"snaps to the line, σ {shown[2].sigma_px:.2f} px")

    def _draw_overlay(self, dl: Any, ov: Overlay) -> None:
        """The overlay's layers shown (:mod:`vebuild.edit.layers`), its lines clipped to the photo,
        the model's edges seen solid and hidden dashed and dim, labels as each layer says."""
        z, (px, py) = self.zoom, self.pan
        w, h = self.photo_size(ov.photo)
        hover = None if self.session.dragging else self.hovered(ov)  # a drag's frames keep their labels
        runs = self.edge_visibility()
        moving = set(self.session._drag.session.moved) if self.session.dragging else set()
        drawn: set[Any] = set()
        for ln in ov.lines:
            if not self.shows(ln.kind):
                continue
            col = u32(ln.colour)
            key: Any = ln.key
            if ln.kind == "edge" and runs is not None and key in runs and key[0] not in moving:
                if key not in drawn:
                    drawn.add(key)
                    self._draw_edge_runs(dl, runs, key, ln, w, h)
                clipped = clip_segment(ln.p, w, h)
            else:
                clipped = clip_segment(ln.p, w, h)
                if clipped is None:
                    continue
                u1, v1, u2, v2 = clipped
                a, b = (px + z * u1, py + z * v1), (px + z * u2, py + z * v2)
                dl.add_line(a, b, col, ln.width)
                if ln.arrow and clipped[2:] == tuple(float(t) for t in ln.p[2:]):
                    self._arrow_head(dl, a, b, col, 6.0 + 2.0 * ln.width)
                if ln.cross is not None:  # a segment left out: crossed at its middle, as in the report
                    mx, my = px + z * 0.5 * (ln.p[0] + ln.p[2]), py + z * 0.5 * (ln.p[1] + ln.p[3])
                    r, cc = CROSS_HALF_PX, u32(ln.cross)
                    dl.add_line((mx - r, my - r), (mx + r, my + r), cc, ln.width + 1.0)
                    dl.add_line((mx - r, my + r), (mx + r, my - r), cc, ln.width + 1.0)
            label = ln.label if ln.label else (f"{key[0]}:{key[1]}" if ln.kind == "edge" else None)
            if clipped is not None and label and self.labelled(ln, ln is hover):
                u1, v1, u2, v2 = clipped
                dl.add_text((px + z * 0.5 * (u1 + u2) + 6, py + z * 0.5 * (v1 + v2) + 2), col, label)
        for pt in ov.points:
            if not self.shows(pt.kind) or (pt.kind != "vp" and not (0 <= pt.uv[0] <= w and 0 <= pt.uv[1] <= h)):
                continue  # what is off the photo is not drawn (but a vanishing point, wherever it is)
            c = (px + z * pt.uv[0], py + z * pt.uv[1])
            col = u32(pt.colour)
            if pt.filled:
                dl.add_circle_filled(c, pt.radius, col)
            else:
                dl.add_circle(c, pt.radius, col, 0, 1.5)
            if pt.label and self.labelled(pt, pt is hover):
                pkey: Any = pt.key
                node = pkey[0] if pt.kind in ("handle", "pin") else None
                text = pt.label if node is None or pt is hover else pt.label.split(": ", 1)[-1]
                dl.add_text((c[0] + pt.radius + 3, c[1] - 7), col, text)
        self._draw_names(dl, ov)

    def _draw_edge_runs(self, dl: Any, runs: dict[Any, Any], key: Any, ln: Any, w: float, h: float) -> None:
        """One model edge (``runs[key]``): its seen runs solid, its hidden runs dashed and dim
        (clipped to the photo). Where they are in the window is worked out once for the
        visibility's runs and the view (zoom, pan): a frame that only moves the cursor draws them
        again from that (on a house's 770 edges, the clipping and dashing had been 57 of an idle
        frame's 83 ms)."""
        z, (px, py) = self.zoom, self.pan
        view = (z, px, py, w, h)
        memo: tuple[Any, Any, dict[Any, Any]] | None = self.__dict__.get("_runs_drawn")
        if memo is None or memo[0] is not runs or memo[1] != view:
            fresh: dict[Any, Any] = {}
            memo = self._runs_drawn = (runs, view, fresh)
        pieces = memo[2].get(key)
        if pieces is None:
            pieces = memo[2][key] = _run_pieces(runs[key], z, px, py, w, h)
        solid = u32(ln.colour)
        dim = u32((*ln.colour[:3], HIDDEN_ALPHA))
        for visible, points in pieces:
            if visible:
                dl.add_polyline(points, solid, thickness=ln.width, flags=0)
            else:
                for a, b in points:
                    dl.add_line(a, b, dim, HIDDEN_WIDTH)

    def _draw_names(self, dl: Any, ov: Overlay) -> None:
        """The picked corner or face (ringed or outlined, named), and with I every face of the
        selected primitive named at its centre."""
        s = self.session
        pk = self.picked
        if s.dragging:  # the pick moves with the drag: named again on release
            return
        faces: list[tuple[str, str]] = []
        if pk is not None and pk["what"] == "face":
            faces.append((pk["node"], pk["stored"]))
        if self.show_names and self.selected is not None:
            seen = s.faces_facing(ov.photo, self.selected)  # a face turned away is not named over the photo
            faces += [(self.selected, f) for f in s.face_names(ov.photo, self.selected) if f in seen]
        col = u32((0.3, 1.0, 1.0, 1.0))
        for node, face in faces:
            from .relating import Pick

            tris = s.pick_outline(ov.photo, Pick(node, face, "face", (0.0, 0.0, 0.0)))
            if not tris:
                continue
            P = np.array(tris, float).reshape(-1, 2)
            c = self.image_to_window(None, P.mean(axis=0))
            picked = pk is not None and (pk["node"], pk["stored"]) == (node, face)
            if picked:
                for t in tris:
                    a, b, d = (self.image_to_window(None, q) for q in t)
                    dl.add_triangle_filled(a, b, d, u32((0.3, 1.0, 1.0, 0.18)))
            name = s.face_names(ov.photo, node).get(face, face)
            dl.add_text((c[0] - 20, c[1] - 7), col, f"{node}: {name}" if picked else name)
        if pk is not None and pk["what"] == "corner":
            X = s.corners_world(pk["node"]).get(pk["stored"])
            cam = s.cameras.get(ov.photo)
            if X is not None and cam is not None:
                from vebuild import camera as cam_math

                if cam_math.world_to_camera(cam.R, cam.C, X)[2] > 0:
                    c = self.image_to_window(None, cam_math.project(cam.K, cam.R, cam.C, X, cam.lens))
                    dl.add_circle(c, 9.0, col, 0, 2.0)
                    dl.add_text((c[0] + 12, c[1] + 4), col, f"{pk['node']}: {pk['shown']}")

    @staticmethod
    def _arrow_head(dl: Any, a: tuple[float, float], b: tuple[float, float], col: int, size: float) -> None:
        dx, dy = b[0] - a[0], b[1] - a[1]
        n = math.hypot(dx, dy)
        if n < 1e-6:
            return
        dx, dy = dx / n, dy / n
        size = min(size, 0.5 * n)
        bx, by = b[0] - size * dx, b[1] - size * dy
        w = 0.45 * size
        dl.add_triangle_filled(b, (bx - w * dy, by + w * dx), (bx + w * dy, by - w * dx), col)

    def _draw_stroke(self, dl: Any) -> None:
        """The stroke being drawn (a segment, an edge) or the segment end being moved."""
        pending = self.pending_length
        if pending is not None and pending["photo"] == self.photo:  # drawn, its metres not typed yet
            a, b = (self.image_to_window(None, e) for e in pending["ends"])
            dl.add_line(a, b, u32(WHITE), 4.0)
            dl.add_circle_filled(a, 4.0, u32(WHITE))
            dl.add_text((0.5 * (a[0] + b[0]) + 8, 0.5 * (a[1] + b[1])), u32(WHITE), "known length: type its metres")
        poly = self.open_polyline
        if poly is not None and poly["photo"] == self.photo:  # clicked so far, and on to the cursor
            col = u32(AXIS_COLOURS[poly["axis"]])
            pts = [self.image_to_window(None, q) for q in poly["points"]] + [self._cursor]
            for a, b in zip(pts[:-1], pts[1:], strict=True):
                dl.add_line(a, b, col, 2.0)
            for q in pts[1:-1]:
                dl.add_circle_filled(q, 3.0, col)
        p = self._press
        if p is None:
            return
        x, y = self._cursor
        if p["kind"] in ("x", "y", "z", "edge", "length"):
            col = u32(AXIS_COLOURS[p["kind"]] if p["kind"] in AXIS_COLOURS else WHITE if p["kind"] == "length" else RED)
            a = self.image_to_window(None, p["uv"])
            dl.add_line(a, (x, y), col, 2.0)
            self._arrow_head(dl, a, (x, y), col, 10.0)
        elif p["kind"] in ("insert-point", "segment-point") and (p.get("moved") or p["kind"] == "insert-point"):
            dl.add_circle((x, y), 5.0, u32(AXIS_COLOURS[p["axis"]]), 0, 2.0)
        elif p["kind"] == "segment-end" and p.get("moved"):
            seg = list(p["segment"])
            seg[2 * p["end"]:2 * p["end"] + 2] = self.window_to_image(x, y)
            col = u32(AXIS_COLOURS[p["axis"]])
            a, b = self.image_to_window(None, seg[:2]), self.image_to_window(None, seg[2:])
            dl.add_line(a, b, col, 2.0)
            self._arrow_head(dl, a, b, col, 10.0)
        elif p["kind"] == "marker-move" and p.get("moved"):
            dl.add_circle((x, y), 6.0, u32((1.0, 0.6, 0.1, 1.0)), 0, 2.0)

    def magnifier_visible(self) -> bool:
        x, y = self._cursor
        want = self.tool in ("x", "y", "z", "marker", "edge", "length") or bool(self._mods & glfw.MOD_SHIFT) \
            or glfw.KEY_LEFT_SHIFT in self._held or glfw.KEY_RIGHT_SHIFT in self._held
        return want and self._photo_takes(x, y) and self._pan_from is None

    def _draw_magnifier(self) -> None:
        if not self.magnifier_visible() or self.photo is None:
            return
        tex = self._photo_texture(self.photo)
        if tex is None:
            return
        x, y = self._cursor
        W, H = self.size()
        side = MAGNIFIER_PX
        px = x + 28 if x + 28 + side < W - PANEL_W else x - 28 - side
        py = y + 28 if y + 28 + side < H - STRIP_H else y - 28 - side
        u, v = self.window_to_image(x, y)
        w, h = self.photo_size()
        half = 0.5 * side / MAGNIFIER_ZOOM
        imgui.set_next_window_pos((px, py), imgui.Cond_.always)
        imgui.push_style_var(imgui.StyleVar_.window_padding, (2, 2))
        imgui.begin("##magnifier", None, imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
                    | imgui.WindowFlags_.no_inputs | imgui.WindowFlags_.no_saved_settings
                    | imgui.WindowFlags_.no_focus_on_appearing | imgui.WindowFlags_.no_nav)
        imgui.image(self.gui.texture_ref(tex, nearest=True, opaque=True), (side, side),
                    ((u - half) / w, (v - half) / h), ((u + half) / w, (v + half) / h))
        mn = imgui.get_item_rect_min()
        c = (mn.x + 0.5 * side, mn.y + 0.5 * side)
        wdl = imgui.get_window_draw_list()
        cross = u32((1.0, 0.2, 0.9, 0.9))
        wdl.add_line((c[0] - side / 2, c[1]), (c[0] - 4, c[1]), cross, 1.0)
        wdl.add_line((c[0] + 4, c[1]), (c[0] + side / 2, c[1]), cross, 1.0)
        wdl.add_line((c[0], c[1] - side / 2), (c[0], c[1] - 4), cross, 1.0)
        wdl.add_line((c[0], c[1] + 4), (c[0], c[1] + side / 2), cross, 1.0)
        p = self._press
        if p is not None and p["kind"] in ("x", "y", "z", "edge"):  # the stroke being drawn, magnified
            col = u32(AXIS_COLOURS[p["kind"]] if p["kind"] in AXIS_COLOURS else RED)
            a = (c[0] + MAGNIFIER_ZOOM * (p["uv"][0] - u), c[1] + MAGNIFIER_ZOOM * (p["uv"][1] - v))
            wdl.push_clip_rect(mn, (mn.x + side, mn.y + side), True)
            wdl.add_line(a, c, col, 1.5)
            wdl.pop_clip_rect()
        imgui.text(f"({u:.2f}, {v:.2f}) px, {MAGNIFIER_ZOOM:.0f}× the photo")
        self._rects["magnifier"] = (mn.x, mn.y, mn.x + side, mn.y + side)
        imgui.end()
        imgui.pop_style_var()


def _run_pieces(runs: Any, z: float, px: float, py: float, w: float, h: float) -> list[tuple[bool, Any]]:
    """An edge's runs in window pixels, clipped to the photo (w × h): (True, polyline points) for a
    seen run, (False, its dashes as (a, b) pairs) for a hidden one."""
    out: list[tuple[bool, Any]] = []
    for run in runs:
        for part in clip_polyline(np.asarray(run.points, float), w, h):
            W = np.column_stack((px + z * part[:, 0], py + z * part[:, 1])).tolist()
            if run.visible:
                out.append((True, [imgui.ImVec2(a, b) for a, b in W]))
            else:
                out.append((False, _dash_segments([(tuple(a), tuple(b)) for a, b in zip(W[:-1], W[1:], strict=True)])))
    return out


def _dash_segments(pieces: list[tuple[tuple[float, float], tuple[float, float]]],
                   dash: float = HIDDEN_DASH_PX) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """Consecutive pieces (window pixels) dashed as one line: the dashes, the pattern carried on
    from piece to piece (dashes and gaps of ``dash`` pixels along the whole)."""
    out = []
    phase = 0.0  # how far along the pattern (dash then gap) the next piece starts
    for a, b in pieces:
        dx, dy = b[0] - a[0], b[1] - a[1]
        n = math.hypot(dx, dy)
        k = 0.0
        while k < n:
            in_dash = phase < dash
            step = min((dash - phase) if in_dash else (2 * dash - phase), n - k)
            if in_dash:
                out.append(((a[0] + dx * k / n, a[1] + dy * k / n), (a[0] + dx * (k + step) / n,
                            a[1] + dy * (k + step) / n)))
            k += step
            phase = (phase + step) % (2 * dash)
    return out


def _dashed(dl: Any, a: tuple[float, float], b: tuple[float, float], col: int, width: float, dash: float = 6.0) -> None:
    """A dashed line from a to b (window pixels): dashes and gaps of ``dash`` pixels."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = math.hypot(dx, dy)
    if n < 1e-6:
        return
    k = 0.0
    while k < n:
        e = min(k + dash, n)
        dl.add_line((a[0] + dx * k / n, a[1] + dy * k / n), (a[0] + dx * e / n, a[1] + dy * e / n), col, width)
        k += 2 * dash
