"""Small video files written with PyAV for the tests of stills from video (vebuild/project/video.py)."""

from __future__ import annotations

from pathlib import Path

import av
import numpy as np
from numpy.typing import NDArray


def random_frames(n: int, w: int = 64, h: int = 48, seed: int = 0) -> list[NDArray[np.uint8]]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for _ in range(n)]


def write_clip(path: Path, frames: list[NDArray[np.uint8]], codec: str = "libx264rgb", rate: int = 25,
               options: dict[str, str] | None = None, pix_fmt: str | None = None) -> Path:
    """Encode the RGB frames; libx264rgb with qp 0 (the default here) is lossless RGB."""
    h, w = frames[0].shape[:2]
    with av.open(str(path), "w") as c:
        s = c.add_stream(codec, rate=rate)
        s.width, s.height = w, h
        s.pix_fmt = pix_fmt or ("rgb24" if codec == "libx264rgb" else "yuv420p")
        s.options = {"qp": "0"} if options is None and codec.startswith("libx264") else (options or {})
        for a in frames:
            for p in s.encode(av.VideoFrame.from_ndarray(a, format="rgb24")):
                c.mux(p)
        for p in s.encode():
            c.mux(p)
    return path


def smooth_scene(w: int, h: int, shift: float) -> NDArray[np.uint8]:
    """A smooth picture (a bright disc on a gradient) with the disc moved ``shift`` pixels right."""
    y, x = np.mgrid[0:h, 0:w].astype(float)
    disc = np.exp(-((x - w / 3 - shift) ** 2 + (y - h / 2) ** 2) / (2 * (h / 6) ** 2))
    grey = 40 + 60 * x / w + 150 * disc
    return np.repeat(np.clip(grey, 0, 255).astype(np.uint8)[..., None], 3, axis=2)


def woven(w: int, h: int, shift: float) -> NDArray[np.uint8]:
    """An interlaced frame: the top field (even rows) of the scene at one moment, the bottom field
    (odd rows) of the scene ``shift`` pixels of motion later."""
    out = smooth_scene(w, h, 0.0)
    out[1::2] = smooth_scene(w, h, shift)[1::2]
    return out
