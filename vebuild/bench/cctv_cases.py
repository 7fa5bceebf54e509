"""The cases of ``vebuild bench cctv`` (:mod:`vebuild.bench.cctv`): generated CCTV cameras
(:mod:`vebuild.synthetic.cctv`), their clips encoded and cached, and the one-photo project a user
makes of each, calibrated and measured through vebuild's API.

Three steps, one function each:

- :func:`add_still`: the still becomes a photo of the project: the frame taken from the video
  file as ``vebuild add clip.mp4@frame=N`` takes it (decoded exactly, written as a lossless PNG,
  the video's SHA-256 and the frame's index and time recorded); a case with no clip gets a plain
  photo of the frame's size, since calibration and measurement read only the marks;
- :func:`calibrated_lens`: what calibration says of the lens;
- :func:`measure_height`: a person's height from the head-top and foot clicks: the
  ``person-height`` analysis kind, no allowance entered (the figure stands upright, barefoot).
"""

from __future__ import annotations

import hashlib
import json
import shutil
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from vebuild.camera import distortion_displacement_px
from vebuild.project import load_project, new_photo_entry, new_project, save_project
from vebuild.project.atomic import write_bytes
from vebuild.project.cameras import photo_camera
from vebuild.resources import cache_dir
from vebuild.synthetic.cctv import (
    FRAME_SIZES,
    SETTINGS,
    CctvCase,
    cctv_case,
    clicks_along,
    edge_candidates,
    marked_edges,
    truth_record,
)
from vebuild.synthetic.cctv_lens import LENS_KINDS, TrueLens, matching_division_lens
from vebuild.synthetic.cctv_render import Line
from vebuild.synthetic.cctv_video import decode, encode, frames, place_frames

Array = NDArray[np.float64]

#: Bump when the generated scenes or their encoding change: old caches are then not reused.
GENERATOR_VERSION = 2
SEED = 20261208
#: Every VIDEO_EVERY-th case is rendered, encoded both ways and decoded; the others are measured
#: from their marks alone (calibration and the measurements read the marks, not the pixels), on
#: a plain photo of the frame's size.
VIDEO_EVERY = 4
#: The user's clicks along the edges: 1σ per coordinate, drawn per case (px); on the head's top
#: and the feet (px).
SEGMENT_CLICK_PX, HEIGHT_CLICK_PX = (0.5, 1.0), 1.0
#: The tape's 1σ on the known length (m).
TAPE_SIGMA_M = 0.003
#: The project's stated click 1σ (px): the largest of the marks' (the head and feet clicks').
PROJECT_CLICK_SIGMA_PX = 1.0


def case_plan(i: int) -> tuple[str, str, tuple[int, int], bool, bool]:
    """Case i's setting, lens, frame size, whether it has a video and whether that is interlaced:
    cycled so that the video cases cover every lens and size."""
    video = i % VIDEO_EVERY == 0
    return (SETTINGS[(i // 3) % 2], LENS_KINDS[i % 3], FRAME_SIZES[(i // 6) % 3], video,
            video and (i // VIDEO_EVERY) % 2 == 1)


def make_case(i: int) -> CctvCase:
    setting, lens, size, _, interlaced = case_plan(i)
    return cctv_case((SEED, i), setting, lens, size, interlaced)


def cache_folder() -> Path:
    return cache_dir() / "bench-cctv" / f"v{GENERATOR_VERSION}"


@dataclass(frozen=True)
class Clip:
    """A case's clip as cached: the two encodings, the SHA-256 of each generated frame, and the
    frame at each of the figure's places."""

    lossless: Path
    lossy: Path
    digests: list[str]
    place_frames: list[int]


def frame_digest(frame: NDArray[np.uint8]) -> str:
    return hashlib.sha256(np.ascontiguousarray(frame).tobytes() + repr(frame.shape).encode()).hexdigest()


def cached_clip(i: int, case: CctvCase) -> Clip:
    """Case i's clip: generated, encoded and cached once (``~/.cache/vebuild/bench-cctv``)."""
    folder = cache_folder() / f"c{i:04d}"
    meta = folder / "clip.json"
    lossless, lossy = folder / "lossless.mp4", folder / "lossy.mp4"
    if meta.is_file() and lossless.is_file() and lossy.is_file():
        rec = json.loads(meta.read_text(encoding="utf-8"))
        return Clip(lossless, lossy, rec["digests"], rec["place_frames"])
    got = frames(case, np.random.default_rng([SEED, i, 7]))
    encode(got, lossless, lossless=True, interlaced=case.interlaced)
    encode(got, lossy, lossless=False, interlaced=case.interlaced)
    clip = Clip(lossless, lossy, [frame_digest(f) for f in got], place_frames(case))
    write_bytes(meta, json.dumps({"digests": clip.digests, "place_frames": clip.place_frames,
                                  "truth": truth_record(case, edge_candidates(case))}).encode())
    return clip


def round_trip(clip: Clip) -> tuple[dict[str, Any], list[NDArray[np.uint8]]]:
    """Both encodings decoded and compared with the generator's frames: how many lossless frames
    are the generator's bit for bit; each lossy frame's PSNR (dB) and largest error (grey levels)
    against the generator's frame (the lossless decoding, where it is bit-exact). Returns the
    figures and the decoded lossy frames."""
    exact = decode(clip.lossless)
    lossy = decode(clip.lossy)
    same = [j < len(exact) and frame_digest(exact[j]) == d for j, d in enumerate(clip.digests)]
    psnr, max_err = [], []
    for j, ok in enumerate(same):
        if ok and j < len(lossy):
            diff = lossy[j].astype(np.float64) - exact[j]
            mse = float(np.mean(diff**2))
            psnr.append(float("inf") if mse == 0 else 10.0 * np.log10(255.0**2 / mse))
            max_err.append(float(np.abs(diff).max()))
    # The stills vebuild takes (vebuild.project.video.decode_still, one frame at a time by its
    # index, as `vebuild add clip.mp4@frame=N` does): the first, the last and each place's frame.
    from vebuild.project.video import decode_still, frame_times

    known = frame_times(clip.lossless)
    picks = sorted({0, len(clip.digests) - 1, *clip.place_frames} & set(range(len(clip.digests))))
    stills = sum(frame_digest(decode_still(clip.lossless, clip.lossless.parent, frame=j, times=known).rgb)
                 == clip.digests[j] for j in picks)
    return {"frames": len(clip.digests), "exact": int(sum(same)), "decoded_lossless": len(exact),
            "decoded_lossy": len(lossy), "psnr_db": psnr, "max_error_grey": max_err,
            "stills_checked": len(picks), "stills_exact": int(stills)}, lossy


# -- the project a user makes ------------------------------------------------------------------


@dataclass(frozen=True)
class Still:
    """The frame of a video file a case is measured on."""

    video: Path
    frame: int


def add_still(folder: Path, photo_id: str, still: Still | None, size: tuple[int, int]) -> dict[str, Any]:
    """The photo entry of the still: frame ``still.frame`` of the video, copied into the project
    folder and imported as ``vebuild add`` imports it; or a plain PNG of the frame's size where the
    case has no video. The photo is called ``photo_id``."""
    from vebuild.project.stills import prepare_photos, write_stills

    (folder / "photos").mkdir(parents=True, exist_ok=True)
    if still is None:
        path = folder / "photos" / f"{photo_id}.png"
        Image.new("RGB", size, (128, 128, 128)).save(path)
        return new_photo_entry(folder, path, photo_id)
    video = folder / "photos" / f"{photo_id}{still.video.suffix}"
    shutil.copyfile(still.video, video)
    (prepared,) = prepare_photos(folder, [f"{video}@frame={still.frame}"])
    write_stills([prepared])
    return {**prepared.entry, "id": photo_id}


def calibrated_lens(project: Any, photo_id: str) -> dict[str, float]:
    """What calibration says of the photo's lens: its focal length and principal point (px) and
    how far it moves the photo's farthest corner (px)."""
    cam = photo_camera(project, photo_id)
    return {"f_px": float(cam.K[0, 0]), "cx": float(cam.K[0, 2]), "cy": float(cam.K[1, 2]), "k1": cam.lens.k1,
            "k2": cam.lens.k2, "corner_displacement_px": distortion_displacement_px(cam.K, cam.width, cam.height,
                                                                                    cam.lens)}


def measure_height(project: Any, photo_id: str, foot: list[float], top: list[float]) -> tuple[float, float | None]:
    """A person's height (m) and its 1σ from the clicks on the point between the feet and the
    head's top: ``vebuild analyse P person-height --photo ID --head U,V --foot U,V``."""
    from vebuild.analysis.recorded import parse_recorded

    words = ["person-height", "--photo", photo_id, "--head", f"{top[0]:.2f},{top[1]:.2f}",
             "--foot", f"{foot[0]:.2f},{foot[1]:.2f}"]
    m = parse_recorded(words).run(project).figures["frame"]
    return float(m["value_m"]), m["sigma_m"]


def _ground_points(case: CctvCase, rng: np.random.Generator, n: int = 200) -> list[Array]:
    """Ground points the camera sees, away from the figure's places."""
    d = case.layout.dims
    lo, hi = ((-20.0, d["near_y"] + 0.3), (20.0, d["far_y"] - 0.3)) if case.setting == "street" else \
        ((0.3, 0.3), (d["lx"] - 0.6, d["ly"] - 0.6))
    X = np.c_[rng.uniform(lo, hi, (n, 2)), np.zeros(n)]
    far = np.array([min(np.hypot(*(x[:2] - p)) for p in case.places) > 0.6 for x in X])
    return list(X[case.sees(X) & far])


def _known_length(case: CctvCase, rng: np.random.Generator) -> tuple[Array, Array] | None:
    """A run along x on the ground the user tapes: along the kerb or a pavement joint (whole
    slabs, 1.2 m) in a street, along a tile joint (whole tiles) in a shop; both ends seen."""
    d = case.layout.dims
    for _ in range(300):
        if case.setting == "street":
            y = float(rng.choice([0.0, d["road_w"], -1.2, d["road_w"] + 1.2]))
            a = 1.2 * float(rng.integers(-15, 15))
            L = 1.2 * float(rng.integers(2, 5))
        else:
            t = d["tile"]
            y = t * float(rng.integers(1, int(d["ly"] / t)))
            a = t * float(rng.integers(1, int(d["lx"] / t) - 3))
            L = t * float(rng.integers(4, 9))
        ends = np.array([[a, y, 0.0], [a + L, y, 0.0]])
        if bool(np.all(case.sees(ends))):
            return ends[0], ends[1]
    return None


@dataclass
class Marks:
    """What a user marks on one case's still, and the truth of each height."""

    segments: dict[str, list[list[float]]]
    origin: list[float]
    known: dict[str, Any]
    heights: list[dict[str, Any]]  # frame, truth_m, foot and top clicks


def user_marks(case: CctvCase, rng: np.random.Generator) -> Marks | None:
    """The marks a user makes (module docstring of :mod:`vebuild.bench.cctv`); None where the
    case shows no origin point or known length."""
    sigma = float(rng.uniform(*SEGMENT_CLICK_PX))
    longer = max(case.width, case.height)
    edges: dict[str, list[tuple[Line, Array]]] = marked_edges(case, rng, edge_candidates(case))
    segs = {a: [[float(v) for v in clicks_along(uv, rng, sigma, longer).reshape(-1)] for _, uv in got]
            for a, got in edges.items() if got}
    ground = _ground_points(case, rng)
    known = _known_length(case, rng)
    if not ground or known is None:
        return None

    def click(X: Array, s: float) -> list[float]:
        return [float(v) for v in case.pixels(np.asarray(X)[None])[0][0] + rng.normal(0.0, s, 2)]

    length = float(np.linalg.norm(known[1] - known[0]))
    kn = {"axis": "x", "length": round(length + float(rng.normal(0.0, TAPE_SIGMA_M)), 3), "sigma": TAPE_SIGMA_M,
          "ends": [click(known[0], HEIGHT_CLICK_PX), click(known[1], HEIGHT_CLICK_PX)], "truth_m": length}
    heights = []
    for k in range(len(case.places)):
        if bool(np.all(case.sees(np.array([case.foot(k), case.top(k)])))):
            heights.append({"place": k, "truth_m": case.figure_height, "foot": click(case.foot(k), HEIGHT_CLICK_PX),
                            "top": click(case.top(k), HEIGHT_CLICK_PX)})
    return Marks(segs, click(ground[0], HEIGHT_CLICK_PX), kn, heights)


def write_case_project(folder: Path, case: CctvCase, marks: Marks, still: Still | None) -> Path:
    """The one-photo project of a case: its still, the edges marked, the origin marker O on the
    ground, the taped length."""
    folder.mkdir(parents=True, exist_ok=True)
    data = new_project("generated CCTV camera")
    data["settings"]["click_sigma_px"] = PROJECT_CLICK_SIGMA_PX
    entry = add_still(folder, "cam", still, (case.width, case.height))
    entry["vanishing_segments"] = marks.segments
    entry["marker_observations"] = {"O": marks.origin}
    data["photos"].append(entry)
    data["markers"] = [{"name": "O", "on_floor": True}]
    data["origin_marker"] = "O"
    data["reference_distances"] = []
    data["known_lengths"] = [{"photo": "cam", **{k: v for k, v in marks.known.items() if k != "truth_m"}}]
    path = folder / "cctv.vebuild.json"
    save_project(path, data)
    return path


def measure_case(folder: Path, case: CctvCase, marks: Marks, still: Still | None) -> dict[str, Any]:
    """Calibrate the case's project (through the API, as ``vebuild calibrate`` does) and measure
    each height: ``{"refused": why}`` or the lens found and the heights."""
    from vebuild.actions.calibrate import calibrate_project
    from vebuild.errors import VebuildError

    path = write_case_project(folder, case, marks, still)
    try:
        project = load_project(path)
        calibrate_project(project)
        save_project(project)
        project = load_project(path)
        lens = calibrated_lens(project, "cam")
    except VebuildError as e:
        return {"refused": str(e).splitlines()[0]}
    rows = []
    for h in marks.heights:
        row: dict[str, Any] = {"truth_m": h["truth_m"], "place": h["place"]}
        try:
            row["value_m"], row["sigma_m"] = measure_height(project, "cam", h["foot"], h["top"])
        except (VebuildError, ValueError) as e:
            row["refused"] = str(e).splitlines()[0]
        rows.append(row)
    return {"lens": lens, "heights": rows}


def reference_case(case: CctvCase) -> CctvCase:
    """The same camera and scene through vebuild's own lens model: the division-model lens with
    the true lens's K-equivalent and corner displacement (the reference run)."""
    if not isinstance(case.lens, TrueLens):
        raise TypeError("the reference of a case is taken from its true lens")
    return replace(case, lens=matching_division_lens(case.lens, case.width, case.height))
