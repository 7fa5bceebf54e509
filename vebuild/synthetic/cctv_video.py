"""The video of a generated CCTV case (:mod:`vebuild.synthetic.cctv`): the figure walking between
its places, each frame ray-cast through the true lens, blurred a little and given sensor noise,
then encoded to H.264 with PyAV.

The clip: a frame with the figure at each of its places and one halfway between each two (it
walks), :data:`FPS` frames a second. An **interlaced** case weaves each frame from two fields
rendered at two instants, as an interlaced camera takes them: the even rows (0, 2, …) at the
frame's instant t, the odd rows at t + 1/50 s, the figure having walked on by then at
:data:`WALK_M_S`. The truth (head-top and foot pixels) is the figure's at t.

Two encodings of the same frames: **lossless** (libx264rgb, qp 0, RGB 4:4:4: decoded, every frame
is the generator's, bit for bit) and **lossy** (libx264, yuv420p, crf 23, as a recorder exports).
Both are flagged interlaced (x264's ``interlaced=1``, top field first) where the case is.
"""

from __future__ import annotations

from pathlib import Path

import av
import cv2
import numpy as np
from numpy.typing import NDArray

from vebuild.project.atomic import write_via_path

from .cctv import CctvCase
from .cctv_render import BODY_RADIUS_M, render

Array = NDArray[np.float64]
Frame = NDArray[np.uint8]

FPS = 25
#: The second field of an interlaced frame is taken this long after the first (s): PAL's 50 fields a second.
FIELD_S = 1.0 / 50.0
#: How fast the figure walks (m/s).
WALK_M_S = 1.4
LOSSY_CRF = 23
#: Pixels left around the figure's image where a frame is cast again over the empty scene.
FIGURE_MARGIN_PX = 4


def positions(case: CctvCase) -> list[tuple[Array, Array]]:
    """Each frame's figure position (x, y) and its walking direction (a unit vector): its places
    with the halfway points between them (module docstring)."""
    out = []
    P = case.places
    for k in range(len(P)):
        ahead = P[k + 1] - P[k] if k + 1 < len(P) else P[k] - P[k - 1]
        u = ahead / max(float(np.linalg.norm(ahead)), 1e-9)
        out.append((np.asarray(P[k], float), u))
        if k + 1 < len(P):
            out.append(((P[k] + P[k + 1]) / 2.0, u))
    return out


def place_frames(case: CctvCase) -> list[int]:
    """The frame in which the figure stands at each of its places."""
    return [2 * k for k in range(len(case.places))]


def _window(case: CctvCase, at: Array) -> tuple[tuple[int, int], tuple[int, int]] | None:
    """The rows and columns (end exclusive) the figure at ``at`` covers, with a margin; None
    where the figure reaches behind the camera (cast the whole frame)."""
    a = np.linspace(0.0, 2.0 * np.pi, 32, endpoint=False)
    z = np.linspace(0.0, case.figure_height, 12)
    rr = BODY_RADIUS_M + 0.01
    X = np.array([[at[0] + rr * np.cos(t), at[1] + rr * np.sin(t), h] for t in a for h in z])
    uv, depth = case.pixels(X)
    if np.any(depth < 0.05):
        return None
    lo = np.floor(uv.min(axis=0)).astype(int) - FIGURE_MARGIN_PX
    hi = np.ceil(uv.max(axis=0)).astype(int) + FIGURE_MARGIN_PX
    c0, r0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
    c1, r1 = min(int(hi[0]), case.width), min(int(hi[1]), case.height)
    if c1 <= c0 or r1 <= r0:
        return (0, 0), (0, 0)
    return (r0, r1), (c0, c1)


def _with_figure(case: CctvCase, empty: Array, at: Array) -> Array:
    """The scene with the figure standing at ``at``: the empty scene cast again over the figure."""
    win = _window(case, at)
    fig = (at, case.figure_height)
    if win is None:
        return render(case.layout, case.lens, case.R, case.C, case.width, case.height, fig, case.tex_seed)[0]
    (r0, r1), (c0, c1) = win
    out = empty.copy()
    if r1 > r0 and c1 > c0:
        out[r0:r1, c0:c1] = render(case.layout, case.lens, case.R, case.C, case.width, case.height, fig,
                                   case.tex_seed, rows=(r0, r1), cols=(c0, c1))[0]
    return out


def finish(case: CctvCase, img: Array, rng: np.random.Generator) -> Frame:
    """A cast frame as the camera delivers it: blurred (Gaussian, the case's σ), sensor noise
    (the case's σ, grey levels) and quantised to 8 bits."""
    blurred = cv2.GaussianBlur(img.astype(np.float32), (0, 0), case.blur_px)
    noisy = blurred + rng.normal(0.0, case.noise_grey, img.shape).astype(np.float32)
    return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)


def empty_scene(case: CctvCase) -> Array:
    """The scene without the figure, cast (before blur and noise)."""
    return render(case.layout, case.lens, case.R, case.C, case.width, case.height, None, case.tex_seed)[0]


def cast_frame(case: CctvCase, empty: Array, at: Array, u: Array) -> Array:
    """A frame cast (before blur and noise) with the figure at ``at`` walking along ``u``; woven
    from two fields where the case is interlaced (module docstring)."""
    img = _with_figure(case, empty, at)
    if case.interlaced:
        later = _with_figure(case, empty, at + WALK_M_S * FIELD_S * u)
        img[1::2] = later[1::2]
    return img


def frames(case: CctvCase, rng: np.random.Generator) -> list[Frame]:
    """The clip's frames (module docstring), RGB (height, width, 3)."""
    empty = empty_scene(case)
    return [finish(case, cast_frame(case, empty, at, u), rng) for at, u in positions(case)]


def encode(frames_: list[Frame], path: Path, lossless: bool, interlaced: bool) -> None:
    """Write the frames to ``path`` (an MP4) as H.264 (module docstring), atomically."""
    h, w = frames_[0].shape[:2]
    path.parent.mkdir(parents=True, exist_ok=True)

    def write(tmp: Path) -> None:
        with av.open(str(tmp), "w", format="mp4") as out:
            stream = out.add_stream("libx264rgb" if lossless else "libx264", rate=FPS)
            stream.width, stream.height = w, h
            stream.pix_fmt = "rgb24" if lossless else "yuv420p"
            opts: dict[str, object] = {"preset": "veryfast", **({"qp": "0"} if lossless else {"crf": str(LOSSY_CRF)})}
            if interlaced:
                opts["x264-params"] = "interlaced=1:tff=1"
            stream.options = opts
            for f in frames_:
                for packet in stream.encode(av.VideoFrame.from_ndarray(f, format="rgb24")):
                    out.mux(packet)
            for packet in stream.encode():
                out.mux(packet)

    write_via_path(path, write)


def decode(path: Path) -> list[Frame]:
    """Every frame of the video at ``path``, RGB (height, width, 3)."""
    with av.open(str(path)) as src:
        return [np.asarray(f.to_ndarray(format="rgb24")) for f in src.decode(video=0)]
