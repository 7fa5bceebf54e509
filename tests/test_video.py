"""Walk-through videos (vebuild/render/video.py): the camera path's maths on synthetic views, and
the MP4 rendered for real on the headless GL context (Mesa's llvmpipe where there is no GPU),
decoded with PyAV, the library that wrote it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import av
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from vebuild.camera import ImageCamera, look_rotation
from vebuild.cli import main
from vebuild.errors import ProjectError, VebuildError
from vebuild.gl import headless_context
from vebuild.project import load_project
from vebuild.project.decode import find_view
from vebuild.render.renderer import Renderer
from vebuild.render.scene import load_scene
from vebuild.render.video import (
    ArcLengthSpline,
    Mp4Writer,
    Timing,
    VideoRequest,
    camera_path,
    check_output,
    horizontal_fov,
    parse_views,
    render_video,
)

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"
W, H = 160, 120
#: Mean absolute difference (sRGB levels) allowed between a decoded keyframe and the renderer's
#: own image of that view. Measured on this room at 160×120: the yuv420p round trip alone (BT.709,
#: half-resolution colour) costs 1.25–1.4 levels, and x264 at CRF 18 brings it to 1.6–1.8; the
#: frames next to a keyframe differ from its view by 10 levels or more.
KEYFRAME_MAD_LEVELS = 3.0


def _view(name: str, position, look_at, fov_deg: float = 60.0, width: int = W, height: int = H) -> ImageCamera:
    C = np.asarray(position, float)
    R = look_rotation(np.asarray(look_at, float) - C)
    f = 0.5 * width / np.tan(np.radians(fov_deg) / 2)
    return ImageCamera(name, np.array([[f, 0, width / 2], [0, f, height / 2], [0, 0, 1.0]]), R, C, width, height)


@pytest.fixture
def walk() -> list[ImageCamera]:
    """Four views through a 5 × 4 m room: a bend, a climb and a change of field of view."""
    return [_view("door", [3.7, 0.3, 1.6], [2.2, 2.7, 0.74], 65),
            _view("table", [2.2, 1.4, 1.5], [2.2, 2.7, 0.74], 55),
            _view("cabinet", [1.0, 1.5, 1.6], [0.2, 2.0, 1.0], 70),
            _view("corner", [4.6, 3.6, 2.3], [2.3, 1.8, 0.3], 74)]


def _positions(path) -> np.ndarray:
    return np.array([path.camera(k).C for k in range(path.n_frames)])


# -- the path ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("timing", [Timing(), Timing(fps=24, speed=0.6, hold=0.5), Timing(fps=25, seconds=1.3)])
def test_the_path_passes_through_every_view_at_its_keyframe(walk, timing):
    path = camera_path(walk, (W, H), timing)
    assert path.keyframes[0] == 0 and path.n_frames == path.keyframes[-1] + path.hold_frames + 1
    for view, k in zip(walk, path.keyframes, strict=True):
        for frame in range(k, k + path.hold_frames + 1):  # reached at k, held still for the hold
            cam = path.camera(frame)
            np.testing.assert_allclose(cam.C, view.C, atol=1e-9)
            np.testing.assert_allclose(cam.R, view.R, atol=1e-9)
            np.testing.assert_allclose(cam.K, view.K, atol=1e-7)
            assert (cam.width, cam.height) == (W, H)
    if timing.seconds is not None:
        assert set(path.segment_frames) == {round(timing.seconds * timing.fps)}


def test_views_are_resized_to_the_video_keeping_their_field_of_view(walk):
    views = [walk[0], _view("big", [2.2, 1.4, 1.5], [2.2, 2.7, 0.74], 55, 1280, 720)]
    path = camera_path(views, (320, 180))
    for view, k in zip(views, path.keyframes, strict=True):
        cam = path.camera(k)
        assert (cam.width, cam.height) == (320, 180)
        assert horizontal_fov(cam) == pytest.approx(horizontal_fov(view), abs=1e-12)
    assert camera_path(views).width == W  # default: the first view's size


def test_the_camera_walks_each_segment_at_constant_speed(walk):
    speed, fps = 0.8, 240  # many frames, so that a step's chord is its arc to 1e-4 even in the tight bend
    path = camera_path(walk, (W, H), Timing(fps=fps, speed=speed))
    P = _positions(path)
    for i, (k0, k1) in enumerate(zip(path.keyframes[:-1], path.keyframes[1:], strict=True)):
        steps = np.linalg.norm(np.diff(P[k0:k1 + 1], axis=0), axis=1)
        # Equal arc lengths: their chords are equal up to κ²Δs²/24 < 1e-4 (κ ≤ 11 /m, Δs = 3.3 mm).
        assert np.ptp(steps) / steps.mean() < 1e-4
        # The segment's speed is the one asked for, up to rounding its time to whole frames.
        seg_speed = path.segment_length[i] / (path.segment_frames[i] / fps)
        assert abs(seg_speed / speed - 1) <= 0.5 / path.segment_frames[i] + 1e-9
        assert steps.mean() * fps == pytest.approx(seg_speed, rel=1e-4)
    assert path.length == pytest.approx(path.segment_length.sum())


def test_arc_length_is_measured_exactly():
    # A circle's quarter through five points: the spline is close to the circle, and equal steps in
    # s are equal steps along the spline (dense chords add up to the arc length).
    a = np.linspace(0, np.pi / 2, 5)
    spline = ArcLengthSpline(np.c_[np.cos(a), np.sin(a), np.zeros(5)])
    assert spline.length == pytest.approx(np.pi / 2, rel=3e-3)
    s = np.linspace(0, spline.length, 20001)
    chords = np.linalg.norm(np.diff(spline(s), axis=0), axis=1)
    np.testing.assert_allclose(chords, s[1], rtol=1e-6)
    assert chords.sum() == pytest.approx(spline.length, rel=1e-8)
    # Two points: a straight line, walked linearly.
    line = ArcLengthSpline(np.array([[0.0, 0, 0], [3.0, 4.0, 0]]))
    np.testing.assert_allclose(line(np.array([0.0, 2.5, 5.0])), [[0, 0, 0], [1.5, 2.0, 0], [3, 4, 0]], atol=1e-12)


def test_the_path_is_smooth(walk):
    fps, speed = 30, 1.0
    path = camera_path(walk, (W, H), Timing(fps=fps, speed=speed))
    P = _positions(path)
    step = np.linalg.norm(np.diff(P, axis=0), axis=1)
    # No jumps: every step is a walking step (1 m/s → 3.3 cm), give or take the rounding of a
    # segment's time to whole frames (at most 0.5 / frames).
    assert step.max() <= (speed / fps) * (1 + 0.5 / path.segment_frames.min()) + 1e-9
    # Bounded second differences: |ΔΔP| ≤ κ (v / fps)² within a segment, κ the curvature (here up to
    # 11 /m in the U-turn at the cabinet, measured on the spline with 0.1 mm steps), plus the change
    # of step at a view.
    s = np.linspace(0, 1e-4 * 60000, 60001)
    kappa = max(np.linalg.norm(np.diff(spline(s[s <= spline.length]), 2, axis=0), axis=1).max() / 1e-8
                for _, _, spline in path._runs)
    dd = np.linalg.norm(np.diff(P, 2, axis=0), axis=1)
    assert 5 < kappa < 15
    assert dd.max() <= 1.01 * kappa * (speed / fps) ** 2 + (speed / fps) * 0.5 / path.segment_frames.min()
    # Orientation: angular steps vary smoothly (RotationSpline: continuous angular rate).
    rot = Rotation.from_matrix([path.camera(k).R.T for k in range(path.n_frames)])
    rate = (rot[:-1].inv() * rot[1:]).as_rotvec() * fps  # rad/s, in the camera's frame
    assert np.linalg.norm(rate, axis=1).max() < np.radians(90)
    assert np.linalg.norm(np.diff(rate, axis=0), axis=1).max() * fps < np.radians(120)  # rad/s², no kicks
    # Field of view: between the views' values (no overshoot) and without jumps.
    fov = np.degrees([horizontal_fov(path.camera(k)) for k in range(path.n_frames)])
    assert fov.min() >= 55 - 1e-9 and fov.max() <= 74 + 1e-9
    assert np.abs(np.diff(fov)).max() < 1.0


def test_two_views_on_a_line_are_walked_in_equal_steps():
    a, b = _view("a", [0, 0, 1.6], [1, 0, 1.6]), _view("b", [3, 0, 1.6], [4, 0, 1.6])
    path = camera_path([a, b], None, Timing(fps=10, speed=1.5))
    assert path.keyframes == [0, 20] and path.n_frames == 21
    np.testing.assert_allclose(_positions(path), np.c_[np.linspace(0, 3, 21), np.zeros(21), np.full(21, 1.6)],
                               atol=1e-9)


def test_turning_on_the_spot_takes_the_turn_rate():
    a = _view("a", [1, 1, 1.6], [2, 1, 1.6])
    b = _view("b", [1, 1, 1.6], [1, 2, 1.6])  # 90° to the left, same place
    c = _view("c", [3, 1, 1.6], [4, 1, 1.6])
    path = camera_path([a, b, c], None, Timing(fps=10, speed=1.0, turn_rate_deg=45))
    assert list(path.segment_frames) == [20, 20]  # 90° at 45°/s; 2 m at 1 m/s (turning back: 90°)
    P = _positions(path)
    np.testing.assert_allclose(P[:21], np.tile([1, 1, 1.6], (21, 1)), atol=1e-12)
    np.testing.assert_allclose(P[-1], c.C, atol=1e-9)


def test_holds_keep_the_camera_still(walk):
    path = camera_path(walk[:2], None, Timing(fps=10, speed=1.0, hold=1.0))
    assert path.hold_frames == 10 and path.keyframes == [0, 10 + path.segment_frames[0]]
    P = _positions(path)
    assert np.ptp(P[:11], axis=0).max() == 0 and np.ptp(P[-11:], axis=0).max() == 0
    assert np.linalg.norm(P[11] - P[10]) > 0


@pytest.mark.parametrize(("options", "match"), [
    (dict(fps=0), r"--fps: expected frames per second between 1 and 240, got 0"),
    (dict(fps=float("nan")), r"--fps: expected frames per second"),
    (dict(speed=0.0), r"--speed: expected a walking speed in metres per second, greater than 0, got 0.0"),
    (dict(speed=-1.0), r"--speed: expected a walking speed"),
    (dict(seconds=float("inf")), r"--seconds: expected the seconds each segment takes"),
    (dict(speed=1.0, seconds=2.0), r"either --speed .* or --seconds"),
    (dict(hold=-0.5), r"--hold: expected seconds to stay at each view, 0 or more"),
    (dict(turn_rate_deg=0), r"--turn-rate: expected degrees per second"),
])
def test_bad_timing_is_refused(walk, options, match):
    """A Timing checks itself when it is made: a bad one never reaches the path."""
    with pytest.raises(VebuildError, match=match):
        camera_path(walk, (W, H), Timing(**options))


@pytest.mark.parametrize(("size", "match"), [
    ((161, 120), r"--size: H.264 \(yuv420p\) needs an even width and height, got 161×120; use --size 160x120"),
    ((0, 120), r"--size: expected a width and height between 2 and 8192 pixels, got 0×120"),
    ((16384, 120), r"between 2 and 8192 pixels"),
])
def test_impossible_sizes_are_refused(walk, size, match):
    with pytest.raises(VebuildError, match=match):
        camera_path(walk, size)


def test_fewer_than_two_views_are_refused(walk):
    with pytest.raises(VebuildError, match=r"--views: expected at least two views to walk between, got 1"):
        camera_path(walk[:1])
    with pytest.raises(VebuildError, match=r"got none"):
        camera_path([])
    with pytest.raises(VebuildError, match=r"--views: expected view names separated by commas"):
        parse_views("door,,table")


def test_output_paths_are_checked_before_any_work(tmp_path):
    with pytest.raises(VebuildError, match=r"--out: the folder .*missing does not exist"):
        check_output(tmp_path / "missing" / "v.mp4")
    with pytest.raises(VebuildError, match=r"--out: expected a file name ending in .mp4"):
        check_output(tmp_path / "v.avi")
    (tmp_path / "d.mp4").mkdir()
    with pytest.raises(VebuildError, match=r"--out: is a folder"):
        check_output(tmp_path / "d.mp4")
    (tmp_path / "file").write_text("")
    with pytest.raises(VebuildError, match=r"does not exist"):  # a file where the folder should be
        check_output(tmp_path / "file" / "v.mp4")


def test_the_writer_refuses_a_bad_quality_and_writes_nothing_on_error(tmp_path):
    with pytest.raises(VebuildError, match=r"--crf: expected an integer from 0 \(best\) to 51"):
        Mp4Writer(tmp_path / "v.mp4", W, H, 30, crf=60)
    out = tmp_path / "v.mp4"
    with pytest.raises(RuntimeError), Mp4Writer(out, W, H, 30) as writer:
        writer.write(np.zeros((H, W, 3), np.uint8))
        raise RuntimeError("stop")
    assert list(tmp_path.iterdir()) == []


# -- rendered for real ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def room(tmp_path_factory) -> Path:
    """The example room calibrated, solved and textured (coarsely: 50 texels/m, a few seconds),
    with four small views and a lighting preset of its own."""
    folder = tmp_path_factory.mktemp("video") / "room"
    shutil.copytree(ROOM, folder)
    proj = folder / "room.vebuild.json"
    assert main(["calibrate", str(proj), "--quiet"]) == 0
    assert main(["solve", str(proj), "--recalibrate"]) == 0
    assert main(["texture", str(proj), "--quiet", "--density", "50"]) == 0
    data = json.loads(proj.read_text())
    size = {"width": W, "height": H}
    data["views"] = [
        {"name": "door", "position": [3.7, 0.3, 1.6], "look_at": [2.2, 2.7, 0.74], "fov_deg": 65, **size},
        {"name": "table", "position": [2.2, 1.4, 1.5], "look_at": [2.2, 2.7, 0.74], "fov_deg": 55, **size},
        {"name": "cabinet", "position": [1.0, 1.5, 1.6], "look_at": [0.2, 2.0, 1.0], "fov_deg": 70, **size},
        {"name": "odd", "position": [4.6, 3.6, 2.3], "look_at": [2.3, 1.8, 0.3], "width": 161, "height": 121},
    ]
    data.setdefault("lighting", {})["presets"] = [{"name": "lamp", "ambient": [0.1, 0.1, 0.1], "lights": [
        {"type": "point", "position": [2.5, 2.0, 2.5], "intensity": 4.0}]}]
    proj.write_text(json.dumps(data, indent=1))
    return proj


@pytest.fixture(scope="module")
def renderer(room):
    r = Renderer(headless_context(), load_scene(load_project(room)))
    yield r
    r.release()


def _decode(path: Path) -> tuple[list[np.ndarray], dict]:
    with av.open(str(path)) as c:
        s = c.streams.video[0]
        frames = [f.to_ndarray(format="rgb24") for f in c.decode(s)]
        info = {"codec": s.codec_context.name, "pix_fmt": s.codec_context.pix_fmt, "rate": s.average_rate,
                "frames": s.frames, "size": (s.codec_context.width, s.codec_context.height),
                "comment": c.metadata.get("comment", "")}
    return frames, info


def test_the_video_decodes_and_shows_each_view_at_its_keyframe(room, renderer, tmp_path):
    project = load_project(room)
    names = ["door", "table", "cabinet"]
    timing = Timing(fps=10, speed=2.0)
    done = []
    out = tmp_path / "walk.mp4"
    # Unmarked: the hatch's fine magenta stripes are what H.264's 4:2:0 chroma keeps worst at 160×120.
    r = render_video(project, VideoRequest(names, out, None, timing, unobserved="off"), lambda *a: done.append(a),
                     renderer)
    renderer.unobserved = "off"
    path = camera_path([find_view(project, n) for n in names], None, timing)
    frames, info = _decode(out)
    assert r.out == out and r.frames == path.n_frames == len(frames) == info["frames"]
    assert info["codec"] == "h264" and info["pix_fmt"] == "yuv420p" and info["rate"] == 10
    assert info["size"] == (W, H) == (r.width, r.height) and frames[0].shape == (H, W, 3)
    assert json.loads(info["comment"])["keyframes"] == path.keyframes
    assert [n for n, _ in r.keyframes] == names and [k for _, k in r.keyframes] == path.keyframes
    assert done[-1][:2] == (r.frames, r.frames) and len(done) == r.frames
    assert [p.name for p in tmp_path.iterdir()] == ["walk.mp4"]  # no temporary file left
    for view, k in zip(path.views, path.keyframes, strict=True):
        truth = renderer.render(view).astype(int)
        mad = [np.abs(frames[j].astype(int) - truth).mean() for j in (k - 1, k, k + 1) if 0 <= j < len(frames)]
        here = np.abs(frames[k].astype(int) - truth).mean()
        assert here < KEYFRAME_MAD_LEVELS, (view.id, here)
        assert min(mad) == here and sorted(mad)[1] > 2 * KEYFRAME_MAD_LEVELS  # this frame, not its neighbour
    renderer.unobserved = "hatch"


def test_stereo_and_lighting(room, renderer, tmp_path):
    project = load_project(room)
    out = tmp_path / "sbs.mp4"
    # Unmarked: the left eye stands just inside a wall whose back (hatched: no photo saw it) it sees.
    r = render_video(project, VideoRequest(["door", "table"], out, (96, 64), Timing(fps=5, speed=2.0),
                                           lighting="lamp", stereo="sbs", unobserved="off"), None, renderer)
    frames, info = _decode(out)
    assert info["size"] == (192, 64) and r.lighting == "lamp" and len(frames) == r.frames
    left, right = frames[0][:, :96].astype(int), frames[0][:, 96:].astype(int)
    assert 0 < np.abs(left - right).mean() < 40  # two eyes 6.3 cm apart: alike, not equal


def test_nothing_is_left_behind_when_interrupted(room, renderer, tmp_path):
    project = load_project(room)
    out = tmp_path / "walk.mp4"
    render_video(project, VideoRequest(["door", "table"], out, (32, 32), Timing(fps=2)), None, renderer)
    older = out.read_bytes()  # an older video vebuild wrote (it replaces no other file)

    def stop(done, total, label):
        if done == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        render_video(project, VideoRequest(["door", "table"], out, None, Timing(fps=10)), stop, renderer)
    assert [p.name for p in tmp_path.iterdir()] == ["walk.mp4"] and out.read_bytes() == older
    # The default output's folder, videos/ beside the project, is not left behind either.
    assert not (room.parent / "videos").exists()
    with pytest.raises(KeyboardInterrupt):
        render_video(project, VideoRequest(["door", "table"], None, None, Timing(fps=10)), stop, renderer)
    assert not (room.parent / "videos").exists()


@pytest.mark.parametrize(("request_kw", "error", "match"), [
    ({"views": ["door", "nowhere"]}, ProjectError, r"\$\.views: no view is called 'nowhere'; the views are: 'door'"),
    ({"views": ["door"]}, VebuildError, r"expected at least two views"),
    ({"views": ["odd", "door"]}, ProjectError, r"\$\.views\[3\] \(width × height of view 'odd', which sets the "
     r"video's size; no --size given\): H.264 \(yuv420p\) needs an even width and height, got 161×121; use "
     r"--size 160x120"),
    ({"views": ["door", "table"], "lighting": "sunset"}, ProjectError, r"no lighting preset is called 'sunset'"),
    ({"views": ["door", "table"], "stereo": "quad"}, VebuildError, r"--stereo: expected one of sbs, tb, anaglyph"),
    ({"views": ["door", "table"], "timing": lambda: Timing(fps=-3)}, VebuildError, r"--fps: expected"),
])
def test_bad_requests_are_refused_before_rendering(room, renderer, tmp_path, request_kw, error, match):
    project = load_project(room)
    with pytest.raises(error, match=match):  # a bad Timing is refused as it is made (a callable here)
        kw = {k: v() if callable(v) else v for k, v in request_kw.items()}
        render_video(project, VideoRequest(out=tmp_path / "v.mp4", **kw), None, renderer)
    assert list(tmp_path.iterdir()) == []


def test_vebuild_video_end_to_end(room, capsys):
    assert main(["video", str(room), "--views", "door, table", "--size", "96x72", "--fps", "8", "--speed", "3",
                 "--hold", "0.25", "--quiet"]) == 0
    out = room.parent / "videos" / "door-table.mp4"
    text = capsys.readouterr().out
    assert f"wrote {out}" in text and "96×72, 8 fps" in text and "views at frames: door 0, table" in text
    frames, info = _decode(out)
    assert info["size"] == (96, 72) and info["rate"] == 8 and len(frames) == info["frames"]


@pytest.mark.parametrize(("args", "message"), [
    (["--views", "door,nowhere"], "no view is called 'nowhere'"),
    (["--views", "door,table", "--size", "big"], "--size: expected WIDTHxHEIGHT"),
    (["--views", "door,table", "--speed", "0"], "--speed: expected a walking speed"),
    (["--views", "door,table", "--out", "/nonexistent/v.mp4"], "the folder /nonexistent does not exist"),
])
def test_vebuild_video_errors_are_one_clear_line(room, capsys, args, message):
    assert main(["video", str(room), "--quiet", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.startswith("vebuild video: error:") and "Traceback" not in err
