"""Texture extraction from start to end: layout, photos streamed through the GPU, merge.

:func:`extract` takes plain data (the model, the calibrated cameras, where each photo is and
the SHA-256 it must have) and returns the atlases in memory; :mod:`vebuild.actions.texture` adds the project file,
the PNGs and the record.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera
from vebuild.errors import ProjectError
from vebuild.gl import headless_context, max_texture_size
from vebuild.model.occlusion import Rooms, rooms_of
from vebuild.model.scene import Model
from vebuild.project import sha256_bytes
from vebuild.project.images import decode_photo
from vebuild.texture import layout as lay
from vebuild.texture.gpu import Extractor
from vebuild.texture.merge import FaceStats, fill_page
from vebuild.texture.options import Options
from vebuild.texture.timings import Timings

Array = NDArray[np.float64]


@dataclass
class PhotoSource:
    """Where one photo's pixels come from, and the SHA-256 they must have."""

    id: str
    path: Path
    sha256: str | None = None
    where: str = ""  # JSON path of the photo's entry, for errors
    project_file: str = ""


@dataclass
class TextureResult:
    faces: list[lay.Face]
    atlases: list[NDArray[np.uint8]]  # (h, w, 3) sRGB per page
    coverage: list[NDArray[np.uint8]]  # (h, w, 4) per page
    face_stats: dict[int, FaceStats]
    face_photos: dict[int, list[str]]  # photos that gave each face texels
    gains: dict[str, Array]
    overlap: dict[str, int]
    order: list[str]
    exposure_scale: float
    page_size: int
    timings: Timings = field(default_factory=Timings)
    #: The faces no photo can see, given token charts (vebuild.texture.visibility).
    token_faces: list[lay.Face] = field(default_factory=list)

    @property
    def unseen_faces(self) -> list[lay.Face]:
        return [f for f in self.faces if self.face_stats[f.id].seen_fraction == 0.0]

    @property
    def atlas_texels(self) -> int:
        """Texels of the atlas pages, gutters included."""
        return sum(int(a.shape[0]) * int(a.shape[1]) for a in self.atlases)


def read_photo(src: PhotoSource, cam: ImageCamera, timings: Timings | None = None) -> NDArray[np.uint8]:
    """Read, check and decode one photo: its bytes must hash to ``src.sha256`` and decode to the
    camera's size. The bytes that are hashed are the bytes that are decoded."""
    timings = timings or Timings()
    with timings.stage("read"):
        try:
            data = src.path.read_bytes()
        except OSError as e:
            raise ProjectError(src.project_file or src.path, f"{src.where}.file" if src.where else "",
                               f"photo '{src.id}' cannot be read: {e.strerror or e} ({src.path})") from None
    with timings.stage("hash"):
        if src.sha256 is not None and sha256_bytes(data) != src.sha256:
            raise ProjectError(src.project_file or src.path, f"{src.where}.sha256" if src.where else "",
                               f"the photo {src.path.name!r} has changed since calibration (its SHA-256 differs "
                               "from the project's); textures are not taken from a changed photo")
    with timings.stage("decode"):
        pixels = decode(data, src)
    if pixels.shape[:2] != (cam.height, cam.width):
        raise ProjectError(src.project_file or src.path, f"{src.where}.width" if src.where else "",
                           f"photo '{src.id}' is {pixels.shape[1]}×{pixels.shape[0]} pixels, but its camera was "
                           f"calibrated for {cam.width}×{cam.height}")
    return pixels


def decode(data: bytes, src: PhotoSource | None = None) -> NDArray[np.uint8]:
    """A photo's bytes → (h, w, 3) uint8 RGB as displayed (:func:`vebuild.project.images.decode_photo`)."""
    name = src.path if src else Path("photo")
    file = src.project_file or name if src else name
    where = f"{src.where}.file" if src and src.where else ""
    return decode_photo(data, name, file, where, label=str(name))


def photo_order(ex: Extractor, cameras: Sequence[ImageCamera]) -> list[ImageCamera]:
    """Photos ordered so that each overlaps those before it as much as possible (the first sees
    the most faces): exposure is compensated against what is already accumulated."""
    sets = {c.id: ex._visible_faces(c) for c in cameras}
    todo = list(cameras)
    first = max(todo, key=lambda c: (len(sets[c.id]), -todo.index(c)))
    order, seen = [first], set(sets[first.id])
    todo.remove(first)
    while todo:
        nxt = max(todo, key=lambda c: (len(sets[c.id] & seen), -todo.index(c)))
        order.append(nxt)
        seen |= sets[nxt.id]
        todo.remove(nxt)
    return order


def extract(model: Model, cameras: Sequence[ImageCamera], sources: dict[str, PhotoSource], options: Options,
            progress: Callable[[int, int, str], None] | None = None, timings: Timings | None = None) -> TextureResult:
    """Extract and merge the textures of every face of ``model`` from the photos of ``cameras``."""
    ctx = headless_context()
    page_size = min(int(options.page_size), max_texture_size(ctx))
    profile = timings is not None
    timings = timings or Timings()
    rooms = rooms_of(model)
    token = (unseen_keys(ctx, model, cameras, options, page_size, timings, profile, rooms) if options.token_charts
             else set())
    faces = lay.layout(model, options.texels_per_metre, options.max_face_texels, page_size, token=token)
    mesh = lay.scene_mesh(model, faces)
    ex = Extractor(ctx, mesh, options, timings if profile else None, rooms)
    try:
        order = photo_order(ex, cameras)
        if options.drop_ratio > 0:
            ex.best_weights(list(order))
        for k, cam in enumerate(order):
            if progress:
                progress(k, len(order), cam.id)
            # The least memory at once for a large photo: its ID buffer first, then the decoded
            # photo onto the GPU, freed before its pyramid is built.
            ex.photo_id_pass(cam)
            pixels = read_photo(sources[cam.id], cam, timings)
            ex.upload_photo(cam, pixels)
            del pixels
            ex.add_photo(cam)
        ex.release_photo()  # the photo-sized targets go before the merge makes its own
        ex.release_best_weights()
        if progress:
            progress(len(order), len(order), "")
        contributions = ex.contributions()
        with timings.stage("merge", ctx if profile else None):
            gains = dict(ex.gains)
            scale = float(np.exp(np.mean([np.log(g).mean() for g in gains.values()]))) if gains else 1.0
            atlases, coverage, stats = [], [], {}
            # Every page resolved (its sums freed) before any is filled: the fill's arrays never
            # coexist with another page's sums.
            resolved = [ex.resolve(p, scale, release_sums=True) for p in range(len(mesh.pages))]
            for p in range(len(resolved)):
                r, resolved[p] = resolved[p], {}
                on_page = [f for f in faces if f.page == p]
                filled, st = fill_page(r["colour"], r["seen"], r["face"], on_page, options.fill,
                                       options.mode == "average")
                stats.update(st)
                atlases.append(filled)
                coverage.append(r["coverage"])
    finally:
        ex.release()
    face_photos = {f.id: [c.id for c in order if contributions[c.id].get(f.id, 0) > 0] for f in faces}
    return TextureResult(faces, atlases, coverage, stats, face_photos, gains, dict(ex.overlap),
                         [c.id for c in order], scale, page_size, timings,
                         [f for f in faces if (f.node, f.name) in token])


def unseen_keys(ctx: Any, model: Model, cameras: Sequence[ImageCamera], options: Options, page_size: int,
                timings: Timings, profile: bool, rooms: Rooms) -> set[tuple[str, str]]:
    """(node, face) of every face that no camera can see (:mod:`vebuild.texture.visibility`): the
    faces that get token charts. Found on the model's mesh before its atlas is laid out (charts
    of one texel: the atlas does not matter to the test). ``rooms``: the model's (:func:`rooms_of`)."""
    from vebuild.texture.visibility import seen_faces, token_faces

    plan = lay.plan_faces(model, options.texels_per_metre, options.max_face_texels, page_size)
    rough = lay.scene_mesh(model, [lay.Face(i + 1, node, name, size, 0, (0, 0, 1, 1))
                                   for i, (node, name, size, _) in enumerate(plan)])
    with timings.stage("visibility", ctx if profile else None):
        return token_faces(rough, seen_faces(ctx, rough, cameras, rooms=rooms))
