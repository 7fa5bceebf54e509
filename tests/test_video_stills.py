"""Stills from video files: exact frames, their provenance, interlacing, the still's PNG, and
`vebuild new` / `vebuild add` refusing bad input with nothing written (vebuild/project/video.py,
vebuild/project/stills.py, vebuild/actions/photos_command.py)."""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from video_clips import random_frames, smooth_scene, woven, write_clip

from vebuild.cli import main
from vebuild.errors import ProjectError
from vebuild.project import load_project, sha256_file
from vebuild.project.video import COMB_THRESHOLD, comb_ratio, decode_still, frame_times, keep_field


@pytest.fixture(scope="module")
def clip(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[np.ndarray]]:
    frames = random_frames(30)
    return write_clip(tmp_path_factory.mktemp("clip") / "clip.mp4", frames), frames


def test_a_lossless_clip_decodes_bit_exact_at_every_frame_asked_by_index(clip) -> None:
    path, frames = clip
    for n in (0, 1, 13, 29):  # 0 and 29: the first and the last; 13: far from the keyframe
        still = decode_still(path, path.parent, frame=n)
        assert np.array_equal(still.rgb, frames[n]), n
        o = still.origin
        assert (o["frame"], o["frames"], o["video"], o["stream"]) == (n, 30, "clip.mp4", 0)
        assert o["sha256"] == sha256_file(path) and o["decoder"].startswith("h264")
        assert Fraction(o["pts"]) * Fraction(o["time_base"]) == pytest.approx(n / 25, abs=1e-9)
        assert not o["interlaced"] and o["field"] == "both"


def test_a_time_picks_the_frame_shown_at_that_time(clip) -> None:
    path, frames = clip
    # At 25 frames a second frame n is shown over [n/25, (n+1)/25).
    for t, n in ((0.0, 0), (0.039, 0), (0.04, 1), (0.5, 12), (0.519, 12), (1.199, 29)):
        still = decode_still(path, path.parent, time=t)
        assert still.origin["frame"] == n, t
        assert np.array_equal(still.rgb, frames[n])


@pytest.mark.parametrize("container", ["avi", "mkv", "mov"])
def test_other_containers_give_the_same_frame_by_index_and_time(tmp_path: Path, container: str) -> None:
    frames = random_frames(20, seed=3)
    path = write_clip(tmp_path / f"c.{container}", frames)
    times = frame_times(path)
    assert len(times.pts) == 20
    a = decode_still(path, tmp_path, frame=11)
    # The time is the file's own (pts × time_base): AVI starts this one at 1/25 s, the others at 0.
    b = decode_still(path, tmp_path, time=times.time(11) + 0.001)
    assert a.origin["frame"] == b.origin["frame"] == 11
    assert np.array_equal(a.rgb, frames[11]) and np.array_equal(b.rgb, frames[11])


def test_a_lossy_clip_decodes_the_frame_asked_not_its_neighbour(tmp_path: Path) -> None:
    """H.264 (yuv420p, crf 23) with B-frames: the frame decoded is nearer the frame encoded at
    that index than any other frame (random frames differ by ~100 grey levels RMS)."""
    frames = random_frames(24, seed=5)
    path = write_clip(tmp_path / "lossy.mp4", frames, codec="libx264", options={"crf": "23", "bf": "2"})
    got = decode_still(path, tmp_path, frame=17).rgb.astype(float)
    errors = [np.sqrt(np.mean((got - f) ** 2)) for f in frames]
    assert int(np.argmin(errors)) == 17


def test_woven_fields_of_a_moving_scene_are_found_combed_and_a_still_scene_is_not() -> None:
    w, h = 96, 64
    progressive = comb_ratio(smooth_scene(w, h, 0.0))
    combed = comb_ratio(woven(w, h, 8.0))
    assert progressive < 1.0 < COMB_THRESHOLD < combed


def test_an_interlaced_clip_is_flagged_by_its_decoder_and_its_content(tmp_path: Path) -> None:
    frames = [woven(96, 64, 8.0 + i) for i in range(6)]
    path = write_clip(tmp_path / "tv.mp4", frames, codec="libx264",
                      options={"qp": "0", "x264-params": "interlaced=1:tff=1"})
    still = decode_still(path, tmp_path, frame=2)
    i = still.origin["interlace"]
    assert i["decoder_flag"] and i["field_order"] == "top first" and i["combed"] and still.origin["interlaced"]
    # An unflagged progressive file of the same woven content: the content check alone finds it.
    plain = write_clip(tmp_path / "plain.mp4", frames)
    still = decode_still(plain, tmp_path, frame=2)
    assert not still.origin["interlace"]["decoder_flag"] and still.origin["interlaced"]


def test_keeping_a_field_keeps_its_rows_exactly_and_fills_the_others_between_them() -> None:
    frame = woven(96, 64, 8.0)
    top, bottom = keep_field(frame, "top"), keep_field(frame, "bottom")
    assert np.array_equal(top[0::2], frame[0::2]) and np.array_equal(bottom[1::2], frame[1::2])
    mean = (frame[0:-2:2].astype(int) + frame[2::2].astype(int) + 1) // 2
    assert np.array_equal(top[1:-1:2], mean)
    assert comb_ratio(top) < 1.0 and comb_ratio(bottom) < 1.0


@pytest.mark.parametrize(("kw", "said"), [
    ({"frame": 30}, "expected a frame number from 0 to 29"),
    ({"frame": -1}, "expected a frame number from 0 to 29"),
    ({"time": -0.5}, "expected a time of 0 seconds or more"),
    ({"time": 1.2}, "expected a time from 0 s to before 1.2 s"),
])
def test_a_frame_outside_the_clip_is_refused_naming_the_file_and_argument(clip, kw, said) -> None:
    path, _ = clip
    with pytest.raises(ProjectError, match=said) as e:
        decode_still(path, path.parent, **kw)
    assert e.value.file == str(path) and f"--{next(iter(kw))}" in str(e.value)


def _run(*words: str) -> int:
    return main([str(w) for w in words])


def test_new_writes_lossless_stills_with_their_origin_and_one_camera_group(tmp_path: Path, capsys) -> None:
    frames = random_frames(30, seed=7)
    write_clip(tmp_path / "cctv.mp4", frames)
    project = tmp_path / "case.vebuild.json"
    assert _run("new", project, tmp_path / "cctv.mp4@frame=4", tmp_path / "cctv.mp4@time=0.9") == 0
    p = load_project(project)  # verifies the stills' hashes and sizes
    a, b = p.data["photos"]
    assert (a["file"], b["file"]) == ("cctv.f000004.png", "cctv.f000022.png")
    assert np.array_equal(np.asarray(Image.open(tmp_path / a["file"])), frames[4])
    assert a["origin"]["sha256"] == sha256_file(tmp_path / "cctv.mp4") and b["origin"]["time"] == pytest.approx(0.88)
    assert p.data["camera_groups"] == [{"id": "video cctv.mp4", "photos": [a["id"], b["id"]]}]
    # A third frame added later joins the group; the report of check verifies the video.
    assert _run("add", project, tmp_path / "cctv.mp4", "--frame", "10", "--field", "top") == 0
    p = load_project(project)
    assert p.data["photos"][2]["origin"]["field"] == "top"
    top = np.asarray(Image.open(tmp_path / "cctv.f000010-top.png"))
    assert np.array_equal(top[0::2], frames[10][0::2])  # the top field's rows, exactly
    assert p.data["camera_groups"][0]["photos"][-1] == p.data["photos"][2]["id"]
    capsys.readouterr()
    assert _run("check", project) == 0
    assert "video 'cctv.mp4': SHA-256 verified" in capsys.readouterr().out


def test_check_says_when_the_video_is_missing_and_fails_when_it_changed(tmp_path: Path, capsys) -> None:
    write_clip(tmp_path / "v.mp4", random_frames(5))
    project = tmp_path / "p.vebuild.json"
    assert _run("new", project, tmp_path / "v.mp4@frame=2") == 0
    (tmp_path / "v.mp4").rename(tmp_path / "elsewhere.mp4")
    capsys.readouterr()
    assert _run("check", project) == 0
    assert "'v.mp4'" in (out := capsys.readouterr().out) and "not found" in out
    write_clip(tmp_path / "v.mp4", random_frames(5, seed=1))
    assert _run("check", project) == 1
    assert "changed: the video 'v.mp4'" in capsys.readouterr().out


@pytest.mark.parametrize(("word", "said"), [
    ("v.mp4@frame=99", "--frame 99: expected a frame number from 0 to 4"),
    ("v.mp4@time=-1", "--time -1: expected a time of 0 seconds or more"),
    ("v.mp4@frame=two", "expected a whole frame number"),
    ("v.mp4", "a video file needs the frame to take"),
    ("text.mp4@frame=0", "cannot read text.mp4 as a video"),
    ("sound.mp4@frame=0", "has no video stream"),
    ("gone.mp4@frame=0", "video file not found"),
])
def test_bad_video_words_exit_2_naming_the_file_and_write_nothing(tmp_path: Path, capsys, word, said) -> None:
    import av

    write_clip(tmp_path / "v.mp4", random_frames(5))
    (tmp_path / "text.mp4").write_text("not a video\n")
    with av.open(str(tmp_path / "sound.mp4"), "w") as c:
        s = c.add_stream("aac", rate=8000)
        frame = av.AudioFrame.from_ndarray(np.zeros((1, 1024), np.float32), format="fltp", layout="mono")
        frame.sample_rate = 8000
        for p in [*s.encode(frame), *s.encode()]:
            c.mux(p)
    before = sorted(tmp_path.iterdir())
    good = tmp_path / "v.mp4@frame=1"  # a good still before the bad word: it is not written either
    assert _run("new", tmp_path / "p.vebuild.json", good, tmp_path / word) == 2
    err = capsys.readouterr().err
    assert said in err and word.split("@")[0] in err
    assert sorted(tmp_path.iterdir()) == before


def test_a_still_is_never_written_over_a_different_file(tmp_path: Path, capsys) -> None:
    frames = random_frames(5)
    write_clip(tmp_path / "v.mp4", frames)
    other = tmp_path / "v.f000001.png"
    Image.fromarray(frames[0]).save(other)
    before = other.read_bytes()
    assert _run("new", tmp_path / "p.vebuild.json", tmp_path / "v.mp4@frame=1") == 2
    assert "will not overwrite" in capsys.readouterr().err and other.read_bytes() == before
    assert not (tmp_path / "p.vebuild.json").exists()
    Image.fromarray(frames[1]).save(other)  # the same pixels: taken as the still, not rewritten
    assert _run("new", tmp_path / "p.vebuild.json", tmp_path / "v.mp4@frame=1") == 0
    assert json.loads((tmp_path / "p.vebuild.json").read_text())["photos"][0]["sha256"] == sha256_file(other)


def test_a_frame_past_damaged_data_is_refused_as_damaged(tmp_path: Path) -> None:
    """A packet's bytes garbled in the file: decoding through it is refused, naming the frame."""
    path = write_clip(tmp_path / "cctv.mkv", [smooth_scene(128, 96, i) for i in range(20)], codec="libx264",
                      options={"crf": "20", "g": "100"})
    import av

    with av.open(str(path)) as c:
        packets = [(p.pos, p.size) for p in c.demux(c.streams.video[0]) if p.size]
    data = bytearray(path.read_bytes())
    pos, size = packets[8]
    for i in range(pos + size // 3, pos + size - 4):
        data[i] = (data[i] * 7 + 13) % 256
    path.write_bytes(bytes(data))
    with pytest.raises(ProjectError, match=r"cannot decode frame 15 of cctv.mkv \(--frame 15\): the file is damaged"):
        decode_still(path, tmp_path, frame=15)
