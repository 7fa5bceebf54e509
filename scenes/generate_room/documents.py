"""The files: JPEG photos with EXIF focal data, the project document and the ground truth."""

from __future__ import annotations

import hashlib
import math
from fractions import Fraction
from pathlib import Path

import numpy as np
from PIL import Image
from PIL.TiffImagePlugin import IFDRational

from .cameras import EXIF_FOCAL_ERROR_REL, SENSOR_PITCH_MM, corner_displacement_px
from .clicks import annotate
from .model import model_handles_world, model_json, rounded, scene_markers, true_model
from .parameters import BASE_WIDTH, CLICK_SIGMA_PX, JPEG_QUALITY, LIGHT_DIR, PIXEL_PITCH_MM, ROOM, SEED


def exif_values(cam: dict) -> dict:
    """EXIF focal data: the sensor's resolution is the true one, and focal_mm × resolution_per_mm
    is f (px) exactly, or off by the photo's EXIF_FOCAL_ERROR_REL (a nominal lens focal length).

    The focal length in mm is that of the scale-1 camera on its sensor (SENSOR_PITCH_MM, else
    PIXEL_PITCH_MM: a small phone sensor); a scaled-down photo keeps the lens and gets coarser
    pixels. The 35 mm equivalent, rounded to 1 mm as cameras write it, follows the recorded focal
    length (the camera computes it from that).
    """
    f = Fraction(cam["f"]).limit_denominator(10**6)
    f_base = f / Fraction(cam["scale"]).limit_denominator(10**6)
    pitch = Fraction(SENSOR_PITCH_MM.get(cam["id"], PIXEL_PITCH_MM)).limit_denominator(10**6)
    true_mm = f_base * pitch
    res = f / true_mm
    error = Fraction(EXIF_FOCAL_ERROR_REL.get(cam["id"], 0.0)).limit_denominator(10**6)
    focal_mm = true_mm * (1 + error)
    diag_px = math.hypot(cam["width"], cam["height"])
    f35 = int(round(float(focal_mm * res) * math.hypot(36.0, 24.0) / diag_px))
    return {"focal_mm": focal_mm, "res_per_mm": res, "f35": f35, "error_rel": float(error)}


def write_jpeg(path: Path, rgb: np.ndarray, cam: dict) -> dict:
    """Write the photo with EXIF focal data; return the project's exif object (read back)."""
    ev = exif_values(cam)
    exif = Image.Exif()
    exif[0x010F] = "vebuild"  # Make
    exif[0x0110] = "synthetic"  # Model
    ifd = exif.get_ifd(0x8769)
    fmm, res = (IFDRational(v.numerator, v.denominator) for v in (ev["focal_mm"], ev["res_per_mm"]))
    ifd[0x920A] = fmm  # FocalLength (RATIONAL, exact)
    ifd[0xA20E] = res  # FocalPlaneXResolution (RATIONAL, exact)
    ifd[0xA20F] = res  # FocalPlaneYResolution
    ifd[0xA210] = 4  # FocalPlaneResolutionUnit: 4 = millimetre (an extension used by cameras)
    ifd[0xA405] = ev["f35"]  # FocalLengthIn35mmFilm (SHORT)
    Image.fromarray(rgb).save(path, "JPEG", quality=JPEG_QUALITY, exif=exif.tobytes())
    return read_exif(path)


def read_exif(path: Path) -> dict:
    """The project's exif object, from the file as written."""
    with Image.open(path) as im:
        ex = im.getexif()
        ifd = ex.get_ifd(0x8769)
    focal_mm, res = float(ifd[0x920A]), float(ifd[0xA20E])
    if int(ifd[0xA210]) != 4:
        raise ValueError(f"{path}: FocalPlaneResolutionUnit {ifd[0xA210]}, expected 4 (mm)")
    return {"make": str(ex[0x010F]), "model": str(ex[0x0110]), "focal_length_mm": focal_mm,
            "focal_length_35mm": int(ifd[0xA405]), "focal_plane_x_resolution_per_mm": res,
            "focal_length_px": focal_mm * res}


def sha256_file(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def photo_annotations_json(ann: dict) -> dict:
    """The vanishing_segments and marker_observations of one photo as written to the project."""
    return {"vanishing_segments": {a: [rounded(s) for s in v] for a, v in ann["vanishing_segments"].items()},
            "marker_observations": {n: rounded(uv) for n, uv in ann["marker_observations"].items()}}


def annotate_all(scene: dict, cams: list[dict]) -> list[dict]:
    """Every photo's annotations, photo k from the noise stream default_rng([SEED, k])."""
    return [annotate(scene, cam, np.random.default_rng([SEED, k])) for k, cam in enumerate(cams)]


def reference_distances(scene: dict) -> list[dict]:
    m = {n: p for n, (p, _) in scene["markers"].items()}
    check = float(np.linalg.norm(m["T2"] - m["C1"]))
    return [
        {"a": "O", "b": "X5", "distance": 5.000, "sigma": 0.002, "role": "scale"},
        {"a": "O", "b": "Y4", "distance": 4.000, "sigma": 0.002, "role": "scale"},
        {"a": "T2", "b": "C1", "distance": round(check, 4), "sigma": 0.002, "role": "check"},
    ]


#: Named evidence views of the example (FORMAT.md, "views"): where a witness stood, with eyes at 1.6 m.
EXAMPLE_VIEWS = [
    {"name": "doorway", "description": "standing in the doorway, looking at the table",
     "position": [3.7, 0.3, 1.6], "look_at": [2.2, 2.7, 0.74], "fov_deg": 65.0, "width": 1280, "height": 720},
    {"name": "by the cabinet", "description": "beside the cabinet, looking across the room to the door",
     "position": [0.8, 1.2, 1.6], "look_at": [3.8, 0.3, 1.0], "fov_deg": 70.0, "width": 1280, "height": 720},
    {"name": "overview", "description": "from the far corner, high",
     "position": [4.8, 3.8, 2.4], "look_at": [2.3, 1.8, 0.3], "focal_length_mm": 24.0, "width": 1280,
     "height": 720},
]
#: Lighting presets of the example (FORMAT.md, "lighting"): irradiance 1 shows a texture as extracted.
EXAMPLE_LIGHTING = {"presets": [
    {"name": "daylight", "description": "sun through the window, as when the photos were taken",
     "ambient": [0.35, 0.35, 0.37],
     "lights": [{"type": "directional", "name": "sun", "direction": (-LIGHT_DIR).round(4).tolist(),
                 "colour": [1.0, 0.97, 0.92], "intensity": 0.9}]},
    {"name": "ceiling lamp", "description": "one bulb under the ceiling's centre, nothing else",
     "ambient": [0.03, 0.03, 0.03],
     "lights": [{"type": "point", "name": "bulb", "position": [2.5, 2.0, 2.5], "colour": [1.0, 0.85, 0.65],
                 "intensity": 4.0}]},
    {"name": "night, torch", "description": "dark room; a torch held in the doorway, aimed at the table",
     "ambient": [0.005, 0.005, 0.006],
     "lights": [{"type": "spot", "name": "torch", "position": [3.7, 0.3, 1.5], "direction": [-1.5, 2.4, -0.76],
                 "inner_cone_deg": 10.0, "outer_cone_deg": 16.0, "intensity": 6.0}]},
]}


def project_json(scene: dict, cams: list[dict], anns: list[dict], photo_files: dict) -> dict:
    """The vebuild project document (scenes/FORMAT.md). photo_files: id → {file, sha256, exif}."""
    seen = {n for a in anns for n in a["marker_observations"]}
    photos = []
    for cam, ann in zip(cams, anns, strict=True):
        pf = photo_files[cam["id"]]
        photos.append({"id": cam["id"], "file": pf["file"], "width": cam["width"], "height": cam["height"],
                       "sha256": pf["sha256"], "exif": pf["exif"], **photo_annotations_json(ann)})
    return {
        "format": "vebuild-project",
        "version": 1,
        # The generator's name as the shipped example has always recorded it (the package was one
        # file): kept so that the example regenerates byte for byte.
        "name": "Example room (synthetic, generated by scenes/generate_room.py)",
        "settings": {"click_sigma_px": CLICK_SIGMA_PX * cams[0]["width"] / BASE_WIDTH},
        "photos": photos,
        "markers": [{"name": n, "description": d} for n, (_, d) in scene["markers"].items() if n in seen],
        "origin_marker": "O",
        "reference_distances": reference_distances(scene),
        "model": model_json(scene, cams),
        "views": EXAMPLE_VIEWS,
        "lighting": EXAMPLE_LIGHTING,
    }


def _l(x):
    return np.asarray(x, dtype=np.float64).tolist()


def ground_truth_json(scene: dict, cams: list[dict], anns: list[dict], scale: float, supersample: int) -> dict:
    photos = {}
    for cam, ann in zip(cams, anns, strict=True):
        photos[cam["id"]] = {
            "width": cam["width"], "height": cam["height"], "K": _l(cam["K"]), "R": _l(cam["R"]),
            "C": _l(cam["C"]), "f": cam["f"], "principal_point": list(cam["principal_point"]),
            "yaw_deg": cam["yaw_deg"], "pitch_deg": cam["pitch_deg"], "roll_deg": cam["roll_deg"],
            "exposure": cam["exposure"],
            # the lens (cameras.py): the division model's k1 on f-normalised coordinates, 0 for a
            # pinhole, and how far it moves the farthest corner from where a pinhole would put it
            "distortion": {"model": "division", "k1": cam["k1"],
                           "corner_displacement_px": corner_displacement_px(cam)},
            # how far the photo's EXIF focal length is off f, relative (its JPEG records it so)
            "exif_focal_error_rel": EXIF_FOCAL_ERROR_REL.get(cam["id"], 0.0),
            "segments": {a: [{"edge": s["edge"], "X1": _l(s["X1"]), "X2": _l(s["X2"])} for s in v]
                         for a, v in ann["segments_truth"].items()},
        }
    nodes = true_model(scene)
    return {
        "generator": "scenes/generate_room.py",  # as recorded since it was one file (see project_json)
        "seed": SEED, "scale": scale, "supersample": supersample,
        "conventions": "DESIGN.md: world +Z up metres; pixel origin at the top-left corner (pixel centre "
                       "i+0.5); x_cam = R (X - C); u ~ K x_cam",
        "room": list(ROOM),
        "light": scene["light"],
        "photos": photos,
        "markers": {n: _l(p) for n, (p, _) in scene["markers"].items()},
        "objects": scene["objects"],
        "quads": [{"name": q["name"], "object": q["object"], "corner": _l(q["corner"]), "edge1": _l(q["edge1"]),
                   "edge2": _l(q["edge2"]), "texture": q["texture"], "shade": q["shade"]}
                  for q in scene["quads"]],
        # the true scene graph (FORMAT.md "The model") and, from it, every handle's world position
        "model": {"nodes": nodes},
        "model_handles": {n: {h: _l(x) for h, x in hs.items()}
                          for n, hs in model_handles_world(nodes, scene_markers(scene)).items()},
    }


def check_coverage(project: dict) -> None:
    """Marker rules of the example: every marker in ≥ 2 photos; O in p1, p2, p3, p5 and not p4;
    p4 sees ≥ 3 markers that other photos see too."""
    obs = {p["id"]: set(p["marker_observations"]) for p in project["photos"]}
    for m in project["markers"]:
        n = sum(m["name"] in o for o in obs.values())
        if n < 2:
            raise AssertionError(f"marker {m['name']} is seen by {n} photo(s), expected >= 2")
    for pid in ("p1", "p2", "p3", "p5"):
        if "O" not in obs[pid]:
            raise AssertionError(f"origin marker O is not seen by {pid}")
    if "O" in obs["p4"]:
        raise AssertionError("p4 must not see the origin marker O")
    others = set().union(*(o for pid, o in obs.items() if pid != "p4"))
    if len(obs["p4"] & others) < 3:
        raise AssertionError(f"p4 shares only {sorted(obs['p4'] & others)} with the other photos")


