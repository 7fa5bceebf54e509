"""The walk-through's presentation mode, for showing a scene to a room: full screen (F11) or in
the window (Tab), the panel hidden and a small legend in the corner in its place.

The legend says what the audience needs to read the picture: the hypothesis label when objects
are not where they were measured (in red), what marks the surfaces no photo saw (a swatch in the
mark's colour), and a scale bar. A perspective picture has no single scale, so the bar is true at
one distance only, which it says: that of the surface at the centre of the view (found with the
renderer's one-pixel ID buffer), as "1 m at 4.2 m from the eye".

What the legend drew in the last frame is kept in :attr:`Presentation.drawn` (its items, their
text and their rectangles in window coordinates), so that tests and the screenshot script can find
it in the frame.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from vebuild.camera import PINHOLE, ImageCamera, world_to_camera
from vebuild.gl.window import Window
from vebuild.render.renderer import Renderer

#: The lengths a scale bar may have (metres: 1, 2, 2.5 and 5 cm to 50 m): the longest that fits in
#: SCALE_BAR_MAX_EM text heights is drawn.
SCALE_BAR_LENGTHS_M = tuple(round(m * 10.0 ** k, 6) for k in range(-2, 2) for m in (1.0, 2.0, 2.5, 5.0))
SCALE_BAR_MAX_EM = 10.0
#: The legend's text as a share of the panel's (a legend is small; it still reads from the room).
LEGEND_TEXT_SHARE = 1.0
LEGEND_BACKGROUND = (0.08, 0.08, 0.08, 0.78)
HYPOTHESIS_RGB = (1.0, 0.25, 0.2)


@dataclass(frozen=True)
class ScaleBar:
    length_m: float
    pixels: float  # in the camera's pixels
    distance_m: float  # the depth at which it is true

    @property
    def label(self) -> str:
        length = f"{self.length_m:g} m" if self.length_m >= 1 else f"{100 * self.length_m:g} cm"
        return f"{length} at {self.distance_m:.1f} m from the eye"


def scale_bar(cam: ImageCamera, point: Any, max_pixels: float) -> ScaleBar | None:
    """The longest round length whose image, at the depth of world ``point`` seen by ``cam``, is
    at most ``max_pixels`` long (the shortest length if none is); None if the point is behind."""
    z = float(world_to_camera(cam.R, cam.C, np.asarray(point, float)[None, :])[0, 2])
    if not z > 1e-6:
        return None
    f = float(cam.K[0, 0])
    fits = [L for L in SCALE_BAR_LENGTHS_M if f * L / z <= max_pixels]
    L = fits[-1] if fits else SCALE_BAR_LENGTHS_M[0]
    return ScaleBar(L, f * L / z, z)


def floor_point(cam: ImageCamera, u: float, v: float) -> Any:
    """Where the ray through pixel (u, v) meets the floor (z = 0), or None if it does not ahead."""
    from vebuild.camera import pixel_rays_world

    d = pixel_rays_world(cam.K, cam.R, np.array([u, v]), cam.lens)
    if d[2] >= -1e-6:
        return None
    return np.asarray(cam.C, float) - float(cam.C[2]) / float(d[2]) * d


class PresentedViewer(Protocol):
    """What presentation mode reads and sets of the walk-through it shows
    (:class:`vebuild.viewer.app.Viewer` is one)."""

    window: Window
    show_panel: bool
    _renderer: Renderer | None

    @property
    def has_model(self) -> bool: ...
    @property
    def renderer(self) -> Renderer: ...
    @property
    def stereo(self) -> str | None: ...
    def camera(self) -> ImageCamera: ...
    def banner(self) -> str | None: ...
    def say(self, text: str) -> None: ...


class Presentation:
    """Presentation mode of a :class:`~vebuild.viewer.app.Viewer` (``viewer.presentation``)."""

    def __init__(self, viewer: PresentedViewer):
        self.v = viewer
        self.on = False
        self.fullscreen = False
        self._panel_was = True
        self._windowed: tuple[int, int, int, int] | None = None  # x, y, width, height before F11
        self._centre_key: Any = None
        self._centre: Any = None
        self.drawn: list[tuple[str, str, tuple[float, float, float, float]]] = []

    # -- modes ----------------------------------------------------------------------------------

    def toggle(self) -> None:
        """Presentation in the window as it is (Tab): the panel hidden and the legend shown, or back."""
        self.set(not self.on)

    def set(self, on: bool) -> None:
        if on and not self.on:
            self._panel_was = self.v.show_panel
            self.v.show_panel = False
        elif self.on and not on:
            self.v.show_panel = self._panel_was
        self.on = on

    def toggle_fullscreen(self) -> None:
        """F11: full screen on the window's monitor (the primary one) and presentation, or back to
        the window where it was."""
        import glfw

        h = self.v.window.handle
        if not self.fullscreen:
            monitor = glfw.get_window_monitor(h) or glfw.get_primary_monitor()
            mode = glfw.get_video_mode(monitor) if monitor else None
            if mode is None:
                self.v.say("no monitor to go full screen on; Tab presents in the window")
                return
            x, y = glfw.get_window_pos(h)
            w, hh = glfw.get_window_size(h)
            self._windowed = (int(x), int(y), int(w), int(hh))
            glfw.set_window_monitor(h, monitor, 0, 0, mode.size.width, mode.size.height, mode.refresh_rate)
            self.fullscreen = True
            self.set(True)
        else:
            x, y, w, hh = self._windowed or (0, 0, 1280, 720)
            glfw.set_window_monitor(h, None, x, y, w, hh, 0)  # type: ignore[arg-type]  # None: windowed
            self.fullscreen = False
            self.set(False)

    # -- the legend ---------------------------------------------------------------------------------

    def centre_point(self) -> Any:
        """The world point at the centre of the view (the renderer's ID buffer), cached per view."""
        cam = self.v.camera()
        if not self.v.has_model:  # the floor where the view's centre meets it (None above the horizon)
            return floor_point(cam, float(cam.K[0, 2]), float(cam.K[1, 2]))
        key = (cam.C.tobytes(), cam.R.tobytes(), cam.width, cam.height, id(self.v.renderer.scene))
        if key != self._centre_key:
            self._centre_key = key
            # the principal point: the same pixel through the lens and without it
            pin = dataclasses.replace(cam, lens=PINHOLE)
            _, self._centre = self.v.renderer.pick(pin, float(cam.K[0, 2]), float(cam.K[1, 2]))
        return self._centre

    def draw_legend(self, imgui: Any, text_px: float, fb_scale: float) -> None:
        """The legend in the lower left corner of the window (window coordinates)."""
        from vebuild.render.observed import LEGEND_TEXT, UNOBSERVED_SRGB

        self.drawn = []
        f = LEGEND_TEXT_SHARE * text_px
        pad, gap = 0.5 * f, 0.3 * f
        rows: list[tuple[str, str, tuple[float, float, float], float]] = []  # kind, text, colour, lead width
        banner = self.v.banner()
        if banner:
            rows.append(("hypothesis", banner, HYPOTHESIS_RGB, 0.0))
        r = self.v._renderer
        if r is not None and r.marks_unobserved:
            rows.append(("unobserved", LEGEND_TEXT[r.unobserved], (1.0, 1.0, 1.0), 1.6 * f))
        bar = None
        if self.v.stereo is None:
            point = self.centre_point()
            if point is not None:
                bar = scale_bar(self.v.camera(), point, SCALE_BAR_MAX_EM * f * fb_scale)
        if bar is not None:
            rows.append(("scale", bar.label, (1.0, 1.0, 1.0), bar.pixels / fb_scale + 0.6 * f))
        if not rows:
            return
        _, H = imgui.get_io().display_size
        imgui.push_font(None, f)
        sizes = [imgui.calc_text_size(text) for _, text, _, _ in rows]
        width = max(lead + s.x for (_, _, _, lead), s in zip(rows, sizes, strict=True)) + 2 * pad
        height = sum(s.y for s in sizes) + gap * (len(rows) - 1) + 2 * pad
        x0, y0 = pad, H - pad - height
        dl = imgui.get_foreground_draw_list()
        dl.add_rect_filled(imgui.ImVec2(x0, y0), imgui.ImVec2(x0 + width, y0 + height),
                           imgui.get_color_u32(imgui.ImVec4(*LEGEND_BACKGROUND)), 0.3 * f)
        self.drawn.append(("legend", "", (x0, y0, x0 + width, y0 + height)))
        y = y0 + pad
        for (kind, text, colour, lead), s in zip(rows, sizes, strict=True):
            x = x0 + pad
            if kind == "unobserved" and r is not None:
                c = [v / 255.0 for v in UNOBSERVED_SRGB]
                box = (x, y + 0.1 * s.y, x + lead - 0.4 * f, y + 0.9 * s.y)
                self._swatch(imgui, dl, box, imgui.get_color_u32(imgui.ImVec4(c[0], c[1], c[2], 1.0)),
                             hatched=r.unobserved == "hatch", stripe=0.2 * f)
                self.drawn.append(("unobserved swatch", r.unobserved, box))
            elif kind == "scale" and bar is not None:
                white = imgui.get_color_u32(imgui.ImVec4(1.0, 1.0, 1.0, 1.0))
                length = bar.pixels / fb_scale
                ym = y + 0.5 * s.y
                box = (x, ym - 0.12 * f, x + length, ym + 0.12 * f)
                dl.add_rect_filled(imgui.ImVec2(box[0], box[1]), imgui.ImVec2(box[2], box[3]), white)
                for xe in (x, x + length):
                    dl.add_line(imgui.ImVec2(xe, ym - 0.4 * f), imgui.ImVec2(xe, ym + 0.4 * f), white,
                                max(1.0, 0.12 * f))
                self.drawn.append(("scale bar", "", box))
            col = imgui.get_color_u32(imgui.ImVec4(colour[0], colour[1], colour[2], 1.0))
            dl.add_text(imgui.ImVec2(x + lead, y), col, text)
            self.drawn.append((kind, text, (x + lead, y, x + lead + s.x, y + s.y)))
            y += s.y + gap
        imgui.pop_font()


    @staticmethod
    def _swatch(imgui: Any, dl: Any, box: tuple[float, float, float, float], colour: int, hatched: bool,
                stripe: float) -> None:
        """The mark's sample: diagonal stripes on light grey as the hatching draws them, or filled."""
        a, b = imgui.ImVec2(box[0], box[1]), imgui.ImVec2(box[2], box[3])
        if not hatched:
            dl.add_rect_filled(a, b, colour)
            return
        dl.add_rect_filled(a, b, imgui.get_color_u32(imgui.ImVec4(0.8, 0.8, 0.8, 1.0)))
        dl.push_clip_rect(a, b, True)
        h = box[3] - box[1]
        x = box[0] - h
        while x < box[2]:
            dl.add_line(imgui.ImVec2(x, box[3]), imgui.ImVec2(x + h, box[1]), colour, stripe)
            x += 2.0 * stripe * 1.4142
        dl.pop_clip_rect()


class PresentationCommands:
    """The walk-through's commands for presentation mode (its key table binds F11 and Tab to them)."""

    _presentation: Presentation | None = None

    @property
    def presentation(self) -> Presentation:
        if self._presentation is None:
            self._presentation = Presentation(self)  # type: ignore[arg-type]  # mixed into the Viewer
        return self._presentation

    def toggle_presentation(self) -> None:
        """Tab: present in the window (the panel hidden, the legend shown), or back."""
        self.presentation.toggle()

    def toggle_fullscreen(self) -> None:
        """F11: present full screen, or back to the window."""
        self.presentation.toggle_fullscreen()
