"""``vebuild view``: the walk-through window (paper §5, Figure 13).

Keys and mouse follow games and 3-D viewers: :data:`vebuild.viewer.keys.VIEWER_KEYS` (the panel lists
them, F1).

The panel also saves the current view as a named view, and the current arrangement as a named
hypothesis, which it lists for loading; while objects are not where they were measured, the window
says "HYPOTHESIS" in red. All of it is written to the project file, the measured model untouched.
"""

from __future__ import annotations

import dataclasses
import math
import time
from pathlib import Path
from typing import Any

import glfw
import moderngl
import numpy as np
from numpy.typing import NDArray

from vebuild.camera import PINHOLE, ImageCamera, focal_to_fov, pixel_rays_world, undistort_pixels
from vebuild.errors import VebuildError
from vebuild.gl import load_program
from vebuild.gl.app import WindowApp
from vebuild.gl.window import Window
from vebuild.model.arrange import CannotMove, ObjectMover
from vebuild.model.collide import Footprint, footprints, local_vertices
from vebuild.model.scene import Model
from vebuild.project import Project, save_project
from vebuild.project.decode import camera_records, find_preset, photo_camera, preset_names, view_camera
from vebuild.project.hypotheses import find_hypothesis, label, save_hypothesis
from vebuild.project.records import view_record
from vebuild.render.renderer import Renderer, RenderOptions, Stereo
from vebuild.render.scene import RenderScene, load_scene
from vebuild.viewer.floor import FloorOverlay, check_viewable, needs_model_error, project_has_model
from vebuild.viewer.keys import TURN_STEP, VIEWER_KEYS
from vebuild.viewer.measure import ViewerMeasure
from vebuild.viewer.moves import describe, moved_line
from vebuild.viewer.panel import ViewerPanel
from vebuild.viewer.presentation import PresentationCommands
from vebuild.viewer.scans import ViewerScans
from vebuild.viewer.walk import Walker

STEREO_CYCLE: list[str | None] = [None, "anaglyph", "sbs", "tb"]
#: A press and release closer than this (pixels) is a click, not a drag.
CLICK_SLOP_PX = 3.0


class Viewer(ViewerMeasure, FloorOverlay, ViewerScans, PresentationCommands, WindowApp):
    """The walk-through over one project in one window; :meth:`frame` draws one frame. A project
    with no model opens at its first calibrated photo (:mod:`vebuild.viewer.floor`)."""

    keys = VIEWER_KEYS
    keys_held_while_typing = False

    def __init__(self, project: Project, window: Window, options: RenderOptions | None = None,
                 hypothesis: str | None = None, view: str | None = None):
        super().__init__()
        self.project = project
        self.window = window
        self.ctx = window.ctx
        scene = load_scene(project) if project_has_model(project) else None  # None: the photos alone
        self.scene: RenderScene | None = scene
        self.messages: list[str] = list(scene.warnings) if scene is not None else []
        model = scene.model if scene is not None else Model([])
        self.mover = ObjectMover(model)
        self._renderer = (Renderer(self.ctx, scene, options or RenderOptions.interactive()) if scene is not None
                          else None)
        self._local = local_vertices(model)
        self._obstacles: list[Footprint] = footprints(model, local=self._local)
        self.walker = Walker()
        self.lightings = preset_names(project)
        self.lighting_index = 0
        self.stereo_modes = STEREO_CYCLE + (["quad"] if window.stereo else [])
        self.stereo_index = 0
        self.selection: str | None = None
        self.hypothesis_name: str | None = None
        self.photo: str | None = None
        self.photo_opacity = 0.5 if scene is not None else 1.0  # nothing under the photo: all of it
        self.show_floor = scene is None
        self._photo_tex: moderngl.Texture | None = None
        self._overlay = load_program(self.ctx, "overlay", vertex="fullscreen")
        self._overlay_vao = self.ctx.vertex_array(self._overlay, [])
        self.view_index = -1
        self.photo_index = -1
        self.show_panel = True
        self.fps = 0.0
        self._look_from: tuple[float, float] | None = None
        self._press: tuple[float, float] | None = None
        self._press_pick: tuple[str | None, NDArray[np.float64] | None] = (None, None)
        self._dragging = False
        self._last = time.perf_counter()
        self.panel = ViewerPanel(self)
        self.screenshots = 0
        # Registered laser scans as points (K): shown where the project has any, read on first draw.
        self.show_scans = bool(project.data.get("scans")) and scene is not None
        self._scan_layer: Any = None
        self.install_callbacks(window.handle)
        views = project.data.get("views", [])
        if view is not None:
            self.jump_to_view(view)
        elif scene is None:
            self.step_photo(1)  # the first calibrated photo, at its camera
        elif views:
            self.jump_to_view(views[0]["name"])
        else:
            lo, hi = scene.bounds()
            self.walker.place(0.5 * (lo + hi))
        if hypothesis is not None:
            self.load_hypothesis(hypothesis)
        if scene is None:
            self.show_saved_single_view()
            where = "the photo at its camera" if self.photo is not None else "the view"
            self.say(f"no model yet: {where} with the floor grid and the axes (G); T measures on a photo shown at its "
                     "camera alone, P steps between the photos")

    # -- GUI is optional so that tests can drive the logic without Dear ImGui ----------------------

    def enable_gui(self) -> None:
        self.gui = self.panel.make_gui()

    # -- state ------------------------------------------------------------------------------------

    @property
    def has_model(self) -> bool:
        """Whether the project has a model to draw (else: its calibrated photos alone)."""
        return self.scene is not None

    @property
    def renderer(self) -> Renderer:
        """The model's renderer; a project with no model has none (a :class:`VebuildError` in words)."""
        if self._renderer is None:
            raise needs_model_error("Drawing the scene")
        return self._renderer

    @property
    def lighting(self) -> str:
        return self.lightings[self.lighting_index]

    @property
    def stereo(self) -> str | None:
        return self.stereo_modes[self.stereo_index]

    @property
    def model(self) -> Any:
        return self.mover.model

    def arranged(self) -> bool:
        """Whether the objects are not where they were measured."""
        return bool(self.mover.arrangement())

    def banner(self) -> str | None:
        """The hypothesis label to show, or None for the measured scene."""
        if not self.arranged():
            return None
        return label(self.hypothesis_name or "unsaved arrangement")

    def say(self, text: str) -> None:
        self.messages = (self.messages + [text])[-4:]

    def _model_changed(self) -> None:
        if self.scene is None:
            return
        self.renderer.set_scene(self.scene.with_model(self.model))
        self._obstacles = footprints(self.model, local=self._local)

    # -- cameras ----------------------------------------------------------------------------------

    def viewport(self) -> tuple[int, int, int, int]:
        """Where the scene is drawn in the window: all of it, or the photo's shape inside it."""
        W, H = self.window.framebuffer_size()
        if self.photo is None:
            return 0, 0, W, H
        p = self.project.photo(self.photo)
        s = min(W / p["width"], H / p["height"])
        w, h = max(1, round(p["width"] * s)), max(1, round(p["height"] * s))
        return (W - w) // 2, (H - h) // 2, w, h

    def camera(self) -> ImageCamera:
        """The camera of the (whole, mono) view being shown."""
        x, y, w, h = self.viewport()
        where = f"the viewer's window ({w}×{h} pixels)"
        if self.photo is not None:
            cam = photo_camera(self.project, self.photo)
            return dataclasses.replace(cam.scaled(w / cam.width), source=where)
        return dataclasses.replace(self.walker.camera(w, h), source=where)

    def eye_camera(self) -> ImageCamera:
        """The camera handed to the renderer: a stereo mode splits the window between the eyes."""
        cam = self.camera()
        if self.stereo == "sbs":
            return cam.resized(max(1, cam.width // 2), cam.height)
        if self.stereo == "tb":
            return cam.resized(cam.width, max(1, cam.height // 2))
        return cam

    def cursor_image(self) -> tuple[float, float] | None:
        """The cursor in the mono view's image coordinates (None outside it)."""
        x, y = self._cursor
        W, H = self.window.framebuffer_size()
        ww, wh = glfw.get_window_size(self.window.handle)
        sx, sy = W / max(ww, 1), H / max(wh, 1)
        vx, vy, vw, vh = self.viewport()
        u, v = x * sx - vx, y * sy - (H - vy - vh)
        if self.stereo in ("sbs", "tb"):
            return None  # picking needs a mono view
        if 0 <= u < vw and 0 <= v < vh:
            return u, v
        return None

    def jump_to_view(self, name: str) -> None:
        views = self.project.data.get("views", [])
        names = [v["name"] for v in views]
        if name not in names:
            raise VebuildError(f"no view is called {name!r}; the views are: {', '.join(map(repr, names)) or 'none'}")
        cam = view_camera(views[names.index(name)])
        self.photo = None
        self.walker.fov_deg = math.degrees(focal_to_fov(cam.K[0, 0], cam.width))
        self.walker.place(cam.C, cam.R)
        if abs(cam.C[2] - self.walker.eye_height) > 0.05:
            self.walker.set_fly(True)  # a view above or below eye height is kept as it is
            self.walker.position = np.asarray(cam.C, float).copy()
        self.view_index = names.index(name)
        self.say(f"view '{name}'")

    def jump_to_photo(self, photo_id: str) -> None:
        from vebuild.texture.extract import PhotoSource, read_photo

        cam = photo_camera(self.project, photo_id)
        i = [p["id"] for p in self.project.data["photos"]].index(photo_id)
        p = self.project.data["photos"][i]
        src = PhotoSource(photo_id, self.project.photo_path(p), p["sha256"], f"$.photos[{i}]", str(self.project.path))
        pixels = read_photo(src, cam)
        if self._photo_tex is not None:
            self._photo_tex.release()
        self._photo_tex = self.ctx.texture((cam.width, cam.height), 3, np.ascontiguousarray(pixels).tobytes())
        self._photo_tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.photo = photo_id
        self.walker.set_fly(True)
        self.walker.place(cam.C, cam.R)
        self.say(f"photo '{photo_id}': its calibrated camera, the photo {100 * self.photo_opacity:.0f} % over the view")

    def leave_photo(self) -> None:
        if self.photo is not None:
            if not self.has_model:
                self.say(f"off photo {self.photo}'s camera: the floor grid, the axes and each photo's camera (its "
                         "frustum); P: back to the photo")
            self.photo = None
            self.walker.set_fly(False)

    # -- objects ----------------------------------------------------------------------------------

    def pick(self) -> tuple[str | None, NDArray[np.float64] | None]:
        uv = self.cursor_image()
        if uv is None or not self.has_model:
            return None, None
        cam = self.camera()  # a photo's camera has its lens: ask the renderer for the cursor's ray
        pin = undistort_pixels(cam.K, np.array(uv, float), cam.lens)
        return self.renderer.pick(dataclasses.replace(cam, lens=PINHOLE), float(pin[0]), float(pin[1]))

    def ray(self) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        uv = self.cursor_image()
        if uv is None:
            return None
        cam = self.camera()
        return np.asarray(cam.C, float), pixel_rays_world(cam.K, cam.R, np.array(uv), cam.lens)

    def select(self, node: str | None) -> None:
        self.selection = node
        if self._renderer is not None:
            self._renderer.highlight = node
        if node is not None:
            self.say(f"selected '{node}'")

    def describe(self, node: str) -> str:
        return describe(self.mover, node)  # in the world frame, metres and degrees (viewer/moves.py)

    def turn_selection(self, angle: float) -> None:
        if self.selection is None:
            return
        try:
            if self.mover.turn(self.selection, angle):
                self._model_changed()
                self.say(moved_line(self.mover, self.mover.movable(self.selection)))
        except CannotMove as e:
            self.say(str(e))

    def undo(self) -> None:
        if self.mover.undo():
            self._model_changed()

    def redo(self) -> None:
        if self.mover.redo():
            self._model_changed()

    def reset(self, everything: bool = False) -> None:
        if everything or self.selection is None:
            self.mover.reset()
            self.hypothesis_name = None
        else:
            self.mover.reset(self.mover.movable(self.selection))
        self._model_changed()

    def load_hypothesis(self, name: str) -> None:
        rec = find_hypothesis(self.project, name)
        self.mover.reset()
        self.mover.apply(rec["joints"])
        self.hypothesis_name = name
        self._model_changed()
        self.say(label(name))

    def save_hypothesis(self, name: str) -> None:
        save_hypothesis(self.project, name, self.mover.arrangement())
        save_project(self.project)
        self.hypothesis_name = name
        self.say(f"hypothesis '{name}' saved in {self.project.path.name} (the measured model is unchanged)")

    def save_view(self, name: str) -> None:
        if not name.strip():
            raise VebuildError("a view needs a name")
        rec = view_record(self.camera(), name.strip())
        views = [v for v in self.project.data.get("views", []) if v["name"] != rec["name"]]
        self.project.data["views"] = views + [rec]
        save_project(self.project)
        self.say(f"view '{rec['name']}' saved in {self.project.path.name}")

    def screenshot(self, folder: Path | None = None) -> Path:
        """The current view rendered off the window's context to a PNG with provenance."""
        from PIL import Image

        from vebuild.project.outputs import check_no_links
        from vebuild.render.observed import finish_image
        from vebuild.render.png import provenance, stamp, write_png

        self.needs_model("A screenshot with provenance (a render of the model)")
        assert self.scene is not None
        folder = folder or self.project.folder / "screenshots"
        check_no_links(folder, "make it a real folder with no link in it", itself=True)  # before anything
        cam = self.camera()
        stereo = Stereo(self.stereo) if self.stereo not in (None, "quad") else None
        img = self.renderer.render(cam if stereo is None else self.eye_camera(), stereo)
        text = provenance(self.project, cam, "viewer", self.lighting, {"mode": self.stereo} if stereo else None,
                          self.scene.page_hashes, {"samples": self.renderer.options.samples,
                                                   "unobserved": self.renderer.unobserved})
        img = finish_image(img, self.renderer.unobserved, self.renderer.marks_unobserved, text,
                           self.scene.mask_hashes)
        banner = self.banner()
        if banner:
            img = stamp(img, banner)
            text["vebuild:hypothesis"] = self.hypothesis_name or "unsaved arrangement"
        folder.mkdir(exist_ok=True)
        self.screenshots += 1
        path = folder / f"{self.project.path.name.split('.')[0]}-{self.screenshots:03d}.png"
        while path.exists():
            self.screenshots += 1
            path = folder / f"{self.project.path.name.split('.')[0]}-{self.screenshots:03d}.png"
        write_png(path, np.asarray(Image.fromarray(img)), text)
        self.say(f"screenshot {path}")
        return path

    # -- input ------------------------------------------------------------------------------------

    def toggle_fly(self) -> None:
        self.leave_photo()
        self.walker.set_fly(not self.walker.fly)
        self.say("flying" if self.walker.fly else "walking")

    def escape(self) -> None:
        """Cancel a drag, or clear the selection."""
        if self._dragging:
            self.mover.cancel()
            self._dragging = False
            self._model_changed()
        else:
            self.select(None)

    def step_view(self, step: int) -> None:
        views = self.project.data.get("views", [])
        if views:
            self.view_index = (self.view_index + step) % len(views)
            self.jump_to_view(views[self.view_index]["name"])

    def step_photo(self, step: int) -> None:
        photos = [p["id"] for p in self.project.data["photos"]
                  if p["id"] in camera_records(self.project.data)]
        if photos:
            self.photo_index = (self.photo_index + step) % len(photos)
            self.jump_to_photo(photos[self.photo_index])

    def change_opacity(self, delta: float) -> None:
        self.photo_opacity = min(1.0, max(0.0, self.photo_opacity + delta))

    def next_lighting(self) -> None:
        self.set_lighting((self.lighting_index + 1) % len(self.lightings))

    def next_unobserved(self) -> None:
        """Show surfaces no photo saw hatched, tinted or as extracted (the next of the three)."""
        self.needs_model("Marking the surfaces no photo saw (the model's textures)")
        from vebuild.render.observed import LEGEND_TEXT, UNOBSERVED_MODES

        mode = UNOBSERVED_MODES[(UNOBSERVED_MODES.index(self.renderer.unobserved) + 1) % len(UNOBSERVED_MODES)]
        self.renderer.unobserved = mode
        self.say(f"unobserved surfaces: {mode}" + (f" ({LEGEND_TEXT[mode]})" if mode in LEGEND_TEXT else
                                                   " (filled-in texture shown unmarked)"))

    def next_stereo(self) -> None:
        self.needs_model("Stereo")
        self.stereo_index = (self.stereo_index + 1) % len(self.stereo_modes)
        self.say(f"stereo: {self.stereo or 'off'}")

    def toggle_panel(self) -> None:
        self.show_panel = not self.show_panel

    def set_lighting(self, index: int) -> None:
        self.needs_model("Lighting presets")
        self.lighting_index = index
        self.renderer.set_lighting(find_preset(self.project, self.lighting))
        self.say(f"lighting: {self.lighting}")

    def on_cursor(self, x: float, y: float) -> None:
        if self.gui is not None:
            self.gui.on_cursor(x, y)
        dx, dy = x - self._cursor[0], y - self._cursor[1]
        self._cursor = (x, y)
        if self._look_from is not None:
            if self.photo is not None:
                self.leave_photo()
            self.walker.look(dx, dy)
        if self._press is not None and self.selection is not None:
            if not self._dragging and math.hypot(x - self._press[0], y - self._press[1]) > CLICK_SLOP_PX:
                self._begin_drag()
            if self._dragging:
                ray = self.ray()
                if ray is not None and self.mover.drag(*ray):
                    self._model_changed()

    def _begin_drag(self) -> None:
        node, point = self._press_pick
        if node is None or point is None or node != self.selection:
            return
        try:
            self.mover.begin(node, point)
            self._dragging = True
        except CannotMove as e:
            self.say(str(e))
            self._press = None

    def on_button(self, button: int, action: int, mods: int = 0) -> None:
        if self.gui is not None:
            self.gui.on_button(button, action)
            if self.gui.wants_mouse() and action == glfw.PRESS:
                return
        if button == glfw.MOUSE_BUTTON_RIGHT:
            self._look_from = self._cursor if action == glfw.PRESS else None
        elif button == glfw.MOUSE_BUTTON_LEFT:
            if action == glfw.PRESS and self.measure_click():
                return
            if action == glfw.PRESS and not self.has_model:
                self.say("nothing to select: the project has no model; T measures on the photo alone")
                return
            if action == glfw.PRESS:
                self._press = self._cursor
                self._press_pick = self.pick()
                node = self._press_pick[0]
                if node is not None:
                    self.select(node)
                    self.say(self.describe(node))
            else:
                if self._dragging:
                    moved = self.mover.grab.node if self.mover.grab is not None else None
                    self.mover.end()
                    self.say(moved_line(self.mover, moved) if moved else "")
                    self._dragging = False
                    self._model_changed()
                elif self._press is not None and self._press_pick[0] is None:
                    self.select(None)
                self._press = None

    def on_scroll(self, dx: float, dy: float) -> None:
        if self.gui is not None:
            self.gui.on_scroll(dx, dy)
            if self.gui.wants_mouse():
                return
        self.turn_selection(dy * TURN_STEP)

    # -- frames -----------------------------------------------------------------------------------

    def update(self, dt: float) -> None:
        """Move the walker for the keys held during ``dt`` seconds."""
        held = self._held
        forward = float(glfw.KEY_W in held or glfw.KEY_UP in held) - float(glfw.KEY_S in held or glfw.KEY_DOWN in held)
        right = float(glfw.KEY_D in held or glfw.KEY_RIGHT in held) - float(glfw.KEY_A in held or glfw.KEY_LEFT in held)
        up = float(glfw.KEY_SPACE in held) - float(glfw.KEY_C in held)
        if forward or right or up:
            self.leave_photo()
            run = glfw.KEY_LEFT_SHIFT in held or glfw.KEY_RIGHT_SHIFT in held
            self.walker.move(forward, right, up if self.walker.fly else 0.0, dt, run, self._obstacles)

    def frame(self) -> None:
        """Poll events, move, draw the scene, the photo overlay and the panel, and swap."""
        now = time.perf_counter()
        dt = min(0.1, now - self._last)
        self._last = now
        if dt > 0:
            self.fps = 1.0 / dt if self.fps == 0 else 0.9 * self.fps + 0.1 / dt
        self.window.poll()
        self.update(dt)
        self.draw()
        self.window.swap()

    def draw(self) -> None:
        ctx = self.ctx
        screen = ctx.screen
        W, H = self.window.framebuffer_size()
        screen.use()
        screen.viewport = (0, 0, W, H)
        screen.clear(0.0, 0.0, 0.0, 1.0, depth=1.0)
        x, y, _, _ = self.viewport()
        stereo = Stereo(self.stereo) if self.stereo else None
        if self._renderer is not None:  # with no model: the photo, and the floor drawn over it (the panel)
            self._renderer.draw(screen, self.eye_camera(), stereo, flip=True, origin=(x, y),
                                select_buffer=self.window.select_buffer if self.stereo == "quad" else None)
        if self.show_scans and self.stereo is None:
            self._draw_scans()
        if self.photo is not None and self._photo_tex is not None and self.photo_opacity > 0:
            self._draw_overlay()
        if self.gui is not None:
            self.panel.draw()

    def _draw_overlay(self) -> None:
        if self._photo_tex is None:
            return
        ctx = self.ctx
        x, y, w, h = self.viewport()
        ctx.screen.viewport = (x, y, w, h)
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        self._photo_tex.use(location=0)
        for name, value in (("photo", 0), ("opacity", float(self.photo_opacity)), ("origin", (x, y)),
                            ("size", (w, h))):
            if name in self._overlay:
                self._overlay[name].value = value  # type: ignore[union-attr]
        self._overlay_vao.render(moderngl.TRIANGLES, vertices=3)
        ctx.disable(moderngl.BLEND)

    def trajectories(self) -> list[Any]:
        """The trajectories the project records (``analyses``), against the objects as they are now."""
        from vebuild.analysis.rays import Occluders
        from vebuild.analysis.recorded import parse_recorded_trajectory

        records = [r for r in self.project.data.get("analyses") or [] if r["command"][:1] == ["trajectory"]]
        if not records or not self.has_model:
            return []
        key = (id(self.renderer.scene), len(records))
        if getattr(self, "_trajectory_key", None) != key:
            occ = Occluders(self.renderer.scene)
            out = []
            for rec in records:
                try:
                    out.append(parse_recorded_trajectory(rec["command"]).trajectory(occ))
                except VebuildError as e:
                    self.say(f"trajectory {rec['name']!r}: {e}")
            from vebuild.analysis.trajectory import path_polylines

            self._trajectory_key = key
            self._trajectory_cache = [(tr, path_polylines(tr)) for tr in out]
        return [tr for tr, _ in self._trajectory_cache]

    def close(self) -> None:
        if self.gui is not None:
            self.gui.release()
            self.gui = None
        if self._photo_tex is not None:
            self._photo_tex.release()
        if self._scan_layer is not None:
            self._scan_layer.release()
        if self._renderer is not None:
            self._renderer.release()


def run_viewer(project: Project, size: tuple[int, int] = (1280, 720), hypothesis: str | None = None,
               view: str | None = None, samples: int = 1, quad_stereo: bool = False,
               frames: int | None = None) -> None:
    """Open the window and run until it is closed (or for ``frames`` frames)."""
    check_viewable(project)  # before a window opens
    with Window(size[0], size[1], f"vebuild — {project.path.name}", stereo=quad_stereo) as window:
        options = RenderOptions.interactive() if samples <= 1 else RenderOptions(samples=samples)
        viewer = Viewer(project, window, options, hypothesis=hypothesis, view=view)
        if window.stereo_note:
            viewer.say(window.stereo_note)
        viewer.enable_gui()
        viewer.run(window, frames)
