"""A photo decoded whole once is known whole by its SHA-256: a later load reads its size from the
record instead of decoding it again, unless the record is another decoder's or unreadable; a
cache that cannot be written changes nothing but the time."""

from __future__ import annotations

import json
import shutil

import pytest

import vebuild.project.images as images
from vebuild.errors import ProjectError
from vebuild.project import load_project
from vebuild.resources import example_project_dir


@pytest.fixture
def room(tmp_path, monkeypatch):
    monkeypatch.setenv("VEBUILD_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "room"
    shutil.copytree(example_project_dir(), folder)
    return folder / "room.vebuild.json"


@pytest.fixture
def decodes(monkeypatch):
    """The photos decoded whole, in order."""
    seen: list[str] = []
    real = images.image_size

    def counted(image, file, where):
        seen.append(image.name)
        return real(image, file, where)

    monkeypatch.setattr(images, "image_size", counted)
    return seen


def _records(room):
    return sorted((room.parent.parent / "cache" / images.DECODED_FOLDER).glob("*.json"))


def test_a_photo_is_decoded_once_then_known_by_its_hash(room, decodes):
    project = load_project(room)
    n = len(project.data["photos"])
    assert len(decodes) == n
    records = _records(room)
    assert sorted(r.stem for r in records) == sorted(p["sha256"] for p in project.data["photos"])
    load_project(room)
    assert len(decodes) == n  # not decoded again


@pytest.mark.parametrize("spoil", ["another decoder", "not JSON", "a size of zero", "a list", "no width"])
def test_a_record_of_another_decoder_or_unreadable_is_decoded_again(room, decodes, spoil):
    load_project(room)
    first = _records(room)[0]
    got = json.loads(first.read_text())
    text = {"another decoder": json.dumps({**got, "decoder": "Pillow 0.1"}), "not JSON": "{width",
            "a size of zero": json.dumps({**got, "width": 0}), "a list": "[1, 2]",
            "no width": json.dumps({k: v for k, v in got.items() if k != "width"})}[spoil]
    first.write_text(text)
    decodes.clear()
    load_project(room)
    assert len(decodes) == 1
    assert json.loads(first.read_text()) == got  # recorded again


def test_a_cache_that_cannot_be_written_only_costs_time(tmp_path, monkeypatch, decodes):
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the cache folder would be")
    monkeypatch.setenv("VEBUILD_CACHE", str(blocker))
    folder = tmp_path / "room"
    shutil.copytree(example_project_dir(), folder)
    project = load_project(folder / "room.vebuild.json")
    load_project(folder / "room.vebuild.json")
    assert len(decodes) == 2 * len(project.data["photos"])


def test_a_damaged_photo_is_refused_though_its_hash_was_updated(room):
    """The record is by the bytes' hash: a truncated photo whose project hash was made to match has
    no record, so it is decoded and refused, as before."""
    data = json.loads(room.read_text())
    photo = room.parent / data["photos"][0]["file"]
    photo.write_bytes(photo.read_bytes()[: photo.stat().st_size // 2])
    data["photos"][0]["sha256"] = images.sha256_file(photo)
    room.write_text(json.dumps(data))
    with pytest.raises(ProjectError, match=photo.name):
        load_project(room)


def test_a_photo_recorded_under_older_pixel_rules_is_checked_again(room):
    """A record names the edition of the pixel-format rules it was made under: a float photo that
    an earlier vebuild decoded whole (and recorded so, as Pillow's alone) is refused now."""
    import io

    import numpy as np
    import PIL
    import tifffile

    data = json.loads(room.read_text())
    entry = data["photos"][0]
    photo = room.parent / entry["file"]
    buf = io.BytesIO()
    tifffile.imwrite(buf, np.full((entry["height"], entry["width"]), 0.5, np.float32))
    photo.write_bytes(buf.getvalue())
    entry["sha256"] = images.sha256_file(photo)
    room.write_text(json.dumps(data))
    old = {"width": entry["width"], "height": entry["height"], "decoder": f"Pillow {PIL.__version__}"}
    record = room.parent.parent / "cache" / images.DECODED_FOLDER / f"{entry['sha256']}.json"
    record.parent.mkdir(parents=True)
    record.write_text(json.dumps(old))
    with pytest.raises(ProjectError, match=rf"\$\.photos\[0\]\.file: the photo .*{photo.name} has pixels of .*'F'"):
        load_project(room)
    assert json.loads(record.read_text()) == old  # a refused photo is not recorded
