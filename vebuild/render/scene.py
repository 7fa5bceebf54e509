"""What the renderer draws: the model's world mesh with its extracted textures (numpy, no GL).

:func:`load_scene` reads the project's solved model and its ``textures`` record. Textures that
are missing (never extracted, a page file gone, or made for another model) are not an error: the
scene is drawn untextured, each face in its recorded average colour or a neutral grey, and
:attr:`RenderScene.warnings` says so. A page whose bytes changed since extraction is an error: a
render must never show an image other than the one the project records.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.errors import VebuildError
from vebuild.model.scene import Model
from vebuild.project import Project
from vebuild.project.decode import TexturePage, load_model, texture_pages
from vebuild.texture import layout as lay
from vebuild.texture.merge import srgb8_to_linear

Array = NDArray[np.float64]

#: sRGB colour of a face with no texture and no recorded average colour.
UNTEXTURED_SRGB = (190, 190, 190)


@dataclass
class RenderScene:
    """The model as one world mesh, and what colours it.

    mesh : world mesh with atlas coordinates (texels on each face's page).
    pages : sRGB atlas pages (h, w, 3) uint8, one per page; empty when untextured.
    face_colour : (n_faces, 3) linear RGB of each face, used where there is no texture.
    model : the scene graph the mesh was built from (for moving objects, naming picks).
    textured : whether the atlas pages are drawn.
    warnings : what the user should know (textures missing, faces drawn untextured).
    page_hashes : the SHA-256 of each atlas page drawn (for a render's provenance).
    page_files : the atlas pages as read from the project (bytes, hash, size), when textured.
    masks : per page, (h, w) uint8: 255 where no photo saw the texel, 0 where one did
        (:func:`vebuild.render.observed.unseen_mask` of the page's coverage map); empty when
        untextured or unknown (then nothing is marked as unobserved).
    mask_hashes : the SHA-256 of each coverage map the masks came from.
    coverage_files : each coverage map's bytes, as recorded (for exports).
    """

    mesh: lay.SceneMesh
    pages: list[NDArray[np.uint8]]
    face_colour: Array
    model: Model
    textured: bool
    warnings: list[str] = field(default_factory=list)
    page_hashes: list[str] = field(default_factory=list)
    page_files: list[TexturePage] = field(default_factory=list)
    masks: list[NDArray[np.uint8]] = field(default_factory=list)
    mask_hashes: list[str] = field(default_factory=list)
    coverage_files: list[bytes] = field(default_factory=list)

    @property
    def node_names(self) -> list[str]:
        """Names of the nodes that have faces, in face order; ``node_index`` indexes this."""
        return list(dict.fromkeys(f.node for f in self.mesh.faces))

    @property
    def node_of_face(self) -> NDArray[np.int32]:
        """(n_faces,) index into :attr:`node_names` of each face (by face id − 1)."""
        index = {n: i for i, n in enumerate(self.node_names)}
        return np.array([index[f.node] for f in self.mesh.faces], np.int32)

    def bounds(self) -> tuple[Array, Array]:
        v = self.mesh.vertices
        if len(v) == 0:
            return np.zeros(3), np.zeros(3)
        return v.min(axis=0), v.max(axis=0)

    def with_model(self, model: Model) -> RenderScene:
        """The same scene with its objects where ``model`` puts them (same faces, same textures)."""
        mesh = lay.scene_mesh(model, self.mesh.faces)
        return RenderScene(mesh, self.pages, self.face_colour, model, self.textured, list(self.warnings),
                           list(self.page_hashes), list(self.page_files), list(self.masks),
                           list(self.mask_hashes), list(self.coverage_files))


def untextured_faces(model: Model) -> list[lay.Face]:
    """A face list for a model that has no texture layout (atlas coordinates are then unused)."""
    return lay.layout(model, texels_per_metre=1.0, max_face_texels=1, page_size=1 << 20)


def scene_from_model(model: Model, record: dict[str, Any] | None = None,
                     pages: Sequence[NDArray[np.uint8]] = (), warnings: Sequence[str] = ()) -> RenderScene:
    """A scene from a model and, optionally, a ``textures`` record with its decoded pages."""
    warnings = list(warnings)
    faces: list[lay.Face] | None = None
    mesh: lay.SceneMesh | None = None
    if record is not None and pages:
        faces = [lay.Face(int(f["id"]), f["node"], f["face"], tuple(f["size_m"]), int(f["page"]), tuple(f["rect"]))
                 for f in record["faces"]]
        try:
            mesh = lay.scene_mesh(model, faces)
        except ValueError:
            mesh = None
        if mesh is None or len(faces) != len(untextured_faces(model)):
            warnings.append("the textures were extracted for another model (its faces differ from the model's "
                            "now); the model is shown untextured; run `vebuild texture` again")
            faces = None
    if faces is None or mesh is None:
        mesh = lay.scene_mesh(model, untextured_faces(model))
        pages = []
    colour = np.tile(srgb8_to_linear(np.array(UNTEXTURED_SRGB, np.uint8)), (len(mesh.faces), 1))
    if record is not None:
        by_key = {(f["node"], f["face"]): f.get("average_colour_srgb") for f in record.get("faces", [])}
        for i, f in enumerate(mesh.faces):
            c = by_key.get((f.node, f.name))
            if c is not None:
                colour[i] = srgb8_to_linear(np.array(c, np.uint8))
    return RenderScene(mesh, list(pages), colour, model, bool(pages), warnings)


def load_scene(project: Project) -> RenderScene:
    """The project's model (as last solved) with its textures; see the module's docstring."""
    data = project.data
    if not (data.get("model") or {}).get("nodes"):
        raise VebuildError(f"{project.path}: $.model: the project has no model yet; build one (`vebuild solve`) "
                           "first")
    model, _, _ = load_model(project)
    if not any(n.primitive is not None for n in model.nodes):
        raise VebuildError(f"{project.path}: $.model.nodes: the model has no primitives to render")
    record = data.get("textures")
    if record is None:
        return scene_from_model(model, None, (), ["the project has no textures yet; the model is shown untextured "
                                                  "(run `vebuild texture` to extract them from the photos)"])
    pages, missing = texture_pages(project)
    if missing:
        return scene_from_model(model, record, (), [f"texture page(s) missing: {', '.join(map(str, missing))}; the "
                                                    "model is shown untextured (run `vebuild texture` again)"])
    scene = scene_from_model(model, record, [p.pixels for p in pages])
    if scene.textured:
        scene.page_hashes = [p.sha256 for p in pages]
        scene.page_files = pages
        masks = coverage_masks(project)
        if masks is None:
            scene.warnings.append("a coverage map is missing (textures/coverage_*.png): surfaces no photo saw cannot "
                                  "be marked; run `vebuild texture` again")
        else:
            scene.masks, scene.mask_hashes, scene.coverage_files = ([m for m, _, _ in masks], [h for _, h, _ in masks],
                                                                    [b for _, _, b in masks])
    return scene


def coverage_masks(project: Project) -> list[tuple[NDArray[np.uint8], str, bytes]] | None:
    """Each page's unseen mask, its coverage map's SHA-256 and bytes, the bytes checked against the
    recorded hash and the size against the page's (errors at the JSON path); None if a coverage
    map is missing (not an error: nothing is then marked, and the scene's warnings say so)."""
    import io

    from vebuild.errors import ProjectError
    from vebuild.project.file import texture_page_path
    from vebuild.project.images import open_image, sha256_bytes
    from vebuild.render.observed import unseen_mask

    out = []
    for k, page in enumerate((project.data.get("textures") or {}).get("pages", [])):
        where = f"$.textures.pages[{k}].coverage"
        if not page.get("coverage"):
            return None
        path = texture_page_path(project, k, "coverage")
        if not path.is_file():
            return None
        try:
            raw = path.read_bytes()
        except OSError as e:
            raise ProjectError(project.path, where, f"cannot read the coverage map {page['coverage']!r}: "
                               f"{e.strerror or e}") from None
        digest = sha256_bytes(raw)
        if digest != page.get("coverage_sha256"):
            raise ProjectError(project.path, f"{where}_sha256", f"the coverage map {page['coverage']!r} changed since "
                               "`vebuild texture` wrote it (its bytes no longer hash to the recorded SHA-256); run "
                               "`vebuild texture` again")
        with open_image(io.BytesIO(raw), project.path, where, label=repr(page["coverage"])) as im:
            if im.size != (page["width"], page["height"]):
                raise ProjectError(project.path, where, f"expected the coverage map {page['coverage']!r} to be "
                                   f"{page['width']}×{page['height']} texels as recorded, found "
                                   f"{im.size[0]}×{im.size[1]}")
            rgba = np.asarray(im.convert("RGBA"))
        out.append((unseen_mask(rgba), digest, raw))
    return out
