"""Photos from the command line's words: image files as they are, video files as stills (layer 3).

A video file becomes a photo through a still: the frame decoded exactly (:mod:`.video`), written as a
lossless PNG beside the project (``CLIP.f000123.png``; ``CLIP.f000123-top.png`` for one field), hashed
like any photo, its record carrying the ``origin`` (the video, its SHA-256, the frame's index and
time, the decoder, the stream, interlacing, the field kept). Frames are named on the command line as

- ``clip.mp4@frame=120`` or ``clip.mp4@time=12.48`` (several words, several stills), or
- ``clip.mp4`` with ``--frame N`` / ``--time T`` (each repeatable): every such frame of every video
  named without ``@``.

Everything is decoded and checked before anything is written (:func:`prepare_photos`); then the PNGs
are written (:func:`write_stills`), each atomically, never over a different existing file. Stills of
one video stream were taken by one fixed camera: :func:`fixed_camera_groups` names them as a camera
group (one camera's intrinsics), and the calibration gives them one pose (vebuild/actions/fixed_camera.py).
"""

from __future__ import annotations

import io
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vebuild import __version__
from vebuild.errors import ProjectError

from .atomic import write_bytes
from .file import Project, new_photo_entry
from .images import sha256_bytes, sha256_file
from .video import FIELDS, decode_still, frame_times, is_video

_AT = re.compile(r"^(?P<file>.+)@(?P<key>frame|time)=(?P<value>[^@=]*)$")
_ID_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]+")


@dataclass(frozen=True)
class Prepared:
    """A photo ready to go into the project: its record, and for a still the PNG to write (``png``
    None: the file is there already, with these pixels)."""

    entry: dict[str, Any]
    path: Path
    png: bytes | None = None


def split_word(word: str) -> tuple[str, str | None, str | None]:
    """``clip.mp4@frame=12`` → (``clip.mp4``, "frame", "12"); a plain file → (word, None, None)."""
    m = _AT.match(word)
    if m and not os.path.exists(word):
        return m["file"], m["key"], m["value"]
    return word, None, None


def _number(file: str, key: str, value: str) -> int | float:
    try:
        return int(value) if key == "frame" else float(value)
    except ValueError:
        want = "a whole frame number from 0" if key == "frame" else "a time in seconds, such as 12.48"
        raise ProjectError(file, "", f"--{key} {value}: expected {want}, found {value!r}") from None


def _requests(words: Sequence[str], frames: Sequence[int], times: Sequence[float]) -> list[tuple[str, str, Any]]:
    """(file, "image" | "frame" | "time", value) for each photo the words ask for."""
    out: list[tuple[str, str, Any]] = []
    plain_videos = []
    for word in words:
        file, key, value = split_word(word)
        if key is not None and value is not None:
            if not is_video(file):
                raise ProjectError(file, "", f"{word}: a frame or time is given only for a video file (MP4, MOV, AVI, "
                                   "MKV, ...); found another kind of file")
            out.append((file, key, _number(file, key, value)))
        elif is_video(file):
            plain_videos.append(file)
            if not frames and not times:
                raise ProjectError(file, "", "a video file needs the frame to take: --frame N (from 0) or --time "
                                   "SECONDS, or name it as FILE@frame=N or FILE@time=SECONDS")
            out.extend((file, "frame", n) for n in frames)
            out.extend((file, "time", t) for t in times)
        else:
            out.append((file, "image", None))
    if (frames or times) and not plain_videos:
        raise ProjectError(words[0] if words else "", "", "--frame and --time choose frames of a video file named "
                           "without @, but no such video file was given")
    return out


def still_name(video: str | os.PathLike[str], frame: int, field: str) -> str:
    """The still's file name: ``CLIP.f000123.png``, ``CLIP.f000123-top.png`` for one field."""
    tail = "" if field == "both" else f"-{field}"
    return f"{Path(video).stem}.f{frame:06d}{tail}.png"


def encode_png(rgb: Any, origin: dict[str, Any]) -> bytes:
    """A lossless PNG of the RGB8 pixels, saying what made it and from which frame."""
    from PIL import Image
    from PIL.PngImagePlugin import PngInfo

    info = PngInfo()
    info.add_text("Software", f"vebuild {__version__}")
    info.add_text("Source", f"{origin['video']} (SHA-256 {origin['sha256']}), frame {origin['frame']} at "
                  f"{origin['time']:g} s, field {origin['field']}")
    buf = io.BytesIO()
    Image.fromarray(np.asarray(rgb, dtype=np.uint8), "RGB").save(buf, "PNG", pnginfo=info, compress_level=6)
    return buf.getvalue()


def _same_pixels(path: Path, rgb: Any) -> bool:
    from PIL import Image

    try:
        with Image.open(path) as im:
            if im.format != "PNG" or im.size != (rgb.shape[1], rgb.shape[0]):
                return False
            return bool(np.array_equal(np.asarray(im.convert("RGB")), rgb))
    except (OSError, ValueError, SyntaxError):
        return False


def prepare_photos(folder: str | os.PathLike[str], words: Sequence[str], frames: Sequence[int] = (),
                   times: Sequence[float] = (), field: str | None = None,
                   taken: Iterable[str] = ()) -> list[Prepared]:
    """The photos the words ask for, decoded and checked; nothing written. ``taken``: photo ids
    already in the project (a still already there is refused as a photo already there)."""
    if field is not None and field not in FIELDS:
        raise ProjectError(folder, "", f"expected --field top or bottom, found {field!r}")
    folder = Path(os.path.abspath(folder))
    out: list[Prepared] = []
    ids = set(taken)
    hashes: dict[str, tuple[Any, str]] = {}
    for file, kind, value in _requests(words, frames, times):
        if kind == "image":
            entry = new_photo_entry(folder, file)
            out.append(Prepared(entry, Path(os.path.abspath(file))))
        else:
            video = Path(os.path.abspath(file))
            if not video.is_relative_to(folder):
                raise ProjectError(video, "", f"the video lies outside the project folder {folder}; copy it into "
                                   "that folder (or a folder inside it) so that the project, its stills and the "
                                   "video they came from move together")
            if str(video) not in hashes:
                known = frame_times(video, f"--{kind} {value:g}")
                hashes[str(video)] = (known, sha256_file(video))
            known, digest = hashes[str(video)]
            still = decode_still(video, folder, times=known, sha256=digest, field=field,
                                 **{kind: value})
            name = still_name(video, still.origin["frame"], still.origin["field"])
            target = video.with_name(name)
            png = encode_png(still.rgb, still.origin)
            if target.exists():
                if not _same_pixels(target, still.rgb):
                    raise ProjectError(target, "", f"a different file is already called {name}; vebuild will not "
                                       f"overwrite it with frame {still.origin['frame']} of {video.name}: move or "
                                       "rename it")
                data, keep = target.read_bytes(), None
            else:
                data, keep = png, png
            h, w = still.rgb.shape[:2]
            entry = {"id": _ID_UNSAFE.sub("_", Path(name).stem), "file": target.relative_to(folder).as_posix(),
                     "width": int(w), "height": int(h), "sha256": sha256_bytes(data), "origin": still.origin,
                     "vanishing_segments": {}, "marker_observations": {}}
            out.append(Prepared(entry, target, keep))
        if out[-1].entry["id"] in ids:
            raise ProjectError(out[-1].path, "", f"the project already has a photo {out[-1].entry['id']!r}; "
                               "expected each photo (and each frame of a video) once")
        ids.add(out[-1].entry["id"])
    return out


def write_stills(prepared: Sequence[Prepared]) -> None:
    """Write the stills' PNGs (each atomically; none is over a different file: checked before)."""
    for p in prepared:
        if p.png is not None:
            try:
                write_bytes(p.path, p.png)
            except OSError as e:
                raise ProjectError(p.path, "", f"cannot write the still {p.path.name}: {e.strerror or e}") from None


def fixed_camera_key(photo: dict[str, Any]) -> tuple[str, int] | None:
    """What makes stills one fixed camera: the video's hash and the stream; None for a photo."""
    origin = photo.get("origin")
    return None if not origin else (str(origin["sha256"]), int(origin["stream"]))


def fixed_camera_groups(data: dict[str, Any]) -> None:
    """Put the stills of each video stream with two or more in the project into one camera group
    (``camera_groups``, id ``video CLIP``), unless the user grouped or released one of them."""
    groups = data.setdefault("camera_groups", [])
    grouped = {pid for g in groups for pid in g["photos"]}
    by_key: dict[tuple[str, int], list[dict[str, Any]]] = {}
    for p in data["photos"]:
        if (key := fixed_camera_key(p)) is not None:
            by_key.setdefault(key, []).append(p)
    used = {g["id"] for g in groups}
    for (_, stream), photos in by_key.items():
        if len(photos) < 2 or any(p.get("own_camera") for p in photos):
            continue
        name = f"video {photos[0]['origin']['video']}" + (f" stream {stream}" if stream else "")
        mine = next((g for g in groups if g["id"] == name), None)
        new = [p["id"] for p in photos if p["id"] not in grouped]
        if mine is None:
            if len(new) < len(photos):
                continue  # the user put some of them in groups of their own: theirs stand
            if name in used:
                continue
            groups.append({"id": name, "photos": new})
        else:
            mine["photos"].extend(new)
    if not groups:
        del data["camera_groups"]


def check_videos(project: Project) -> tuple[list[str], bool]:
    """``vebuild check``'s lines on the videos the stills came from, and whether one has changed:
    each present video's SHA-256 is verified; a missing one is said (the still, whose own hash is
    verified with the photos, remains the evidence)."""
    lines: list[str] = []
    changed = False
    seen: dict[str, str] = {}
    for i, photo in enumerate(project.data["photos"]):
        origin = photo.get("origin")
        if not origin or origin["video"] in seen:
            continue
        video = project.folder.joinpath(*Path(origin["video"]).parts)
        if not video.is_file():
            seen[origin["video"]] = "missing"
            lines.append(f"video {origin['video']!r} (of the still {photo['file']!r} and any other of it): not found "
                         f"beside the project, so its SHA-256 {origin['sha256'][:12]}… cannot be verified; the "
                         "still's own hash is, and the still is the evidence the marks were made on")
            continue
        found = sha256_file(video)
        seen[origin["video"]] = found
        if found != origin["sha256"]:
            changed = True
            lines.append(f"changed: the video {origin['video']!r} is not the one the still {photo['file']!r} was "
                         f"taken from ($.photos[{i}].origin.sha256): expected SHA-256 {origin['sha256'][:12]}…, "
                         f"found {found[:12]}…; the still is unchanged, but it can no longer be traced to this file")
        else:
            lines.append(f"video {origin['video']!r}: SHA-256 verified (the source of its stills)")
    return lines, changed


def origin_summary(photo: dict[str, Any]) -> dict[str, Any] | None:
    """What the report and the HTML viewer say of a still's source (None for a photo): the video
    file, its SHA-256, the frame's index and time, the field used and whether it is interlaced."""
    origin = photo.get("origin")
    if not origin:
        return None
    return {"video": origin["video"], "sha256": origin["sha256"], "frame": origin["frame"], "time": origin["time"],
            "field": origin["field"], "interlaced": origin["interlaced"], "decoder": origin["decoder"],
            "words": f"frame {origin['frame']} at {origin['time']:g} s of {origin['video']} (SHA-256 "
                     f"{origin['sha256']}), {_field_words(origin)}"}


def _field_words(origin: dict[str, Any]) -> str:
    interlaced = "interlaced" if origin["interlaced"] else "progressive"
    if origin["field"] == "both":
        return f"whole frame ({interlaced})"
    return f"{origin['field']} field only ({interlaced}; the other field's rows interpolated)"
