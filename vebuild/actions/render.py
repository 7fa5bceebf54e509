"""``vebuild render``: an evidence view or a photo's own camera rendered headless to a PNG.

The PNG carries its provenance in text chunks (:data:`vebuild.render.png.PROVENANCE_KEYS`): the SHA-256 of the
project file it was made from, the camera (named view or photo, with K, R, C and size), the
lighting preset and its lights, the stereo settings, the texture pages' hashes and the software
version, and no time stamp, so that the same project and options give the same file, byte for
byte. A photo's own camera is rendered as its lens shows it (its lens distortion, if calibrated:
:mod:`vebuild.render.renderer`), so that the render lies on the photo. Rendering it with
``validate`` also writes an overlay of the photo on the render and measures how well the model
explains the photo: the RMS colour difference over the pixels the model covers (measured on
the render without the marks of unobserved surfaces).

Surfaces no photo saw are hatched by default (``unobserved``: hatch, tint or off;
:mod:`vebuild.render.observed`), with a legend in the image's lower left corner and the setting in
its ``vebuild:unobserved`` text chunk.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from vebuild.camera import ImageCamera
from vebuild.errors import ProjectError, VebuildError
from vebuild.project import Project
from vebuild.render.png import check_output, provenance, stamp, write_png

if TYPE_CHECKING:
    from vebuild.render.scene import RenderScene
from vebuild.texture.merge import linear_to_srgb8, srgb8_to_linear

#: Share of a pixel the model must cover to count in the validation's colour difference.
FULL_COVERAGE = 0.999


@dataclass
class RenderRequest:
    """What to render. Exactly one of ``view`` and ``photo``."""

    out: Path
    view: str | None = None
    photo: str | None = None
    size: tuple[int, int] | None = None
    size_source: str = "--size"  # where ``size`` came from, for the messages about it
    lighting: str | None = None
    stereo: str | None = None
    eye_separation: float = 0.063
    convergence: float | None = None
    samples: int = 4
    shadows: bool = True
    validate: bool = False
    hypothesis: str | None = None
    markers: bool = True  # draw the project's evidence markers (mono views)
    unobserved: str = "hatch"  # how surfaces no photo saw are shown (vebuild.render.observed)
    png_compress_level: int = 6  # zlib's, for the PNG (and overlay): the demo writes fast ones

    def __post_init__(self) -> None:
        """Each option checked when the request is made, its error naming the option (as the
        command line spells it) and what was expected."""
        if (self.view is None) == (self.photo is None):
            raise VebuildError("render: give exactly one of a view (--view NAME) or a photo (--photo ID)")
        if self.stereo is not None:
            from vebuild.render.renderer import STEREO_MODES

            if self.stereo not in STEREO_MODES[:3]:
                raise VebuildError(f"--stereo: expected one of sbs, tb, anaglyph (quad-buffered stereo needs a "
                                   f"window), got {self.stereo!r}")
        if self.validate and (self.photo is None or self.stereo is not None):
            raise VebuildError("--validate compares a render with its photo: use it with --photo and without "
                               "--stereo")
        if not (self.eye_separation > 0):
            raise VebuildError(f"--eye-separation: expected a distance > 0 m, got {self.eye_separation}")
        if self.convergence is not None and not (self.convergence > 0):
            raise VebuildError(f"--convergence: expected a distance > 0 m, got {self.convergence}")
        if self.samples < 1:
            raise VebuildError(f"--samples: expected 1 or more, got {self.samples}")
        if not (isinstance(self.png_compress_level, int) and 0 <= self.png_compress_level <= 9):
            raise VebuildError(f"render: the PNG's compression level: expected a whole number 0 to 9, got "
                               f"{self.png_compress_level!r}")
        from vebuild.render.observed import check_mode

        check_mode(self.unobserved)


@dataclass
class RenderResult:
    out: Path
    camera: ImageCamera
    size: tuple[int, int]
    lighting: str
    warnings: list[str] = field(default_factory=list)
    overlay: Path | None = None
    rms_colour_difference: float | None = None  # sRGB levels (0–255), over covered pixels
    exposure_gain: float | None = None  # photo / render, linear, fitted before the difference
    covered_fraction: float | None = None


def overlay_path(out: Path) -> Path:
    """Where ``--validate`` writes the photo overlaid on the render of ``out``."""
    return out.with_name(out.stem + "-overlay.png")


def render_evidence(project: Project, req: RenderRequest, scene: RenderScene | None = None) -> RenderResult:
    """Render ``req`` and write its PNG (and overlay); see the module's docstring. ``scene``: the
    project's :func:`~vebuild.render.scene.load_scene`, loaded once by a caller that renders many
    views (its pages and coverage maps decoded once)."""
    from vebuild.gl import headless_context
    from vebuild.project.decode import find_preset, find_view, photo_camera
    from vebuild.project.outputs import begin_stage
    from vebuild.render.renderer import Renderer, RenderOptions, Stereo
    from vebuild.render.scene import load_scene
    from vebuild.render.sizes import check_camera

    if req.stereo is not None:
        from vebuild.project.units import length_unit

        length_unit(project.data).refuse(f"render --stereo: the eyes' separation ({req.eye_separation:g})")
    out = check_output(Path(req.out), project=project)
    if req.validate:
        check_output(overlay_path(out), project=project)
    begin_stage(project, out.parent if str(out.parent) else ".")
    kind = "view" if req.view is not None else "photo"
    cam = find_view(project, req.view) if req.view is not None else photo_camera(project, str(req.photo))
    if req.size is not None:
        cam = cam.resized(*req.size, source=req.size_source)
    try:
        check_camera(cam, req.stereo)  # before the scene is loaded or GL is asked
    except VebuildError as e:
        raise _size_error(project, req, e) from None
    lighting = find_preset(project, req.lighting)
    scene = load_scene(project) if scene is None else scene
    if req.hypothesis is not None:
        from vebuild.project.hypotheses import hypothesis_model

        scene = scene.with_model(hypothesis_model(project, scene.model, req.hypothesis))
    ctx = headless_context()
    stereo = Stereo(req.stereo, req.eye_separation, req.convergence) if req.stereo else None
    renderer = Renderer(ctx, scene, RenderOptions(samples=req.samples, shadows=req.shadows,
                                                  unobserved=req.unobserved))
    try:
        try:
            W, H = renderer.check_size(cam, stereo)
        except VebuildError as e:
            raise _size_error(project, req, e) from None
        renderer.set_lighting(lighting)
        rgba = renderer.render_rgba(cam, stereo)
        marked = renderer.marks_unobserved
        plain = rgba
        if req.validate and marked:  # the colour difference is the textures', not the marks'
            renderer.unobserved = "off"
            plain = renderer.render_rgba(cam, stereo)
        placed = []
        if req.markers and stereo is None and project.data.get("evidence_markers"):
            from vebuild.analysis.markers import visible_markers

            placed = visible_markers(renderer, cam, project.data["evidence_markers"])
        stereo_rec = None
        if stereo is not None:
            conv = stereo.convergence if stereo.convergence is not None else renderer.default_convergence(cam)
            stereo_rec = {"mode": stereo.mode, "eye_separation_m": stereo.separation, "convergence_m": conv}
    finally:
        renderer.release()
    options = {"samples": req.samples, "shadows": req.shadows, "size": [cam.width, cam.height],
               "unobserved": req.unobserved}
    text = provenance(project, cam, kind, lighting.name, stereo_rec, scene.page_hashes, options)
    result = RenderResult(out, cam, (W, H), lighting.name, list(scene.warnings))
    if req.validate:
        _validate(project, str(req.photo), cam, plain, out, text, result, rgba, req.unobserved, marked,
                  scene.mask_hashes, req.png_compress_level)
    image = rgba[..., :3]
    if placed:
        from vebuild.analysis.markers import draw_markers

        image = draw_markers(image, placed)
        text["vebuild:evidence_markers"] = json.dumps([m["label"] for m, _, _ in placed], ensure_ascii=False)
    if req.hypothesis is not None:
        from vebuild.project.hypotheses import label

        image = stamp(image, label(req.hypothesis))
        text["vebuild:hypothesis"] = req.hypothesis
    from vebuild.render.observed import finish_image

    image = finish_image(image, req.unobserved, marked, text, scene.mask_hashes)
    write_png(out, image, text, req.png_compress_level)
    return result


def _size_error(project: Project, req: RenderRequest, e: VebuildError) -> VebuildError:
    """A refused image size: as it is where ``--size`` (or the caller's ``size_source``) gave the
    size, which the message names; where the size is the project's (a view's or a photo's, whose
    JSON path the message names), a ProjectError naming the project file too."""
    return e if req.size is not None else ProjectError(project.path, "", str(e))


def _validate(project: Project, photo_id: str, cam: ImageCamera, rgba: NDArray[np.uint8], out: Path,
              text: dict[str, str], result: RenderResult, shown: NDArray[np.uint8], unobserved: str, marked: bool,
              coverage_hashes: list[str], compress_level: int = 6) -> None:
    """Overlay the photo on its render and measure the colour difference where the model covers:
    measured on ``rgba`` (unmarked), the overlay drawn from ``shown`` (surfaces no photo saw marked
    as ``unobserved`` says, with the legend)."""
    from vebuild.render.observed import finish_image
    from vebuild.texture.extract import PhotoSource, read_photo

    i = [p["id"] for p in project.data["photos"]].index(photo_id)
    photo = project.data["photos"][i]
    src = PhotoSource(photo_id, project.photo_path(photo), photo["sha256"], f"$.photos[{i}]", str(project.path))
    pixels = read_photo(src, ImageCamera(photo_id, cam.K, cam.R, cam.C, photo["width"], photo["height"]))
    if pixels.shape[:2] != (cam.height, cam.width):
        pixels = np.asarray(Image.fromarray(pixels).resize((cam.width, cam.height), Image.Resampling.BOX))
    render, cover = rgba[..., :3], rgba[..., 3].astype(float) / 255.0
    full = cover >= FULL_COVERAGE
    result.covered_fraction = float(full.mean())
    if not full.any():
        raise VebuildError(f"photo {photo_id!r}: the model covers no pixel of this photo; nothing to compare")
    # One exposure gain (linear light) between photo and render, fitted by least squares over the
    # covered pixels: the textures are at the photos' average exposure, not this photo's.
    lp, lr = srgb8_to_linear(pixels[full]), srgb8_to_linear(render[full])
    gain = float((lp * lr).sum() / max((lr * lr).sum(), 1e-12))
    matched = linear_to_srgb8(np.clip(lr * gain, 0.0, 1.0)).astype(float)
    rms = float(np.sqrt(np.mean((matched - pixels[full].astype(float)) ** 2)))
    result.rms_colour_difference, result.exposure_gain = rms, gain
    # The overlay: the photo and the render half and half where the model covers, the photo
    # dimmed elsewhere.
    alpha = 0.5 * cover[..., None]
    overlay = pixels.astype(float) * (1.0 - alpha) * np.where(cover[..., None] > 0, 1.0, 0.6) \
        + shown[..., :3].astype(float) * alpha
    result.overlay = overlay_path(out)
    text = {**text, "vebuild:validation": json.dumps({"photo": photo_id, "photo_sha256": photo["sha256"],
                                                      "rms_colour_difference_srgb_levels": round(rms, 4),
                                                      "exposure_gain": round(gain, 6),
                                                      "covered_fraction": round(result.covered_fraction, 6)},
                                                     sort_keys=True)}
    image = finish_image(np.clip(np.rint(overlay), 0, 255).astype(np.uint8), unobserved, marked, text, coverage_hashes)
    write_png(result.overlay, image, text, compress_level)
