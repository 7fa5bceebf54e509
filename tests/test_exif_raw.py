"""Real photographs: EXIF read and turned into a focal prior with an honest 1σ, the sensor database,
lens profiles, EXIF orientation, camera RAW files, and every message a user can get from them."""

from __future__ import annotations

import io
import math
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image, ImageOps

from vebuild.calibration import exif as cx
from vebuild.errors import ProjectError
from vebuild.project import load_project, new_photo_entry, new_project, read_exif, save_project, sha256_file
from vebuild.project.images import decode_photo, image_size, is_raw

W, H = 96, 64  # stored size of the test images: wider than tall, so that a quarter turn shows


# ---- helpers -------------------------------------------------------------------------------------


def _pattern(w: int = W, h: int = H) -> np.ndarray:
    """An image whose every quadrant differs: a red block at the stored top left, a green one at
    the stored top right, a smooth blue ramp down the rows."""
    img = np.zeros((h, w, 3), np.uint8)
    img[..., 2] = np.linspace(0, 255, h, dtype=np.uint8)[:, None]
    img[: h // 3, : w // 3] = (250, 20, 20)
    img[: h // 3, -w // 3:] = (20, 250, 20)
    return img


def _exif(orientation: int | None = None, make: str | None = "NIKON CORPORATION", model: str | None = "NIKON D7000",
          **sub_tags: object) -> Image.Exif:
    exif = Image.Exif()
    if make:
        exif[0x010F] = make
    if model:
        exif[0x0110] = model
    if orientation is not None:
        exif[0x0112] = orientation
    sub = exif.get_ifd(0x8769)
    for tag, value in sub_tags.items():
        sub[int(tag[1:], 16 if tag.startswith("x") else 10)] = value
    return exif


def _jpeg(path: Path, exif: Image.Exif | None = None, pixels: np.ndarray | None = None) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    img = Image.fromarray(_pattern() if pixels is None else pixels)
    img.save(path, format="JPEG", quality=95, **({"exif": exif} if exif is not None else {}))
    return path


def _dng(path: Path, orientation: int = 1, w: int = W, h: int = H, exif: bool = True) -> Path:
    """A small valid camera RAW file: a DNG of a Bayer (RGGB) mosaic, bright in the stored top-left
    third, with the camera's make, model, focal length and orientation in IFD0 (where DNG may keep
    EXIF)."""
    tifffile = pytest.importorskip("tifffile")
    path.parent.mkdir(parents=True, exist_ok=True)
    y, x = np.mgrid[0:h, 0:w]
    cfa = (200 + 2 * x + y).astype(np.uint16)
    cfa[: h // 3, : w // 3] = 3800
    tags = [
        (50706, "B", 4, (1, 4, 0, 0), True),  # DNGVersion
        (50707, "B", 4, (1, 1, 0, 0), True),  # DNGBackwardVersion
        (50708, "s", 0, "vebuild test camera", True),  # UniqueCameraModel
        (33421, "H", 2, (2, 2), True),  # CFARepeatPatternDim
        (33422, "B", 4, (0, 1, 1, 2), True),  # CFAPattern: R G / G B
        (50717, "I", 1, 4095, True),  # WhiteLevel
        (50721, "2i", 9, (1000, 1000, 0, 1000, 0, 1000, 0, 1000, 1000, 1000, 0, 1000, 0, 1000, 0, 1000,
                          1000, 1000), True),  # ColorMatrix1: identity
        (50778, "H", 1, 21, True),  # CalibrationIlluminant1: D65
        (274, "H", 1, orientation, True),
    ]
    if exif:
        tags += [(271, "s", 0, "NIKON CORPORATION", True), (272, "s", 0, "NIKON D7000", True),
                 (37386, "2I", 1, (180, 10), True), (41989, "H", 1, 27, True)]
    tifffile.imwrite(path, cfa, photometric=32803, extratags=tags, subfiletype=0, metadata=None)
    return path


# ---- EXIF orientation ----------------------------------------------------------------------------


@pytest.mark.parametrize("orientation", range(1, 9))
def test_decode_turns_as_exif_transpose(tmp_path: Path, orientation: int) -> None:
    # The one decoder turns a real JPEG exactly as Pillow's ImageOps.exif_transpose does, without
    # a second copy; its size is the displayed one.
    path = _jpeg(tmp_path / "p.jpg", _exif(orientation))
    data = path.read_bytes()
    pixels = decode_photo(data, path, "proj", "$.photos[0].file")
    with Image.open(io.BytesIO(data)) as im:
        expected = np.asarray(ImageOps.exif_transpose(im).convert("RGB"))
    assert pixels.shape == expected.shape
    np.testing.assert_array_equal(pixels, expected)
    turned = orientation >= 5
    assert image_size(path, "proj", "") == ((H, W) if turned else (W, H))
    assert pixels.flags.c_contiguous


def test_quarter_turns_put_the_top_where_the_camera_meant(tmp_path: Path) -> None:
    # Orientation 6: the camera was turned clockwise; the stored top row is the displayed right
    # column, so the stored top-left red block shows at the top right. 8: at the bottom left.
    for orientation, corner in ((6, (0, -1)), (8, (-1, 0)), (3, (-1, -1))):
        path = _jpeg(tmp_path / f"o{orientation}.jpg", _exif(orientation))
        pixels = decode_photo(path.read_bytes(), path, "p", "")
        r, c = corner
        rows = slice(0, 10) if r == 0 else slice(-10, None)
        cols = slice(0, 10) if c == 0 else slice(-10, None)
        block = pixels[rows, cols].reshape(-1, 3).mean(axis=0)
        assert block[0] > 200 and block[1] < 60, (orientation, block)


def test_new_photo_entry_of_a_turned_jpeg(tmp_path: Path) -> None:
    path = _jpeg(tmp_path / "shots" / "door.jpg", _exif(6, t37386=18.0, t41989=27))
    before = path.read_bytes()
    entry = new_photo_entry(tmp_path, path)
    assert (entry["width"], entry["height"]) == (H, W)  # as displayed
    assert entry["sha256"] == sha256_file(path)  # the original file's bytes
    assert path.read_bytes() == before  # never altered
    assert entry["exif"]["orientation"] == 6
    # The sensor's x axis is the displayed vertical: f = 18 mm × 96 px / 23.6 mm (database).
    assert entry["exif"]["focal_length_px"] == pytest.approx(18.0 * W / 23.6)


@pytest.mark.parametrize("value", [0, 9, 65535])
def test_orientation_out_of_range_is_refused(tmp_path: Path, value: int) -> None:
    path = _jpeg(tmp_path / "odd.jpg", _exif(value))
    before = path.read_bytes()
    with pytest.raises(ProjectError, match=rf"odd\.jpg has EXIF orientation \(tag 274\) {value}; expected 1 to 8 "
                       r".*will not guess which way up it is.*add that copy"):
        new_photo_entry(tmp_path, path)
    with pytest.raises(ProjectError, match=r"\$\.photos\[2\]\.file: the photo .* expected 1 to 8"):
        decode_photo(before, path, "proj.vebuild.json", "$.photos[2].file")
    assert path.read_bytes() == before


def test_project_made_before_orientation_is_explained(tmp_path: Path) -> None:
    # A project that recorded the stored size of a turned photo: its marks do not fit the photo as
    # shown; the message says so and what to do.
    path = _jpeg(tmp_path / "door.jpg", _exif(8))
    doc = new_project("old")
    entry = new_photo_entry(tmp_path, path)
    entry["width"], entry["height"] = W, H
    doc["photos"].append(entry)
    save_project(tmp_path / "old.vebuild.json", doc)
    with pytest.raises(ProjectError, match=r"\$\.photos\[0\]\.width: the photo 'door\.jpg' is 64×96 pixels, but the "
                       r"project says 96×64: the photo's EXIF orientation turns it a quarter.*Add the photo again"):
        load_project(tmp_path / "old.vebuild.json")


def test_read_exif_records_lens_and_orientation(tmp_path: Path) -> None:
    path = _jpeg(tmp_path / "a.jpg", _exif(3, xA433="Nikon", xA434="AF-S DX Zoom-Nikkor 18-55mm f/3.5-5.6G ED",
                                           t37386=18.0, t41989=27, xA002=4928, xA003=3264))
    exif = read_exif(path)
    assert exif["lens_make"] == "Nikon"
    assert exif["lens_model"] == "AF-S DX Zoom-Nikkor 18-55mm f/3.5-5.6G ED"
    assert exif["orientation"] == 3
    assert (exif["pixel_x_dimension"], exif["pixel_y_dimension"]) == (4928, 3264)
    assert list(exif) == ["make", "model", "lens_make", "lens_model", "orientation", "focal_length_mm",
                          "focal_length_35mm", "pixel_x_dimension", "pixel_y_dimension", "focal_length_px"]


# ---- the focal prior ------------------------------------------------------------------------------


def _rel(prior) -> float:
    return prior.sigma / prior.value


def test_focal_prior_from_focal_plane_resolution() -> None:
    # Canon writes the focal-plane resolution: 5184 px over a 22.3 mm sensor.
    exif = {"make": "Canon", "model": "Canon EOS 600D", "focal_length_mm": 18.0,
            "focal_plane_x_resolution_per_mm": 5184 / 22.3}
    prior = cx.focal_prior(exif, 5184, 3456)
    assert prior.value == pytest.approx(18.0 * 5184 / 22.3)
    assert prior.source.startswith("exif: 18 mm × focal-plane resolution 232.47 px/mm (sensor 22.3 mm wide)")
    # 3 % for what EXIF cannot know, 1 mm rounding (whole millimetres) at 18 mm: √(3² + 1.60²) %
    assert _rel(prior) == pytest.approx(math.sqrt(0.03**2 + (1 / math.sqrt(12) / 18) ** 2))


def test_focal_prior_from_the_sensor_database_on_a_turned_photo() -> None:
    # Nikon writes no focal-plane resolution: the database's 23.6 mm for a D7000; the photo is
    # shown upright (orientation 6), so the sensor's 4928 px run down the displayed photo.
    exif = {"make": "NIKON CORPORATION", "model": "NIKON D7000", "orientation": 6, "focal_length_mm": 18.0,
            "focal_length_35mm": 27.0}
    prior = cx.focal_prior(exif, 3264, 4928)
    assert prior.value == pytest.approx(18.0 * 4928 / 23.6)
    assert prior.source == ("exif: 18 mm × sensor 23.6 mm (database: Nikon Nikon D7000, AliceVision cameraSensors.db; "
                            "dpreview digicamdb imaging-resource dxomark)")
    upright = cx.focal_prior({**exif, "orientation": 1}, 4928, 3264)
    assert upright.value == pytest.approx(prior.value)


def test_focal_prior_from_the_35mm_equivalent() -> None:
    exif = {"make": "Unknown maker", "model": "X1", "focal_length_mm": 4.5, "focal_length_35mm": 26.0}
    prior = cx.focal_prior(exif, 4000, 3000)
    assert prior.value == pytest.approx(26.0 * 5000 / math.hypot(36, 24))
    assert prior.source == "exif: 35 mm equivalent 26 mm over the image diagonal"
    # A 4:3 image: the width-based definition differs by 4 %; that, the 1 mm rounding and the floor.
    by_width = 26.0 * 4000 / 36.0
    spread = abs(by_width - prior.value) / prior.value
    assert 0.035 < spread < 0.045
    assert _rel(prior) == pytest.approx(math.sqrt(0.03**2 + (1 / math.sqrt(12) / 26) ** 2 + spread**2 / 12))


def test_focal_prior_none_without_focal_length() -> None:
    assert cx.focal_prior({"make": "Canon", "model": "Canon EOS 600D"}, 100, 100) is None
    assert cx.focal_prior({}, 100, 100) is None
    assert cx.exif_focal_prior({"width": 10, "height": 10}) is None


def test_focal_plane_resolution_of_a_resized_photo() -> None:
    # The camera wrote a 4000 px image (PixelXDimension) at 4000 / 6.17 px/mm; the photo was resized
    # to 640 px since: the sensor is still 6.17 mm wide and f scales with the photo.
    exif = {"focal_length_mm": 4.5, "focal_plane_x_resolution_per_mm": 4000 / 6.17, "pixel_x_dimension": 4000}
    prior = cx.focal_prior(exif, 640, 480)
    assert prior.value == pytest.approx(4.5 * 640 / 6.17)


def test_focal_plane_resolution_disagreeing_with_the_database_is_not_used() -> None:
    # A resolution implying a 30 mm sensor on a D7000 (23.6 mm): the database's width is used.
    exif = {"make": "NIKON CORPORATION", "model": "NIKON D7000", "focal_length_mm": 35.0,
            "focal_plane_x_resolution_per_mm": 4928 / 30.0}
    prior = cx.focal_prior(exif, 4928, 3264)
    assert prior.value == pytest.approx(35.0 * 4928 / 23.6)
    assert "database" in prior.source


def test_rounding_step_of_the_focal_length() -> None:
    base = {"focal_plane_x_resolution_per_mm": 200.0}
    whole = _rel(cx.focal_prior({**base, "focal_length_mm": 18.0}, 4000, 3000, floor_rel=0.0))
    tenth = _rel(cx.focal_prior({**base, "focal_length_mm": 18.3}, 4000, 3000, floor_rel=0.0))
    assert whole == pytest.approx(1 / math.sqrt(12) / 18.0)
    assert tenth == pytest.approx(0.1 / math.sqrt(12) / 18.3)


def test_focal_sigma_covers_real_exif_errors() -> None:
    # EXIF errors as real cameras make them (module docstring): a lens up to 5 % off its marked
    # focal length, focusing at 2–5 m with an 18–35 mm lens, a rounding to whole millimetres, a
    # nominal sensor width. The prior's 95 % interval holds 93–99.5 % of the truths; the 4.1 %
    # error of the public set of real photos lies inside it.
    rng = np.random.default_rng(16)
    inside, n = 0, 4000
    for _ in range(n):
        marked = float(rng.choice([18.0, 20.0, 24.0, 28.0, 35.0]))
        true_mm = marked * (1 + rng.uniform(-0.05, 0.05))
        distance_mm = rng.uniform(2000, 5000)
        true_mm *= distance_mm / (distance_mm - true_mm)  # the image distance when focused there
        sensor_true = 23.6 * (1 + 0.01 * rng.standard_normal())
        f_true = true_mm * 4928 / sensor_true
        prior = cx.focal_prior({"make": "NIKON CORPORATION", "model": "NIKON D7000", "focal_length_mm": marked},
                               4928, 3264)
        inside += abs(prior.value - f_true) < 1.96 * prior.sigma
    assert 0.93 <= inside / n <= 0.995
    prior = cx.focal_prior({"make": "NIKON CORPORATION", "model": "NIKON D7000", "focal_length_mm": 18.0}, 4928, 3264)
    assert 0.041 < 1.96 * _rel(prior) < 0.10


def test_the_projects_setting_is_the_floor(tmp_path: Path) -> None:
    photo = {"width": 4928, "height": 3264, "exif": {"make": "NIKON CORPORATION", "model": "NIKON D7000",
                                                   "focal_length_mm": 18.3}}
    wide, narrow = cx.exif_focal_prior(photo, 0.05), cx.exif_focal_prior(photo, 0.001)
    assert _rel(wide) == pytest.approx(math.hypot(0.05, 0.1 / math.sqrt(12) / 18.3))
    assert _rel(narrow) == pytest.approx(math.hypot(0.001, 0.1 / math.sqrt(12) / 18.3))
    from vebuild.project import DEFAULT_SETTINGS

    assert DEFAULT_SETTINGS["exif_focal_sigma_rel"] == cx.NOMINAL_FOCAL_SIGMA_REL


# ---- the sensor database --------------------------------------------------------------------------


@pytest.mark.parametrize(("make", "model", "width"), [
    ("NIKON CORPORATION", "NIKON D7000", 23.6),
    ("NIKON CORPORATION", "NIKON Z 6", 35.9),
    ("Canon", "Canon EOS 5D Mark III", 36.0),
    ("SONY", "ILCE-7M3", 35.6),
    ("SONY", "DSC-RX100", 13.2),
    ("FUJIFILM", "X-T2", 23.6),
    ("OLYMPUS IMAGING CORP.", "E-M5", 17.3),
    ("OLYMPUS CORPORATION", "E-M1MarkII", 17.4),
    ("Panasonic", "DMC-GH4", 17.3),
    ("RICOH IMAGING COMPANY, LTD.", "PENTAX K-1", 35.9),
    ("Apple", "iPhone 6", 4.89),
    ("DJI", "FC6310", 13.2),
])
def test_find_sensor(make: str, model: str, width: float) -> None:
    entry = cx.find_sensor(make, model)
    assert entry is not None and entry.width_mm == width


def test_find_sensor_unknown() -> None:
    assert cx.find_sensor("Canon", "Canon EOS 9999Z") is None
    assert cx.find_sensor("NIKON CORPORATION", "") is None
    assert cx.find_sensor(None, None) is None


def test_sensor_database_is_sourced_and_well_formed() -> None:
    from vebuild.resources import package_data_file

    header = package_data_file(cx.SENSOR_DATABASE).read_text(encoding="utf-8").split("\n# make,model")[0]
    assert "AliceVision" in header and "Mozilla Public License 2.0" in header
    db = cx.sensor_database()
    assert len(db) > 250
    assert all(1.0 < e.width_mm < 60.0 and e.make and e.model for e in db)
    keys = [(cx._maker(e.make), cx._model_key(cx._maker(e.make), e.model)) for e in db]
    assert len(keys) == len(set(keys))  # no camera twice


# ---- the lens profile -----------------------------------------------------------------------------


def test_lens_profile_gives_a_division_model_prior() -> None:
    lensfunpy = pytest.importorskip("lensfunpy")
    exif = {"make": "NIKON CORPORATION", "model": "NIKON D7000",
            "lens_model": "AF-S DX Zoom-Nikkor 18-55mm f/3.5-5.6G ED", "focal_length_mm": 18.0}
    w, h = 1200, 800
    f = 18.0 * w / 23.6
    prior = cx.lens_distortion_prior(exif, w, h, f)
    assert prior is not None
    assert prior.source.startswith("lens profile: Nikon Nikon AF-S DX Zoom-Nikkor 18-55mm f/3.5-5.6G ED at 18 mm")
    assert prior.k1 < 0  # barrel, as an 18 mm kit zoom is
    assert 0.2 * abs(prior.k1) < prior.sigma < 0.5 * abs(prior.k1)
    # Independent of the fit: where lensfun puts the corner and where the division model does.
    db = lensfunpy.Database()
    cam = db.find_cameras("NIKON CORPORATION", "NIKON D7000")[0]
    lens = db.find_lenses(cam, None, exif["lens_model"])[0]
    mod = lensfunpy.Modifier(lens, cam.crop_factor, w, h)
    mod.initialize(18.0, 8.0, 1000.0)
    grid = mod.apply_geometry_distortion()
    c = np.array([(w - 1) / 2, (h - 1) / 2])
    r_u = np.linalg.norm(np.array([0.0, 0.0]) - c) / f
    r_d = np.linalg.norm(grid[0, 0] - c) / f
    r_mid_u, r_mid_d = np.linalg.norm(np.array([w / 4, h / 4]) - c) / f, np.linalg.norm(grid[h // 4, w // 4] - c) / f
    s = r_mid_u * (1 + prior.k1 * r_mid_d**2) / r_mid_d  # the corrected image's scale, from mid-way
    corner_px = abs(s * r_d / (1 + prior.k1 * r_d**2) - r_u) * f
    lensfun_px = abs(r_d - r_u) * f
    assert corner_px < 0.1 * lensfun_px + 1.0


def test_lens_profile_of_a_photo_object() -> None:
    pytest.importorskip("lensfunpy")
    exif = {"make": "NIKON CORPORATION", "model": "NIKON D7000",
            "lens_model": "AF-S DX Zoom-Nikkor 18-55mm f/3.5-5.6G ED", "focal_length_mm": 18.0}
    photo = {"width": 1200, "height": 800, "exif": exif}
    prior = cx.exif_distortion_prior(photo)
    assert prior == cx.lens_distortion_prior(exif, 1200, 800, 18.0 * 1200 / 23.6)
    no_focal = {k: v for k, v in exif.items() if k != "focal_length_mm"}
    assert cx.exif_distortion_prior({**photo, "exif": no_focal}) is None


def test_lens_profile_none_where_unknown() -> None:
    pytest.importorskip("lensfunpy")
    base = {"make": "NIKON CORPORATION", "model": "NIKON D7000", "focal_length_mm": 18.0}
    assert cx.lens_distortion_prior(base, 600, 400, 460.0) is None  # no lens named
    assert cx.lens_distortion_prior({**base, "lens_model": "Nonexistent 12-13mm f/99"}, 600, 400, 460.0) is None
    # A focal length outside the lens's range: no profile applies.
    outside = {**base, "focal_length_mm": 70.0, "lens_model": "AF-S DX Zoom-Nikkor 18-55mm f/3.5-5.6G ED"}
    assert cx.lens_distortion_prior(outside, 600, 400, 1800.0) is None


# ---- camera RAW -----------------------------------------------------------------------------------


def test_new_photo_entry_of_a_dng(tmp_path: Path) -> None:
    path = _dng(tmp_path / "shots" / "scene.dng", orientation=6)
    before = path.read_bytes()
    assert is_raw(path) and is_raw("X.NEF") and is_raw("a.cr2") and is_raw("b.ARW") and not is_raw("c.jpg")
    entry = new_photo_entry(tmp_path, path)
    assert (entry["width"], entry["height"]) == (H, W)  # developed and turned: 64 wide, 96 tall
    assert entry["sha256"] == sha256_file(path)
    assert path.read_bytes() == before
    exif = entry["exif"]
    assert (exif["make"], exif["model"], exif["orientation"]) == ("NIKON CORPORATION", "NIKON D7000", 6)
    assert exif["focal_length_mm"] == pytest.approx(18.0) and exif["focal_length_35mm"] == 27.0
    assert exif["focal_length_px"] == pytest.approx(18.0 * W / 23.6)  # the sensor's x runs down the photo


def test_dng_decodes_turned_and_through_read_photo(tmp_path: Path) -> None:
    from vebuild.camera import ImageCamera
    from vebuild.texture.extract import PhotoSource, read_photo

    path = _dng(tmp_path / "scene.dng", orientation=6)
    pixels = decode_photo(path.read_bytes(), path, "p", "")
    assert pixels.shape == (W, H, 3) and pixels.dtype == np.uint8
    # The bright stored top-left third shows at the top right once turned a quarter clockwise.
    top_right = pixels[:20, -15:].mean()
    assert top_right > pixels[-20:, :15].mean() + 50 and top_right > pixels[:20, :15].mean() + 50
    cam = ImageCamera("scene", np.eye(3), np.eye(3), np.zeros(3), H, W)
    src = PhotoSource("scene", path, sha256_file(path), "$.photos[0]", "p.vebuild.json")
    np.testing.assert_array_equal(read_photo(src, cam), pixels)


def test_dng_project_loads_and_verifies(tmp_path: Path) -> None:
    doc = new_project("raw")
    doc["photos"].append(new_photo_entry(tmp_path, _dng(tmp_path / "a.dng")))
    save_project(tmp_path / "raw.vebuild.json", doc)
    project = load_project(tmp_path / "raw.vebuild.json")
    assert (project.data["photos"][0]["width"], project.data["photos"][0]["height"]) == (W, H)


def test_dng_without_exif(tmp_path: Path) -> None:
    entry = new_photo_entry(tmp_path, _dng(tmp_path / "bare.dng", exif=False))
    assert "exif" not in entry or "focal_length_px" not in entry["exif"]


def test_unreadable_raw_is_refused(tmp_path: Path) -> None:
    bad = tmp_path / "shot.nef"
    bad.write_bytes(b"this is no camera RAW file" * 40)
    with pytest.raises(ProjectError, match=r"shot\.nef: cannot read .*shot\.nef as a camera RAW file: LibRaw "
                       r"\d+\.\d+\.\d+ says Unsupported file format or not RAW file \(is it a RAW file of a camera "
                       r"LibRaw supports, and whole\?\)"):
        new_photo_entry(tmp_path, bad)
    with pytest.raises(ProjectError, match=r"proj: \$\.photos\[0\]\.file: cannot read shot\.nef as a camera RAW"):
        decode_photo(bad.read_bytes(), bad, "proj", "$.photos[0].file", label="shot.nef")
    assert bad.read_bytes() == b"this is no camera RAW file" * 40


def test_truncated_raw_is_refused(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    # LibRaw's own complaint (written by C to the process's standard error) is quoted in the one
    # message, not left on the terminal beside it.
    whole = _dng(tmp_path / "whole.dng", w=256, h=256).read_bytes()
    cut = tmp_path / "cut.dng"
    cut.write_bytes(whole[: len(whole) // 3])
    capfd.readouterr()
    with pytest.raises(ProjectError, match=r"cut\.dng as a camera RAW file: LibRaw \S+ says Input/output error \(its "
                       r"own words: .*Unexpected end of file\) \(is it a RAW file of a camera LibRaw supports, and "
                       r"whole\?\)"):
        new_photo_entry(tmp_path, cut)
    assert capfd.readouterr().err == ""


def test_raw_too_large_is_refused_before_developing(tmp_path: Path) -> None:
    path = _dng(tmp_path / "a.dng")
    with pytest.raises(ProjectError, match=r"a\.dng is 96×64 = 0\.006144 megapixels, more than the 0\.001 megapixels "
                       r"vebuild reads \(refused before developing it\)"):
        decode_photo(path.read_bytes(), path, "p", "", max_pixels=1000)


def test_missing_photo_file(tmp_path: Path) -> None:
    with pytest.raises(ProjectError, match=r"photo file not found: .*gone\.dng"):
        image_size(tmp_path / "gone.dng", "p", "")


# ---- the large-photo benchmark ----------------------------------------------------------------------


def test_big_photo_bench_decodes_a_jpeg_and_a_raw(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The benchmark at a small size (its 45 MP figures are in docs/accuracy.md): each case written,
    # decoded in a fresh process by the one photo decoder, its figures named with their units.
    pytest.importorskip("tifffile")
    from vebuild.bench import big_photo

    monkeypatch.setattr(big_photo, "SIZE_45MP", (192, 128))
    for case in ("jpeg", "raw"):
        fig = big_photo.measure(case, tmp_path, 0, stages=("decode",))
        assert (fig["width_px"], fig["height_px"]) == (192, 128)
        assert fig["decoded_mb"] == pytest.approx(3 * 192 * 128 / 2**20)
        assert fig["decode_peak_rss_mb"] >= fig["decode_baseline_rss_mb"] > 0
        assert fig["decode_peak_over_decoded"] == pytest.approx(fig["decode_peak_rss_mb"] / fig["decoded_mb"])
        assert fig["decode_seconds"] > 0 and fig["file_mb"] > 0
    assert not list(tmp_path.iterdir())  # the photos are removed


def test_big_photo_bench_refuses_an_unknown_case(capsys: pytest.CaptureFixture[str]) -> None:
    from vebuild.bench import big_photo

    with pytest.raises(SystemExit) as e:
        big_photo.main(["--cases", "jpeg,tiff"])
    assert e.value.code == 2
    assert "unknown case or stage: tiff" in capsys.readouterr().err


@pytest.mark.parametrize(("key", "value", "expected"), [
    ("orientation", 9, "expected a number at least 1 and at most 8 (an EXIF orientation: 1 upright, 3 upside down, "
                       "6 and 8 turned a quarter, 2, 4, 5 and 7 mirrored), found the number 9"),
    ("orientation", 0, "at most 8 (an EXIF orientation: 1 upright"),
    ("pixel_x_dimension", 0, "expected a number at least 1 and at most 1000000 (the image's width in pixels as the "
                             "camera wrote it; no camera writes a side of a million pixels), found the number 0"),
    ("pixel_y_dimension", 2.5, "expected a whole number (the image's height in pixels"),
    ("lens_model", 3, "expected text in quotes, found the number 3"),
])
def test_exif_record_fields_are_checked_when_loaded(tmp_path: Path, key: str, value: object, expected: str) -> None:
    import json

    doc = new_project("x")
    entry = new_photo_entry(tmp_path, _jpeg(tmp_path / "a.jpg"))
    entry["exif"] = {key: value}
    doc["photos"].append(entry)
    (tmp_path / "p.vebuild.json").write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(ProjectError, match=re.escape(f"$.photos[0].exif.{key}: ") + ".*" + re.escape(expected)):
        load_project(tmp_path / "p.vebuild.json")


def test_exif_values_outside_the_formats_bounds_are_left_out(tmp_path: Path) -> None:
    # A camera's odd EXIF must not make the photo's entry invalid: such values are not recorded.
    path = _jpeg(tmp_path / "odd.jpg", _exif(None, t37386=20000.0, t41989=200000, t41486=1e9, t41488=4,
                                             xA002=2_000_000, xA003=0))
    entry = new_photo_entry(tmp_path, path)
    assert entry["exif"] == {"make": "NIKON CORPORATION", "model": "NIKON D7000"}
    doc = new_project("odd")
    doc["photos"].append(entry)
    save_project(tmp_path / "odd.vebuild.json", doc)  # valid


def test_focal_plane_resolution_in_micrometres(tmp_path: Path) -> None:
    # Unit 5 (µm): 0.25 px per µm is 250 px per mm (tests/test_project.py has the other units).
    exif = read_exif(_jpeg(tmp_path / "um.jpg", _exif(None, t37386=4.5, t41486=0.25, t41488=5)))
    assert exif["focal_plane_x_resolution_per_mm"] == pytest.approx(250.0)


def test_modelling_screen_adds_and_shows_turned_and_raw_photos(tmp_path: Path) -> None:
    # The modelling screen's session adds a turned JPEG and a DNG and loads their pixels through
    # the same decoder: as displayed, the size the project records.
    from vebuild.edit.session import EditSession

    save_project(tmp_path / "s.vebuild.json", new_project("s"))
    session = EditSession(load_project(tmp_path / "s.vebuild.json"), autosave=False)
    jpeg = _jpeg(tmp_path / "door.jpg", _exif(8))
    dng = _dng(tmp_path / "scene.dng", orientation=6)
    for path in (jpeg, dng):
        pid = session.add_photo(path)
        photo = session.photo(pid)
        pixels = session.photo_pixels(pid)
        assert pixels.shape == (photo["height"], photo["width"], 3) == (W, H, 3)
    with Image.open(jpeg) as im:
        np.testing.assert_array_equal(session.photo_pixels("door"), np.asarray(ImageOps.exif_transpose(im)))


def test_vebuild_new_from_a_turned_jpeg_and_a_dng(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from vebuild.cli import main

    _jpeg(tmp_path / "door.jpg", _exif(6, t37386=18.0))
    _dng(tmp_path / "scene.dng", orientation=1)
    assert main(["new", str(tmp_path / "r.vebuild.json"), str(tmp_path / "door.jpg"), str(tmp_path / "scene.dng")]) == 0
    photos = load_project(tmp_path / "r.vebuild.json").data["photos"]
    assert [(p["id"], p["width"], p["height"]) for p in photos] == [("door", H, W), ("scene", W, H)]
    assert photos[0]["exif"]["orientation"] == 6 and "focal_length_px" in photos[1]["exif"]


@pytest.mark.parametrize(("name", "content", "expected"), [
    ("shot.nef", b"not a raw file" * 50, "as a camera RAW file: LibRaw"),
    ("odd.jpg", None, "EXIF orientation (tag 274) 9; expected 1 to 8"),
])
def test_vebuild_new_refuses_with_one_message(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str,
                                              content: bytes | None, expected: str) -> None:
    from vebuild.cli import main

    path = tmp_path / name
    if content is None:
        _jpeg(path, _exif(9))
    else:
        path.write_bytes(content)
    capsys.readouterr()
    assert main(["new", str(tmp_path / "r.vebuild.json"), str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and err.count("\n") == 1 and expected in err and name in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # nothing written


def test_raw_that_libraw_cannot_develop(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # A file LibRaw unpacks but fails to develop (its data corrupt past the header): LibRaw's
    # development raises, and the message says so. LibRaw is asked for real to open the file; its
    # development is made to fail as LibRaw's does, since no small file is known to fail only there.
    import contextlib

    import rawpy

    from vebuild.project import images

    path = _dng(tmp_path / "bad.dng")
    real_open = images._open_raw

    class Failing:
        def __init__(self, raw):
            self.raw = raw

        def postprocess(self, **_):
            raise rawpy.LibRawDataError(b"Data error")

    @contextlib.contextmanager
    def open_failing(*args, **kwargs):
        with real_open(*args, **kwargs) as raw:
            yield Failing(raw)

    monkeypatch.setattr(images, "_open_raw", open_failing)
    with pytest.raises(ProjectError, match=r"p: \$\.photos\[0\]\.file: cannot develop the RAW file bad\.dng: LibRaw "
                       r"says Data error \(the file may be damaged or truncated\)"):
        decode_photo(path.read_bytes(), path, "p", "$.photos[0].file", label="bad.dng")


def _exif_bytes(num: int, den: int) -> bytes:
    """An EXIF block written by hand, as a camera writes it: an Exif IFD whose FocalLength is the
    rational num/den unreduced (Pillow reduces the rationals it writes; cameras do not)."""
    import struct

    tiff = b"II*\x00" + struct.pack("<I", 8)
    tiff += struct.pack("<H", 1) + struct.pack("<HHII", 0x8769, 4, 1, 26) + struct.pack("<I", 0)  # IFD0 → Exif IFD
    tiff += struct.pack("<H", 1) + struct.pack("<HHII", 0x920A, 5, 1, 44) + struct.pack("<I", 0)  # FocalLength
    tiff += struct.pack("<II", num, den)
    return b"Exif\x00\x00" + tiff


@pytest.mark.parametrize(("num", "den", "step"), [(180, 10, 0.1), (18, 1, 1.0), (4250, 1000, 0.001), (81, 40, 0.0)])
def test_the_step_the_focal_length_was_written_to(tmp_path: Path, num: int, den: int, step: float) -> None:
    # 180/10 is 18 mm to a tenth; 18/1 to the millimetre; 81/40 an exact fraction, no rounding.
    path = tmp_path / "f.jpg"
    Image.fromarray(_pattern()).save(path, format="JPEG", exif=_exif_bytes(num, den))
    exif = read_exif(path)
    assert exif["focal_length_mm"] == pytest.approx(num / den)
    assert exif["focal_length_mm_step"] == pytest.approx(step)
    prior = cx.focal_prior({**exif, "focal_plane_x_resolution_per_mm": 100.0}, W, H, floor_rel=0.0)
    assert _rel(prior) == pytest.approx(step / math.sqrt(12) / (num / den))
