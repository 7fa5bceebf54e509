"""Project file I/O: every error a user can make gets a message naming where and what."""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

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
            "$.photos[0].vanishing_segments.x[1]: expected a directed segment [u1, v1, u2, v2] in pixels "
            "with exactly 4 items, found a list of 3 items")) as e:
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
                                                     "greater than 0, found the number 0")):
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
                             "cameras": {"door": {"mode": "3vp", "K": [[1, 0, 2], [0, 1, 3], [0, 0, 1]]}},
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


@pytest.mark.parametrize(("unit", "per_mm"), [(2, 1000 / 25.4), (4, 1000.0), (5, 1e6), (None, 1000 / 25.4)])
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
