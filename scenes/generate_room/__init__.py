"""Generate the example project ``scenes/room``: a furnished room photographed six times.

    python scenes/generate_room [--out scenes/room] [--scale 1.0] [--supersample 2]

(or ``python -m scenes.generate_room`` from the repository's root). In code, :func:`generate`
writes the example into a folder and returns what it wrote; the parts it is made of are public
here too (``build_scene``, ``cameras``, ``render_photo``, ``trace``, ...), for the tests that hold
vebuild against them.

Everything here is written independently of the ``vebuild`` package on purpose: the photographs,
the "user's" clicks and the ground truth come from this package's own geometry, projection and ray
caster, so a convention slip in vebuild (an axis flip, a half-pixel offset) cannot cancel against
the same slip in its test data. Only numpy and Pillow are used; hashes and JSON are written here.

Conventions are those of ``shared/DESIGN.md`` (restated where they are used):

- world: right-handed, metres, +Z up, floor z = 0; the room spans x∈[0, 5], y∈[0, 4], z∈[0, 2.6];
- pixels (u, v): origin at the top-left *corner* of the image, so pixel column i, row j has its
  centre at (i + 0.5, j + 0.5);
- camera: ``x_cam = R (X − C)``, ``u ~ K x_cam``, K = [[f, 0, cx], [0, f, cy], [0, 0, 1]], the camera
  looks along +z_cam, v grows along +y_cam;
- yaw / pitch / roll as defined at the end of ``scenes/FORMAT.md``;
- a directed vanishing segment runs from p1 to p2 in the positive sense of its world axis.

Every surface is a planar rectangle ("quad": a corner and two edge vectors); its outward normal is
``edge1 × edge2``. Shading is Lambertian with one directional light and an ambient term, so each
quad has one constant shade factor (no shadows); each photo has its own exposure gain. Albedo is
defined in sRGB, shading happens in linear light and the result is encoded back to 8-bit sRGB.

Five photos are pinholes from a phone-sized sensor. The sixth, p6, is an overview from the
south-west corner, held high, through an 18 mm lens on an APS-C sensor with barrel distortion
(the division model, k1 = −0.035 on f-normalised coordinates: its farthest corner moves 25 px,
2.5 % of the half-diagonal; cameras.py): each pixel's ray leaves through the pinhole coordinate
its position undistorts to, every click on it is where the lens put the point, and its vanishing
segments are polylines of 3–5 points along the bent images of straight edges (the middle points
carry the curvature, from which a calibration can estimate k1). p4's JPEG records a nominal focal
length 2.5 % short of the true one (cameras.EXIF_FOCAL_ERROR_REL); every other EXIF focal length
is exact. ``ground_truth.json`` records each photo's lens and EXIF error.

The annotations (vanishing segments, marker clicks) depend on geometry only, never on the
rendered pixels, so they are the same at any rendering quality and cheap to regenerate in tests.

The modelling stage (paper §3) is simulated too: ``ground_truth.json`` holds the room's true scene
graph in the project format (``model``) and the world position of every primitive handle it implies
(``model_handles``, from this package's own forward kinematics, which the tests hold to the rendered
corners); the project holds the rough model a user has after dropping primitives onto the photos,
the handles a careful user pins to visible corners, and a few edge observations. The walls are in
the model too, as boxes a measured thickness thick behind the rendered wall planes, with the
doorway left open; the user places them from measurements taken in the room, not from the photos.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from pathlib import Path

from .cameras import (
    CAMERA_SPECS,
    EXIF_FOCAL_ERROR_REL,
    LENS_K1,
    SENSOR_PITCH_MM,
    cameras,
    corner_displacement_px,
    distort_normalised,
    pinhole_pixels,
    pixel_rays,
    project,
    rotation_from_ypr,
    undistort_normalised,
)
from .clicks import annotate, choose_segments, polyline_points
from .documents import (
    EXAMPLE_LIGHTING,
    EXAMPLE_VIEWS,
    annotate_all,
    check_coverage,
    exif_values,
    ground_truth_json,
    photo_annotations_json,
    project_json,
    read_exif,
    reference_distances,
    sha256_file,
    write_jpeg,
)
from .model import (
    BOX_EDGES,
    QUAD_EDGES,
    check_model_coverage,
    face_frame,
    joint_transform,
    model_handles_world,
    model_json,
    model_world_transforms,
    primitive_edges,
    primitive_handles,
    rough_model,
    scene_markers,
    true_model,
    true_walls,
)
from .parameters import (
    AMBIENT,
    BASE_HEIGHT,
    BASE_WIDTH,
    BOX_CENTRE,
    BOX_SIZE,
    BOX_YAW_DEG,
    CABINET_DEPTH,
    CABINET_H,
    CABINET_Y,
    CLICK_SIGMA_PX,
    DIFFUSE,
    DOOR_AJAR_DEG,
    DOOR_H,
    DOOR_X0,
    DOOR_X1,
    EDGE_SAMPLES,
    IMAGE_MARGIN_PX,
    JPEG_QUALITY,
    LIGHT_DIR,
    PIXEL_PITCH_MM,
    POLYLINE_POINTS,
    POLYLINE_STEP_PX,
    ROOM,
    SEED,
    SEGMENT_MIN_PX,
    TABLE_CENTRE,
    TABLE_LEG,
    TABLE_LEG_INSET,
    TABLE_SIZE,
    TABLE_TOP_THICK,
    TABLE_TOP_Z,
    VISIBILITY_EPS_M,
    WALL_THICK,
)
from .raycast import quad_image_bounds, render_photo, shade_hits, trace, visible
from .scene import box_quads, build_scene, quad
from .textures import TEXTURES, linear_to_srgb, srgb_to_linear, to_8bit

#: The bundled example's folder: scenes/room beside this package.
DEFAULT_OUT = Path(__file__).resolve().parent.parent / "room"


@dataclass(frozen=True)
class Generated:
    """What :func:`generate` wrote: the project document, the ground truth and the folder."""

    out: Path
    project: dict
    ground_truth: dict


def generate(out: Path = DEFAULT_OUT, scale: float = 1.0, supersample: int = 2,
             log=print) -> Generated:
    """Render the photos and write ``photos/``, ``room.vebuild.json`` and ``ground_truth.json``
    into ``out``; ``scale`` multiplies the 1600 × 1200 photo size, ``supersample`` is the samples
    per pixel side. The same arguments give the same bytes."""
    out = Path(out)
    t0 = time.perf_counter()
    scene = build_scene()
    cams = cameras(scale)
    anns = annotate_all(scene, cams)
    (out / "photos").mkdir(parents=True, exist_ok=True)
    files = {}
    for cam in cams:
        t1 = time.perf_counter()
        rgb = render_photo(scene, cam, cam["width"], cam["height"], supersample)
        rel = f"photos/{cam['id']}.jpg"
        exif = write_jpeg(out / rel, rgb, cam)
        f_exif = cam["f"] * (1 + EXIF_FOCAL_ERROR_REL.get(cam["id"], 0.0))
        if abs(exif["focal_length_px"] / f_exif - 1) > 1e-4:
            raise AssertionError(f"{rel}: EXIF focal {exif['focal_length_px']} px, expected {f_exif}")
        files[cam["id"]] = {"file": rel, "sha256": sha256_file(out / rel), "exif": exif}
        log(f"{rel}: {cam['width']}x{cam['height']}, {time.perf_counter() - t1:.1f} s, "
            f"{(out / rel).stat().st_size / 1024:.0f} KiB")
    project_doc = project_json(scene, cams, anns, files)
    check_coverage(project_doc)
    check_model_coverage(project_doc["model"], true_model(scene))
    gt = ground_truth_json(scene, cams, anns, scale, supersample)
    for name, doc in (("room.vebuild.json", project_doc), ("ground_truth.json", gt)):
        tmp = out / (name + ".tmp")
        tmp.write_text(json.dumps(doc, indent=1) + "\n")
        tmp.replace(out / name)
    log(f"wrote {out} in {time.perf_counter() - t0:.1f} s")
    return Generated(out, project_doc, gt)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--scale", type=float, default=1.0, help="multiplies the 1600 x 1200 photo size")
    ap.add_argument("--supersample", type=int, default=2, help="s x s samples per pixel")
    args = ap.parse_args(argv)
    generate(args.out, args.scale, args.supersample)


__all__ = [
    "AMBIENT",
    "BASE_HEIGHT",
    "BASE_WIDTH",
    "BOX_CENTRE",
    "BOX_EDGES",
    "BOX_SIZE",
    "BOX_YAW_DEG",
    "CABINET_DEPTH",
    "CABINET_H",
    "CABINET_Y",
    "CAMERA_SPECS",
    "CLICK_SIGMA_PX",
    "DEFAULT_OUT",
    "DIFFUSE",
    "DOOR_AJAR_DEG",
    "DOOR_H",
    "DOOR_X0",
    "DOOR_X1",
    "EDGE_SAMPLES",
    "EXAMPLE_LIGHTING",
    "EXAMPLE_VIEWS",
    "EXIF_FOCAL_ERROR_REL",
    "Generated",
    "IMAGE_MARGIN_PX",
    "JPEG_QUALITY",
    "LENS_K1",
    "LIGHT_DIR",
    "PIXEL_PITCH_MM",
    "POLYLINE_POINTS",
    "POLYLINE_STEP_PX",
    "QUAD_EDGES",
    "ROOM",
    "SEED",
    "SEGMENT_MIN_PX",
    "SENSOR_PITCH_MM",
    "TABLE_CENTRE",
    "TABLE_LEG",
    "TABLE_LEG_INSET",
    "TABLE_SIZE",
    "TABLE_TOP_THICK",
    "TABLE_TOP_Z",
    "TEXTURES",
    "VISIBILITY_EPS_M",
    "WALL_THICK",
    "annotate",
    "annotate_all",
    "box_quads",
    "build_scene",
    "cameras",
    "check_coverage",
    "check_model_coverage",
    "choose_segments",
    "corner_displacement_px",
    "distort_normalised",
    "exif_values",
    "face_frame",
    "generate",
    "ground_truth_json",
    "joint_transform",
    "linear_to_srgb",
    "main",
    "model_handles_world",
    "model_json",
    "model_world_transforms",
    "photo_annotations_json",
    "polyline_points",
    "pinhole_pixels",
    "pixel_rays",
    "primitive_edges",
    "primitive_handles",
    "project",
    "project_json",
    "quad",
    "quad_image_bounds",
    "read_exif",
    "reference_distances",
    "render_photo",
    "rotation_from_ypr",
    "rough_model",
    "scene_markers",
    "sha256_file",
    "shade_hits",
    "srgb_to_linear",
    "to_8bit",
    "trace",
    "true_model",
    "undistort_normalised",
    "true_walls",
    "visible",
    "write_jpeg",
]
