"""Project file I/O: every error a user can make gets a message naming where and what."""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from vebuild import project as vp
from vebuild.errors import ProjectError
from vebuild.project import (
    Project,
    canonical_input_hash,
    load_project,
    new_photo_entry,
    new_project,
    read_exif,
    save_project,
    sha256_file,
)
from vebuild.project.records import camera_record

W, H = 64, 48


def make_image(path: Path, color=(120, 90, 60), size=(W, H), exif: Image.Exif | None = None) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    img = Image.new("RGB", size, color)
    img.save(path, **({"exif": exif} if exif is not None else {}))
    return path


@pytest.fixture
def proj(tmp_path: Path) -> Path:
    """A valid project with two photos, three markers and two distances; returns its file."""
    doc = new_project("test room")
    for i, name in enumerate(["door", "window"]):
        image = make_image(tmp_path / "photos" / f"{name}.jpg", color=(40 * i, 100, 200))
        doc["photos"].append(new_photo_entry(tmp_path, image))
    doc["photos"][0]["vanishing_segments"] = {"x": [[1.0, 2.0, 30.5, 4.0], [1, 40, 30, 38]],
                                              "z": [[5, 40, 5, 2]]}
    doc["photos"][0]["marker_observations"] = {"A": [10.5, 20.25], "B": [30, 40]}
    doc["photos"][1]["marker_observations"] = {"A": [11, 21], "C": [50, 8]}
    doc["markers"] = [{"name": "A", "description": "floor corner"}, {"name": "B"},
                      {"name": "C", "position": [1.0, 2.0, 0.0]}]
    doc["origin_marker"] = "A"
    doc["reference_distances"] = [{"a": "A", "b": "B", "distance": 2.5, "role": "scale"},
                                  {"a": "A", "b": "C", "distance": 1.25, "sigma": 0.003, "role": "check"}]
    path = tmp_path / "room.vebuild.json"
    save_project(path, doc)
    return path


def rewrite(path: Path, edit) -> None:
    """Change the file behind vebuild's back (no validation), as a hand edit would."""
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data, indent=2))


def test_valid_project_loads(proj: Path) -> None:
    p = load_project(proj)
    assert p.folder == proj.parent
    assert p.marker_names() == ["A", "B", "C"]
    assert p.photo("window")["file"] == "photos/window.jpg"
    assert p.photo_path("window") == proj.parent / "photos" / "window.jpg"
    assert p.photo_path(p.photo("door")).is_file()
    assert p.settings == vp.DEFAULT_SETTINGS


def test_settings_merge_over_defaults(proj: Path) -> None:
    rewrite(proj, lambda d: d.__setitem__("settings", {"click_sigma_px": 0.5}))
    s = load_project(proj).settings
    assert s["click_sigma_px"] == 0.5
    assert s["exif_focal_sigma_rel"] == vp.DEFAULT_SETTINGS["exif_focal_sigma_rel"]


def test_unknown_photo_id(proj: Path) -> None:
    with pytest.raises(ProjectError, match=r"no photo has the id 'kitchen'.*'door', 'window'"):
        load_project(proj).photo("kitchen")


# ---- errors in the project file ------------------------------------------------------------------


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ProjectError, match="project file not found") as e:
        load_project(tmp_path / "nope.vebuild.json")
    assert e.value.file.endswith("nope.vebuild.json")


def test_malformed_json_reports_line_and_column(proj: Path) -> None:
    lines = proj.read_text().splitlines()
    lines[3] = lines[3] + ","  # a trailing comma after "name": a common hand-editing slip
    proj.write_text("\n".join(lines))
    with pytest.raises(ProjectError, match=r"not valid JSON: .* at line \d+, column \d+"):
        load_project(proj)


def test_duplicate_json_key(proj: Path) -> None:
    proj.write_text(proj.read_text().replace('"name": "test room",', '"name": "a",\n  "name": "b",'))
    with pytest.raises(ProjectError, match="the key 'name' appears twice"):
        load_project(proj)


def test_nan_is_not_json(proj: Path) -> None:
    proj.write_text(proj.read_text().replace('"distance": 2.5', '"distance": NaN'))
    with pytest.raises(ProjectError, match="NaN is not a JSON number"):
        load_project(proj)


def test_top_level_not_an_object(tmp_path: Path) -> None:
    (tmp_path / "p.json").write_text("[1, 2]")
    with pytest.raises(ProjectError, match=r"\$: expected a JSON object .* found a list of 2 items"):
        load_project(tmp_path / "p.json")


def test_wrong_format(proj: Path) -> None:
    rewrite(proj, lambda d: d.__setitem__("format", "blender-scene"))
    with pytest.raises(ProjectError, match=r'\$\.format: not a vebuild project file: expected "format": '
                                           r'"vebuild-project", found the text "blender-scene"'):
        load_project(proj)


def test_wrong_version_comes_before_schema_errors(proj: Path) -> None:
    def newer(d):
        d["version"] = 2
        d["photos"] = "stored elsewhere in version 2"  # a schema error that must not be reported
    rewrite(proj, newer)
    with pytest.raises(ProjectError, match=r"\$\.version: this file is format version 2, but this vebuild "
                                           r"\(.*\) reads format version 1 only; .*newer vebuild"):
        load_project(proj)


def test_version_must_be_a_whole_number(proj: Path) -> None:
    rewrite(proj, lambda d: d.__setitem__("version", "1"))
    with pytest.raises(ProjectError, match=r'\$\.version: expected the format version as a whole number.*'
                                           r'found the text "1"'):
        load_project(proj)


def test_schema_error_names_json_path(proj: Path) -> None:
    rewrite(proj, lambda d: d["photos"][0]["vanishing_segments"]["x"][1].pop())
    with pytest.raises(ProjectError, match=re.escape(
            "$.photos[0].vanishing_segments.x[1]: expected a directed segment [u1, v1, u2, v2] in pixels, or a "
            "polyline [u1, v1, u2, v2, ..., un, vn] of n ≥ 2 points along one straight edge, directed first to last "
            "with at least 4 items, found a list of 3 items")) as e:
        load_project(proj)
    assert e.value.where == "$.photos[0].vanishing_segments.x[1]"


def test_schema_error_wrong_type(proj: Path) -> None:
    rewrite(proj, lambda d: d["photos"][1].__setitem__("width", "64"))
    with pytest.raises(ProjectError, match=re.escape('$.photos[1].width: expected a whole number') +
                       '.*' + re.escape('found the text "64"')):
        load_project(proj)


def test_schema_error_misspelt_key(proj: Path) -> None:
    rewrite(proj, lambda d: d["photos"][1].__setitem__("widht", d["photos"][1].pop("width")))
    expected = "$.photos[1]: unexpected key 'widht'; did you mean 'width'?"
    with pytest.raises(ProjectError, match=re.escape(expected)):
        load_project(proj)


def test_schema_error_missing_key_and_bad_values(proj: Path) -> None:
    rewrite(proj, lambda d: d["reference_distances"][0].pop("role"))
    with pytest.raises(ProjectError, match=re.escape("$.reference_distances[0]: the key 'role' is required")):
        load_project(proj)
    rewrite(proj, lambda d: d["reference_distances"][0].update(role="Scale"))
    with pytest.raises(ProjectError, match=re.escape('$.reference_distances[0].role: expected "scale" or '
                                                     '"check", found the text "Scale"')):
        load_project(proj)
    rewrite(proj, lambda d: d["reference_distances"][0].update(role="scale", distance=0))
    with pytest.raises(ProjectError, match=re.escape("$.reference_distances[0].distance: expected a number "
                                                     "at least 0.0001 and at most 10000 (a length in metres")):
        load_project(proj)


def test_schema_error_bad_photo_id_and_hash(proj: Path) -> None:
    rewrite(proj, lambda d: d["photos"][1].update(id="front door"))
    with pytest.raises(ProjectError, match=re.escape("$.photos[1].id: expected a photo id made of letters")):
        load_project(proj)
    rewrite(proj, lambda d: d["photos"][1].update(id="window", sha256="ABC"))
    with pytest.raises(ProjectError, match=re.escape("$.photos[1].sha256: expected a SHA-256 hash")):
        load_project(proj)


def test_marker_observation_path_quotes_odd_names(proj: Path) -> None:
    rewrite(proj, lambda d: d["photos"][1]["marker_observations"].update({"door corner": [1, 2, 3]}))
    expected = ('$.photos[1].marker_observations["door corner"]: '
                "expected a pixel position [u, v] with exactly 2 items")
    with pytest.raises(ProjectError, match=re.escape(expected)):
        load_project(proj)


def test_duplicate_photo_id(proj: Path) -> None:
    rewrite(proj, lambda d: d["photos"][1].update(id="door"))
    with pytest.raises(ProjectError, match=re.escape("$.photos[1].id: the photo id 'door' is already used by "
                                                     "$.photos[0]; each photo id must be unique")):
        load_project(proj)


def test_duplicate_marker_name(proj: Path) -> None:
    rewrite(proj, lambda d: d["markers"].append({"name": "B"}))
    expected = "$.markers[3].name: the marker name 'B' is already used by $.markers[1]"
    with pytest.raises(ProjectError, match=re.escape(expected)):
        load_project(proj)


def test_observation_of_unknown_marker(proj: Path) -> None:
    rewrite(proj, lambda d: d["photos"][1]["marker_observations"].update(D=[3, 4]))
    expected = ("$.photos[1].marker_observations.D: names the marker 'D', but $.markers has no marker of "
                "that name (the markers are: 'A', 'B', 'C')")
    with pytest.raises(ProjectError, match=re.escape(expected)):
        load_project(proj)


def test_reference_distance_to_unknown_marker_or_itself(proj: Path) -> None:
    rewrite(proj, lambda d: d["reference_distances"][1].update(b="Z"))
    with pytest.raises(ProjectError, match=re.escape("$.reference_distances[1].b: names the marker 'Z'")):
        load_project(proj)
    rewrite(proj, lambda d: d["reference_distances"][1].update(b="A"))
    with pytest.raises(ProjectError, match=re.escape("$.reference_distances[1]: runs from the marker 'A' to "
                                                     "itself")):
        load_project(proj)


def test_unknown_origin_marker(proj: Path) -> None:
    rewrite(proj, lambda d: d.update(origin_marker="Q"))
    with pytest.raises(ProjectError, match=re.escape("$.origin_marker: names the marker 'Q'")):
        load_project(proj)


@pytest.mark.parametrize("bad", ["/home/me/door.jpg", "../door.jpg", "photos\\door.jpg", "C:/door.jpg"])
def test_photo_path_must_stay_in_project_folder(proj: Path, bad: str) -> None:
    rewrite(proj, lambda d: d["photos"][0].update(file=bad))
    with pytest.raises(ProjectError, match=re.escape("$.photos[0].file: expected a path inside the project "
                                                     "folder")):
        load_project(proj, verify_photos=False)


# ---- errors in the photos -----------------------------------------------------------------------


def test_missing_photo(proj: Path) -> None:
    (proj.parent / "photos" / "window.jpg").unlink()
    with pytest.raises(ProjectError, match=re.escape("$.photos[1].file: photo file not found: "
                                                     "'photos/window.jpg'")):
        load_project(proj)
    load_project(proj, verify_photos=False)  # marks can still be read without the photos


def test_changed_photo(proj: Path) -> None:
    image = proj.parent / "photos" / "door.jpg"
    expected = sha256_file(image)
    data = bytearray(image.read_bytes())
    data[-3] ^= 0x01  # one bit in the compressed data: the picture looks the same
    image.write_bytes(bytes(data))
    found = sha256_file(image)
    with pytest.raises(ProjectError, match=re.escape(
            f"$.photos[0].sha256: the photo 'photos/door.jpg' has changed since it was added to the project: "
            f"expected SHA-256 {expected[:12]}..., found {found[:12]}...; vebuild will not use a changed "
            "photo")):
        load_project(proj)


def test_wrong_pixel_size(proj: Path) -> None:
    rewrite(proj, lambda d: d["photos"][1].update(width=640, height=480))
    with pytest.raises(ProjectError, match=re.escape("$.photos[1].width: the photo 'photos/window.jpg' is "
                                                     "64×48 pixels, but the project says 640×480")):
        load_project(proj)


def test_photo_that_is_not_an_image(proj: Path) -> None:
    image = proj.parent / "photos" / "door.jpg"
    image.write_text("not a picture")
    rewrite(proj, lambda d: d["photos"][0].update(sha256=sha256_file(image)))
    with pytest.raises(ProjectError, match=r"\$\.photos\[0\]\.file: cannot open .* as an image"):
        load_project(proj)


# ---- saving -------------------------------------------------------------------------------------


def test_round_trip(proj: Path) -> None:
    p = load_project(proj)
    p.data["photos"][0]["focal_px"] = {"value": 1234.5678901234567, "sigma": 0.1}
    p.data["calibration"] = {"software": "vebuild 0.1.0", "input_sha256": canonical_input_hash(p.data),
                             "cameras": {"door": {"mode": "3vp", **camera_record(
                                 np.array([[1.0, 0, 2], [0, 1, 3], [0, 0, 1]]), np.eye(3), np.zeros(3),
                                 np.eye(9))}},
                             "extra_result": [1, 2]}
    save_project(p)
    again = load_project(proj)
    assert again.data == p.data
    assert list(again.data) == list(p.data)  # key order kept
    assert again.data["photos"][0]["focal_px"]["value"] == 1234.5678901234567  # floats exact


def test_saved_text_layout(proj: Path) -> None:
    text = proj.read_text(encoding="utf-8")
    assert text.endswith("}\n") and not text.endswith("\n\n")
    assert text.startswith('{\n  "format": "vebuild-project",\n  "version": 1,\n')


def _temp_files(folder: Path) -> list[Path]:
    return [f for f in folder.iterdir() if f.name.endswith(".tmp") or f.name.endswith(".vebuild-tmp")]


@pytest.mark.parametrize("target", ["json.dump", "os.replace", "os.fsync"])
def test_failed_save_leaves_old_file(proj: Path, monkeypatch: pytest.MonkeyPatch, target: str) -> None:
    before = proj.read_bytes()
    p = load_project(proj)
    p.data["name"] = "changed"

    def boom(*args, **kwargs):
        raise OSError(28, "No space left on device")

    module, name = target.split(".")
    monkeypatch.setattr({"json": json, "os": os}[module], name, boom)
    with pytest.raises(ProjectError, match=r"cannot write the project file \(No space left on device\); "
                                           "the file on disk is unchanged"):
        save_project(p)
    monkeypatch.undo()
    assert proj.read_bytes() == before
    assert _temp_files(proj.parent) == []


def test_save_refuses_invalid_document(proj: Path) -> None:
    before = proj.read_bytes()
    p = load_project(proj)
    p.data["photos"][0]["width"] = -1
    with pytest.raises(ProjectError, match=re.escape("$.photos[0].width: expected a number at least 1")):
        save_project(p)
    p.data["photos"][0]["width"] = W
    p.data["reference_distances"][0]["distance"] = math.nan
    with pytest.raises(ProjectError, match=re.escape("$.reference_distances[0].distance: expected a finite "
                                                     "number, found nan")):
        save_project(p)
    assert proj.read_bytes() == before
    assert _temp_files(proj.parent) == []


def test_failed_save_of_a_non_os_error_is_not_hidden(proj: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    before = proj.read_bytes()

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(json, "dump", interrupted)
    with pytest.raises(KeyboardInterrupt):
        save_project(load_project(proj))
    monkeypatch.undo()
    assert proj.read_bytes() == before
    assert _temp_files(proj.parent) == []


def test_save_into_missing_folder(tmp_path: Path) -> None:
    with pytest.raises(ProjectError, match="cannot write the project file"):
        save_project(tmp_path / "absent" / "p.vebuild.json", new_project("x"))


def test_save_keeps_file_mode(proj: Path) -> None:
    os.chmod(proj, 0o640)
    save_project(load_project(proj))
    assert proj.stat().st_mode & 0o777 == 0o640


def test_save_path_needs_data(tmp_path: Path) -> None:
    with pytest.raises(TypeError):
        save_project(tmp_path / "p.json")


def test_new_project_is_valid(tmp_path: Path) -> None:
    path = save_project(tmp_path / "empty.vebuild.json", new_project("empty"))
    p = load_project(path)
    assert isinstance(p, Project) and p.data["photos"] == [] and p.marker_names() == []


def test_canonical_input_hash_ignores_results(proj: Path) -> None:
    data = load_project(proj).data
    h = canonical_input_hash(data)
    assert re.fullmatch("[0-9a-f]{64}", h)
    assert canonical_input_hash({**data, "calibration": {"software": "x"}}) == h
    assert canonical_input_hash(dict(reversed(list(data.items())))) == h  # key order does not matter
    data["photos"][0]["marker_observations"]["A"][0] += 0.5
    assert canonical_input_hash(data) != h


# ---- photos and EXIF ----------------------------------------------------------------------------


def test_sha256_file_matches_hashlib(tmp_path: Path) -> None:
    import hashlib

    blob = os.urandom(3 * (1 << 20) + 17)  # more than one chunk, not a whole number of them
    (tmp_path / "b").write_bytes(blob)
    assert sha256_file(tmp_path / "b") == hashlib.sha256(blob).hexdigest()


def _exif(**tags) -> Image.Exif:
    exif = Image.Exif()
    exif[0x010F] = "Canon\x00"
    exif[0x0110] = "PowerShot G9"
    sub = exif.get_ifd(0x8769)
    for tag, value in tags.items():
        sub[int(tag[1:])] = value
    return exif


def test_read_exif_focal_plane(tmp_path: Path) -> None:
    # 4.2 mm lens, 1000 pixels per cm on the sensor: f = 4.2 mm × 100 px/mm = 420 px
    image = make_image(tmp_path / "a.jpg", exif=_exif(t37386=4.2, t41989=26, t41486=1000.0, t41488=3))
    exif = read_exif(image)
    assert exif == {"make": "Canon", "model": "PowerShot G9", "focal_length_mm": pytest.approx(4.2),
                    "focal_length_35mm": 26.0, "focal_plane_x_resolution_per_mm": pytest.approx(100.0),
                    "focal_length_px": pytest.approx(420.0)}
    assert all(isinstance(v, float) for k, v in exif.items() if k not in ("make", "model"))


@pytest.mark.parametrize(("unit", "per_mm"), [(2, 1000 / 25.4), (4, 1000.0), (None, 1000 / 25.4)])
def test_read_exif_resolution_units(tmp_path: Path, unit: int | None, per_mm: float) -> None:
    tags = {"t37386": 5.0, "t41486": 1000.0} | ({"t41488": unit} if unit else {})  # no unit: inches
    exif = read_exif(make_image(tmp_path / "a.jpg", exif=_exif(**tags)))
    assert exif["focal_plane_x_resolution_per_mm"] == pytest.approx(per_mm)
    assert exif["focal_length_px"] == pytest.approx(5.0 * per_mm)


def test_read_exif_35mm_equivalent(tmp_path: Path) -> None:
    exif = read_exif(make_image(tmp_path / "a.jpg", exif=_exif(t37386=4.2, t41989=28)))
    assert "focal_plane_x_resolution_per_mm" not in exif
    assert exif["focal_length_px"] == pytest.approx(28 * math.hypot(W, H) / math.hypot(36, 24))


def test_read_exif_zero_means_unknown(tmp_path: Path) -> None:
    exif = read_exif(make_image(tmp_path / "a.jpg", exif=_exif(t37386=0.0, t41989=0)))
    assert exif == {"make": "Canon", "model": "PowerShot G9"}


def test_read_exif_none(tmp_path: Path) -> None:
    assert read_exif(make_image(tmp_path / "a.png")) == {}


def test_new_photo_entry(tmp_path: Path) -> None:
    image = make_image(tmp_path / "shots" / "front door (1).jpg", exif=_exif(t37386=4.2, t41989=26))
    entry = new_photo_entry(tmp_path, image)
    assert list(entry) == ["id", "file", "width", "height", "sha256", "exif", "vanishing_segments",
                           "marker_observations"]
    assert entry["id"] == "front_door_1_"
    assert entry["file"] == "shots/front door (1).jpg"
    assert (entry["width"], entry["height"]) == (W, H)
    assert entry["sha256"] == sha256_file(image)
    assert entry["exif"]["focal_length_mm"] == pytest.approx(4.2)
    assert new_photo_entry(tmp_path, image, "front")["id"] == "front"
    with pytest.raises(ProjectError, match="expected a photo id made of letters"):
        new_photo_entry(tmp_path, image, "front door")


def test_new_photo_entry_without_exif_has_no_exif_key(tmp_path: Path) -> None:
    assert "exif" not in new_photo_entry(tmp_path, make_image(tmp_path / "p.png"))


def test_new_photo_entry_outside_project_folder(tmp_path: Path) -> None:
    image = make_image(tmp_path / "elsewhere" / "a.jpg")
    with pytest.raises(ProjectError, match="the photo lies outside the project folder"):
        new_photo_entry(tmp_path / "project", image)


def test_new_photo_entry_not_an_image(tmp_path: Path) -> None:
    (tmp_path / "notes.jpg").write_text("hello")
    with pytest.raises(ProjectError, match="cannot open .* as an image"):
        new_photo_entry(tmp_path, tmp_path / "notes.jpg")
    with pytest.raises(ProjectError, match="photo file not found"):
        new_photo_entry(tmp_path, tmp_path / "absent.jpg")


# --------------------------------------------------------------------------------------------------
# `vebuild check` refuses, with the file, the field and what was expected (exit status 2, no
# traceback), everything a later command would refuse or get wrong.

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"


@pytest.fixture
def room(tmp_path: Path) -> Path:
    """A copy of the example room (model and pins, not calibrated); returns its project file."""
    import shutil

    shutil.copytree(ROOM, tmp_path / "room")
    return tmp_path / "room" / "room.vebuild.json"


def check_refuses(path: Path, capsys: pytest.CaptureFixture, *parts: str, command: str = "check") -> str:
    """Run `vebuild COMMAND path`; assert status 2, one message naming the file and holding every part."""
    from vebuild.cli import main

    capsys.readouterr()
    assert main([command, str(path)]) == 2
    # A record written by hand is not known to be current: the command warns so before its error.
    lines = capsys.readouterr().err.splitlines(keepends=True)
    err = "".join(line for line in lines if not line.startswith("warning: "))
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert err.startswith(f"vebuild {command}: error: {path}: "), err
    for part in parts:
        assert part in err, f"{part!r} not in {err!r}"
    return err


def edit_text(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


def node(data: dict, name: str) -> dict:
    return next(n for n in data["model"]["nodes"] if n["name"] == name)


def test_example_project_checks(room: Path, capsys: pytest.CaptureFixture) -> None:
    from vebuild.cli import main

    assert main(["check", str(room)]) == 0
    out = capsys.readouterr().out
    assert "valid vebuild project" in out and "model: 17 node(s), 105 pin(s)" in out


def test_whole_number_of_5001_digits(proj: Path, capsys: pytest.CaptureFixture) -> None:
    edit_text(proj, f'"width": {W}', '"width": ' + "9" * 5001)
    check_refuses(proj, capsys, "$.photos[0].width: expected a number of at most 20 digits, found a whole number "
                  "of 5001 digits")


@pytest.mark.parametrize("depth", [40, 1200, 100_000])
def test_deep_nesting(proj: Path, capsys: pytest.CaptureFixture, depth: int) -> None:
    edit_text(proj, '"name": "test room"', '"name": ' + "[" * depth + "]" * depth)
    check_refuses(proj, capsys, "$.name", "nested more than 32 deep")


def test_deep_nesting_in_a_result_record(proj: Path, capsys: pytest.CaptureFixture) -> None:
    rewrite(proj, lambda d: d.update(calibration={"anything": json.loads("[" * 200 + "]" * 200)}))
    check_refuses(proj, capsys, "$.calibration.anything" + "[0]" * 30, "nested more than 32 deep")


def test_lone_surrogate_in_text_or_key(proj: Path, capsys: pytest.CaptureFixture) -> None:
    edit_text(proj, '"name": "test room"', '"name": "test \\ud800room"')
    for command in ("check", "calibrate"):  # calibrate once failed on saving its results
        check_refuses(proj, capsys, "$.name: expected text made of characters that can be written in UTF-8, found "
                      "the lone surrogate \\ud800", command=command)
    edit_text(proj, '"name": "test \\ud800room"', '"name": "test room"')
    edit_text(proj, '"description": "floor corner"', '"description": "floor corner", "\\udc80": 1')
    check_refuses(proj, capsys, "$.markers[0]: expected key made of characters", "\\udc80")


@pytest.mark.parametrize(("edit", "where", "expected"), [
    (lambda d: d["reference_distances"][0].update(distance=1e308), "$.reference_distances[0].distance",
     "at least 0.0001 and at most 10000 (a length in metres"),
    (lambda d: d["reference_distances"][1].update(sigma=1e-300), "$.reference_distances[1].sigma",
     "at least 1e-06 and at most 10000"),
    (lambda d: d["settings"].update(click_sigma_px=1e-300), "$.settings.click_sigma_px",
     "at least 0.001 and at most 1000 (a 1σ in pixels"),
    (lambda d: d["settings"].update(exif_focal_sigma_rel=2.0), "$.settings.exif_focal_sigma_rel",
     "at least 1e-06 and at most 1 (a relative 1σ"),
    (lambda d: d["settings"].update(principal_point_sigma_rel=1e-300), "$.settings.principal_point_sigma_rel",
     "at least 1e-06 and at most 1 (a relative 1σ"),
    (lambda d: d["photos"][0].update(focal_px={"value": 1e308, "sigma": 1.0}), "$.photos[0].focal_px.value",
     "at least 1 and at most 1e+07 (a focal length in pixels"),
    (lambda d: d["photos"][0].update(exif={"focal_length_px": 1e308}), "$.photos[0].exif.focal_length_px",
     "at most 1e+07"),
    (lambda d: d["markers"][2].update(position=[1e9, 0, 0]), "$.markers[2].position[0]",
     "at least -10000 and at most 10000 (a coordinate in metres within ±10 km"),
    (lambda d: d["photos"][0].update(principal_point={"value": [1e308, 3], "sigma": 1}),
     "$.photos[0].principal_point.value[0]", "at least -1e+06 and at most 1e+06"),
    (lambda d: d["photos"][0].update(principal_point={"value": [32, 1e5], "sigma": 1}),
     "$.photos[0].principal_point.value", f"within 4 image sizes of the {W}×{H} photo"),
    (lambda d: d["photos"][0]["marker_observations"].update(A=[1e9, 3]), "$.photos[0].marker_observations.A[0]",
     "at most 1e+06"),
    (lambda d: d["photos"][0]["marker_observations"].update(A=[-300, 3]), "$.photos[0].marker_observations.A",
     f"(u from {-4 * W} to {5 * W}), found u = -300"),
    (lambda d: d["photos"][0]["vanishing_segments"]["x"][1].__setitem__(3, 1e5), "$.photos[0].vanishing_segments.x[1]",
     "within 4 image sizes"),
    (lambda d: d["photos"][0].update(width=70000), "$.photos[0].width", "at most 65535"),
    (lambda d: d["photos"][0].update(width=60000, height=60000), "$.photos[0].width",
     "at most 120 megapixels (more than any camera takes), found 60000×60000"),
    (lambda d: d.update(views=[{"name": "v", "position": [0, 0, 1.6], "look_at": [1, 0, 1.6], "fov_deg": 1e-300,
                                "width": 64, "height": 48}]), "$.views[0].fov_deg", "at least 0.1 and at most 170"),
    (lambda d: d.update(views=[{"name": "v", "position": [0, 0, 1.6], "look_at": [1e308, 0, 1.6],
                                "width": 64, "height": 48}]), "$.views[0].look_at[0]", "at most 10000"),
    (lambda d: d.update(views=[{"name": "v", "position": [0, 0, 1.6], "direction": [1e-300, 0, 0],
                                "width": 64, "height": 48}]), "$.views[0].direction",
     "at least 1e-06 long"),
    (lambda d: d.update(views=[{"name": "v", "position": [0, 0, 1.6], "look_at": [1e-12, 0, 1.6],
                                "width": 64, "height": 48}]), "$.views[0].look_at",
     "a point away from the view's position"),
])
def test_values_outside_physical_sense(proj: Path, capsys: pytest.CaptureFixture, edit, where: str,
                                       expected: str) -> None:
    rewrite(proj, edit)
    check_refuses(proj, capsys, f"{where}: expected ", expected)


def _room_edit(room: Path, edit) -> None:
    rewrite(room, edit)


@pytest.mark.parametrize(("edit", "where", "expected"), [
    (lambda d: node(d, "box")["primitive"]["params"].update(width=1e308),
     "$.model.nodes[2].primitive.params.width", "at most 10000"),
    (lambda d: node(d, "box")["primitive"]["params"].update(width=-1),
     "$.model.nodes[2].primitive.params.width", "at least 0 and at most 10000"),
    (lambda d: node(d, "box")["joint"].update(position=[1e308, 0]), "$.model.nodes[2].joint.position[0]",
     "at most 10000"),
    (lambda d: node(d, "door")["joint"].update(axis=[0, 0, 0]), "$.model.nodes[9].joint.axis",
     "the axis of the hinge joint (a non-zero vector"),
    (lambda d: node(d, "door")["joint"].update(limits_deg=[150, 0]), "$.model.nodes[9].joint.limits_deg",
     "with lo no greater than hi, found [150°, 0°] (reversed?)"),
    (lambda d: node(d, "box").update(joint={"type": "slider", "axis": [1, 0, 0], "limits": [1, -1]}),
     "$.model.nodes[2].joint.limits", "found [1 m, -1 m]"),
    (lambda d: node(d, "box")["joint"].update(yaw_deg=1e308), "$.model.nodes[2].joint.yaw_deg",
     "within ±3600"),
    (lambda d: d["model"]["pins"][0].update(uv=[1e9, 0]), "$.model.pins[0].uv[0]", "at most 1e+06"),
    (lambda d: d["model"]["pins"][0].update(uv=[9000, 0]), "$.model.pins[0].uv",
     "within 4 image sizes of the 1600×1200 photo"),
    (lambda d: d["model"]["edge_observations"][0]["points"][1].__setitem__(1, -6000),
     "$.model.edge_observations[0].points[1]", "v from -4800 to 6000"),
])
def test_model_values_refused_at_load(room: Path, capsys: pytest.CaptureFixture, edit, where: str,
                                      expected: str) -> None:
    rewrite(room, edit)
    check_refuses(room, capsys, f"{where}: ", expected)
    check_refuses(room, capsys, f"{where}: ", expected, command="solve")


@pytest.mark.parametrize(("edit", "where", "expected"), [
    (lambda d: node(d, "table").update(parent="table.top"), "$.model.nodes[3].parent",
     "the scene graph has a cycle: table → table.top → table"),
    (lambda d: node(d, "box")["primitive"]["params"].pop("height"),
     "$.model.nodes[2].primitive.params", "box needs params width, depth, height; missing height"),
    (lambda d: node(d, "box")["primitive"]["params"].update(width=0),
     "$.model.nodes[2].primitive.params.width", "box: width must be > 0, got 0"),
    (lambda d: node(d, "box")["primitive"]["params"].update(width=0.0005),
     "$.model.nodes[2].primitive.params.width", "box: width must be at least 0.001 m"),
    (lambda d: node(d, "box")["primitive"]["params"].update(radius=1.0),
     "$.model.nodes[2].primitive.params", "box: unknown param 'radius'"),
    (lambda d: node(d, "table.top").update(parent="tabel"), "$.model.nodes[4].parent",
     "node 'table.top' is attached to parent 'tabel', which is not a node"),
    (lambda d: node(d, "box")["joint"].update(face="side"), "$.model.nodes[2].joint.face",
     "node 'box' rests on face 'side' of 'floor', which has faces: top"),
    (lambda d: d["model"]["pins"][0].update(handle="v9"), "$.model.pins[0].handle",
     "node 'floor' has no handle 'v9'; its handles are: v0, v1, v2, v3"),
    (lambda d: d["model"]["edge_observations"][0].update(edge="e9"), "$.model.edge_observations[0].edge",
     "node 'floor' has no edge 'e9'; its edges are: e0, e1, e2, e3"),
    (lambda d: node(d, "table.leg1").update(hold=["height", "hieght"]), "$.model.nodes[5].hold[1]",
     "'hieght' is not a parameter of this node (it has: width, depth, height)"),
    (lambda d: node(d, "floor")["joint"].update(marker="nowhere"), "$.model.nodes[0].joint.marker",
     "the joint ties the node to marker 'nowhere', which has no calibrated position"),
    (lambda d: node(d, "floor")["joint"].update(handle="v7"), "$.model.nodes[0].joint.handle",
     "handle 'v7' is not a handle of this node's primitive (its handles are: v0, v1, v2, v3)"),
    (lambda d: node(d, "door")["joint"].update(angle_deg=170), "$.model.nodes[9].joint.angle_deg",
     "hinge angle 170.0° lies outside its limits [0.0°, 150.0°]"),
])
def test_check_decodes_the_model_as_solve_does(room: Path, capsys: pytest.CaptureFixture, edit, where: str,
                                               expected: str) -> None:
    rewrite(room, edit)
    err = check_refuses(room, capsys, f"{where}: {expected}")
    # solve stops earlier (the example is not calibrated) or with the very same message.
    from vebuild.cli import main

    assert main(["solve", str(room)]) == 2
    solve_err = capsys.readouterr().err
    assert "Traceback" not in solve_err
    assert solve_err.split(": error: ", 1)[1] == err.split(": error: ", 1)[1] or "calibrat" in solve_err


def _calibrate_by_hand(d: dict) -> None:
    """A calibration record for every photo (not a calibration: cameras where the fields need them)."""
    from vebuild.project.records import camera_record

    K = np.array([[1350.0, 0, 800], [0, 1350, 600], [0, 0, 1]])
    cameras = {p["id"]: {"mode": "1vp", **camera_record(K, np.eye(3), np.array([0.0, -3, 1.5]), np.eye(9) * 1e-4)}
               for p in d["photos"]}
    d["calibration"] = {"software": "vebuild test", "cameras": cameras,
                        "markers": {m["name"]: {"position": [0.0, 0.0, 0.0], "sigma": [0.0, 0.0, 0.0]}
                                    for m in d["markers"]}}


def test_calibrated_example_checks(room: Path, capsys: pytest.CaptureFixture) -> None:
    from vebuild.cli import main

    rewrite(room, _calibrate_by_hand)
    assert main(["check", str(room)]) == 1  # valid, but a record written by hand is not known to be current
    out = capsys.readouterr().out
    assert "calibration: 6 camera(s)" in out and "not known to be current" in out


@pytest.mark.parametrize(("edit", "where", "expected"), [
    (lambda d: d["calibration"]["cameras"]["p2"].update(R=[[0, 0, 0]] * 3), "$.calibration.cameras.p2.R",
     "expected a rotation matrix"),
    (lambda d: d["calibration"]["cameras"]["p2"].update(R=[[2, 0, 0], [0, 1, 0], [0, 0, 1]]),
     "$.calibration.cameras.p2.R", "expected a rotation matrix"),
    (lambda d: d["calibration"]["cameras"]["p2"].update(K=[[0, 0, 800], [0, 0, 600], [0, 0, 1]]),
     "$.calibration.cameras.p2.K", "expected a focal length from 1 to 1e7 pixels"),
    (lambda d: d["calibration"]["cameras"]["p2"].update(K=[[1350, 0, 800], [0, 1350, 600], [0, 1, 1]]),
     "$.calibration.cameras.p2.K", "expected a pinhole matrix"),
    (lambda d: d["calibration"]["cameras"]["p2"]["position"].update(value=[0, 1e308, 0]),
     "$.calibration.cameras.p2.position.value[1]", "at most 10000"),
    (lambda d: d["calibration"]["cameras"]["p2"].pop("covariance"), "$.calibration.cameras.p2",
     "the key 'covariance' is required"),
    (lambda d: d["calibration"]["cameras"].update(p9=d["calibration"]["cameras"]["p1"]),
     "$.calibration.cameras.p9", "a camera for the photo 'p9', but $.photos has no photo of that id"),
])
def test_calibration_cameras_checked(room: Path, capsys: pytest.CaptureFixture, edit, where: str,
                                     expected: str) -> None:
    rewrite(room, _calibrate_by_hand)
    rewrite(room, edit)
    check_refuses(room, capsys, f"{where}: ", expected)
    check_refuses(room, capsys, f"{where}: ", expected, command="solve")


@pytest.mark.parametrize(("command", "expected"), [
    (["frobnicate", "x"], "invalid choice: 'frobnicate'"),
    (["distance", "cabinet:v4"], "the following arguments are required: b"),
    (["distance", "--help"], "the command asks for help ('--help'), which is not an analysis"),
    (["-h"], "the command asks for help ('-h')"),
    (["checks", "--hel"], "the command asks for help ('--hel')"),
])
def test_recorded_analyses_must_parse(room: Path, capsys: pytest.CaptureFixture, command, expected: str) -> None:
    rewrite(room, lambda d: d.update(analyses=[{"name": "ok", "command": ["distance", "cabinet:v4", "table.top@top"]},
                                               {"name": "bad", "command": command}]))
    check_refuses(room, capsys, "$.analyses[1].command: ", expected)


def test_more_lights_than_the_renderer_draws(room: Path, capsys: pytest.CaptureFixture) -> None:
    from vebuild.lighting import MAX_LIGHTS

    assert vp.schema()["$defs"]["lightingPreset"]["properties"]["lights"]["maxItems"] == MAX_LIGHTS
    lamp = {"type": "point", "position": [1.0, 1.0, 2.5]}
    rewrite(room, lambda d: d["lighting"]["presets"][0].update(lights=[lamp] * (MAX_LIGHTS + 1)))
    check_refuses(room, capsys, "$.lighting.presets[0].lights: expected a list of lights (the renderer draws at most "
                  f"{MAX_LIGHTS}) with at most {MAX_LIGHTS} items, found a list of {MAX_LIGHTS + 1} items")


def test_check_imports_no_gl() -> None:
    import subprocess
    import sys

    code = ("import sys\nfrom vebuild.project import load_project\nfrom vebuild.actions.check import check_project\n"
            f"check_project(load_project({str(ROOM / 'room.vebuild.json')!r}))\n"
            "assert 'moderngl' not in sys.modules, 'check imported moderngl'\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOM.parents[1])
    assert run.returncode == 0, run.stderr


def _solution(**top) -> dict:
    return {"software": "vebuild test", "recalibrated": False, "rms_px": 0.5, "variance_factor": 1.0,
            "iterations": 3, "nodes": {"box": {"joint": "rests_on", "dofs": {},
                                               "params": {"width": {"value": 0.7, "sigma": 0.01, "ci95": [0.68, 0.72]}},
                                               "handles": {}}},
            "covariance": {"parameters": ["box.width"], "matrix": [[1e-4]]}, **top}


@pytest.mark.parametrize(("solution", "where", "expected"), [
    (_solution(rms_px="0.5"), "$.model_solution.rms_px", "expected a number"),
    (_solution(variance_factor="high"), "$.model_solution.variance_factor", "expected a number or null"),
    (_solution(nodes={"box": {"params": {"width": {"value": "0.7", "sigma": 0.01}}}}),
     "$.model_solution.nodes.box.params.width.value", "expected a number"),
    (_solution(covariance={"parameters": ["box.width"], "matrix": [["1e-4"]]}),
     "$.model_solution.covariance.matrix[0][0]", "expected a number or null"),
])
def test_result_records_hold_numbers(room: Path, capsys: pytest.CaptureFixture, solution, where: str,
                                     expected: str) -> None:
    from vebuild.cli import main

    rewrite(room, lambda d: d.update(model_solution=_solution()))
    assert main(["check", str(room)]) == 1  # valid; a record written by hand is not known to be current
    rewrite(room, lambda d: d.update(model_solution=solution))
    check_refuses(room, capsys, f"{where}: {expected}")


# -- image files: decoded whole, bounded in pixels before decoding


def _png_header(width: int, height: int) -> bytes:
    """A PNG that declares a size and holds no pixels: what a decompression bomb's header says."""
    import struct
    import zlib

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"")) + chunk(b"IEND", b""))


def _truncate(path: Path) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def test_truncated_jpeg_refused_by_new_and_check(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from vebuild.cli import main

    image = tmp_path / "photos" / "door.jpg"
    Image.fromarray(np.random.default_rng(1).integers(0, 255, (480, 640, 3), dtype=np.uint8)).save(image.parent.mkdir()
                                                                                                   or image)
    good = image.read_bytes()
    _truncate(image)
    proj = tmp_path / "p.vebuild.json"
    assert main(["new", str(proj), str(image)]) == 2
    err = capsys.readouterr().err
    assert "cannot be decoded: it is damaged or truncated" in err and "Traceback" not in err and not proj.exists()
    image.write_bytes(good)
    assert main(["new", str(proj), str(image)]) == 0
    _truncate(image)
    rewrite(proj, lambda d: d["photos"][0].update(sha256=sha256_file(image)))
    check_refuses(proj, capsys, "$.photos[0].file: the image", "cannot be decoded: it is damaged or truncated")


@pytest.mark.parametrize(("size", "expected"), [
    ((11000, 11000), "is 11000×11000 = 121 megapixels, more than the 120 megapixels vebuild reads"),
    ((20000, 20000), "has more than 120 megapixels, more than vebuild reads"),
])
def test_huge_image_refused_before_decoding(tmp_path: Path, capsys: pytest.CaptureFixture, size,
                                            expected: str) -> None:
    from vebuild.cli import main

    image = tmp_path / "bomb.png"
    image.write_bytes(_png_header(*size))
    proj = tmp_path / "p.vebuild.json"
    assert main(["new", str(proj), str(image)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"vebuild new: error: {image}: the image {image} ") and expected in err, err
    assert "Traceback" not in err and not proj.exists()


# -- texture pages: confined to the project folder and bounded like photos


def _textured(proj: Path, atlas: str = "textures/atlas_0.png", size: tuple[int, int] = (16, 8),
              declared: tuple[int, int] | None = None) -> Path:
    page = proj.parent / "textures" / "atlas_0.png"
    page.parent.mkdir(exist_ok=True)
    Image.new("RGB", size, (10, 20, 30)).save(page)
    w, h = declared or size
    rewrite(proj, lambda d: d.update(textures={
        "software": "vebuild test", "input_hash": "0" * 64, "options": {}, "photos": [], "faces": [],
        "pages": [{"atlas": atlas, "coverage": "textures/coverage_0.png", "width": w, "height": h,
                   "atlas_sha256": sha256_file(page), "coverage_sha256": "0" * 64}]}))
    return page


def test_texture_pages_check(room: Path, capsys: pytest.CaptureFixture) -> None:
    from vebuild.cli import main

    _textured(room)
    assert main(["check", str(room)]) == 1  # valid; a record written by hand is not known to be current
    assert "textures: 1 of 1 atlas page(s) present, hashes verified" in capsys.readouterr().out


@pytest.mark.parametrize(("key", "bad"), [("atlas", "/etc/passwd"), ("atlas", "../../secret.png"),
                                          ("coverage", "textures/../../x.png"), ("atlas", "C:/x.png")])
def test_texture_page_paths_stay_in_the_project_folder(room: Path, capsys: pytest.CaptureFixture, key: str,
                                                       bad: str) -> None:
    _textured(room)
    rewrite(room, lambda d: d["textures"]["pages"][0].update({key: bad}))
    check_refuses(room, capsys, f"$.textures.pages[0].{key}: expected a path inside the project folder", repr(bad))


def test_texture_page_through_a_symlink_out_of_the_folder(room: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture) -> None:
    from vebuild.project.decode import texture_pages

    outside = tmp_path / "outside.png"
    Image.new("RGB", (16, 8)).save(outside)
    _textured(room, "textures/link.png")
    (room.parent / "textures" / "link.png").symlink_to(outside)
    check_refuses(room, capsys, "$.textures.pages[0].atlas: expected a file inside the project folder, found "
                  "'textures/link.png', which leads outside it through a symbolic link")
    with pytest.raises(ProjectError, match="leads outside it through a symbolic link"):
        texture_pages(load_project(room, verify_photos=False))  # what `vebuild export` and `render` read


def test_changed_texture_page_names_no_hash_of_its_bytes(room: Path, capsys: pytest.CaptureFixture) -> None:
    page = _textured(room)
    Image.new("RGB", (16, 8), (1, 2, 3)).save(page)
    err = check_refuses(room, capsys, "$.textures.pages[0].atlas_sha256: the atlas page 'textures/atlas_0.png' "
                        "changed since `vebuild texture` wrote it")
    assert sha256_file(page)[:8] not in err


@pytest.mark.parametrize(("declared", "expected"), [
    ((50000, 50000), "$.textures.pages[0].width: expected a number at least 1 and at most 16384"),
    ((16000, 16000), "$.textures.pages[0].width: expected an atlas page of at most 120 megapixels"),
    ((32, 8), "$.textures.pages[0]: expected the atlas page 'textures/atlas_0.png' to be 32×8 texels as recorded, "
              "found 16×8"),
])
def test_texture_page_sizes_bounded(room: Path, capsys: pytest.CaptureFixture, declared, expected: str) -> None:
    _textured(room, declared=declared)
    check_refuses(room, capsys, expected)


def test_texture_page_bomb(room: Path, capsys: pytest.CaptureFixture) -> None:
    page = _textured(room, declared=(10000, 10000))
    page.write_bytes(_png_header(20000, 20000))
    rewrite(room, lambda d: d["textures"]["pages"][0].update(atlas_sha256=sha256_file(page)))
    check_refuses(room, capsys, "$.textures.pages[0].atlas: the image 'textures/atlas_0.png' has more than 120 "
                  "megapixels")


@pytest.mark.parametrize(("face", "where", "expected"), [
    ({"page": 1}, "$.textures.faces[0].page", "names the atlas page 1, but $.textures.pages has 1 page(s)"),
    ({"rect": [10, 0, 8, 8]}, "$.textures.faces[0].rect", "expected a rectangle inside its 16×8 atlas page"),
    ({"average_colour_srgb": [300, 0, 0]}, "$.textures.faces[0].average_colour_srgb[0]",
     "expected a number at least 0 and at most 255"),
    ({"page": "0"}, "$.textures.faces[0].page", "expected a whole number"),
])
def test_texture_face_records_checked(room: Path, capsys: pytest.CaptureFixture, face, where: str,
                                      expected: str) -> None:
    from vebuild.cli import main

    good = {"id": 1, "node": "floor", "face": "top", "page": 0, "rect": [0, 0, 16, 8], "size_m": [6.1, 4.9],
            "average_colour_srgb": [120, 110, 100]}
    _textured(room)
    rewrite(room, lambda d: d["textures"].update(faces=[good]))
    assert main(["check", str(room)]) == 1  # valid; a record written by hand is not known to be current
    rewrite(room, lambda d: d["textures"].update(faces=[{**good, **face}]))
    check_refuses(room, capsys, f"{where}: {expected}")


def test_a_slider_without_limits_is_written_without_them(room: Path) -> None:
    from vebuild.model.scene import model_from_dict

    rewrite(room, lambda d: node(d, "box").update(joint={"type": "slider", "axis": [1, 0, 0]}))
    project = load_project(room, verify_photos=False)
    project.data["model"]["nodes"] = model_from_dict(project.data["model"]["nodes"],
                                                     {"O": np.zeros(3)}).to_dict()
    assert "limits" not in node(project.data, "box")["joint"]
    save_project(project)  # JSON has no infinity: unlimited is no "limits" key


def test_marker_positions_are_decoded_from_one_place() -> None:
    from vebuild.project.decode import known_points, marker_sigmas, markers

    data = {"markers": [{"name": "O", "position": [0, 0, 0]}, {"name": "T"}],
            "calibration": {"markers": {"O": {"position": [0, 0, 0], "sigma": [0, 0, 0]},
                                        "T": {"position": [1, 2, 0], "sigma": [0.01, None, 0.02]}}},
            "model_solution": {"nodes": {"box": {"handles": {"v0": {"value": [1, 1, 0]}}}}}}
    assert {n: p.tolist() for n, p in markers(data).items()} == {"O": [0, 0, 0], "T": [1, 2, 0]}
    assert {n: p.tolist() for n, p in markers(data, "surveyed").items()} == {"O": [0, 0, 0]}
    assert {n: p.tolist() for n, p in markers(data, "named").items()} == {"O": [0, 0, 0], "T": [0, 0, 0]}
    assert markers(data, "joints")["T"].tolist() == [1, 2, 0]  # calibrated: where the calibration put it
    uncalibrated = {"markers": data["markers"]}
    assert markers(uncalibrated) == {} and list(markers(uncalibrated, "joints")) == ["O", "T"]
    sigma = marker_sigmas(data)["T"]
    assert sigma[[0, 2]].tolist() == [0.01, 0.02] and sigma[1] == np.finfo(float).max  # undetermined: the largest
    assert known_points(data)["box:v0"].tolist() == [1, 1, 0]


def test_a_photos_camera_is_the_one_decoded_camera(room: Path) -> None:
    """render/export/analyse take a photo's camera from the same decoder as solve and texture: the
    same K, R, C, size and covariance; only its source (for size errors) names the photo."""
    from vebuild.project.decode import cameras_from_calibration, photo_camera

    rewrite(room, _calibrate_by_hand)
    project = load_project(room, verify_photos=False)
    decoded = cameras_from_calibration(project)
    second = project.data["photos"][1]["id"]
    for name in (second, "2"):  # by id, or by its 1-based position
        cam = photo_camera(project, name)
        ref = decoded[second]
        assert cam.id == second and (cam.width, cam.height) == (ref.width, ref.height)
        assert np.array_equal(cam.K, ref.K) and np.array_equal(cam.R, ref.R) and np.array_equal(cam.C, ref.C)
        assert cam.covariance is not None and np.allclose(cam.covariance, np.eye(9) * 1e-4)
        assert cam.source == f"$.photos[1] (photo {second!r}: width × height)"
    with pytest.raises(ProjectError, match=r"\$\.photos: no photo has the id 'nope'"):
        photo_camera(project, "nope")
