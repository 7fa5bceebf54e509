"""The renderer (paper §5): the textured model drawn with moderngl, off-screen or into a window.

One :class:`Renderer` serves the headless context (evidence views, videos, benchmarks) and a
window's (the walk-through): it draws an :class:`~vebuild.camera.ImageCamera`'s view through the
one camera-to-clip conversion (:func:`vebuild.camera.gl_projection`) straight into the
destination: off-screen a multisampled 8-bit target resolved into a texture in image order (row 0
at the top), or a window's framebuffer (``flip_y``). Shading is computed in linear light and
encoded to sRGB once, in the fragment shader; textures are sRGB, decoded by the sampler.

Two modes: unlit, the extracted textures as photographed (the built-in ``as-photographed``
preset), and re-lit, the textures as surface colour under a preset's lights
(:mod:`vebuild.lighting`), with shadow maps for the lights that cast them: one tile of a
shared depth atlas for a directional light (orthographic, fitted to the scene) or a spot light
(perspective, its cone), six for a point light (one per cube face; :mod:`vebuild.render.shadows`).
Shadow maps are rendered when the scene or the lighting changes, not every frame. The scene
program is compiled per lighting preset and mode (:mod:`vebuild.render.variants`), and each view
draws closed primitives' back faces culled, nearest blocks first (:mod:`vebuild.render.draworder`).

A photo's camera with lens distortion (``ImageCamera.lens`` not the pinhole) is drawn as the lens shows it, so
that the render lies on the photo: the scene is drawn as the pinhole image over the photo's
undistorted bounds (:func:`vebuild.texture.lens.pinhole_cover`), then resampled onto the photo's
pixels through the division model (``shaders/lens.frag``: each pixel undistorted in closed form,
the pinhole image sampled bilinearly in linear light). Its ID buffer and picks are the lens's too:
pixel (u, v) of such a camera is where the lens put what it shows. Named views and stereo eyes are
pinholes, drawn directly.

Stereo (:func:`vebuild.camera.stereo_pair`): parallel eyes with off-axis frusta, composed
side by side (``sbs``, the left eye left), top and bottom (``tb``, the left eye on top), as a
red-cyan anaglyph with Dubois's least-squares matrices, or into a window's left and right back
buffers (``quad``) where its context offers quad-buffered stereo.

Texels no photo saw (the scene's masks, from the coverage maps: :mod:`vebuild.render.observed`)
are hatched, tinted or left as extracted (``RenderOptions.unobserved``, or the renderer's
``unobserved`` attribute, which may change between frames); hatched by default.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import moderngl
import numpy as np
from numpy.typing import NDArray

from vebuild.camera import (
    ImageCamera,
    depth_range,
    gl_projection,
    near_reach,
    stereo_pair,
    undistort_pixels,
    view_matrix,
    world_to_camera,
)
from vebuild.errors import VebuildError
from vebuild.gl import load_program
from vebuild.gl.context import make_current, max_texture_size
from vebuild.gl.shaders import set_uniforms, uniform
from vebuild.lighting import AS_PHOTOGRAPHED_LIGHTING, MAX_LIGHTS, Lighting
from vebuild.render.draworder import DrawOrder, side_planes
from vebuild.render.observed import (
    DEFAULT_UNOBSERVED,
    HATCH_DUTY,
    HATCH_PERIOD_M,
    HATCH_STRENGTH,
    TINT_STRENGTH,
    UNOBSERVED_MODES,
    UNOBSERVED_SRGB,
    check_mode,
)
from vebuild.render.scene import RenderScene
from vebuild.render.shadows import MAX_TILES, ShadowAtlas
from vebuild.render.sizes import check_camera, gl_limits
from vebuild.render.variants import UNIFORM_ARRAYS, light_uniforms, scene_defines
from vebuild.render.variants import vertex_array as _vertex_array
from vebuild.texture.lens import pinhole_cover
from vebuild.texture.merge import srgb8_to_linear

Array = NDArray[np.float64]

GL_SRGB8 = 0x8C41
STEREO_MODES = ("sbs", "tb", "anaglyph", "quad")
#: Red-cyan anaglyph matrices (E. Dubois, "A projection method to generate anaglyph stereo
#: images", ICASSP 2001): the least-squares fit of the perceived colours through red and cyan
#: filters to those of the two views; rows give (r, g, b) out, columns (r, g, b) of each eye.
ANAGLYPH_LEFT = np.array([[0.456, 0.500, 0.176], [-0.040, -0.038, -0.016], [-0.015, -0.021, -0.005]])
ANAGLYPH_RIGHT = np.array([[-0.043, -0.088, -0.002], [0.378, 0.734, -0.018], [-0.072, -0.113, 1.226]])
ANAGLYPH_LEFT.flags.writeable = ANAGLYPH_RIGHT.flags.writeable = False  # shared constants


@dataclass(frozen=True)
class RenderOptions:
    """Choices that hold for every frame of a renderer."""

    samples: int = 4  # multisample anti-aliasing (1: off)
    anisotropy: float = 8.0  # anisotropic texture filtering (1: trilinear only; costly on software GL)
    trilinear: bool = True  # blend between mipmap levels (False: the nearest level, ~20 % faster on llvmpipe)
    shadows: bool = True  # draw the shadows of lights that cast them
    shadow_size: int = 1024  # texels along a shadow tile's side
    background_srgb: tuple[int, int, int] = (38, 38, 44)
    highlight_srgb: tuple[int, int, int] = (255, 190, 0)
    unobserved: str = DEFAULT_UNOBSERVED  # how texels no photo saw are shown: hatch, tint or off

    @classmethod
    def interactive(cls) -> RenderOptions:
        """Settings for a frame loop on software GL: no multisampling or anisotropy, the nearest mip."""
        return cls(samples=1, anisotropy=1.0, trilinear=False)


@dataclass(frozen=True)
class Stereo:
    """A stereo pair: composition mode, eye separation (m) and convergence distance (m; None: the
    depth of the scene's centre in front of the camera, at least 0.5 m)."""

    mode: str
    separation: float = 0.063
    convergence: float | None = None


class Renderer:
    """Draws one :class:`RenderScene` from any camera (see the module's docstring)."""

    def __init__(self, ctx: moderngl.Context, scene: RenderScene, options: RenderOptions | None = None):
        self.ctx = ctx
        make_current(ctx)  # every entry point draws in its own context, whatever was current before
        self.options = options or RenderOptions()
        # The scene program's variants (vebuild.render.variants), and a vertex array for each used.
        self._vaos: dict[int, moderngl.VertexArray] = {}
        self.shadow_program = load_program(ctx, "shadow")
        self.pick_program = load_program(ctx, "id")  # the ID-buffer pass of texture extraction
        self._pick_target: moderngl.Framebuffer | None = None
        self.composite = load_program(ctx, "anaglyph", vertex="fullscreen")
        self._fullscreen = ctx.vertex_array(self.composite, [])
        self.lens_program = load_program(ctx, "lens", vertex="fullscreen")
        self._lens_fullscreen = ctx.vertex_array(self.lens_program, [])
        self._blank = ctx.texture((1, 1), 3, bytes([255, 255, 255]))
        self._shadow_blank = ctx.depth_texture((1, 1))
        self._shadow_blank.compare_func = "<="
        self._targets: dict[tuple[int, int, str], tuple[moderngl.Framebuffer, moderngl.Framebuffer,
                                                        moderngl.Texture]] = {}
        self._shadow = ShadowAtlas(ctx)
        self._shadow_state: dict[str, object] | None = None
        self.lighting: Lighting = AS_PHOTOGRAPHED_LIGHTING
        self.highlight: str | None = None
        #: How texels no photo saw are drawn (one of UNOBSERVED_MODES); may change between frames.
        self.unobserved: str = check_mode(self.options.unobserved, "unobserved")
        #: Leave out what the walls of the camera's room hide (vebuild.model.occlusion: the same pixels but at cracks).
        self.rooms_occlude = True
        self._pages: list[moderngl.Texture] = []
        self._masks: list[moderngl.Texture] = []
        self._no_mask = ctx.texture((1, 1), 1, bytes([0]))
        self._resources: list[moderngl.Buffer | moderngl.VertexArray] = []
        self.scene: RenderScene
        self._upload_pages(scene)
        self.set_scene(scene)

    # -- scene and lighting ------------------------------------------------------------------------

    def _upload_pages(self, scene: RenderScene) -> None:
        limit = max_texture_size(self.ctx)
        for page in scene.pages:
            h, w = page.shape[:2]
            if max(w, h) > limit:
                raise VebuildError(f"an atlas page of {w}×{h} texels is larger than this GPU's largest texture "
                                   f"({limit}); extract the textures again on this machine (`vebuild texture`)")
            tex = self.ctx.texture((w, h), 3, np.ascontiguousarray(page).tobytes(), internal_format=GL_SRGB8)
            tex.build_mipmaps()
            tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR if self.options.trilinear else moderngl.LINEAR_MIPMAP_NEAREST,
                          moderngl.LINEAR)
            tex.anisotropy = float(self.options.anisotropy)
            tex.repeat_x = tex.repeat_y = False
            self._pages.append(tex)
        for m in scene.masks:
            mask = self.ctx.texture((m.shape[1], m.shape[0]), 1, np.ascontiguousarray(m, np.uint8).tobytes())
            mask.filter = (moderngl.LINEAR, moderngl.LINEAR)  # a crisp edge at 0.5 between seen and unseen
            mask.repeat_x = mask.repeat_y = False
            self._masks.append(mask)
        self._any_unseen = scene.textured and any(bool((m > 127).any()) for m in scene.masks)

    @property
    def marks_unobserved(self) -> bool:
        """Whether frames mark something as unobserved now: the mode is not ``off`` and some
        texel of the scene's pages no photo saw (what a legend is drawn for)."""
        return self.unobserved != "off" and self._any_unseen

    def set_scene(self, scene: RenderScene) -> None:
        """Draw ``scene`` from now on (objects moved, say); its textures must be the same pages."""
        make_current(self.ctx)
        for r in [*self._resources, *self._vaos.values()]:
            r.release()
        mesh = scene.mesh
        self.scene = scene
        faces = mesh.face_of_vertex - 1
        page_of_face = np.array([f.page for f in mesh.faces], np.int32)
        sizes = np.array(mesh.pages if scene.textured else [(1, 1)], float)
        vpage = page_of_face[faces] if scene.textured else np.zeros(len(faces), np.int32)
        uv = mesh.atlas / sizes[vpage] if scene.textured else np.zeros((len(faces), 2))
        data = np.hstack([mesh.vertices, mesh.normals, uv, scene.face_colour[faces],
                          scene.node_of_face[faces][:, None], mesh.face_of_vertex[:, None]]).astype("f4")
        tri_page = vpage[mesh.triangles[:, 0]] if len(mesh.triangles) else np.zeros(0, np.int32)
        order = np.argsort(tri_page, kind="stable")
        index = mesh.triangles[order].astype("i4")
        self._order = DrawOrder(scene, tri_page.astype(np.int32))
        self._draw_ibo = self.ctx.buffer(self._order.index.tobytes())  # rewritten per view (draworder)
        self._vbo = vbo = self.ctx.buffer(data.tobytes())
        ibo = self.ctx.buffer(index.tobytes())
        self._vaos = {}
        self._shadow_vao = _vertex_array(self.ctx, self.shadow_program, vbo, ibo)
        self._pick_vao = _vertex_array(self.ctx, self.pick_program, vbo, self._draw_ibo)  # as the colour pass
        self._resources = [self._shadow_vao, self._pick_vao, vbo, ibo, self._draw_ibo]
        self._n_indices = int(index.size)
        self._bounds = scene.bounds()
        self._shadow_state = None  # the geometry moved: shadows are drawn again

    def set_lighting(self, lighting: Lighting) -> None:
        """Use a lighting preset from now on (``AS_PHOTOGRAPHED_LIGHTING``: unlit)."""
        if len(lighting.lights) > MAX_LIGHTS:
            raise VebuildError(f"lighting preset {lighting.name!r} has {len(lighting.lights)} lights; the renderer "
                               f"draws at most {MAX_LIGHTS}")
        tiles = sum(6 if light.type == "point" else 1 for light in lighting.shadow_casters)
        if self.options.shadows and tiles > MAX_TILES:
            raise VebuildError(f"lighting preset {lighting.name!r} needs {tiles} shadow maps (a point light takes "
                               f"six); the renderer has {MAX_TILES}: set \"shadows\": false on some lights")
        self.lighting = lighting
        self._shadow_state = None

    # -- shadows ---------------------------------------------------------------------------------

    def _update_shadows(self) -> None:
        lights = self.lighting.lights if self.options.shadows and self.lighting.lit else ()
        self._shadow_state = self._shadow.update(lights, int(self.options.shadow_size), self._bounds,
                                                 self.shadow_program, self._shadow_vao, self._n_indices)

    # -- drawing ---------------------------------------------------------------------------------

    def _near_far(self, cam: ImageCamera) -> tuple[float, float]:
        if isinstance(cam, _NarrowCamera):
            return cam.near, cam.far
        lo, hi = self._bounds
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        return depth_range(cam.R, cam.C, corners)

    def default_convergence(self, cam: ImageCamera) -> float:
        """Depth of the scene's centre in front of ``cam``, at least 0.5 m (the default screen plane)."""
        centre = 0.5 * (self._bounds[0] + self._bounds[1])
        return max(0.5, float(world_to_camera(cam.R, cam.C, centre)[2]))

    def _unobserved_mode(self) -> int:
        return (UNOBSERVED_MODES.index(check_mode(self.unobserved, "unobserved")) + 1
                if self.unobserved != "off" and self._masks else 0)

    @property
    def program(self) -> moderngl.Program:
        """The scene program's variant for the current lighting and modes (compiled once)."""
        defines = scene_defines(self.lighting, self.options.shadows, self.scene.textured, self._unobserved_mode())
        return load_program(self.ctx, "scene", defines)

    def _vao(self, prog: moderngl.Program) -> moderngl.VertexArray:
        if prog.glo not in self._vaos:
            self._vaos[prog.glo] = _vertex_array(self.ctx, prog, self._vbo, self._draw_ibo)
        return self._vaos[prog.glo]

    def _set_uniforms(self, cam: ImageCamera, flip: bool, prog: moderngl.Program) -> tuple[float, float]:
        near, far = self._near_far(cam)
        light = self.lighting
        values: dict[str, object] = {
            "view": view_matrix(cam.R, cam.C).T,
            "projection": gl_projection(cam.K, cam.width, cam.height, near, far, flip_y=flip).T,
            "eye": np.asarray(cam.C, float),
            "ambient": light.ambient,
            "n_lights": len(light.lights),
            "highlight_colour": srgb8_to_linear(np.array(self.options.highlight_srgb, np.uint8)),
            "highlight_node": self.scene.node_names.index(self.highlight)
            if self.highlight in self.scene.node_names else -1,
            "unobserved_mode": self._unobserved_mode(),
            "unobserved_colour": srgb8_to_linear(np.array(UNOBSERVED_SRGB, np.uint8)),
            "unobserved_strength": HATCH_STRENGTH if self.unobserved == "hatch" else TINT_STRENGTH,
            "hatch_period": HATCH_PERIOD_M,
            "hatch_duty": HATCH_DUTY,
        }
        if light.lit:
            if self._shadow_state is None:
                self._update_shadows()
            state = self._shadow_state or {}
            values.update(light_uniforms(light, state.get("first", {})))  # type: ignore[arg-type]
            if state.get("n"):
                values.update(shadow_matrix=state["matrices"], shadow_rect=state["rects"],
                              shadow_texel=state["texels"])
        for name, v in values.items():
            if name in prog:
                u = uniform(prog, name)
                if isinstance(v, bool | int | np.integer):
                    u.value = int(v)
                else:  # a variant may use the first elements of an array only
                    v = np.asarray(v)[: u.array_length] if name in UNIFORM_ARRAYS else v
                    u.write(np.ascontiguousarray(v, dtype="f4").tobytes())
        for name, unit in (("atlas", 0), ("shadow_atlas", 1), ("unseen_mask", 2)):
            if name in prog:
                uniform(prog, name).value = unit
        return near, far

    def _target(self, w: int, h: int, key: str) -> tuple[moderngl.Framebuffer, moderngl.Framebuffer,
                                                         moderngl.Texture]:
        """(draw, resolve, image) of size w × h: a multisampled sRGB 8-bit target with depth, and the
        single-sample texture it resolves into (the same framebuffer without multisampling)."""
        k = (w, h, key)
        if k not in self._targets:
            ctx = self.ctx
            samples = max(1, min(int(self.options.samples), int(ctx.info.get("GL_MAX_SAMPLES", 1))))
            image = ctx.texture((w, h), 4)
            image.filter = (moderngl.NEAREST, moderngl.NEAREST)
            if samples > 1:
                draw = ctx.framebuffer([ctx.renderbuffer((w, h), 4, samples=samples)],
                                       ctx.depth_renderbuffer((w, h), samples=samples))
                resolve = ctx.framebuffer([image])
            else:
                draw = resolve = ctx.framebuffer([image], ctx.depth_renderbuffer((w, h)))
            self._targets[k] = (draw, resolve, image)
        return self._targets[k]

    def _draw_scene(self, cam: ImageCamera, target: moderngl.Framebuffer, origin: tuple[int, int],
                    flip: bool) -> None:
        """One view of the scene into ``target``'s viewport at ``origin`` (sRGB encoded)."""
        ctx = self.ctx
        prog = self.program
        near, _ = self._set_uniforms(cam, flip, prog)  # may render shadow maps, so before binding the target
        viewport = (origin[0], origin[1], cam.width, cam.height)
        target.use()
        target.viewport = viewport
        bg = np.array(self.options.background_srgb, float) / 255.0
        # Alpha is cleared to 0 and drawn as 1: off-screen, it is the share of each pixel the model covers.
        target.clear(float(bg[0]), float(bg[1]), float(bg[2]), 0.0, depth=1.0, viewport=viewport)
        ctx.enable(moderngl.DEPTH_TEST)
        shadow_tex = self._shadow.texture if (self._shadow.texture is not None
                                              and (self._shadow_state or {}).get("n")) else self._shadow_blank
        shadow_tex.use(location=1)
        if "textured" in prog:
            uniform(prog, "textured").value = int(self.scene.textured)
        self._draw_ordered(self._vao(prog), cam, near, flip, textures=True)
        ctx.disable(moderngl.DEPTH_TEST)

    def _draw_ordered(self, vao: moderngl.VertexArray, cam: ImageCamera, near: float, flip: bool,
                      textures: bool) -> None:
        """All triangles through ``vao``, closed primitives' back faces culled, nearest first
        (:mod:`vebuild.render.draworder`); ``textures``: bind each page's atlas and mask."""
        ctx = self.ctx
        reach = cam.reach if isinstance(cam, _NarrowCamera) else near_reach(cam.K, cam.width, cam.height, near)
        planes = side_planes(cam.K, cam.R, cam.width, cam.height)
        index, ranges = self._order.plan(np.asarray(cam.C, float), reach, planes, self.rooms_occlude)
        if index is not None:
            self._draw_ibo.write(index.tobytes())
        # Outward (counter-clockwise) triangles wind clockwise in image order, counter-clockwise flipped.
        ctx.front_face = "ccw" if flip else "cw"
        bound = -1
        for r in ranges:
            if textures and r.page != bound:
                bound = r.page
                (self._pages[r.page] if self.scene.textured else self._blank).use(location=0)
                (self._masks[r.page] if self.scene.textured and r.page < len(self._masks)
                 else self._no_mask).use(location=2)
            (ctx.enable if r.cull else ctx.disable)(moderngl.CULL_FACE)
            vao.render(moderngl.TRIANGLES, vertices=r.count, first=r.first)
        ctx.disable(moderngl.CULL_FACE)
        ctx.front_face = "ccw"

    def _anaglyph(self, target: moderngl.Framebuffer, origin: tuple[int, int], left: ImageCamera,
                  right: ImageCamera, flip: bool) -> None:
        images = []
        for side, cam in (("left", left), ("right", right)):
            draw, resolve, image = self._target(cam.width, cam.height, f"anaglyph-{side}")
            self._draw_scene(cam, draw, (0, 0), flip=False)
            if draw is not resolve:
                self.ctx.copy_framebuffer(resolve, draw)
            images.append(image)
        prog = self.composite
        target.use()
        target.viewport = (origin[0], origin[1], left.width, left.height)
        images[0].use(location=0)
        images[1].use(location=1)
        for name, v in {"left": 0, "right": 1, "flip": int(flip), "origin": origin}.items():
            if name in prog:
                uniform(prog, name).value = v
        uniform(prog, "anaglyph_left").write(ANAGLYPH_LEFT.T.astype("f4").tobytes())
        uniform(prog, "anaglyph_right").write(ANAGLYPH_RIGHT.T.astype("f4").tobytes())
        self._fullscreen.render(moderngl.TRIANGLES, vertices=3)

    def _draw_through_lens(self, cam: ImageCamera, target: moderngl.Framebuffer, origin: tuple[int, int],
                           flip: bool) -> None:
        """``cam``'s view as its lens shows it (``cam.lens`` not the pinhole): the pinhole cover drawn off-screen,
        then resampled through the lens into ``target``'s viewport at ``origin``."""
        cover, corner = pinhole_cover(cam)
        draw, resolve, image = self._target(cover.width, cover.height, "lens")
        self._draw_scene(cover, draw, (0, 0), flip=False)
        if draw is not resolve:
            self.ctx.copy_framebuffer(resolve, draw)
        prog = self.lens_program
        target.use()
        target.viewport = (origin[0], origin[1], cam.width, cam.height)
        self.ctx.disable(moderngl.BLEND)
        image.use(location=0)
        K = np.asarray(cam.K, float)
        set_uniforms(prog, pinhole=0, focal=float(K[0, 0]), principal=(float(K[0, 2]), float(K[1, 2])),
                     k1=float(cam.lens.k1), k2=float(cam.lens.k2), cover_origin=(float(corner[0]), float(corner[1])),
                     size=(float(cam.width), float(cam.height)), origin=(float(origin[0]), float(origin[1])),
                     flip=int(flip))
        self._lens_fullscreen.render(moderngl.TRIANGLES, vertices=3)

    def check_size(self, cam: ImageCamera, stereo: Stereo | None = None) -> tuple[int, int]:
        """The composed image's width and height, if this context can draw it; otherwise a
        VebuildError naming where the size came from (``cam.source``) and what is allowed
        (:mod:`vebuild.render.sizes`). Every image the renderer allocates passes here first: for
        a camera with lens distortion, its pinhole cover too (drawn before the lens's resampling)."""
        limits = gl_limits(self.ctx)
        size = check_camera(cam, stereo.mode if stereo else None, **limits)
        if stereo is None and not cam.lens.is_pinhole:
            check_camera(pinhole_cover(cam)[0], None, **limits)
        return size

    def output_size(self, cam: ImageCamera, stereo: Stereo | None = None) -> tuple[int, int]:
        """Width and height of the composed image."""
        w, h = cam.width, cam.height
        mode = stereo.mode if stereo else None
        return (2 * w, h) if mode == "sbs" else (w, 2 * h) if mode == "tb" else (w, h)

    def eyes(self, cam: ImageCamera, stereo: Stereo | None) -> list[ImageCamera]:
        """The cameras drawn: ``cam`` alone, or its stereo pair (left, right)."""
        if stereo is None:
            return [cam]
        if stereo.mode not in STEREO_MODES:
            raise VebuildError(f"unknown stereo mode {stereo.mode!r}; expected one of {', '.join(STEREO_MODES)}")
        conv = stereo.convergence if stereo.convergence is not None else self.default_convergence(cam)
        try:
            return list(stereo_pair(cam, stereo.separation, conv))
        except ValueError as e:
            raise VebuildError(f"stereo: {e}") from None

    def draw(self, target: moderngl.Framebuffer, cam: ImageCamera, stereo: Stereo | None = None, flip: bool = False,
             origin: tuple[int, int] = (0, 0), select_buffer: Callable[[str], None] | None = None) -> None:
        """Draw ``cam``'s view (or its stereo composition) into ``target`` at ``origin``.

        ``flip``: the target is a window's framebuffer (image row 0 at the top of the screen);
        off-screen, framebuffer row 0 is the image's top row so that a read-back is in image order.
        ``select_buffer``: for ``quad`` stereo, selects the window's "left" or "right" back buffer.
        """
        make_current(self.ctx)
        eyes = self.eyes(cam, stereo)
        w, h = cam.width, cam.height
        x, y = origin
        mode = stereo.mode if stereo else None
        if mode is None and not cam.lens.is_pinhole:
            self._draw_through_lens(cam, target, origin, flip)
        elif mode is None:
            self._draw_scene(cam, target, origin, flip)
        elif mode == "anaglyph":
            self._anaglyph(target, origin, eyes[0], eyes[1], flip)
        elif mode == "quad":
            if select_buffer is None:
                raise VebuildError("quad-buffered stereo needs a window whose OpenGL context offers it; off-screen, "
                                   "use sbs, tb or anaglyph")
            for side, eye in zip(("left", "right"), eyes, strict=True):
                select_buffer(side)
                self._draw_scene(eye, target, origin, flip)
        else:
            # The left eye goes left (sbs) or on top (tb): the image's top is framebuffer row 0
            # off-screen and the last row in a window.
            if mode == "sbs":
                places = [(x, y), (x + w, y)]
            else:
                places = [(x, y + h), (x, y)] if flip else [(x, y), (x, y + h)]
            for place, eye in zip(places, eyes, strict=True):
                self._draw_scene(eye, target, place, flip)

    def frame(self, cam: ImageCamera, stereo: Stereo | None = None) -> moderngl.Texture:
        """Draw one frame off-screen (no read-back); returns the texture holding it (image order)."""
        W, H = self.check_size(cam, stereo)
        draw, resolve, image = self._target(W, H, "output")
        self.draw(draw, cam, stereo)
        if draw is not resolve:
            self.ctx.copy_framebuffer(resolve, draw)
        return image

    def render(self, cam: ImageCamera, stereo: Stereo | None = None) -> NDArray[np.uint8]:
        """The composed image as (height, width, 3) sRGB uint8, row 0 at the top."""
        return self.render_rgba(cam, stereo)[..., :3].copy()

    def render_rgba(self, cam: ImageCamera, stereo: Stereo | None = None) -> NDArray[np.uint8]:
        """(height, width, 4): the image and, in alpha, the share of each pixel the model covers
        (255 inside, fractions at anti-aliased silhouettes, 0 on the background; 255 everywhere
        for an anaglyph)."""
        W, H = self.output_size(cam, stereo)
        data = self.frame(cam, stereo).read(alignment=1)
        return np.frombuffer(data, np.uint8).reshape(H, W, 4).copy()

    def id_buffer(self, cam: ImageCamera) -> tuple[NDArray[np.int32], NDArray[np.float32]]:
        """The ID buffer of ``cam``'s view (the texture-extraction pass, paper Figure 8): per pixel
        the 1-based global face id seen at its centre (0: nothing) and that face's camera depth.

        With lens distortion, the pixel centres are where the lens put them: each is undistorted
        and looked up (nearest pixel) in the ID buffer of the camera's pinhole cover."""
        make_current(self.ctx)
        self.check_size(cam)
        if cam.lens.is_pinhole:
            return self._pinhole_id_buffer(cam)
        cover, corner = pinhole_cover(cam)
        ids, depth = self._pinhole_id_buffer(cover)
        j, i = np.mgrid[0:cam.height, 0:cam.width]
        uv = undistort_pixels(cam.K, np.stack([i + 0.5, j + 0.5], axis=-1), cam.lens) - np.array(corner, float)
        col, row = np.floor(uv[..., 0]).astype(np.intp), np.floor(uv[..., 1]).astype(np.intp)
        inside = (col >= 0) & (row >= 0) & (col < cover.width) & (row < cover.height)
        col, row = np.where(inside, col, 0), np.where(inside, row, 0)
        return np.where(inside, ids[row, col], 0).astype(np.int32), np.where(inside, depth[row, col], 0.0).astype(
            np.float32)

    def _pinhole_id_buffer(self, cam: ImageCamera) -> tuple[NDArray[np.int32], NDArray[np.float32]]:
        """:meth:`id_buffer` of a pinhole camera (its lens ignored)."""
        near, far = self._near_far(cam)
        key = (cam.width, cam.height)
        if self._pick_target is None or self._pick_target.size != key:
            self._release_pick_target()
            tex = self.ctx.texture(key, 2, dtype="f4")
            self._pick_target = self.ctx.framebuffer([tex], self.ctx.depth_renderbuffer(key))
        fbo = self._pick_target
        fbo.use()
        fbo.viewport = (0, 0, cam.width, cam.height)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        prog = self.pick_program
        uniform(prog, "view").write(view_matrix(cam.R, cam.C).T.astype("f4").tobytes())
        P = gl_projection(cam.K, cam.width, cam.height, near, far)
        uniform(prog, "projection").write(P.T.astype("f4").tobytes())
        self.ctx.enable(moderngl.DEPTH_TEST)
        self._draw_ordered(self._pick_vao, cam, near, False, textures=False)
        self.ctx.disable(moderngl.DEPTH_TEST)
        target = fbo.color_attachments[0]
        assert isinstance(target, moderngl.Texture)
        data = np.frombuffer(target.read(), "f4").reshape(cam.height, cam.width, 2)
        ids = np.rint(np.nan_to_num(data[..., 0], nan=-1.0, posinf=-1.0, neginf=-1.0))  # no face: nothing
        return np.where((ids >= 0) & (ids <= len(self.scene.mesh.faces)), ids, 0).astype(np.int32), data[..., 1].copy()

    def node_mask(self, cam: ImageCamera, node: str) -> NDArray[np.bool_]:
        """(height, width) pixels of ``cam``'s view where ``node`` (or a part of it) is what is seen."""
        faces, _ = self.id_buffer(cam)
        names = set(self.scene.model.subtree(node))
        of_node = np.array([False] + [f.node in names for f in self.scene.mesh.faces])
        return of_node[faces]

    def pick(self, cam: ImageCamera, u: float, v: float) -> tuple[str | None, Array | None]:
        """The node and the world point seen at pixel position (u, v) of ``cam``'s view, through an
        ID buffer of that one pixel (the camera's frustum narrowed to it); (None, None) on the
        background."""
        if not (0 <= u < cam.width and 0 <= v < cam.height):
            return None, None
        if not cam.lens.is_pinhole:  # where the pinhole of the same K shows what the lens put at (u, v)
            u, v = (float(t) for t in undistort_pixels(cam.K, np.array([u, v], float), cam.lens))
        near, far = self._near_far(cam)
        K = np.array(cam.K, float)  # (u, v) at the centre of a 1 × 1 image, same near and far planes
        K[0, 2] -= u - 0.5
        K[1, 2] -= v - 0.5
        reach = near_reach(cam.K, cam.width, cam.height, near)  # the whole view's, so that it culls alike
        faces, depth = self.id_buffer(_NarrowCamera(cam.id, K, cam.R, cam.C, 1, 1, near, far, reach))
        face = int(faces[0, 0])
        if face == 0:
            return None, None
        node = self.scene.mesh.faces[face - 1].node
        ray = np.linalg.solve(cam.K, [u, v, 1.0])  # camera coordinates at depth 1
        return node, np.asarray(cam.C, float) + float(depth[0, 0]) * (np.asarray(cam.R, float).T @ ray)

    def _release_pick_target(self) -> None:
        if self._pick_target is not None:
            for t in self._pick_target.color_attachments:
                t.release()
            self._pick_target.release()
            self._pick_target = None

    def release(self) -> None:
        """Free the GPU resources."""
        make_current(self.ctx)  # released in another context, the names would free that one's objects
        for r in [*self._resources, *self._vaos.values()]:
            r.release()
        self._resources, self._vaos = [], {}
        for t in [*self._pages, *self._masks, self._no_mask]:
            t.release()
        self._pages, self._masks = [], []
        for draw, resolve, image in self._targets.values():
            if draw is not resolve:
                draw.release()
            resolve.release()
            image.release()
        self._targets.clear()
        self._shadow.release()
        self._release_pick_target()


@dataclass(frozen=True)
class _NarrowCamera(ImageCamera):
    """A camera narrowed to part of another's image, keeping its near and far planes (depths agree)."""

    near: float = 0.0
    far: float = 0.0
    reach: float = 0.0  # how far the whole view's near plane reaches (vebuild.render.draworder)
