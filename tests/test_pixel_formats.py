"""Every pixel format Pillow hands back is decoded to the right values or refused by name.

Each image is built with known values (tests/pixel_formats.py); the decoded RGB is compared with
the value computed from the published formula for its format, within the rounding its decoding
allows (the tolerances are named there). A refused image is refused by the one decoder of photos
and by the check that `vebuild check` and `vebuild new` run, with the same message: the file, the
field, the photo and its Pillow mode.
"""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image
from pixel_formats import ACCEPTED, REFUSED, Maker, png16

from vebuild.errors import ProjectError
from vebuild.project.images import decode_photo, image_size
from vebuild.project.pixels import check_pixel_format, rgb_image

FILE, WHERE = "room.vebuild.json", "$.photos[0].file"
H, W = 6, 9


def _name(make: Maker) -> str:
    return make(np.random.default_rng(0), 2, 2).name


def _decoded(sample, tmp_path) -> np.ndarray:
    if sample.data is None:
        return np.asarray(rgb_image(sample.image, FILE, WHERE, "photo.x"))
    assert Image.open(io.BytesIO(sample.data)).mode == sample.mode  # the format this case is about
    path = tmp_path / "photo.img"
    path.write_bytes(sample.data)
    assert image_size(path, FILE, WHERE) == (W, H)  # what `vebuild check` decodes accepts it too
    return decode_photo(sample.data, path.name, FILE, WHERE)


@pytest.mark.parametrize("make", ACCEPTED, ids=_name)
def test_each_accepted_pixel_format_decodes_to_its_values(make: Maker, tmp_path) -> None:
    sample = make(np.random.default_rng(7), H, W)
    got = _decoded(sample, tmp_path)
    assert got.dtype == np.uint8 and got.shape == (H, W, 3)
    err = np.abs(got.astype(np.float64) - sample.expected).max()
    assert err <= sample.tolerance, (sample.name, err)


@pytest.mark.parametrize("make", REFUSED, ids=_name)
def test_each_refused_pixel_format_is_refused_by_name(make: Maker, tmp_path) -> None:
    sample = make(np.random.default_rng(7), H, W)
    assert sample.data is not None and Image.open(io.BytesIO(sample.data)).mode == sample.mode
    path = tmp_path / "photo.img"
    path.write_bytes(sample.data)
    with pytest.raises(ProjectError) as decoding:
        decode_photo(sample.data, path.name, FILE, WHERE, label=str(path))
    with pytest.raises(ProjectError) as checking:
        image_size(path, FILE, WHERE)
    for message in (str(decoding.value), str(checking.value)):
        assert message.startswith(f"{FILE}: {WHERE}: "), message
        for word in (str(path), f"Pillow mode {sample.mode!r}", sample.refusal, "expected"):
            assert word.lower() in message.lower(), (word, message)
    assert str(decoding.value) == str(checking.value)


def test_a_16_bit_grey_photo_keeps_its_brightness() -> None:
    """The case that was decoded all white: a 16-bit grey PNG whose mean is 137 of 255."""
    ramp = np.linspace(0.0, 2 * 137 / 255, 64 * 48).clip(0, 1).reshape(48, 64)
    levels = np.round(ramp * 65535).astype(np.uint16)
    got = decode_photo(png16(levels, 0), "grey16.png", FILE, WHERE)
    assert abs(got.mean() - (levels / 257.0).mean()) < 0.01  # rounding to levels averages out
    assert got.min() == 0 and got.max() == 255


def test_a_mode_vebuild_does_not_know_is_refused_by_name() -> None:
    img = Image.new("L", (4, 3))
    img._mode = "BGR;24"  # a mode Pillow once had, as a later Pillow might add another
    with pytest.raises(ProjectError, match=r"photo\.x has pixels of Pillow mode 'BGR;24'.*expected"):
        check_pixel_format(img, FILE, WHERE, "photo.x")


def test_a_monochrome_raw_file_decodes_as_grey(tmp_path) -> None:
    """A camera RAW file of a monochrome sensor (a DNG whose colour filter is one colour): LibRaw
    develops one channel, which becomes grey, r = g = b, at the size `vebuild check` records. (The
    grey levels are LibRaw's; of this small synthetic file they are not the same from run to run,
    so only the shape and the equal channels are asserted.)"""
    import rawpy
    import tifffile

    y, x = np.mgrid[0:H * 8, 0:W * 8]
    tags = [(50706, "B", 4, (1, 4, 0, 0), True), (50707, "B", 4, (1, 1, 0, 0), True),
            (50708, "s", 0, "vebuild test monochrome camera", True), (50717, "I", 1, 4095, True),
            (33421, "H", 2, (1, 1), True), (33422, "B", 1, (1,), True)]  # a 1×1 pattern of one colour
    path = tmp_path / "mono.dng"
    tifffile.imwrite(path, (200 + 20 * x + y).astype(np.uint16), photometric=32803, extratags=tags,
                     subfiletype=0, metadata=None)
    with rawpy.imread(str(path)) as raw:
        assert raw.postprocess(output_bps=8, use_camera_wb=True).shape == (H * 8, W * 8, 1)  # what LibRaw gives
    got = decode_photo(path.read_bytes(), path.name, FILE, WHERE)
    assert got.shape == (H * 8, W * 8, 3) and got.dtype == np.uint8
    assert (got == got[..., :1]).all() and got.max() > 0  # r = g = b, and not all black
    assert image_size(path, FILE, WHERE) == (W * 8, H * 8)


def test_a_16_bit_grey_photo_in_a_project_is_checked_and_read_as_its_grey(tmp_path, monkeypatch) -> None:
    """The example room with its first photo saved as 16-bit grey: `vebuild check` accepts it, and
    the texture stage and the modelling screens read the photo's own grey, not white."""
    import contextlib
    import hashlib
    import json
    import shutil

    from vebuild.actions.detect import photo_pixels
    from vebuild.cli import main
    from vebuild.project import load_project
    from vebuild.resources import example_project_dir
    from vebuild.texture.extract import decode

    monkeypatch.setenv("VEBUILD_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "room"
    shutil.copytree(example_project_dir(), folder)
    project_file = folder / "room.vebuild.json"
    doc = json.loads(project_file.read_text())
    photo = folder / doc["photos"][0]["file"]
    grey = np.asarray(Image.open(photo).convert("L"))
    photo.write_bytes(png16(grey.astype(np.uint16) * 257, 0))  # 8-bit grey v as 16-bit v · 257, exactly
    doc["photos"][0]["sha256"] = hashlib.sha256(photo.read_bytes()).hexdigest()
    project_file.write_text(json.dumps(doc))
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["check", str(project_file)]) == 0
    project = load_project(project_file)
    for pixels in (photo_pixels(project, doc["photos"][0]["id"]), decode(photo.read_bytes())):
        assert (pixels == grey[..., None]).all()
