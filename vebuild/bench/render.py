"""``vebuild bench render``: frames per second of the renderer (paper §5) at 1280×720 per eye.

Scenes: the example room (its true model, textures extracted from its five photos, seen from its
first photo's camera) and 200 primitives (boxes, cylinders, cones, wedges and spheres on a
16 × 12 m floor, a procedural atlas at the extraction's default 200 texels per metre, seen from
a corner at eye height). Lighting: unlit (``as-photographed``), re-lit by a sun without shadows,
and by a sun with shadows. Views: mono, and a side-by-side stereo pair (two eyes of 1280×720).

Figures per case, as fps from the fastest frame of a run (at least 3 frames and 1 s; quick: one)
after one warm-up frame: other work on the machine only adds time, so the fastest frame is the
renderer's own speed (the minimum, as ``timeit`` takes it); the load average is reported too:

- ``frame_loop``: ``RenderOptions.interactive()`` (1 sample, trilinear filtering),
  ``Renderer.frame`` + ``ctx.finish()``, no read-back: the walk-through window's frame
  (``vebuild view`` draws the same scene with the same settings into its back buffer) measured
  off-screen, without a display, its swap, photo overlay or panel.
- ``render``: ``Renderer.render`` (colour read back to numpy) at pyrender's settings: 4× MSAA,
  trilinear filtering (anisotropy 1), a 2048² shadow map. The equal-work comparison.
- ``stills``: ``Renderer.render`` at the stills defaults, ``RenderOptions()`` (4× MSAA, 8×
  anisotropic filtering, 1024² shadow map). Full run only.
- ``pyrender``: the reference, pyrender's ``OffscreenRenderer.render`` in the same process on the
  same triangles, normals, atlas pages and UVs, camera and lights (see :func:`_pyrender_reference`).
  It reads back colour and depth every frame, and redraws its shadow maps every frame; vebuild
  draws them when the scene or lighting changes, so ``render_shadows_redrawn`` times vebuild with
  its shadow map redrawn every frame too.

The floor (:mod:`vebuild.bench.render_floor`): a minimal program drawing the same triangles with
one texture and no lighting, timed frame by frame alternately with each mono ``frame_loop`` case;
``frame_fps_<setting>`` and ``frame_share_of_floor_<setting>`` (settings ``example_unlit``,
``example_lit_sun``, ``example_shadows``, ``200_unlit``, ``200_lit``, ``200_shadows``) and
``frame_fps_floor_example`` / ``frame_fps_floor_200`` say how near the frame loop comes to it.

pyrender is optional (``pip install 'vebuild[bench]'``); without it, or where it fails, the
figures say why (``*_pyrender_unavailable``) and vebuild's are still reported. It is used here
only, never by vebuild itself.

Two OpenGL contexts in one process: moderngl's (vebuild's, from :func:`headless_context`) and
pyrender's EGL context share one EGL display. pyrender makes its context current in every
``render`` and leaves it current; vebuild's is made current (``Context.__enter__``) before each of
its draws and left current at the end, since glcontext's ``__exit__`` leaves no context current.
pyrender's own ``delete`` ends with ``eglTerminate`` on that shared display, which would end
vebuild's context too, so the bench frees pyrender's context itself (:func:`_close_pyrender`).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import moderngl
import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera, depth_range, intrinsic_matrix, look_rotation
from vebuild.console.bars import Bar
from vebuild.gl.context import headless_context, renderer_name
from vebuild.lighting import AS_PHOTOGRAPHED_LIGHTING, Lighting
from vebuild.model.scene import Model, model_from_dict
from vebuild.project.decode import preset_from_record
from vebuild.render.renderer import Renderer, RenderOptions, Stereo
from vebuild.render.scene import RenderScene, scene_from_model
from vebuild.texture import layout as lay

from .render_floor import Floor, paired_fps

GOALS = {"frame_loop_mono_fps": 60.0, "speedup_over_pyrender": 10.0, "share_of_floor": 0.6}
#: The frame loop's settings as its figures name them (``frame_fps_<name>``), and their fps goals.
FRAME_SETTINGS = {("example", "unlit"): "example_unlit", ("example", "lit"): "example_lit_sun",
                  ("example", "shadows"): "example_shadows", ("primitives200", "unlit"): "200_unlit",
                  ("primitives200", "lit"): "200_lit", ("primitives200", "shadows"): "200_shadows"}
FRAME_GOALS = {"example_lit_sun": 60.0, "example_shadows": 45.0, "200_unlit": 60.0, "200_lit": 30.0}
FLOOR_NAMES = {"example": "example", "primitives200": "200"}
WIDTH, HEIGHT = 1280, 720
SCENES = {"example": "example room", "primitives200": "200 primitives"}
LIGHTINGS = {"unlit": "unlit", "lit": "sun, no shadows", "shadows": "sun + shadows"}
VIEWS = {"mono": "mono", "stereo": "stereo (sbs)"}
SUN: dict[str, Any] = {"name": "sun", "ambient": [0.2, 0.2, 0.2],
                       "lights": [{"type": "directional", "direction": [0.5, 0.3, -1.0], "intensity": 1.2,
                                   "shadows": True}]}
#: The measured renderers' settings (see the module's docstring).
PYRENDER_SHADOW_SIZE = 2048  # pyrender.constants.SHADOW_TEX_SZ
SETTINGS = {"frame_loop": RenderOptions.interactive(),
            "render": RenderOptions(samples=4, anisotropy=1.0, shadow_size=PYRENDER_SHADOW_SIZE),
            "stills": RenderOptions()}
N_PRIMITIVES = 200
FLOOR_M = (16.0, 12.0)
PYRENDER_MISSING = "pyrender is not installed (pip install 'vebuild[bench]')"


@dataclass
class Timing:
    seconds: float  # run at least this long after the warm-up frame
    min_frames: int
    max_frames: int


def _fps(draw: Callable[[], object], timing: Timing) -> float:
    """Frames per second from the fastest call of ``draw`` after one warm-up call."""
    draw()
    times: list[float] = []
    end = time.perf_counter() + timing.seconds
    while len(times) < timing.min_frames or (time.perf_counter() < end and len(times) < timing.max_frames):
        t = time.perf_counter()
        draw()
        times.append(time.perf_counter() - t)
    return 1.0 / min(times)


# -- the scenes ------------------------------------------------------------------------------------


def example_scene() -> tuple[RenderScene, ImageCamera]:
    """The example room's true model with textures extracted from its photos, and its first
    photo's camera at 1280×720 (the same horizontal field of view)."""
    from vebuild.actions import example_truth as truth
    from vebuild.texture.extract import PhotoSource, extract
    from vebuild.texture.options import Options

    model, cams = truth.true_model(), truth.true_cameras()
    result = extract(model, cams, {c.id: PhotoSource(c.id, truth.photo_path(c.id)) for c in cams}, Options())
    scene = scene_from_model(model, _record(result.faces), result.atlases)
    return scene, cams[0].resized(WIDTH, HEIGHT)


def primitives_model(n: int = N_PRIMITIVES, seed: int = 3) -> Model:
    """A floor with ``n`` primitives of five kinds resting on it at random (seeded)."""
    rng = np.random.default_rng(seed)
    w, d = FLOOR_M
    nodes: list[Mapping[str, Any]] = [
        {"name": "floor", "primitive": {"type": "quad", "params": {"width": w, "depth": d}},
         "joint": {"type": "marker", "marker": "O", "handle": "v0", "yaw_deg": 0.0}}]
    kinds = ("box", "box", "box", "cylinder", "frustum", "wedge", "sphere")
    for k in range(n):
        kind = kinds[k % len(kinds)]
        a, b, h = (float(v) for v in rng.uniform(0.3, 1.5, 3))
        params = {"box": {"width": a, "depth": b, "height": h}, "wedge": {"width": a, "depth": b, "height": h},
                  "cylinder": {"radius": a / 2, "height": h},
                  "frustum": {"radius_bottom": a / 2, "radius_top": b / 4, "height": h},
                  "sphere": {"radius": a / 2}}[kind]
        pos = [float(rng.uniform(-w / 2 + 1, w / 2 - 1)), float(rng.uniform(-d / 2 + 1, d / 2 - 1))]
        nodes.append({"name": f"{kind}{k}", "parent": "floor", "primitive": {"type": kind, "params": params},
                      "joint": {"type": "rests_on", "face": "top", "position": pos,
                                "yaw_deg": float(rng.uniform(0, 90))}})
    return model_from_dict(nodes, {"O": np.zeros(3)})


def primitives_scene(texels_per_metre: float = 200.0) -> tuple[RenderScene, ImageCamera]:
    """:func:`primitives_model` with a procedural atlas (a checker in each face's own colour), and a
    camera in a corner of the floor at eye height looking across it."""
    model = primitives_model()
    # A drawn atlas, not an extraction's: the extraction's limit on its sums (2 GiB) does not apply.
    faces = lay.layout(model, texels_per_metre, 2048, 4096, max_texels=1 << 27)
    sizes = lay.page_sizes(faces)
    rng = np.random.default_rng(5)
    pages = [np.full((h, w, 3), 128, np.uint8) for w, h in sizes]
    for f in faces:
        x0, y0, fw, fh = f.rect
        checker = ((np.arange(fh)[:, None] >> 4) + (np.arange(fw)[None, :] >> 4)) & 1
        colour = rng.uniform(60.0, 230.0, 3)
        pages[f.page][y0:y0 + fh, x0:x0 + fw] = (colour * (0.75 + 0.25 * checker[..., None])).astype(np.uint8)
    scene = scene_from_model(model, _record(faces), pages)
    C = np.array([-2.5, -2.5, 2.4])
    K = intrinsic_matrix(1000.0, WIDTH / 2, HEIGHT / 2)
    target = np.array([FLOOR_M[0] / 2, FLOOR_M[1] / 2, 0.3])
    return scene, ImageCamera("corner", K, look_rotation(target - C), C, WIDTH, HEIGHT)


def _record(faces: list[lay.Face]) -> dict[str, Any]:
    """The ``textures`` record's faces, as :func:`scene_from_model` reads them."""
    return {"faces": [{"id": f.id, "node": f.node, "face": f.name, "size_m": list(f.size_m), "page": f.page,
                       "rect": list(f.rect)} for f in faces]}


def _describe(scene: RenderScene) -> dict[str, Any]:
    m = scene.mesh
    return {"primitives": sum(1 for n in scene.model.nodes if n.primitive is not None), "faces": len(m.faces),
            "triangles": len(m.triangles), "pages": len(scene.pages),
            "texels_millions": sum(p.shape[0] * p.shape[1] for p in scene.pages) / 1e6}


# -- vebuild ---------------------------------------------------------------------------------------


def _current(ctx: moderngl.Context) -> None:
    """Make vebuild's context current (pyrender leaves its own current after drawing); see the
    module's docstring for why it is never exited."""
    ctx.__enter__()


def _lightings() -> dict[str, Lighting]:
    no_shadows = {**SUN, "lights": [{**SUN["lights"][0], "shadows": False}]}
    return {"unlit": AS_PHOTOGRAPHED_LIGHTING, "lit": preset_from_record(no_shadows),
            "shadows": preset_from_record(SUN)}


def measure_vebuild(ctx: moderngl.Context, scene: RenderScene, cam: ImageCamera, settings: str, timing: Timing,
                    views: tuple[str, ...], bar: Bar,
                    prefix: str) -> tuple[dict[str, float], dict[str, np.ndarray], list[ImageCamera]]:
    """fps of one settings row for every lighting and view; the mono images (``render`` row);
    the stereo pair's eyes."""
    _current(ctx)
    r = Renderer(ctx, scene, SETTINGS[settings])
    floor = Floor(ctx, scene, cam) if settings == "frame_loop" else None
    out: dict[str, float] = {}
    images: dict[str, np.ndarray] = {}
    eyes = r.eyes(cam, Stereo("sbs"))
    try:
        for lname, lighting in _lightings().items():
            r.set_lighting(lighting)
            for view in views:
                stereo = Stereo("sbs") if view == "stereo" else None
                if settings == "frame_loop":
                    def draw(stereo: Stereo | None = stereo) -> None:
                        _current(ctx)
                        r.frame(cam, stereo)
                        ctx.finish()
                else:
                    def draw(stereo: Stereo | None = stereo) -> None:
                        _current(ctx)
                        r.render(cam, stereo)
                if floor is not None and view == "mono":  # beside the floor, frame by frame
                    c = f"{prefix}_{lname}_{view}"
                    out[f"{c}_{settings}_fps"], out[f"{c}_floor_fps"], out[f"{c}_share_of_floor"] = paired_fps(
                        draw, floor.frame, max(10, timing.min_frames), timing.seconds, timing.max_frames)
                else:
                    out[f"{prefix}_{lname}_{view}_{settings}_fps"] = _fps(draw, timing)
                bar.update(1)
                if settings == "render" and view == "mono":
                    images[lname] = r.render(cam)
            if settings == "render" and lname == "shadows":
                for view in views:  # the shadow map redrawn every frame, as pyrender does
                    stereo = Stereo("sbs") if view == "stereo" else None

                    def redraw(stereo: Stereo | None = stereo, lighting: Lighting = lighting) -> None:
                        _current(ctx)
                        r.set_lighting(lighting)
                        r.render(cam, stereo)
                    out[f"{prefix}_shadows_{view}_render_shadows_redrawn_fps"] = _fps(redraw, timing)
    finally:
        _current(ctx)
        r.release()
        if floor is not None:
            floor.release()
    return out, images, eyes


# -- pyrender --------------------------------------------------------------------------------------


def _import_pyrender() -> tuple[Any, str]:
    """(the pyrender module or None, why not)."""
    platform = os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    if platform != "egl":
        return None, f"the bench drives pyrender on EGL only (PYOPENGL_PLATFORM={platform!r})"
    try:
        import pyrender
    except ImportError:
        return None, PYRENDER_MISSING
    except Exception as e:  # an unmaintained package on a newer stack: say what broke
        return None, f"pyrender failed to import: {type(e).__name__}: {e}"
    return pyrender, ""


def _gl_pose(R: NDArray[np.float64], C: NDArray[np.float64]) -> NDArray[np.float64]:
    """Camera (or light) to world for pyrender: OpenGL axes (looking along −Z, +Y up) of a
    camera whose world → camera rotation is ``R`` (vebuild's convention: +z ahead, +y down)."""
    pose = np.eye(4)
    pose[:3, :3] = np.asarray(R, float).T @ np.diag([1.0, -1.0, -1.0])
    pose[:3, 3] = C
    return pose


def _near_far(scene: RenderScene, cam: ImageCamera) -> tuple[float, float]:
    lo, hi = scene.bounds()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return depth_range(cam.R, cam.C, corners)


def _pyrender_scene(pyrender: Any, scene: RenderScene, lighting: Lighting, background: tuple[int, int, int]) -> Any:
    """The scene's world mesh as pyrender primitives (one per atlas page, sharing nothing with
    vebuild), its pages as textures, and the lighting's directional lights."""
    from pyrender.constants import GLTF

    mesh = scene.mesh
    page_of_face = np.array([f.page for f in mesh.faces])
    tri_page = page_of_face[mesh.triangle_faces - 1]
    prims = []
    for p, page in enumerate(scene.pages):
        tris = mesh.triangles[tri_page == p]
        used, index = np.unique(tris, return_inverse=True)
        # pyrender uploads RGB rows with OpenGL's default 4-byte row alignment: pad them to match.
        page = np.pad(page, ((0, 0), (0, -page.shape[1] % 4), (0, 0)), mode="edge")
        h, w = page.shape[:2]
        # pyrender flips a texture's rows on upload (glTF's v grows up): v = 1 − y / height.
        uv = np.column_stack([mesh.atlas[used, 0] / w, 1.0 - mesh.atlas[used, 1] / h])
        sampler = pyrender.Sampler(wrapS=GLTF.CLAMP_TO_EDGE, wrapT=GLTF.CLAMP_TO_EDGE)
        texture = pyrender.Texture(source=page, source_channels="RGB", sampler=sampler)
        material = pyrender.MetallicRoughnessMaterial(baseColorTexture=texture, metallicFactor=0.0,
                                                      roughnessFactor=1.0, doubleSided=True)
        prims.append(pyrender.Primitive(positions=mesh.vertices[used].astype(np.float32),
                                        normals=mesh.normals[used].astype(np.float32),
                                        texcoord_0=uv.astype(np.float32),
                                        indices=index.reshape(-1, 3).astype(np.uint32), material=material))
    pmesh = pyrender.Mesh(prims)
    # pyrender 0.1.45's Mesh.bounds uses np.infty, gone in numpy 2 (shadows need the bounds): set them.
    pmesh._bounds = np.array([mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)])
    bg = [c / 255.0 for c in background] + [1.0]
    ps = pyrender.Scene(bg_color=bg, ambient_light=np.asarray(lighting.ambient, float))
    ps.add(pmesh)
    for light in lighting.lights:
        if light.type != "directional":
            raise ValueError(f"the bench maps directional lights only, not {light.type}")
        assert light.direction is not None  # a directional light has one
        peak = float(np.max(light.colour))
        # pyrender's Lambert term is colour·intensity·(n·l)/π: intensity π·E gives irradiance E.
        pl = pyrender.DirectionalLight(color=light.colour / peak, intensity=math.pi * peak)
        ps.add(pl, pose=_gl_pose(look_rotation(light.direction), np.zeros(3)))
    return ps


def _close_pyrender(r: Any) -> None:
    """Free pyrender's renderer and EGL context without its ``delete``'s ``eglTerminate``."""
    from OpenGL import EGL  # type: ignore[import-not-found,import-untyped,unused-ignore]  # PyOpenGL, pyrender's dependency: no stubs

    plat = r._platform
    if plat is None:
        return
    plat.make_current()
    r._renderer.delete()
    EGL.eglMakeCurrent(plat._egl_display, EGL.EGL_NO_SURFACE, EGL.EGL_NO_SURFACE, EGL.EGL_NO_CONTEXT)
    EGL.eglDestroyContext(plat._egl_display, plat._egl_context)
    r._renderer = r._platform = None  # its __del__ then has nothing to delete


def _pyrender_reference(pyrender: Any, ctx: moderngl.Context, scene: RenderScene, cam: ImageCamera,
                        eyes: list[ImageCamera], timing: Timing, views: tuple[str, ...], bar: Bar,
                        prefix: str) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """pyrender's fps for every lighting and view (stereo: both eyes rendered), and its mono images."""
    from pyrender import RenderFlags

    out: dict[str, Any] = {}
    images: dict[str, np.ndarray] = {}
    flags = {"unlit": RenderFlags.FLAT, "lit": RenderFlags.NONE, "shadows": RenderFlags.SHADOWS_DIRECTIONAL}
    renderer = None
    try:
        renderer = pyrender.OffscreenRenderer(WIDTH, HEIGHT)
    except Exception as e:
        why = f"pyrender could not make its context: {type(e).__name__}: {e}"
        for lname in LIGHTINGS:
            for view in views:
                out[f"{prefix}_{lname}_{view}_pyrender_unavailable"] = why
                bar.update(1)
        return out, images
    try:
        # One scene for the three cases: FLAT ignores the lights, and only SHADOWS_DIRECTIONAL draws shadows.
        ps = _pyrender_scene(pyrender, scene, _lightings()["shadows"], RenderOptions().background_srgb)
        nodes = {}
        for c in (cam, *eyes):
            near, far = _near_far(scene, c)
            pc = pyrender.IntrinsicsCamera(c.K[0, 0], c.K[1, 1], c.K[0, 2], c.K[1, 2], znear=near, zfar=far)
            nodes[c.id] = ps.add(pc, pose=_gl_pose(c.R, c.C))
        for lname in LIGHTINGS:
            for view in views:
                key = f"{prefix}_{lname}_{view}_pyrender"
                shots = [cam] if view == "mono" else eyes

                def draw(shots: list[ImageCamera] = shots, f: int = flags[lname]) -> Any:
                    for c in shots:
                        ps.main_camera_node = nodes[c.id]
                        colour, _ = renderer.render(ps, flags=f)
                    return colour
                try:
                    out[f"{key}_fps"] = _fps(draw, timing)
                    if view == "mono":
                        images[lname] = np.asarray(draw([cam]))[..., :3].copy()
                except Exception as e:
                    out[f"{key}_unavailable"] = f"{type(e).__name__}: {str(e).strip()[:200]}"
                bar.update(1)
    except Exception as e:  # the scene or cameras could not be built: no case ran
        for lname in LIGHTINGS:
            for view in views:
                out[f"{prefix}_{lname}_{view}_pyrender_unavailable"] = f"{type(e).__name__}: {str(e).strip()[:200]}"
                bar.update(1)
    finally:
        _close_pyrender(renderer)
        _current(ctx)
    return out, images


def _agreement(a: np.ndarray, b: np.ndarray, background: tuple[int, int, int]) -> dict[str, float]:
    """Mean |a − b| in 8-bit levels, and each image's share of pixels off the background."""
    bg = np.array(background, int)
    fg = lambda im: float(np.mean(np.abs(im.astype(int) - bg).max(axis=-1) > 3))  # noqa: E731
    return {"mean_abs_diff_levels": float(np.mean(np.abs(a.astype(int) - b.astype(int)))),
            "foreground_share": fg(a), "pyrender_foreground_share": fg(b)}


# -- the bench -------------------------------------------------------------------------------------


def run(quick: bool = False, progress: bool = True) -> dict[str, Any]:
    ctx = headless_context()
    _current(ctx)
    fig: dict[str, Any] = {"renderer": renderer_name(ctx), "width": WIDTH, "height": HEIGHT, "quick": quick,
                           "cpus": os.cpu_count() or 0, "load_average_start": os.getloadavg()[0]}
    # Quick: mono only, one timed frame per figure, no stills, the 200 primitives' atlas at 50 texels/m.
    timing = Timing(0.0, 1, 1) if quick else Timing(1.0, 3, 100)
    settings = ("frame_loop", "render") if quick else ("frame_loop", "render", "stills")
    views = ("mono",) if quick else tuple(VIEWS)
    density = 50.0 if quick else 200.0
    platform = os.environ.get("PYOPENGL_PLATFORM")
    pyrender, why = _import_pyrender()
    fig["pyrender_version"] = getattr(pyrender, "__version__", None) if pyrender else None
    if not pyrender:
        fig["pyrender_unavailable"] = why
    steps = len(SCENES) * len(LIGHTINGS) * len(views) * (len(settings) + 1)
    bar = Bar(total=steps, desc="bench render", unit="case", disable=not progress)
    builds = {"example": example_scene, "primitives200": lambda: primitives_scene(density)}
    for prefix, build in builds.items():
        t = time.perf_counter()
        _current(ctx)
        scene, cam = build()
        fig[f"{prefix}_build_s"] = time.perf_counter() - t
        fig.update({f"{prefix}_{k}": v for k, v in _describe(scene).items()})
        ours: dict[str, np.ndarray] = {}
        for s in settings:
            values, images, eyes = measure_vebuild(ctx, scene, cam, s, timing, views, bar, prefix)
            fig.update(values)
            ours.update(images)
        if pyrender:
            values, theirs = _pyrender_reference(pyrender, ctx, scene, cam, eyes, timing, views, bar, prefix)
            fig.update(values)
            for lname, img in theirs.items():
                for k, v in _agreement(ours[lname], img, RenderOptions().background_srgb).items():
                    fig[f"{prefix}_{lname}_mono_{k}"] = v
        else:
            for lname in LIGHTINGS:
                for view in views:
                    fig[f"{prefix}_{lname}_{view}_pyrender_unavailable"] = why
            bar.update(len(LIGHTINGS) * len(views))
        for lname in LIGHTINGS:
            for view in views:
                c = f"{prefix}_{lname}_{view}"
                if ref := fig.get(f"{c}_pyrender_fps"):
                    fig[f"{c}_speedup_over_pyrender"] = fig[f"{c}_render_fps"] / ref
                    if lname == "shadows":
                        fig[f"{c}_shadows_redrawn_speedup_over_pyrender"] = fig[f"{c}_render_shadows_redrawn_fps"] / ref
        del scene
    bar.close()
    if platform is None:  # set for pyrender's contexts only: leave the environment as it was
        os.environ.pop("PYOPENGL_PLATFORM", None)
    _current(ctx)
    fig["load_average_end"] = os.getloadavg()[0]
    loop = [fig[f"{p}_{lname}_mono_frame_loop_fps"] for p in SCENES for lname in ("unlit", "lit")]
    fig["frame_loop_mono_no_shadows_fps_min"] = min(loop)
    fig["goal_frame_loop_met"] = bool(min(loop) >= GOALS["frame_loop_mono_fps"])
    _frame_figures(fig)
    speedups = [v for k, v in fig.items() if k.endswith("_speedup_over_pyrender") and "redrawn" not in k]
    if speedups:
        fig["speedup_over_pyrender_min"] = min(speedups)
        fig["goal_speedup_met"] = bool(min(speedups) >= GOALS["speedup_over_pyrender"])
    return fig


def _frame_figures(fig: dict[str, Any]) -> None:
    """The frame loop's figures by setting: ``frame_fps_<setting>``, ``frame_share_of_floor_<setting>``,
    ``frame_fps_floor_<scene>`` (its fastest frame over the runs beside the settings) and the goals."""
    for (p, lname), name in FRAME_SETTINGS.items():
        c = f"{p}_{lname}_mono"
        fig[f"frame_fps_{name}"] = fig[f"{c}_frame_loop_fps"]
        fig[f"frame_share_of_floor_{name}"] = fig[f"{c}_share_of_floor"]
    for p, name in FLOOR_NAMES.items():
        fig[f"frame_fps_floor_{name}"] = max(fig[f"{p}_{lname}_mono_floor_fps"] for lname in LIGHTINGS)
    fig["goal_frame_fps_met"] = all(fig[f"frame_fps_{n}"] >= g for n, g in FRAME_GOALS.items())
    fig["goal_share_of_floor_met"] = all(fig[f"frame_share_of_floor_{n}"] >= GOALS["share_of_floor"]
                                         for n in FRAME_SETTINGS.values())


def floor_table(fig: dict[str, Any]) -> list[str]:
    """The frame loop beside the floor program, one row per setting."""
    if "frame_fps_floor_example" not in fig:
        return []
    share = GOALS["share_of_floor"]
    lines = ["", f"{'frame loop vs the floor':<36}{'fps':>8}{'goal':>8}{'ms':>8}{'floor fps':>11}"
             f"{'share':>8}  (goal ≥ {share:.1f})"]
    for (p, _), name in FRAME_SETTINGS.items():
        fps, goal = fig[f"frame_fps_{name}"], FRAME_GOALS.get(name)
        lines.append(f"{'  ' + name:<36}{fps:>8.1f}{_cell(goal, '{:.0f}'):>8}{1000 / fps:>8.1f}"
                     f"{fig[f'frame_fps_floor_{FLOOR_NAMES[p]}']:>11.1f}{fig[f'frame_share_of_floor_{name}']:>8.2f}")
    lines += ["floor: a minimal program in the same context drawing the same triangles (none culled) with one "
              "texture, no lighting;",
              "  share: the median over alternating frame pairs of floor time / frame time (robust to other load).",
              f"goal: fps goals {'met' if fig['goal_frame_fps_met'] else 'NOT met'}; every share ≥ {share:.1f} "
              f"{'met' if fig['goal_share_of_floor_met'] else 'NOT met'}"]
    return lines


def _cell(v: float | None, fmt: str = "{:.1f}") -> str:
    return "—" if v is None else fmt.format(v)


def table(fig: dict[str, Any]) -> str:
    settings = [s for s in ("frame_loop", "render", "stills")
                if any(k.endswith(f"_{s}_fps") for k in fig)]
    heads = {"frame_loop": "frame loop", "render": "render", "stills": "stills"}
    lines = [f"render benchmark on {fig['renderer']}, {fig['width']}×{fig['height']} per eye"
             f"{' (quick)' if fig['quick'] else ''}; load average {fig['load_average_start']:.2f} at the start, "
             f"{fig['load_average_end']:.2f} at the end, {fig['cpus']} CPUs", ""]
    for p, title in SCENES.items():
        lines.append(f"{title}: {fig[f'{p}_primitives']} primitives, {fig[f'{p}_faces']} faces, "
                     f"{fig[f'{p}_triangles']} triangles, {fig[f'{p}_pages']} atlas page(s) of "
                     f"{fig[f'{p}_texels_millions']:.1f} M texels in all")
    lines += ["", f"{'frames per second':<36}" + "".join(f"{heads[s]:>12}" for s in settings)
              + f"{'pyrender':>12}{'render/pyrender':>17}"]
    notes: dict[str, int] = {}
    for p, title in SCENES.items():
        lines.append(title)
        for lname, ltitle in LIGHTINGS.items():
            for view, vtitle in VIEWS.items():
                c = f"{p}_{lname}_{view}"
                if f"{c}_frame_loop_fps" not in fig:
                    continue
                ref = fig.get(f"{c}_pyrender_fps")
                if ref is None:
                    why = fig.get(f"{c}_pyrender_unavailable", "not run")
                    n = notes.setdefault(why, len(notes) + 1)
                    ref_cell = f"n/a [{n}]"
                else:
                    ref_cell = _cell(ref)
                lines.append(f"{'  ' + ltitle + ', ' + vtitle:<36}"
                             + "".join(f"{_cell(fig.get(f'{c}_{s}_fps')):>12}" for s in settings)
                             + f"{ref_cell:>12}{_cell(fig.get(f'{c}_speedup_over_pyrender'), '{:.1f}×'):>17}")
        for view, vtitle in VIEWS.items():
            c = f"{p}_shadows_{view}_render_shadows_redrawn_fps"
            if c in fig:
                lines.append(f"{'  shadow map redrawn, ' + vtitle:<36}{'':>12}{fig[c]:>12.1f}")
    lines += ["",
              "fps from the fastest frame of each run after a warm-up frame (others' work on the machine only adds "
              "time).",
              "frame loop: RenderOptions.interactive() (1 sample, trilinear), Renderer.frame + ctx.finish(), no "
              "read-back:",
              "  the walk-through window's frame measured off-screen (no display, swap or panel).",
              f"render: Renderer.render (colour read back) at pyrender's settings: 4× MSAA, trilinear, "
              f"{PYRENDER_SHADOW_SIZE}² shadow map;",
              "  shadow maps are drawn when the lighting or scene changes; 'shadow map redrawn' draws it every frame.",
              "stills: Renderer.render at RenderOptions() (4× MSAA, 8× anisotropic, 1024² shadow map)."]
    if fig.get("pyrender_version"):
        lines += [f"pyrender {fig['pyrender_version']}: OffscreenRenderer.render (4× MSAA, trilinear, reads back "
                  "colour and depth), same triangles, pages, UVs, camera;",
                  "  unlit: RenderFlags.FLAT; lit: its PBR shader (metallic 0, roughness 1); shadows: "
                  f"SHADOWS_DIRECTIONAL, its {PYRENDER_SHADOW_SIZE}² map redrawn every frame."]
        agree = [f"{SCENES[p]} {lname} {fig[f'{p}_{lname}_mono_mean_abs_diff_levels']:.1f}"
                 for p in SCENES for lname in LIGHTINGS if f"{p}_{lname}_mono_mean_abs_diff_levels" in fig]
        if agree:
            lines.append("image check, mono render vs pyrender, mean |Δ| (8-bit levels): " + ", ".join(agree))
            shares = [f"{SCENES[p]} {100 * fig[f'{p}_unlit_mono_foreground_share']:.1f} % / "
                      f"{100 * fig[f'{p}_unlit_mono_pyrender_foreground_share']:.1f} %"
                      for p in SCENES if f"{p}_unlit_mono_foreground_share" in fig]
            lines.append("  pixels off the background, vebuild / pyrender: " + ", ".join(shares))
    for why, n in notes.items():
        lines.append(f"[{n}] pyrender unavailable: {why}")
    lines += floor_table(fig)
    lines += ["", f"goal: frame loop ≥ {GOALS['frame_loop_mono_fps']:.0f} fps mono without shadows (unlit and lit, "
              f"both scenes): slowest {fig['frame_loop_mono_no_shadows_fps_min']:.1f} fps, "
              f"{'met' if fig['goal_frame_loop_met'] else 'NOT met'}"]
    if "speedup_over_pyrender_min" in fig:
        lines.append(f"goal: render ≥ {GOALS['speedup_over_pyrender']:.0f}× pyrender on equal work: slowest "
                     f"{fig['speedup_over_pyrender_min']:.1f}×, {'met' if fig['goal_speedup_met'] else 'NOT met'}")
    else:
        lines.append(f"goal: render ≥ {GOALS['speedup_over_pyrender']:.0f}× pyrender: not measured (no reference)")
    return "\n".join(lines)
