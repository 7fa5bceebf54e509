"""Walk-through videos: a smooth camera path through named views, rendered headless to MP4.

The path (pure numpy/scipy, no GL):

- **Positions** run through the views' centres on a natural cubic spline (C2) over chord length,
  re-parameterised by arc length, so the camera walks each segment (view i → view i+1) at constant
  speed. A segment takes ``length / speed`` seconds but at least the time to turn through its
  change of view direction (or field of view) at ``turn_rate_deg`` per second (``--speed``), or
  the time given (``--seconds``); its frame count is that time rounded to whole frames (at least 1),
  so view i is reached exactly at an integer frame, :attr:`CameraPath.keyframes`. The rounding
  changes a segment's speed by at most half a frame's worth (0.5 / frames); the speed is constant
  within a segment and changes only at the views. Consecutive views at the same place split the
  spline: the camera stops there and turns on the spot.
- **Orientations** follow :class:`scipy.spatial.transform.RotationSpline` (continuous angular
  rate and acceleration) through every view's rotation at its keyframe time.
- **Field of view**: the horizontal field of view (and the principal point, as a fraction of the
  image) is interpolated with a monotone cubic (PCHIP: C1, no overshoot between views).
- **Size**: one image size for the whole video (default: the first view's); each view is
  :meth:`~vebuild.camera.ImageCamera.resized` to it (its horizontal field of view is kept).
- **Holds**: with ``hold`` seconds the camera stays still at each view (first and last included)
  for ``round(hold · fps)`` frames after its keyframe.

The video: one :class:`~vebuild.render.renderer.Renderer`, one frame at a time streamed into an
H.264 encoder (PyAV's FFmpeg with libx264, yuv420p, BT.709 limited range, so ordinary players open
it; width and height must be even), never all frames in memory. The MP4 is written to a temporary
name beside the output and moved into place only when complete; on any error or Ctrl-C nothing is
left behind.

Surfaces no photo saw are hatched by default (``VideoRequest.unobserved``: hatch, tint or off;
:mod:`vebuild.render.observed`); each frame then carries the legend in its lower left corner, and
the MP4's comment metadata records the setting (``"unobserved"``).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline, PchipInterpolator
from scipy.spatial.transform import Rotation, RotationSpline

from vebuild import __version__
from vebuild.camera import ImageCamera, focal_to_fov, intrinsic_matrix
from vebuild.determinism import filled_allocations
from vebuild.errors import ProjectError, VebuildError
from vebuild.project.atomic import commit, temp_path
from vebuild.project.provenance import stage_hashes, stale_record

if TYPE_CHECKING:
    from vebuild.project import Project
    from vebuild.render.renderer import Renderer

Array = NDArray[np.float64]

DEFAULT_FPS = 30.0
#: Walking speed (m/s) when neither ``speed`` nor ``seconds`` is given: a slow, steady walk.
DEFAULT_SPEED = 1.0
#: How fast the camera may turn (or zoom), degrees per second: sets the time of a segment that
#: turns much and moves little.
DEFAULT_TURN_RATE_DEG = 45.0
#: x264's constant rate factor: 18 is near visually lossless (lower: better and bigger).
DEFAULT_CRF = 18
MAX_FPS = 240.0
#: Largest side of an encoded frame: H.264 level 6.2 goes to 8192 pixels.
MAX_SIDE = 8192
#: Consecutive view centres closer than this (m) are the same place.
SAME_PLACE_M = 1e-6
STEREO_MODES = ("sbs", "tb", "anaglyph")
#: The arc length table: samples of the spline's parameter (chord length) this far apart (m), at
#: least 16 between two views, each sub-interval integrated with Gauss-Legendre points. Inverted by
#: a cubic spline, it gives the speed along the path to about 1e-6 even in tight bends.
_ARC_STEP_M = 0.005
_ARC_GAUSS_POINTS = 5


# -- the path (pure numpy/scipy) -------------------------------------------------------------------


@dataclass(frozen=True)
class Timing:
    """How the camera moves along the path. ``speed`` (m/s) and ``seconds`` (per segment) exclude
    each other; with neither, the speed is :data:`DEFAULT_SPEED`."""

    fps: float = DEFAULT_FPS
    speed: float | None = None
    seconds: float | None = None
    hold: float = 0.0
    turn_rate_deg: float = DEFAULT_TURN_RATE_DEG

    def __post_init__(self) -> None:
        self.check()  # a Timing that exists is a valid one

    def check(self) -> None:
        """An error naming the option and what was expected, for any bad value."""
        def bad(option: str, expected: str, value: object) -> VebuildError:
            return VebuildError(f"{option}: expected {expected}, got {value!r}")

        if not (_finite(self.fps) and 1.0 <= self.fps <= MAX_FPS):
            raise bad("--fps", f"frames per second between 1 and {MAX_FPS:g}", self.fps)
        if self.speed is not None and self.seconds is not None:
            raise VebuildError("give either --speed (metres per second) or --seconds (per segment), not both")
        if self.speed is not None and not (_finite(self.speed) and self.speed > 0):
            raise bad("--speed", "a walking speed in metres per second, greater than 0", self.speed)
        if self.seconds is not None and not (_finite(self.seconds) and self.seconds > 0):
            raise bad("--seconds", "the seconds each segment takes, greater than 0", self.seconds)
        if not (_finite(self.hold) and self.hold >= 0):
            raise bad("--hold", "seconds to stay at each view, 0 or more", self.hold)
        if not (_finite(self.turn_rate_deg) and self.turn_rate_deg > 0):
            raise bad("--turn-rate", "degrees per second, greater than 0", self.turn_rate_deg)


def _finite(x: object) -> bool:
    return isinstance(x, int | float | np.floating | np.integer) and bool(np.isfinite(x))


class ArcLengthSpline:
    """A natural cubic spline through ``points`` (n ≥ 2, consecutive ones distinct) over chord
    length, evaluated by arc length s ∈ [0, length]: ``self(s)``. ``knot_s[i]`` is the arc length
    at ``points[i]``, where the curve passes exactly through it."""

    def __init__(self, points: Array):
        points = np.asarray(points, float)
        u = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        self.curve = CubicSpline(u, points, bc_type="natural")
        velocity = self.curve.derivative()
        counts = np.maximum(16, np.ceil(np.diff(u) / _ARC_STEP_M)).astype(int)
        grid = np.concatenate([np.linspace(a, b, m, endpoint=False)
                               for a, b, m in zip(u[:-1], u[1:], counts, strict=True)] + [u[-1:]])
        x, w = np.polynomial.legendre.leggauss(_ARC_GAUSS_POINTS)
        mid, half = 0.5 * (grid[1:] + grid[:-1]), 0.5 * (grid[1:] - grid[:-1])
        t = mid[:, None] + half[:, None] * x[None, :]
        speed = np.linalg.norm(velocity(t.ravel()), axis=1).reshape(t.shape)
        s = np.concatenate([[0.0], np.cumsum((speed * w).sum(axis=1) * half)])
        self.knot_s = s[np.concatenate([[0], np.cumsum(counts)])]  # the grid holds every knot u[i]
        self.length = float(s[-1])
        self._t_of_s = CubicSpline(s, grid)  # the inverse of s(t), C2 where the curve's speed is not 0

    def __call__(self, s: float | Array) -> Array:
        return self.curve(self._t_of_s(np.clip(s, 0.0, self.length)))


def horizontal_fov(cam: ImageCamera) -> float:
    """The horizontal field of view (radians) of a camera with square pixels."""
    return focal_to_fov(cam.K[0, 0], cam.width)


class CameraPath:
    """The camera of every frame of a walk-through through ``views`` (see the module's docstring).

    Attributes: ``views`` (resized to ``width`` × ``height``), ``keyframes`` (the frame at which
    each view is reached), ``n_frames``, ``fps``, ``segment_frames`` (frames from view i to view
    i+1), ``segment_length`` (m of path from view i to view i+1).
    """

    def __init__(self, views: Sequence[ImageCamera], width: int, height: int, timing: Timing):
        timing.check()
        if len(views) < 2:
            raise VebuildError(f"--views: expected at least two views to walk between, got {len(views)}")
        check_size(width, height, views[0].source or "--size")
        self.timing = timing
        self.fps = float(timing.fps)
        self.width, self.height = int(width), int(height)
        self.views = [v.resized(self.width, self.height) for v in views]
        n = len(self.views)
        C = np.array([v.C for v in self.views], float)
        self._cam_to_world = Rotation.from_matrix(np.array([np.asarray(v.R, float).T for v in self.views]))
        fov = np.array([horizontal_fov(v) for v in self.views])

        # Positions: one arc-length spline per run of distinct consecutive centres.
        same = np.linalg.norm(np.diff(C, axis=0), axis=1) < SAME_PLACE_M
        self._runs: list[tuple[int, int, ArcLengthSpline]] = []  # (first view, last view, spline)
        start = 0
        for i in range(n - 1):
            if same[i] or i == n - 2:
                last = i if same[i] else i + 1
                if last > start:
                    self._runs.append((start, last, ArcLengthSpline(C[start:last + 1])))
                start = i + 1
        seg_length = np.zeros(n - 1)
        self._run_of_segment = [-1] * (n - 1)
        for r, (a, b, spline) in enumerate(self._runs):
            seg_length[a:b] = np.diff(spline.knot_s)
            for i in range(a, b):
                self._run_of_segment[i] = r
        self.segment_length = seg_length

        # Frames per segment: walking time (or the fixed time), at least the turning time.
        turn = (self._cam_to_world[:-1].inv() * self._cam_to_world[1:]).magnitude()
        turn = np.maximum(turn, np.abs(np.diff(fov)))
        if timing.seconds is not None:
            seconds = np.full(n - 1, float(timing.seconds))
        else:
            seconds = np.maximum(seg_length / (timing.speed if timing.speed is not None else DEFAULT_SPEED),
                                 turn / np.radians(timing.turn_rate_deg))
        self.segment_frames = np.maximum(1, np.round(seconds * self.fps)).astype(int)
        self.hold_frames = int(round(timing.hold * self.fps))
        self.keyframes = [int(k) for k in np.concatenate([[0], np.cumsum(self.segment_frames)])
                          + self.hold_frames * np.arange(n)]
        self.n_frames = self.keyframes[-1] + self.hold_frames + 1

        # Motion time τ (s) of each view: holds do not advance it.
        self.view_times = np.concatenate([[0.0], np.cumsum(self.segment_frames)]) / self.fps
        self._rotation = RotationSpline(self.view_times, self._cam_to_world)
        pp = np.array([[v.K[0, 2] / v.width, v.K[1, 2] / v.height] for v in self.views])
        self._fov = PchipInterpolator(self.view_times, fov)
        self._principal = PchipInterpolator(self.view_times, pp, axis=0)

    @property
    def duration(self) -> float:
        """Length of the video in seconds (n_frames / fps)."""
        return self.n_frames / self.fps

    @property
    def length(self) -> float:
        """Length of the path in metres."""
        return float(self.segment_length.sum())

    def motion_time(self, frame: int) -> tuple[int, float]:
        """(segment, τ) of a frame: the segment it is on (the last view's index − 1 at the end) and
        its motion time in seconds (holds do not advance τ)."""
        if not 0 <= frame < self.n_frames:
            raise IndexError(f"frame {frame} is outside the video's 0…{self.n_frames - 1}")
        i = int(np.searchsorted(self.keyframes, frame, side="right")) - 1
        step = frame - self.keyframes[i] - self.hold_frames
        tau = self.view_times[i] + max(0, step) / self.fps
        return min(i, len(self.views) - 2), float(tau)

    def position(self, segment: int, tau: float) -> Array:
        """Camera centre at motion time τ on ``segment`` (constant speed along it)."""
        t0, t1 = self.view_times[segment], self.view_times[segment + 1]
        r = self._run_of_segment[segment]
        if r < 0:  # the views at both ends are at the same place
            return np.array(self.views[segment].C, float)
        first, _, spline = self._runs[r]
        s0, s1 = spline.knot_s[segment - first], spline.knot_s[segment - first + 1]
        phase = min(1.0, max(0.0, (tau - t0) / (t1 - t0)))
        return np.asarray(spline(s0 + phase * (s1 - s0)), float)

    def camera(self, frame: int) -> ImageCamera:
        """The camera of ``frame``."""
        segment, tau = self.motion_time(frame)
        C = self.position(segment, tau)
        R = self._rotation(tau).as_matrix().T
        f = 0.5 * self.width / np.tan(0.5 * float(self._fov(tau)))
        px, py = self._principal(tau)
        K = intrinsic_matrix(f, px * self.width, py * self.height)
        return ImageCamera(f"frame {frame}", K, R, C, self.width, self.height, source=self.views[0].source)

    def cameras(self) -> Iterator[ImageCamera]:
        """Every frame's camera, in order."""
        for k in range(self.n_frames):
            yield self.camera(k)


def camera_path(views: Sequence[ImageCamera], size: tuple[int, int] | None = None,
                timing: Timing | None = None) -> CameraPath:
    """The path through ``views`` at ``size`` (default: the first view's)."""
    if not views:
        raise VebuildError("--views: expected at least two views to walk between, got none")
    w, h = size if size is not None else (views[0].width, views[0].height)
    return CameraPath(views, w, h, timing or Timing())


def check_size(width: int, height: int, source: str = "--size") -> None:
    """Even sides of 2 … :data:`MAX_SIDE` pixels (H.264 in yuv420p halves the colour resolution,
    so it needs even sides) within the limits of every render (:mod:`vebuild.render.sizes`); an
    error naming ``source`` (where the size came from) otherwise."""
    from vebuild.render.sizes import check_render_size

    if not all(isinstance(v, int | np.integer) and 2 <= v <= MAX_SIDE for v in (width, height)):
        raise VebuildError(f"{source}: expected a width and height between 2 and {MAX_SIDE} pixels, "
                           f"got {width}×{height}")
    check_render_size(width, height, source, max_side=MAX_SIDE)
    if width % 2 or height % 2:
        raise VebuildError(f"{source}: H.264 (yuv420p) needs an even width and height, got {width}×{height}; "
                           f"use --size {width - width % 2}x{height - height % 2}")


def parse_views(text: str) -> list[str]:
    """'A,B,C' → ['A', 'B', 'C'] (spaces around names dropped)."""
    names = [n.strip() for n in (text or "").split(",")]
    if any(not n for n in names):
        raise VebuildError(f"--views: expected view names separated by commas (such as door,table), "
                           f"got {text!r}")
    return names


# -- the MP4 file ----------------------------------------------------------------------------------


class Mp4Writer:
    """An H.264 MP4 written frame by frame, atomically: a context manager whose :meth:`write` takes
    (height, width, 3) sRGB uint8 frames; the file appears at ``out`` only when the block ends
    without an error (the temporary file is removed otherwise)."""

    CODEC = "libx264"

    def __init__(self, out: Path, width: int, height: int, fps: float, crf: int = DEFAULT_CRF,
                 preset: str = "medium", metadata: dict[str, str] | None = None):
        check_size(width, height)
        if not (isinstance(crf, int | np.integer) and 0 <= crf <= 51):
            raise VebuildError(f"--crf: expected an integer from 0 (best) to 51 (worst), got {crf!r}")
        self.out = Path(out)
        self.width, self.height = int(width), int(height)
        self.rate = Fraction(fps).limit_denominator(1001)
        self.crf, self.preset = int(crf), preset
        self.metadata = dict(metadata or {})
        self.metadata.setdefault("description", f"vebuild {__version__}")  # how vebuild knows its own videos
        self.tmp = temp_path(self.out)
        self.frames = 0
        self._container: Any = None
        self._stream: Any = None
        self._filled = contextlib.ExitStack()  # holds filled_allocations() while the encoder is open

    def __enter__(self) -> Mp4Writer:
        try:
            import av
        except ImportError:
            raise VebuildError("PyAV is not installed; `pip install av` (its wheels bring FFmpeg "
                               "with the H.264 encoder)") from None
        try:
            av.codec.Codec(self.CODEC, "w")
        except Exception:
            raise VebuildError(f"this PyAV's FFmpeg has no H.264 encoder ({self.CODEC}); install PyAV's "
                               "wheel from PyPI (`pip install --force-reinstall av`), which includes it") from None
        self._filled.enter_context(filled_allocations())  # its bytes must not depend on the heap's past
        try:
            self._container = av.open(str(self.tmp), "w", format="mp4", options={"movflags": "+faststart"})
        except (OSError, av.error.FFmpegError) as e:
            self.tmp.unlink(missing_ok=True)
            self._filled.close()
            raise VebuildError(f"{self.out}: cannot write the video ({getattr(e, 'strerror', None) or e})") from None
        try:
            self._container.metadata.update(self.metadata)
            s = self._container.add_stream(self.CODEC, rate=self.rate)
            s.width, s.height, s.pix_fmt = self.width, self.height, "yuv420p"
            s.codec_context.time_base = 1 / self.rate
            # One encoder thread: x264's output depends on its thread count (which it takes from the
            # machine's cores) and, with frame threads, may change from run to run; a second examiner
            # must get the same bytes on another machine (scenes/FORMAT.md, "The same bytes").
            s.options = {"crf": str(self.crf), "preset": self.preset, "threads": "1"}
            # BT.709 (sRGB's primaries), limited range: what players assume for HD and are told here.
            cc = s.codec_context
            cc.colorspace, cc.color_primaries, cc.color_trc, cc.color_range = 1, 1, 1, 1
            self._stream = s
        except BaseException:
            self._abort()
            raise
        return self

    def write(self, rgb: NDArray[np.uint8]) -> None:
        """Encode one frame (height, width, 3) sRGB uint8."""
        import av

        if rgb.shape != (self.height, self.width, 3) or rgb.dtype != np.uint8:
            raise ValueError(f"expected a ({self.height}, {self.width}, 3) uint8 frame, got {rgb.shape} {rgb.dtype}")
        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24")
        # Bit-exact, accurately rounded conversion: the same YUV from the same RGB on any processor
        # (swscale's SIMD paths otherwise round differently from one CPU to another).
        frame = frame.reformat(format="yuv420p", dst_colorspace="itu709", dst_color_range="MPEG",
                               interpolation=_same_on_any_cpu())
        frame.pts, frame.time_base = self.frames, 1 / self.rate
        self._mux(self._stream.encode(frame))
        self.frames += 1

    def _mux(self, packets: Any) -> None:
        try:
            self._container.mux(packets)
        except OSError as e:
            raise VebuildError(f"{self.out}: cannot write the video ({e.strerror or e})") from None

    def _abort(self) -> None:
        try:
            if self._container is not None:
                self._container.close()
        except Exception:  # closing a half-written file may fail too; it is deleted anyway
            pass
        self._container = None
        self.tmp.unlink(missing_ok=True)
        self._filled.close()

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        if exc_type is not None:
            self._abort()
            return
        try:
            self._mux(self._stream.encode(None))  # flush the encoder's delayed frames
            self._container.close()
            self._container = None
            self._filled.close()
            commit(self.tmp, self.out)
        except BaseException as e:
            self._abort()
            if isinstance(e, OSError):
                raise VebuildError(f"{self.out}: cannot write the video ({e.strerror or e})") from None
            raise


# -- rendering -------------------------------------------------------------------------------------


@dataclass
class VideoRequest:
    """What to render: the views walked through, in order, and how."""

    views: list[str]
    out: Path | None = None  # default: videos/<view names>.mp4 beside the project file
    size: tuple[int, int] | None = None  # default: the first view's size
    timing: Timing = field(default_factory=Timing)
    lighting: str | None = None  # a preset's name; None: as photographed
    stereo: str | None = None  # sbs, tb or anaglyph
    crf: int = DEFAULT_CRF
    unobserved: str = "hatch"  # how surfaces no photo saw are shown (vebuild.render.observed)

    def __post_init__(self) -> None:
        from vebuild.render.observed import check_mode

        check_mode(self.unobserved)


@dataclass
class VideoResult:
    out: Path
    frames: int
    fps: float
    width: int  # of the encoded frame (twice the view's for side-by-side stereo, say)
    height: int
    duration: float  # seconds
    length: float  # metres of path
    keyframes: list[tuple[str, int]]  # (view, the frame that shows it), in order
    lighting: str
    encoder: str
    bytes: int
    render_seconds: float  # wall time of rendering and encoding all frames
    warnings: list[str] = field(default_factory=list)


def default_output(project: Project, views: Sequence[str]) -> Path:
    """``videos/<view>-<view>-….mp4`` beside the project file (names made safe for a file name)."""
    slug = "-".join(re.sub(r"[^A-Za-z0-9._]+", "_", v).strip("_") or "view" for v in views)
    return project.folder / "videos" / f"{slug[:120]}.mp4"


def check_output(path: Path, project: Project | None = None) -> Path:
    """Fail before any rendering if ``path`` cannot be an MP4 written by us (also where the output
    policy, :mod:`vebuild.project.outputs`, forbids it)."""
    from vebuild.project.outputs import check_file

    path = Path(path)
    check_file(project, path, "video", ".mp4")
    if path.suffix.lower() != ".mp4":
        raise VebuildError(f"{path}: --out: expected a file name ending in .mp4")
    if path.is_dir():
        raise VebuildError(f"{path}: --out: is a folder; expected a file name ending in .mp4")
    folder = path.parent
    if not folder.is_dir():
        raise VebuildError(f"{path}: --out: the folder {folder} does not exist; create it first or choose "
                           "another path")
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise VebuildError(f"{path}: --out: cannot be written (permission denied)")
    return path


def render_video(project: Project, request: VideoRequest,
                 progress: Callable[[int, int, str], None] | None = None,
                 renderer: Renderer | None = None) -> VideoResult:
    """Render the walk-through of ``request`` to an MP4 (see the module's docstring).

    ``progress(done, total, label)`` is called after each frame. ``renderer``: one to reuse (its
    lighting is set here); by default one is made on the headless context and released after.
    """
    from vebuild.project.decode import find_preset, find_view
    from vebuild.render.sizes import check_camera

    if request.stereo is not None and request.stereo not in STEREO_MODES:
        raise VebuildError(f"--stereo: expected one of {', '.join(STEREO_MODES)}, got {request.stereo!r}")
    cams = [find_view(project, name) for name in request.views]
    if request.size is not None:
        cams = [c.resized(*request.size, source="--size") for c in cams]
    elif cams:
        first = cams[0].source.replace(" (width × height)", "")
        source = (f"{first} (width × height of view {request.views[0]!r}, which sets the video's size; "
                  "no --size given)")
        cams = [c.resized(c.width, c.height, source=source) for c in cams]
    if len(cams) >= 2:
        try:
            check_size(cams[0].width, cams[0].height, cams[0].source)
            check_camera(cams[0], request.stereo, max_side=MAX_SIDE)
        except VebuildError as e:
            raise (e if request.size is not None else ProjectError(project.path, "", str(e))) from None
    path = camera_path(cams, request.size, request.timing)
    lighting = find_preset(project, request.lighting)
    created_folder = False
    if request.out is None:
        out = default_output(project, request.views)
        created_folder = not out.parent.exists()
        out.parent.mkdir(parents=True, exist_ok=True)
    else:
        out = Path(request.out)
    try:
        check_output(out, project)
        from vebuild.project.outputs import begin_stage

        begin_stage(project, out.parent)
        return _render(project, request, path, lighting, out, progress, renderer)
    except BaseException:
        if created_folder and not any(out.parent.iterdir()):
            out.parent.rmdir()
        raise


def _render(project: Project, request: VideoRequest, path: CameraPath, lighting: Any, out: Path,
            progress: Callable[[int, int, str], None] | None, renderer: Renderer | None) -> VideoResult:
    from vebuild.gl import headless_context
    from vebuild.project.provenance import inputs_sha256
    from vebuild.render.observed import draw_legend
    from vebuild.render.renderer import Renderer, Stereo
    from vebuild.render.scene import load_scene
    from vebuild.render.sizes import check_camera, gl_limits

    own = renderer is None
    warnings: list[str] = []
    mode = None if renderer is None else renderer.unobserved  # a caller's renderer gets its mode back
    if renderer is None:
        scene = load_scene(project)
        warnings = list(scene.warnings)
        renderer = Renderer(headless_context(), scene)
    try:
        stereo = Stereo(request.stereo) if request.stereo else None
        limits = gl_limits(renderer.ctx)
        W, H = check_camera(path.views[0], request.stereo,
                            **{**limits, "max_side": min(MAX_SIDE, limits.get("max_side", MAX_SIDE))})
        renderer.set_lighting(lighting)
        renderer.unobserved = request.unobserved
        marked = renderer.marks_unobserved
        meta = {"title": " → ".join(request.views), "encoder": f"vebuild {__version__}",
                "comment": json.dumps({"project": project.path.name, "inputs_sha256": inputs_sha256(project.data),
                                       "views": request.views, "keyframes": path.keyframes,
                                       "lighting": lighting.name, "stereo": request.stereo,
                                       "fps": path.fps, "unobserved": request.unobserved,
                                       "unobserved_marked": marked, "stages": stage_hashes(project.data),
                                       "stale": stale_record(project.data)}, ensure_ascii=False)}
        start = time.perf_counter()
        with Mp4Writer(out, W, H, path.fps, request.crf, metadata=meta) as writer:
            for k in range(path.n_frames):
                frame = renderer.render(path.camera(k), stereo)
                writer.write(draw_legend(frame, request.unobserved) if marked else frame)
                if progress is not None:
                    progress(k + 1, path.n_frames, _label(path, request.views, k))
        seconds = time.perf_counter() - start
    finally:
        if own:
            renderer.release()
        elif mode is not None:
            renderer.unobserved = mode
    return VideoResult(out, path.n_frames, path.fps, W, H, path.duration, path.length,
                       list(zip(request.views, path.keyframes, strict=True)),
                       lighting.name, Mp4Writer.CODEC, out.stat().st_size, seconds, warnings)


def _label(path: CameraPath, names: Sequence[str], frame: int) -> str:
    """What a frame shows, for the progress bar: a view's name, or 'A → B' between two."""
    i = int(np.searchsorted(path.keyframes, frame, side="right")) - 1
    return names[i] if frame - path.keyframes[i] <= path.hold_frames else f"{names[i]} → {names[i + 1]}"


def _same_on_any_cpu() -> Any:
    """swscale's flags for a conversion that gives the same bytes on every processor."""
    from av.video.reformatter import Interpolation

    return Interpolation.BICUBIC | Interpolation.BITEXACT | Interpolation.ACCURATE_RND
