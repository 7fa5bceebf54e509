"""Dear ImGui (imgui-bundle) in a vebuild window: input from glfw, drawing with moderngl.

imgui-bundle's own Python back ends draw through PyOpenGL; vebuild draws everything through
moderngl, so this module feeds ImGui the window's events and draws its lists with a moderngl
program (shaders/imgui.*), including the textures ImGui asks for (its font atlas) and the ones the
application shows (:meth:`Gui.texture_ref`: photos, thumbnails, an off-screen render).

A Gui without a window (``window=None``) draws into a given framebuffer at a given display size,
with events fed by the caller: the modelling screen's benchmark and tests run it off-screen.
"""

from __future__ import annotations

import ctypes
import time
from typing import Any

import glfw
import moderngl
import numpy as np
from imgui_bundle import imgui

from vebuild.gl import load_program

_KEYS = {glfw.KEY_TAB: imgui.Key.tab, glfw.KEY_LEFT: imgui.Key.left_arrow, glfw.KEY_RIGHT: imgui.Key.right_arrow,
         glfw.KEY_UP: imgui.Key.up_arrow, glfw.KEY_DOWN: imgui.Key.down_arrow, glfw.KEY_HOME: imgui.Key.home,
         glfw.KEY_END: imgui.Key.end, glfw.KEY_DELETE: imgui.Key.delete, glfw.KEY_BACKSPACE: imgui.Key.backspace,
         glfw.KEY_ENTER: imgui.Key.enter, glfw.KEY_KP_ENTER: imgui.Key.keypad_enter,
         glfw.KEY_ESCAPE: imgui.Key.escape, glfw.KEY_SPACE: imgui.Key.space,
         glfw.KEY_LEFT_CONTROL: imgui.Key.left_ctrl, glfw.KEY_RIGHT_CONTROL: imgui.Key.right_ctrl,
         glfw.KEY_LEFT_SHIFT: imgui.Key.left_shift, glfw.KEY_RIGHT_SHIFT: imgui.Key.right_shift,
         glfw.KEY_A: imgui.Key.a, glfw.KEY_C: imgui.Key.c, glfw.KEY_V: imgui.Key.v, glfw.KEY_X: imgui.Key.x,
         glfw.KEY_Y: imgui.Key.y, glfw.KEY_Z: imgui.Key.z, glfw.KEY_PAGE_UP: imgui.Key.page_up,
         glfw.KEY_PAGE_DOWN: imgui.Key.page_down}
#: Ids of the application's textures (:meth:`Gui.texture_ref`) start here, above any GL object name.
_USER_TEXTURE_IDS = 1 << 30  # ImTextureID is 32 bits here; GL names stay far below


class Gui:
    """One ImGui context drawn into one window. Call the ``on_*`` methods from the window's glfw
    callbacks; :meth:`wants_mouse`/:meth:`wants_keyboard` say when ImGui took an event.

    ``window`` is a glfw window handle, or None for a Gui drawn off-screen: then ``display_size``
    (width, height in pixels) is its size and ``target`` the framebuffer it draws into (the
    context's screen when not given). ``font``: a TrueType file to draw text with, at
    ``font_size_px`` (default: ImGui's own font).
    """

    def __init__(self, ctx: moderngl.Context, window: Any, *, display_size: tuple[int, int] | None = None,
                 target: moderngl.Framebuffer | None = None, font: str | None = None, font_size_px: float = 15.0):
        if window is None and display_size is None:
            raise ValueError("a Gui without a window needs its display_size")
        self.ctx = ctx
        self.window = window
        self.display_size: tuple[int, int] = display_size if display_size is not None else (0, 0)
        self.target = target
        self.context = imgui.create_context()
        imgui.set_current_context(self.context)
        io = imgui.get_io()
        io.set_ini_filename("")  # no imgui.ini beside the user's files
        io.backend_flags |= imgui.BackendFlags_.renderer_has_textures
        limit = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
        imgui.get_platform_io().renderer_texture_max_width = limit
        imgui.get_platform_io().renderer_texture_max_height = limit
        if font is not None:  # a TrueType font (ImGui's own covers Latin-1 only: no –, …, σ, ≥)
            io.fonts.add_font_from_file_ttf(str(font), font_size_px)
        imgui.style_colors_dark()
        self.program = load_program(ctx, "imgui")
        self._vbo = ctx.buffer(reserve=1 << 16, dynamic=True)
        self._ibo = ctx.buffer(reserve=1 << 16, dynamic=True)
        self._vao = ctx.vertex_array(self.program, [(self._vbo, "2f 2f 4f1", "in_position", "in_uv", "in_colour")],
                                     index_buffer=self._ibo, index_element_size=imgui.INDEX_SIZE)
        self._textures: dict[int, moderngl.Texture] = {}
        self._samplers: dict[int, moderngl.Sampler] = {}
        self._opaque: set[int] = set()
        self._user_ids: dict[tuple[int, bool, bool], int] = {}
        self._time: float | None = None
        self._moved = False  # the mouse moved since the frame began
        self._later: list[tuple[str, tuple[Any, ...]]] = []  # mouse events held for the next frame

    # -- input ----------------------------------------------------------------------------------

    def on_key(self, key: int, action: int, mods: int) -> None:
        io = imgui.get_io()
        if key in _KEYS and action in (glfw.PRESS, glfw.RELEASE):
            io.add_key_event(_KEYS[key], action == glfw.PRESS)
        io.add_key_event(imgui.Key.mod_ctrl, bool(mods & glfw.MOD_CONTROL))
        io.add_key_event(imgui.Key.mod_shift, bool(mods & glfw.MOD_SHIFT))

    def on_char(self, char: int) -> None:
        if 0 < char < 0x10000:
            imgui.get_io().add_input_character(char)

    def on_cursor(self, x: float, y: float) -> None:
        self._mouse("pos", x, y)

    def on_button(self, button: int, action: int) -> None:
        if button < 3:
            self._mouse("button", button, action == glfw.PRESS)

    def on_scroll(self, dx: float, dy: float) -> None:
        self._mouse("wheel", dx, dy)

    def _mouse(self, kind: str, *args: Any) -> None:
        """Give ImGui a mouse event; a press, release or wheel after a move in the same frame (a
        quick move and click while a slow frame was drawn) waits for the next frame, and every
        mouse event after it, in order. ImGui takes a move and a press in one frame together, and
        then does not find the widget under the new position: the click was lost."""
        if self._later or (kind != "pos" and self._moved):
            self._later.append((kind, args))
            return
        io = imgui.get_io()
        if kind == "pos":
            io.add_mouse_pos_event(*args)
            self._moved = True
        elif kind == "button":
            io.add_mouse_button_event(*args)
        else:
            io.add_mouse_wheel_event(*args)

    def wants_mouse(self) -> bool:
        return bool(imgui.get_io().want_capture_mouse)

    def wants_keyboard(self) -> bool:
        return bool(imgui.get_io().want_capture_keyboard)

    # -- frames ---------------------------------------------------------------------------------

    def size(self) -> tuple[int, int]:
        """The display size (window coordinates, where ImGui and the mouse live)."""
        if self.window is None:
            return self.display_size
        w, h = glfw.get_window_size(self.window)
        return int(w), int(h)

    def framebuffer_size(self) -> tuple[int, int]:
        if self.window is None:
            return self.target.size if self.target is not None else self.display_size
        w, h = glfw.get_framebuffer_size(self.window)
        return int(w), int(h)

    def new_frame(self) -> None:
        imgui.set_current_context(self.context)
        io = imgui.get_io()
        w, h = self.size()
        fw, fh = self.framebuffer_size()
        io.display_size = imgui.ImVec2(max(w, 1), max(h, 1))
        io.display_framebuffer_scale = imgui.ImVec2(fw / max(w, 1), fh / max(h, 1))
        now = glfw.get_time() if self.window is not None else time.perf_counter()
        io.delta_time = max(1e-4, now - self._time) if self._time is not None else 1.0 / 60.0
        self._time = now
        imgui.new_frame()
        self._moved = False
        later, self._later = self._later, []
        for kind, args in later:  # what waited for this frame, in order (some may wait again)
            self._mouse(kind, *args)

    def render(self) -> None:
        """End the frame and draw it over what the window holds."""
        imgui.render()
        data = imgui.get_draw_data()
        io = imgui.get_io()
        self._update_textures()
        fw = int(io.display_size.x * io.display_framebuffer_scale.x)
        fh = int(io.display_size.y * io.display_framebuffer_scale.y)
        if fw <= 0 or fh <= 0:
            return
        data.scale_clip_rects(io.display_framebuffer_scale)
        ctx = self.ctx
        target = self.target if self.target is not None else ctx.screen
        target.use()
        target.viewport = (0, 0, fw, fh)
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        self.program["display_size"].value = (io.display_size.x, io.display_size.y)  # type: ignore[union-attr]
        self.program["tex"].value = 0  # type: ignore[union-attr]
        for commands in data.cmd_lists:
            vsize = commands.vtx_buffer.size() * imgui.VERTEX_SIZE
            isize = commands.idx_buffer.size() * imgui.INDEX_SIZE
            for buf, size in ((self._vbo, vsize), (self._ibo, isize)):
                if buf.size < size:
                    buf.orphan(max(size, 2 * buf.size))
            self._vbo.write(ctypes.string_at(commands.vtx_buffer.data_address(), vsize))
            self._ibo.write(ctypes.string_at(commands.idx_buffer.data_address(), isize))
            for cmd in commands.cmd_buffer:
                key = int(cmd.tex_ref.get_tex_id())
                tex = self._textures.get(key)
                if tex is None or cmd.elem_count == 0:
                    continue
                tex.use(location=0)
                sampler = self._samplers.get(key)
                if sampler is not None:
                    sampler.use(location=0)
                x0, y0, x1, y1 = cmd.clip_rect.x, cmd.clip_rect.y, cmd.clip_rect.z, cmd.clip_rect.w
                ctx.scissor = (int(x0), int(fh - y1), int(x1 - x0), int(y1 - y0))
                opaque = key in self._opaque
                if opaque:
                    ctx.disable(moderngl.BLEND)
                self._vao.render(moderngl.TRIANGLES, vertices=cmd.elem_count, first=cmd.idx_offset)
                if opaque:
                    ctx.enable(moderngl.BLEND)
                if sampler is not None:
                    sampler.clear(location=0)
        ctx.scissor = None
        ctx.disable(moderngl.BLEND)

    def _update_textures(self) -> None:
        for tex in imgui.get_platform_io().textures:
            status = tex.status
            if status == imgui.ImTextureStatus.ok:
                continue
            if status in (imgui.ImTextureStatus.want_create, imgui.ImTextureStatus.want_updates):
                pixels = np.ascontiguousarray(tex.get_pixels_array(), np.uint8)
                key = int(tex.tex_id)
                gl_tex = self._textures.get(key)
                if gl_tex is None or gl_tex.size != (tex.width, tex.height):
                    gl_tex = self.ctx.texture((tex.width, tex.height), 4, pixels.tobytes())
                    gl_tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
                    gl_tex.repeat_x = gl_tex.repeat_y = False
                    key = gl_tex.glo
                    self._textures[key] = gl_tex
                    tex.set_tex_id(key)
                else:
                    gl_tex.write(pixels.tobytes())
                tex.status = imgui.ImTextureStatus.ok
            elif status == imgui.ImTextureStatus.want_destroy:
                gl_tex = self._textures.pop(int(tex.tex_id), None)
                if gl_tex is not None:
                    gl_tex.release()
                tex.set_tex_id(0)
                tex.status = imgui.ImTextureStatus.destroyed

    def texture_ref(self, texture: moderngl.Texture, nearest: bool = False, opaque: bool = False) -> imgui.ImTextureRef:
        """An id under which ImGui draws one of the application's textures (``imgui.image``,
        ``ImDrawList.add_image``). ``nearest``: sampled with nearest-texel filtering (magnified
        pixels stay square), whatever the texture's own filter. ``opaque``: drawn without blending
        (a photo: a software renderer then spends a third less on it). The texture stays the
        caller's; :meth:`forget_texture` before releasing it."""
        key = (texture.glo, bool(nearest), bool(opaque))
        tid = self._user_ids.get(key)
        if tid is None or self._textures.get(tid) is not texture:
            tid = _USER_TEXTURE_IDS + 4 * texture.glo + 2 * int(opaque) + int(nearest)
            self._user_ids[key] = tid
            self._textures[tid] = texture
            if opaque:
                self._opaque.add(tid)
            if nearest and tid not in self._samplers:
                sampler = self.ctx.sampler(filter=(moderngl.NEAREST, moderngl.NEAREST), repeat_x=False,
                                           repeat_y=False)
                self._samplers[tid] = sampler
        return imgui.ImTextureRef(tid)

    def forget_texture(self, texture: moderngl.Texture) -> None:
        """Stop drawing ``texture`` (about to be released)."""
        for nearest, opaque in ((False, False), (True, False), (False, True), (True, True)):
            tid = self._user_ids.pop((texture.glo, nearest, opaque), None)
            if tid is not None:
                self._textures.pop(tid, None)
                self._opaque.discard(tid)
                sampler = self._samplers.pop(tid, None)
                if sampler is not None:
                    sampler.release()

    def release(self) -> None:
        for key, t in self._textures.items():
            if key < _USER_TEXTURE_IDS:
                t.release()  # the application's textures are its own to release
        self._textures.clear()
        for sampler in self._samplers.values():
            sampler.release()
        self._samplers.clear()
        self._user_ids.clear()
        self._vao.release()
        self._vbo.release()
        self._ibo.release()
        imgui.destroy_context(self.context)
