"""Texture extraction on the GPU: ID buffers, pyramid, texel projection and accumulation.

The definitions are in :mod:`vebuild.texture`; this module draws them with moderngl. One photo is
on the GPU at a time; per-texel sums for all photos stay on the GPU until the merge
(:meth:`Extractor.resolve`) draws them into colours a page at a time. The exposure statistics'
view of a photo's texels is :mod:`vebuild.texture.gpu_exposure`.
"""

from __future__ import annotations

import moderngl
import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera, depth_range, gl_projection, view_matrix
from vebuild.gl import load_program
from vebuild.gl.shaders import set_uniforms
from vebuild.model.occlusion import Rooms
from vebuild.texture import BEST_WEIGHT_SCALE, DEPTH_TOLERANCE, pre_pass_erosion
from vebuild.texture.gpu_exposure import ExposureView
from vebuild.texture.gpu_page import Page
from vebuild.texture.gpu_pyramid import PhotoPyramid, fullscreen_vao
from vebuild.texture.id_edges import EDGE_SHRINK, edge_lines
from vebuild.texture.layout import SceneMesh
from vebuild.texture.lens import lens_uniforms, pinhole_cover
from vebuild.texture.options import Options
from vebuild.texture.timings import Timings
from vebuild.texture.visibility import FaceQueries, face_points, faces_in_view, faces_not_hidden

Array = NDArray[np.float64]


def _mat3(M: Array) -> NDArray[np.float32]:
    return np.asarray(M, "f4").T.copy()  # GLSL is column-major


#: A photo of this many pixels or more has its ID pass's depth buffer and the driver's staging copy
#: of its pixels freed at once (waiting for the GPU), not when the driver next flushes (24 MP of
#: depth is 92 MiB, and while it waits to be freed the next photo is decoded beside it), and is
#: itself freed before the next photo is decoded.
FREE_NOW_PIXELS = 16 * 2**20


#: GL_CLIP_DISTANCE0: pass 2's texel programs clip each chart to the photo's frame (texel.vert).
GL_CLIP_DISTANCE0 = 0x3000
#: The clip planes texel.vert writes (four sides of the frame and the camera's plane).
CLIP_PLANES = 5


#: Texture units the passes bind (and :meth:`Extractor._unbind` rebinds to a 1×1 texture).
IDLE_UNITS = 8


class Extractor(ExposureView):
    """Streams photos through the ID and texel passes into per-page sums on the GPU."""

    def __init__(self, ctx: moderngl.Context, mesh: SceneMesh, options: Options, timings: Timings | None = None,
                 rooms: Rooms | None = None):
        self.ctx, self.mesh, self.opt, self.rooms = ctx, mesh, options, rooms
        self.timings = timings or Timings()
        self._profile = timings is not None
        ctx.disable(moderngl.CULL_FACE)
        self._programs = {
            "id": load_program(ctx, "id"),
            "edges": load_program(ctx, "edges"),
            "pyramid": load_program(ctx, "pyramid", vertex="fullscreen"),
            "resolve": load_program(ctx, "resolve", vertex="fullscreen"),
            "blank": load_program(ctx, "blank", vertex="fullscreen"),
            **{m: load_program(ctx, "texel", {"MODE": i})
               for i, m in enumerate(("accumulate", "view", "best", "geometry"))},
        }
        # Pass 1's mesh: world vertices with their face ids.
        ids = np.column_stack([mesh.vertices, mesh.face_of_vertex]).astype("f4")
        self._id_vbo = ctx.buffer(ids.tobytes())
        self._id_ibo = ctx.buffer(mesh.triangles.astype("i4").tobytes())
        self._id_vao = ctx.vertex_array(self._programs["id"], [(self._id_vbo, "3f 1f", "in_position", "in_face")],
                                        self._id_ibo)
        self._face_queries = FaceQueries(ctx, self._programs["id"], self._id_vbo, mesh)
        #: The faces that hold a pixel of the last ID buffer drawn (:meth:`id_pass`).
        self.id_faces: set[int] = set()
        self._border, self._interior = mesh.boundary_edges()
        self._edge_vbo = ctx.buffer(reserve=max(1, (len(self._border) + len(self._interior)) * 2 * 12))
        self._edge_vao = ctx.vertex_array(self._programs["edges"], [(self._edge_vbo, "3f", "in_position")])
        # Pass 2's mesh: a triangle soup in atlas space, grouped by page and face.
        soup = mesh.triangle_soup()
        order = np.lexsort((soup["face"], soup["page"]))
        soup = {k: v[order] for k, v in soup.items()}
        data = np.column_stack([soup["position"], soup["normal"], soup["atlas"], soup["face"], soup["e_u"],
                                soup["e_v"]]).astype("f4")
        self._soup_vbo = ctx.buffer(data.tobytes())
        starts = np.flatnonzero(np.r_[True, np.diff(soup["face"]) != 0])
        ends = np.r_[starts[1:], len(soup["face"])]
        #: Each face's run of soup vertices: (first, count); faces with no area in the atlas have none.
        self._face_range = {int(soup["face"][a]): (int(a), int(b - a)) for a, b in zip(starts, ends, strict=True)}
        self._face_page = {f.id: f.page for f in mesh.faces}
        self._soup_vaos: dict[str, moderngl.VertexArray] = {}
        self._face_points = face_points(mesh)
        self._pages = [self._make_page(size) for size in mesh.pages]
        self._photo = PhotoPyramid(ctx)
        self._fullscreen_vaos: dict[int, moderngl.VertexArray] = {}
        self._id_tex: moderngl.Texture | None = None
        self._view_fbo: moderngl.Framebuffer | None = None  # MODE 1's targets (view)
        self._id_for: tuple[str, set[int]] | None = None  # the photo whose ID buffer is in _id_tex, its faces
        self._idle_fbo = ctx.framebuffer(color_attachments=[ctx.texture((1, 1), 4)])
        self._uploaded: str | None = None  # the id of the photo on the GPU
        self.gains: dict[str, NDArray[np.float64]] = {}
        self._queries: dict[int, moderngl.Query] = {}  # one per face, reused photo after photo
        self._pending: tuple[str, dict[int, moderngl.Query]] | None = None
        self._contributions: dict[str, dict[int, int]] = {}
        self.overlap: dict[str, int] = {}

    # -- set-up ------------------------------------------------------------------------------

    def _make_page(self, size: tuple[int, int]) -> Page:
        ctx = self.ctx
        # The kept views' sums in float32; the dropped views' (weights relative to the best, each
        # below drop_ratio) and the view counts (whole numbers) in half floats: 44 bytes a texel.
        acc = [ctx.texture(size, 4, dtype=d) for d in ("f4", "f4", "f2")] + [ctx.texture(size, 2, dtype="f2")]
        for t in acc:
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        fbo = ctx.framebuffer(color_attachments=acc)
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        best = ctx.texture(size, 1, dtype="f4")
        best.filter = (moderngl.NEAREST, moderngl.NEAREST)
        best_fbo = ctx.framebuffer(color_attachments=[best])
        best_fbo.clear(0.0, 0.0, 0.0, 0.0)
        return Page(size, acc, fbo, best, best_fbo)

    def _unbind(self, free_now: bool = False) -> None:
        """Draw into a 1×1 target: GL frees a released texture only once no bound framebuffer holds
        it. ``free_now``: and wait for the GPU, so that what is released next is freed now rather
        than when the driver next flushes (Mesa keeps it till then). A texture the last draw
        sampled is freed only at a later draw (a clear does not count): the 1×1 target is drawn
        over by a program that samples nothing, and :meth:`_free_released` draws again after releasing."""
        self._idle_fbo.use()
        if free_now:
            idle = self._idle_fbo.color_attachments[0]
            assert isinstance(idle, moderngl.Texture)
            for unit in range(IDLE_UNITS):  # sampler bindings hold textures too
                idle.use(unit)
            prog = self._programs["blank"]
            fullscreen_vao(self.ctx, self._fullscreen_vaos, prog).render(moderngl.TRIANGLES, vertices=3)
            self._idle_fbo.clear(0.0, 0.0, 0.0, 0.0)
            self.ctx.finish()

    def _free_released(self) -> None:
        """Have the memory of the textures just released back now: the driver frees a deleted
        texture at the next draw, so draw (:meth:`_unbind`) and wait. Measured on the house:
        without it each page's sums (0.6 GiB) were freed only at the next page's draw in the
        merge, and the last photo's ID buffer and pyramid only at the merge's first."""
        self._unbind(free_now=True)

    def _release_id_target(self) -> None:
        if self._id_tex is not None:
            self._unbind()
            self._id_tex.release()
            self._id_tex = None
        self._id_for = None

    def release_photo(self) -> None:
        """Free what is the size of a photo (the photo, its pyramid, the ID buffer) and the
        exposure statistics' targets: after the pre-pass and after the last photo, before the
        merge allocates its own targets."""
        self._unbind(free_now=True)
        self._release_id_target()
        self._release_view_target()
        self._photo.release()
        self._uploaded = None
        self._free_released()

    # -- pass 1 ------------------------------------------------------------------------------

    def _near_far(self, cam: ImageCamera) -> tuple[float, float]:
        return depth_range(cam.R, cam.C, self.mesh.vertices)

    def id_pass(self, cam: ImageCamera, erode_px: float) -> moderngl.Texture:
        """Render the ID buffer (face id, depth) of ``cam``; returns its texture. For a photo with
        lens distortion the buffer is its :func:`~vebuild.texture.lens.pinhole_cover`'s (a pinhole
        image over the photo's undistorted bounds); for a pinhole, the photo's own frame.

        Sets :attr:`id_faces`: the faces in view that are the nearest surface at some pixel centre
        (occlusion queries on the depth buffer, before the edges are drawn). Pass 2 sees a texel
        only where its face holds the texel's pixel in the ID buffer, so no other face has a texel
        this photo sees, and pass 2 draws only these: in a house, a photo's frustum takes in the
        rooms behind its walls (on the quick house, 1,345 faces in view, 94 seen). From inside a
        room (:attr:`rooms`), what its walls hide is neither drawn nor queried."""
        ctx = self.ctx
        in_view = self._visible_faces(cam)
        cam, _ = pinhole_cover(cam)
        near, far = self._near_far(cam)
        unhidden = (faces_not_hidden(self._face_points, self.rooms, cam, near)
                    if self._face_queries.in_mesh_order else None)
        if unhidden is not None:
            in_view &= unhidden
        key = (cam.width, cam.height)
        if self._id_tex is None or self._id_tex.size != key:  # one size at a time: photos rarely differ
            if self._id_tex is not None:  # (a portrait photo after a landscape one): never two at once
                self._release_id_target()
                self._free_released()
            self._id_tex = ctx.texture(key, 2, dtype="f4")
            self._id_tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        tex = self._id_tex
        # The depth buffer serves this pass only: freed before the photo and its pyramid are made
        # (for a 169-megapixel photo, 0.6 GiB less at the peak).
        depth = ctx.depth_renderbuffer(key)
        fbo = ctx.framebuffer(color_attachments=[tex], depth_attachment=depth)
        V = view_matrix(cam.R, cam.C).astype("f4").T.copy()
        P = gl_projection(cam.K, cam.width, cam.height, near, far).astype("f4").T.copy()
        fbo.use()
        fbo.viewport = (0, 0, cam.width, cam.height)
        fbo.clear(0.0, 3.0e38, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.BLEND)
        ctx.depth_func = "<"
        fbo.depth_mask = True
        set_uniforms(self._programs["id"], view=V, projection=P)
        if unhidden is None:
            self._id_vao.render(moderngl.TRIANGLES)
        else:
            self._face_queries.draw(unhidden)
        self.id_faces = self._face_queries.nearest(fbo, in_view)
        if erode_px > 0:
            lines = edge_lines(self.mesh, self._border, self._interior, cam, near)
            if len(lines):
                self._edge_vbo.orphan(max(self._edge_vbo.size, lines.nbytes))
                self._edge_vbo.write(lines.tobytes())
                set_uniforms(self._programs["edges"], view=V, projection=P, shrink=EDGE_SHRINK,
                     viewport=(float(cam.width), float(cam.height)), half_width=float(erode_px))
                ctx.depth_func = "<="
                fbo.depth_mask = False
                self._edge_vao.render(moderngl.LINES, vertices=len(lines))
                fbo.depth_mask = True
        ctx.disable(moderngl.DEPTH_TEST)
        self._unbind(free_now=key[0] * key[1] >= FREE_NOW_PIXELS)
        fbo.release()
        depth.release()
        self._id_for = None
        return tex

    # -- the photo -----------------------------------------------------------------------------

    def upload(self, pixels: NDArray[np.uint8]) -> None:
        """Put a photo (height, width, 3) uint8 sRGB on the GPU and build its pyramid."""
        self._write_photo(pixels)
        self._pyramid_stage()

    def _pyramid_stage(self) -> None:
        with self.timings.stage("pyramid", self.ctx if self._profile else None):
            prog = self._programs["pyramid"]
            self._photo.build(prog, fullscreen_vao(self.ctx, self._fullscreen_vaos, prog))

    def _write_photo(self, pixels: NDArray[np.uint8], finish: bool = False) -> None:
        with self.timings.stage("upload", self.ctx if self._profile else None):
            self._photo.write(pixels, finish)

    # -- pass 2 ------------------------------------------------------------------------------

    def _visible_faces(self, cam: ImageCamera) -> set[int]:
        """Faces that may show in ``cam`` (:func:`vebuild.texture.visibility.faces_in_view`)."""
        return faces_in_view(self._face_points, cam)

    def _draw_texels(self, mode: str, page: int, faces: set[int] | None,
                     queries: dict[int, moderngl.Query] | None = None) -> None:
        """Draw the texels of ``faces`` (all when None) on ``page`` with the texel program of
        ``mode``, one face's run of the soup at a time; with ``queries``, each face inside an
        occlusion query of its own (kept across photos, see add_photo)."""
        if mode not in self._soup_vaos:
            self._soup_vaos[mode] = self.ctx.vertex_array(
                self._programs[mode], [(self._soup_vbo, "3f 3f 2f 1f 3f 3f", "in_position", "in_normal",
                                        "in_atlas", "in_face", "in_eu", "in_ev")], skip_errors=True)
        vao = self._soup_vaos[mode]
        clip = mode != "geometry"
        if clip:
            for k in range(CLIP_PLANES):
                self.ctx.enable_direct(GL_CLIP_DISTANCE0 + k)
        try:
            self._draw_faces(vao, page, faces, queries)
        finally:
            if clip:
                for k in range(CLIP_PLANES):
                    self.ctx.disable_direct(GL_CLIP_DISTANCE0 + k)

    def _draw_faces(self, vao: moderngl.VertexArray, page: int, faces: set[int] | None,
                    queries: dict[int, moderngl.Query] | None) -> None:
        for fid in sorted(self._face_range if faces is None else faces):
            if self._face_page[fid] != page or fid not in self._face_range:
                continue
            first, count = self._face_range[fid]
            if queries is None:
                vao.render(moderngl.TRIANGLES, vertices=count, first=first)
                continue
            if fid not in self._queries:
                self._queries[fid] = self.ctx.query(samples=True)
            q = queries[fid] = self._queries[fid]
            with q:
                vao.render(moderngl.TRIANGLES, vertices=count, first=first)

    def _texel_uniforms(self, prog: moderngl.Program, cam: ImageCamera, id_tex: moderngl.Texture,
                        page_size: tuple[int, int], atlas_scale: float = 1.0, weight_scale: float = 1.0) -> None:
        id_tex.use(0)
        values: dict[str, object] = dict(
            K=_mat3(cam.K), R=_mat3(cam.R), C=np.asarray(cam.C, "f4"),
            image_size=(float(cam.width), float(cam.height)), weight_scale=float(weight_scale),
            depth_tolerance=DEPTH_TOLERANCE, id_depth=0, page_size=(float(page_size[0]), float(page_size[1])),
            atlas_scale=float(atlas_scale), detail_levels=float(self.opt.detail_levels),
            sharpness=float(self.opt.detail_sharpness), drop_ratio=float(self.opt.drop_ratio),
            **lens_uniforms(cam),
        )
        self._photo.bind(prog, values)
        set_uniforms(prog, **values)

    def best_weights(self, cameras: list[ImageCamera]) -> None:
        """Pre-pass (no photo needed): each texel's best weight over all photos, for dropping
        views far worse than the best."""
        prog = self._programs["best"]
        for cam in cameras:
            small = cam.scaled(BEST_WEIGHT_SCALE)
            with self.timings.stage("best_weight", self.ctx if self._profile else None):
                id_tex = self.id_pass(small, pre_pass_erosion(self.opt.erode_px))
                faces = self.id_faces
                self.ctx.enable(moderngl.BLEND)
                self.ctx.blend_func = moderngl.ONE, moderngl.ONE
                self.ctx.blend_equation = moderngl.MAX, moderngl.MAX
                for k, page in enumerate(self._pages):
                    assert page.best_fbo is not None, "the best weights are freed after the last photo"
                    page.best_fbo.use()
                    page.best_fbo.viewport = (0, 0, *page.size)
                    self._texel_uniforms(prog, small, id_tex, page.size, weight_scale=1.0 / BEST_WEIGHT_SCALE)
                    self._draw_texels("best", k, faces)
                self.ctx.blend_equation = moderngl.FUNC_ADD, moderngl.FUNC_ADD
                self.ctx.disable(moderngl.BLEND)
        self._unbind(free_now=True)  # its ID buffer is freed before the first photo's is made
        self._release_id_target()

    def photo_id_pass(self, cam: ImageCamera) -> None:
        """Pass 1 for ``cam`` ahead of its photo (it needs none): :func:`extract` runs it before
        decoding the photo, so that the ID pass's depth buffer and the decoded photo are never held
        at once. :meth:`add_photo` runs it if it was not. A large last photo is freed first (not
        its pyramid's targets, which the next photo reuses): the next one is decoded beside
        neither it nor the ID pass's depth buffer."""
        if self._photo.photo is not None and cam.width * cam.height >= FREE_NOW_PIXELS:
            self._photo.free_photo()
            self._free_released()
        with self.timings.stage("id_pass", self.ctx if self._profile else None):
            self.id_pass(cam, self.opt.erode_px)
            self._id_for = (cam.id, self.id_faces)

    def upload_photo(self, cam: ImageCamera, pixels: NDArray[np.uint8]) -> None:
        """Put ``cam``'s photo on the GPU for :meth:`add_photo`, which builds its pyramid; the
        caller may free ``pixels`` in between (one copy of the photo fewer at the peak)."""
        if pixels.shape[:2] != (cam.height, cam.width):
            raise ValueError(f"photo {cam.id}: pixels are {pixels.shape[1]}×{pixels.shape[0]}, "
                             f"the camera is for {cam.width}×{cam.height}")
        self._collect()
        # The driver's staging copy of a large photo goes before the pyramid is made.
        self._write_photo(pixels, finish=cam.width * cam.height >= FREE_NOW_PIXELS)
        self._uploaded = cam.id

    def add_photo(self, cam: ImageCamera, pixels: NDArray[np.uint8] | None = None) -> None:
        """Pass 1 and pass 2 for one photo (its ``pixels``, or those of :meth:`upload_photo`); its
        texels join the sums."""
        if pixels is not None:
            self.upload_photo(cam, pixels)
        if self._uploaded != cam.id:
            raise ValueError(f"photo {cam.id}: its pixels are not on the GPU (upload_photo first)")
        self._uploaded = None
        self._collect()
        if not self._photo.ready:
            self._pyramid_stage()
        if self._id_for is None or self._id_for[0] != cam.id:
            self.photo_id_pass(cam)
        assert self._id_tex is not None and self._id_for is not None
        id_tex, faces = self._id_tex, self._id_for[1]
        with self.timings.stage("texel_pass", self.ctx if self._profile else None):
            gain = self._exposure_gain(cam, id_tex, faces) if self.opt.exposure else np.ones(3)
            self.gains[cam.id] = gain
            prog = self._programs["accumulate"]
            self.ctx.enable(moderngl.BLEND)
            self.ctx.blend_func = moderngl.ONE, moderngl.ONE
            self.ctx.blend_equation = moderngl.FUNC_ADD, moderngl.FUNC_ADD
            queries: dict[int, moderngl.Query] = {}
            for k, page in enumerate(self._pages):
                page.fbo.use()
                page.fbo.viewport = (0, 0, *page.size)
                assert page.best is not None, "the best weights are freed after the last photo"
                page.best.use(4)
                self._texel_uniforms(prog, cam, id_tex, page.size)
                set_uniforms(prog, best_weight=4, inverse_gain=(1.0 / gain).astype("f4"))
                self._draw_texels("accumulate", k, faces, queries)  # last photo's queries were read
            self.ctx.disable(moderngl.BLEND)
            # Read at the next photo (or by `contributions`): reading now would wait for the GPU
            # instead of letting it finish this photo while the next one is decoded.
            self._pending = (cam.id, queries)

    def _collect(self) -> None:
        if self._pending is not None:
            pid, queries = self._pending
            self._contributions[pid] = {fid: q.samples for fid, q in queries.items() if q.samples > 0}
            self._pending = None

    def contributions(self) -> dict[str, dict[int, int]]:
        """Per photo, the texels it gave each face (kept or dropped), counted by occlusion queries."""
        self._collect()
        return dict(self._contributions)

    # -- results -------------------------------------------------------------------------------

    def _geometry_targets(self, page: int, normals: bool = True) -> tuple[moderngl.Framebuffer, list[moderngl.Texture]]:
        """MODE 3 drawn into new targets: (face, position) and (normal, 1); without ``normals``
        the face id alone, into one channel (4 bytes a texel, not 32)."""
        p = self._pages[page]
        size = p.size
        targets = ([self.ctx.texture(size, 4, dtype="f4") for _ in range(2)] if normals
                   else [self.ctx.texture(size, 1, dtype="f4")])
        for t in targets:
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        fbo = self.ctx.framebuffer(color_attachments=targets)
        fbo.use()
        fbo.viewport = (0, 0, *size)
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        self.ctx.disable(moderngl.BLEND)
        prog = self._programs["geometry"]
        set_uniforms(prog, page_size=(float(size[0]), float(size[1])), atlas_scale=1.0)
        self._draw_texels("geometry", page, None)
        return fbo, targets

    def geometry(self, page: int) -> dict[str, NDArray[np.float32]]:
        """Each texel's world position, face id (0 off every face) and normal on ``page``."""
        w, h = self._pages[page].size
        fbo, targets = self._geometry_targets(page)
        try:
            out = [np.frombuffer(fbo.read(components=4, dtype="f4", attachment=i), "f4").reshape(h, w, 4)
                   for i in range(2)]
        finally:
            fbo.release()
            for t in targets:
                t.release()
        return {"position": out[0][..., 1:], "face": out[0][..., 0].astype(np.int32), "normal": out[1][..., :3]}

    def resolve(self, page: int, exposure_scale: float, release_sums: bool = False) -> dict[str, NDArray]:
        """The merge on the GPU: 'colour' (h, w, 3) uint8 sRGB, 'seen' (h, w) bool, 'coverage'
        (h, w, 4) uint8 (colours: vebuild.texture.merge.COVERAGE_*) and 'face' (h, w) int32.
        ``release_sums``: the page's sums are freed once drawn, before the results are read back."""
        from vebuild.texture.merge import COVERAGE_DROPPED_ONLY, COVERAGE_UNSEEN, COVERAGE_VIEWS

        p = self._pages[page]
        w, h = p.size
        gfbo, gtex = self._geometry_targets(page, normals=False)
        targets = [self.ctx.texture((w, h), 4) for _ in range(2)]
        fbo = self.ctx.framebuffer(color_attachments=targets)
        try:
            fbo.use()
            fbo.viewport = (0, 0, w, h)
            prog = self._programs["resolve"]
            for unit, tex in enumerate([*p.acc, gtex[0]]):
                tex.use(unit)
            rgba = lambda c: tuple(v / 255.0 for v in c)  # noqa: E731
            set_uniforms(prog, low_sum=0, detail_sum=1, dropped_sum=2, counts=3, geometry=4,
                 exposure_scale=float(exposure_scale), coverage_unseen=rgba(COVERAGE_UNSEEN),
                 coverage_dropped_only=rgba(COVERAGE_DROPPED_ONLY),
                 coverage_views=np.array([rgba(c) for c in COVERAGE_VIEWS], "f4"))
            fullscreen_vao(self.ctx, self._fullscreen_vaos, prog).render(moderngl.TRIANGLES, vertices=3)
            if release_sums:
                self.release_sums(page)
            face = np.frombuffer(gfbo.read(components=1, dtype="f4"), "f4").reshape(h, w).astype(np.int32)
            colour = np.frombuffer(fbo.read(components=4, attachment=0), np.uint8).reshape(h, w, 4)
            coverage = np.frombuffer(fbo.read(components=4, attachment=1), np.uint8).reshape(h, w, 4).copy()
        finally:
            fbo.release()
            gfbo.release()
            for t in (*targets, *gtex):
                t.release()
        return {"colour": colour[..., :3].copy(), "seen": colour[..., 3] > 127, "coverage": coverage, "face": face}

    def release_sums(self, page: int) -> None:
        """Free ``page``'s sums (44 bytes a texel) once :meth:`resolve` has drawn with them."""
        p = self._pages[page]
        self._unbind(free_now=True)
        for t in p.acc:
            t.release()
        p.fbo.release()
        p.acc = []
        self._release_best(p)
        self._free_released()

    def release_best_weights(self) -> None:
        """Free every page's best weights (4 bytes a texel) once the last photo is in."""
        self._unbind(free_now=True)
        for p in self._pages:
            self._release_best(p)
        self._free_released()

    @staticmethod
    def _release_best(p: Page) -> None:
        if p.best is not None and p.best_fbo is not None:
            p.best.release()
            p.best_fbo.release()
        p.best = p.best_fbo = None

    def sums(self, page: int) -> dict[str, NDArray[np.float32]]:
        """The per-texel sums of ``page`` (MODE 0's four targets), read back."""
        p = self._pages[page]
        w, h = p.size
        fbo = p.fbo
        out = [np.frombuffer(fbo.read(components=4 if i < 3 else 2, dtype="f4", attachment=i), "f4")
               .reshape(h, w, 4 if i < 3 else 2) for i in range(4)]
        return {"low": out[0], "detail": out[1], "dropped": out[2], "counts": out[3]}

    def release(self) -> None:
        self._unbind()
        for page in self._pages:
            if not page.acc:  # released by release_sums
                continue
            for t in page.acc:
                t.release()
            page.fbo.release()
            self._release_best(page)
        self.release_photo()
        for a in self._idle_fbo.color_attachments:
            a.release()
        self._idle_fbo.release()
        for vao in self._soup_vaos.values():
            vao.release()
        self._face_queries.release()
        for b in (self._id_vbo, self._id_ibo, self._edge_vbo, self._soup_vbo):
            b.release()
