"""Stills from video files: one frame decoded exactly, with where it came from (layer 3, project I/O).

A frame is chosen by its index or by a time. Both are exact, not the nearest keyframe:

- the video stream's packets are read (not decoded) once, and their presentation times (pts) sorted:
  frame index N is the N-th frame in presentation order, counted from 0, and time t picks the frame
  shown at t, the last one whose pts × time_base ≤ t;
- the decoder is sent to the keyframe at or before that frame's pts and decodes forward until the
  frame of that pts comes out; its pixels are converted to RGB8 by libswscale.

The provenance (:class:`Still`) names the video file (relative to the project), its SHA-256, the
container format, the stream, the decoder, the frame's index, pts and time, its size, and whether it
is interlaced: the decoder's flag and field order, AND a content check (:func:`comb_ratio`), since
many files do not flag interlaced video. :func:`keep_field` keeps one field of an interlaced frame.

Every fault of the file or of the request is a :class:`~vebuild.errors.ProjectError` naming the
video file and the argument (``--frame``, ``--time``), what was expected and what was found.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.errors import ProjectError

from .images import sha256_file

#: File name endings taken as video files (what PyAV's FFmpeg demuxes; the content decides in the end).
VIDEO_SUFFIXES = frozenset({".mp4", ".m4v", ".mov", ".avi", ".mkv", ".webm", ".mts", ".m2ts", ".ts", ".mpg",
                            ".mpeg", ".wmv", ".3gp"})
#: A frame is taken as combed (interlaced content) where the energy of its rows' differences across
#: fields is more than this many times that within a field (:func:`comb_ratio`). A smooth progressive
#: picture gives 0.07 (neighbouring rows are closer than rows two apart), noise 1.0; two fields of a
#: moving scene woven together 17 (2 px of motion between them) to 260 (8 px): tests/video_clips.py.
COMB_THRESHOLD = 2.0
#: FFmpeg's AVFieldOrder values: which field is shown first (AV_FIELD_TT, BB, TB, BT).
_FIELD_ORDER = {1: "progressive", 2: "top first", 3: "bottom first", 4: "bottom first", 5: "top first"}
FIELDS = ("top", "bottom")


def is_video(path: str | os.PathLike[str]) -> bool:
    """Whether the file's name ends as a video file's does."""
    return Path(path).suffix.lower() in VIDEO_SUFFIXES


@dataclass(frozen=True)
class Still:
    """One decoded frame and its provenance: ``rgb`` (h, w, 3) uint8; ``origin`` the record written
    into the photo (scenes/FORMAT.md "Stills from video")."""

    rgb: NDArray[np.uint8]
    origin: dict[str, Any]


@dataclass(frozen=True)
class FrameTimes:
    """A video stream's frames in presentation order: their pts (ints, sorted) and time base."""

    pts: tuple[int, ...]
    time_base: Fraction

    def time(self, index: int) -> float:
        return float(self.pts[index] * self.time_base)

    def index_at(self, seconds: float) -> int:
        """The frame shown at ``seconds``: the last whose time is ≤ it (within half a tick)."""
        ticks = Fraction(seconds).limit_denominator(10**9) / self.time_base
        i = int(np.searchsorted(np.asarray(self.pts, dtype=np.int64), float(ticks) + 0.5, side="right")) - 1
        return max(i, 0)


def _open(video: Path, arg: str) -> Any:
    import av

    if not video.is_file():
        raise ProjectError(video, "", f"video file not found: {video} (given as {arg})")
    try:
        container = av.open(str(video), "r")
    except av.error.FFmpegError as e:
        raise ProjectError(video, "", f"cannot read {video.name} as a video ({arg}): expected a video file "
                           f"(MP4, MOV, AVI, MKV, ...) that FFmpeg decodes, found {_why(e)}") from None
    except OSError as e:
        raise ProjectError(video, "", f"cannot read {video.name} ({arg}): {e.strerror or e}") from None
    if not container.streams.video:
        container.close()
        raise ProjectError(video, "", f"{video.name} has no video stream ({arg}): expected a video file, found "
                           f"a {container.format.long_name or container.format.name} file with "
                           f"{len(container.streams)} other stream(s)")
    return container


def _why(e: BaseException) -> str:
    text = getattr(e, "strerror", None) or str(e)
    return f"a file FFmpeg refuses ({text})"


def frame_times(video: str | os.PathLike[str], arg: str = "the video") -> FrameTimes:
    """The pts of the first video stream's frames, in presentation order, read from its packets."""
    import av

    video = Path(video)
    with _open(video, arg) as container:
        stream = container.streams.video[0]
        try:
            pts = sorted(p.pts if p.pts is not None else p.dts for p in container.demux(stream)
                         if p.size and (p.pts is not None or p.dts is not None))
        except av.error.FFmpegError as e:
            raise ProjectError(video, "", f"cannot read the frames of {video.name} ({arg}): the file is damaged "
                               f"or truncated ({_why(e)})") from None
        if not pts:
            raise ProjectError(video, "", f"{video.name} has no frames ({arg}): its video stream is empty")
        return FrameTimes(tuple(int(p) for p in pts), Fraction(stream.time_base))


def decode_still(video: str | os.PathLike[str], folder: str | os.PathLike[str], *, frame: int | None = None,
                 time: float | None = None, field: str | None = None, times: FrameTimes | None = None,
                 sha256: str | None = None) -> Still:
    """Decode one frame of ``video`` exactly: by its index ``frame`` (from 0) or the ``time`` in
    seconds (one of them), and keep one ``field`` ("top" or "bottom") if asked.

    folder : the project's folder; the origin names the video relative to it (absolute if outside).
    times, sha256 : the video's :func:`frame_times` and hash, where already known (stepping on screen).
    """
    import av

    video = Path(video)
    arg = f"--frame {frame}" if frame is not None else f"--time {time:g}" if time is not None else "no frame"
    if (frame is None) == (time is None):
        raise ProjectError(video, "", f"expected a frame number (--frame N) or a time (--time SECONDS) for "
                           f"{video.name}, found {'both' if frame is not None else 'neither'}")
    if field is not None and field not in FIELDS:
        raise ProjectError(video, "", f"expected --field top or bottom, found {field!r}")
    times = times or frame_times(video, arg)
    n = len(times.pts)
    if frame is not None:
        if frame < 0 or frame >= n:
            raise ProjectError(video, "", f"{arg}: expected a frame number from 0 to {n - 1} ({video.name} has {n} "
                               f"frames), found {frame}")
        index = frame
    else:
        assert time is not None
        end = times.time(n - 1)
        start = times.time(0)
        if not np.isfinite(time) or time < 0:
            raise ProjectError(video, "", f"{arg}: expected a time of 0 seconds or more, found {time:g}")
        last = end + _frame_span(times)
        if time >= last or time < start:
            raise ProjectError(video, "", f"{arg}: expected a time from {start:g} s to before {last:g} s (the "
                               f"{n} frames of {video.name} are shown from {start:g} s until {last:g} s), "
                               f"found {time:g}")
        index = times.index_at(time)
    target = times.pts[index]
    with _open(video, arg) as container:
        stream = container.streams.video[0]
        try:
            container.seek(target, stream=stream, backward=True, any_frame=False)
            decoded = next((f for f in container.decode(stream) if _pts(f) >= target), None)
        except av.error.FFmpegError as e:
            raise ProjectError(video, "", f"cannot decode frame {index} of {video.name} ({arg}): the file is "
                               f"damaged or truncated ({_why(e)})") from None
        if decoded is None or _pts(decoded) != target:
            raise ProjectError(video, "", f"cannot decode frame {index} of {video.name} ({arg}): the decoder "
                               f"gave no frame at its time ({times.time(index):g} s); the file may be damaged")
        if getattr(decoded, "is_corrupt", False):
            raise ProjectError(video, "", f"frame {index} of {video.name} ({arg}) decodes damaged (the decoder marks "
                               "it corrupt: its data is missing or broken in the file); expected a whole frame, so "
                               "choose another one")
        rgb = np.ascontiguousarray(decoded.to_ndarray(format="rgb24"), dtype=np.uint8)
        ctx = stream.codec_context
        order = _FIELD_ORDER.get(int(getattr(ctx, "field_order", 0) or 0), "unknown")
        origin: dict[str, Any] = {
            "video": _relative(video, folder),
            "sha256": sha256 or sha256_file(video),
            "container": str(container.format.name),
            "stream": int(stream.index),
            "decoder": f"{ctx.codec.name} (FFmpeg libavcodec {_libavcodec()})",
            "frame": int(index),
            "frames": n,
            "pts": int(target),
            "time_base": f"{times.time_base.numerator}/{times.time_base.denominator}",
            "time": round(times.time(index), 6),
            "width": int(decoded.width),
            "height": int(decoded.height),
        }
    ratio = comb_ratio(rgb)
    flagged = bool(decoded.interlaced_frame)
    origin["interlace"] = {"decoder_flag": flagged, "field_order": order if flagged or order != "unknown"
                           else "unknown", "comb_ratio": round(ratio, 4), "combed": ratio > COMB_THRESHOLD}
    origin["interlaced"] = flagged or ratio > COMB_THRESHOLD
    origin["field"] = field or "both"
    if field is not None:
        rgb = keep_field(rgb, field)
    return Still(rgb, origin)


def _frame_span(times: FrameTimes) -> float:
    """How long the last frame is shown: the median step between frames (0 for one frame)."""
    if len(times.pts) < 2:
        return 0.0
    step = int(np.median(np.diff(np.asarray(times.pts, dtype=np.int64))))
    return float(step * times.time_base)


def _pts(frame: Any) -> int:
    return int(frame.pts if frame.pts is not None else frame.dts if frame.dts is not None else -(1 << 62))


def _libavcodec() -> str:
    import av

    v = av.library_versions.get("libavcodec", ())
    return ".".join(str(x) for x in v) or "unknown version"


def _relative(video: Path, folder: str | os.PathLike[str]) -> str:
    base = Path(os.path.abspath(folder))
    path = Path(os.path.abspath(video))
    return path.relative_to(base).as_posix() if path.is_relative_to(base) else path.as_posix()


def comb_ratio(rgb: NDArray[np.uint8]) -> float:
    """How combed a frame looks: the mean squared deviation of each row from the mean of its two
    neighbours (rows of the other field) over that from the mean of the rows two above and below
    (its own field), on the luma. A frame whose two fields were taken at different moments of a
    moving scene has rows that disagree with their neighbours but not with their own field's."""
    y = rgb[..., :3].astype(np.float64) @ np.array([0.299, 0.587, 0.114])
    if y.shape[0] < 5:
        return 0.0
    across = y[2:-2] - 0.5 * (y[1:-3] + y[3:-1])
    within = y[2:-2] - 0.5 * (y[:-4] + y[4:])
    # One grey level squared is added below: a flat frame (no detail in either) is not combed, and
    # the ratio stays finite.
    return float(np.mean(across ** 2)) / (float(np.mean(within ** 2)) + 1.0)


def keep_field(rgb: NDArray[np.uint8], field: str) -> NDArray[np.uint8]:
    """One field of an interlaced frame at the frame's full size ("bob"): the field's rows are kept
    exactly, at their own rows (top: 0, 2, 4, ...; bottom: 1, 3, 5, ...), and each row of the other
    field is the mean of the field's rows above and below it (the nearest one at the edges). Every
    pixel stays where the camera put it, so the camera's K is the full frame's (square pixels); the
    vertical detail is the field's, half the frame's."""
    first = FIELDS.index(field)
    out = rgb.copy()
    h = rgb.shape[0]
    kept = rgb[first::2].astype(np.uint16)
    for j in range(1 - first, h, 2):
        above, below = j - 1, j + 1
        if above < 0:
            out[j] = rgb[below]
        elif below >= h:
            out[j] = rgb[above]
        else:
            out[j] = ((kept[(above - first) // 2] + kept[(below - first) // 2] + 1) // 2).astype(np.uint8)
    return out
