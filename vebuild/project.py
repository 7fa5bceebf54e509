"""The project file: load, validate, save; photo hashes and EXIF (layer 3, project I/O).

The format is specified in ``scenes/FORMAT.md`` and, for machines, in the JSON Schema shipped as
``vebuild/schema/project-v1.schema.json``. Every problem with the file or a photo it names is a
:class:`~vebuild.errors.ProjectError` that says where (JSON path), what was expected and what was
found, in words meant for the person who made the project rather than for a programmer.
"""

from __future__ import annotations

import contextlib
import difflib
import hashlib
import json
import math
import os
import re
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path, PurePosixPath
from typing import Any

import jsonschema
from PIL import Image, UnidentifiedImageError

from . import __version__
from .errors import ProjectError

FORMAT = "vebuild-project"
VERSION = 1
#: Values of ``settings`` that a project does not give (FORMAT.md, "settings").
DEFAULT_SETTINGS: dict[str, float] = {
    "click_sigma_px": 1.0,
    "principal_point_sigma_rel": 0.01,
    "exif_focal_sigma_rel": 0.01,
}
#: Top-level keys written by vebuild's stages; they are not input, so the input hash skips them.
RESULT_KEYS = ("calibration", "model_solution", "textures")

#: The deepest nesting of lists and objects a project file may have. The deepest the format uses is 7
#: (``model_solution.nodes.N.handles.H.value``); the bound keeps every reader far from Python's
#: recursion limit, which a hand-made file nested 1000 deep would otherwise hit.
MAX_DEPTH = 32
#: The most digits a whole number in a project file may have: the largest the format holds is a
#: 64-bit count (20 digits); Python refuses to read more than 4300 digits, and any bound of the
#: format is far below 10^20.
MAX_INT_DIGITS = 20
#: The most pixels an image vebuild reads may have: 120 megapixels, more than the largest camera
#: sensor in use (100 MP) and below Pillow's decompression-bomb guard (179 MP). Larger images are
#: refused before they are decoded.
MAX_IMAGE_PIXELS = 120_000_000
#: How far outside its photo a pixel position may lie, in image sizes: a mark is placed on the
#: photo, a vanishing segment or a principal point a little beyond its edge at most.
PIXEL_MARGIN = 4
#: The shortest direction or axis vector accepted: any length gives the same direction, but the
#: components of a shorter one lose it to rounding.
MIN_DIRECTION_LENGTH = 1e-6

_CHUNK = 1 << 20
_ID_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]+")
_HASH_SHOWN = 12  # hex digits of a hash quoted in a message: enough to tell two apart


@dataclass
class Project:
    """A loaded project file.

    Attributes
    ----------
    path : the project file.
    data : the JSON document, as plain dicts and lists.
    """

    path: Path
    data: dict[str, Any]

    @property
    def folder(self) -> Path:
        """The folder that photo paths are relative to."""
        return self.path.parent

    @property
    def settings(self) -> dict[str, float]:
        """``settings`` merged over :data:`DEFAULT_SETTINGS`."""
        return {**DEFAULT_SETTINGS, **self.data.get("settings", {})}

    def photo(self, photo_id: str) -> dict[str, Any]:
        """The photo object with this id; ProjectError if there is none."""
        for photo in self.data["photos"]:
            if photo["id"] == photo_id:
                return photo
        known = _listing(p["id"] for p in self.data["photos"])
        raise ProjectError(self.path, "$.photos",
                           f"no photo has the id {photo_id!r} (the photos are: {known})")

    def photo_path(self, photo_or_id: dict[str, Any] | str) -> Path:
        """Where a photo's image file is: its ``file`` taken relative to :attr:`folder`."""
        photo = self.photo(photo_or_id) if isinstance(photo_or_id, str) else photo_or_id
        return self.folder.joinpath(*PurePosixPath(photo["file"]).parts)

    def marker_names(self) -> list[str]:
        """The marker names, in file order."""
        return [m["name"] for m in self.data["markers"]]


# --------------------------------------------------------------------------------------------------
# Load and save


def load_project(path: str | os.PathLike[str], *, verify_photos: bool = True) -> Project:
    """Read and validate a project file.

    Parameters
    ----------
    path : the project file.
    verify_photos : also check that every photo exists, is unchanged (SHA-256) and has the
        recorded pixel size.

    Raises
    ------
    ProjectError : the file is missing, not JSON, of another format or version, does not match the
        schema, is inconsistent (duplicate or unknown names), or a photo is missing or changed.
    """
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise ProjectError(path, "", "project file not found") from None
    except UnicodeDecodeError as e:
        raise ProjectError(path, "", f"not a text file in UTF-8 (byte {e.start} cannot be read)") from None
    except OSError as e:
        raise ProjectError(path, "", f"cannot read the project file: {e.strerror}") from None
    try:
        data = json.loads(text, object_pairs_hook=_unique_keys, parse_constant=_reject_constant,
                          parse_int=_parse_int)
    except _JsonFault as fault:
        raise _located(path, text, fault) from None
    except json.JSONDecodeError as e:
        where = f"line {e.lineno}, column {e.colno}"
        raise ProjectError(path, "", f"not valid JSON: {e.msg} at {where}") from None
    except RecursionError:
        where, line, col = _too_deep(text)
        raise ProjectError(path, where, f"lists and objects are nested more than {MAX_DEPTH} deep (at line {line}, "
                           f"column {col}); a vebuild project nests at most 7 deep") from None
    validate(data, path)
    project = Project(path, data)
    if verify_photos:
        for i, photo in enumerate(data["photos"]):
            _verify_photo(project, i, photo)
    return project


def save_project(project_or_path: Project | str | os.PathLike[str],
                 data: dict[str, Any] | None = None, *, validated: bool = False) -> Path:
    """Validate a document and write it atomically.

    Parameters
    ----------
    project_or_path : a Project (its path, and its data unless ``data`` is given) or a file path.
    data : the document to write; required when a path is given.
    validated : the caller has just validated this very document (the modelling screen, which
        validates every edit before autosaving it): not validated twice.

    Returns
    -------
    The path written. Nothing is written if the document is invalid; if writing fails for any
    reason the old file is left as it was and no temporary file remains.

    Raises
    ------
    ProjectError : the document is invalid, or the file system refused the write.
    """
    if isinstance(project_or_path, Project):
        path = project_or_path.path
        data = project_or_path.data if data is None else data
    else:
        path = Path(project_or_path)
        if data is None:
            raise TypeError("save_project(path, data): data is required when a path is given")
    if not validated:
        validate(data, path)

    import io

    from .atomic import write_with  # beside the target, fsync'ed, renamed over it (vebuild/atomic.py)

    def write(f: Any) -> None:
        text = io.TextIOWrapper(f, encoding="utf-8", newline="\n")
        json.dump(data, text, indent=2, ensure_ascii=False, allow_nan=False)
        text.write("\n")
        text.flush()
        text.detach()

    try:
        write_with(path, write)
    except OSError as e:
        raise ProjectError(path, "", f"cannot write the project file ({e.strerror or e}); "
                           "the file on disk is unchanged") from e
    return path


def new_project(name: str) -> dict[str, Any]:
    """An empty, valid project document with the default settings written out."""
    return {
        "format": FORMAT,
        "version": VERSION,
        "name": name,
        "settings": dict(DEFAULT_SETTINGS),
        "photos": [],
        "markers": [],
        "reference_distances": [],
    }


def canonical_input_hash(data: dict[str, Any]) -> str:
    """SHA-256 (hex) of the document without its results: the provenance of what a stage read."""
    inputs = {k: v for k, v in data.items() if k not in RESULT_KEYS}
    text = json.dumps(inputs, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


# --------------------------------------------------------------------------------------------------
# Validation


@cache
def schema() -> dict[str, Any]:
    """The JSON Schema of format version 1."""
    text = resources.files("vebuild.schema").joinpath("project-v1.schema.json").read_text("utf-8")
    return json.loads(text)


@cache
def _validator() -> jsonschema.Draft202012Validator:
    return jsonschema.Draft202012Validator(schema())


def validate(data: Any, file: str | os.PathLike[str]) -> None:
    """Check a document against format version 1; ProjectError naming ``file`` if it does not match.

    Checked in order: that it is a vebuild project of version 1 (so that a file of another version
    gets that message rather than a list of schema differences), the schema, then what a schema
    cannot say (unique names, names that refer to something, finite numbers, relative paths).
    """
    _check_format_version(data, file)
    _check_values(data, file)
    errors = list(_validator().iter_errors(data))
    if errors:
        raise _schema_error(errors, file)
    _check_semantics(data, file)


def _check_format_version(data: Any, file: Any) -> None:
    if not isinstance(data, dict):
        raise ProjectError(file, "$", f"expected a JSON object {{...}} at the top, found {_describe(data)}")
    if data.get("format") != FORMAT:
        found = _describe(data["format"]) if "format" in data else "no \"format\" key"
        raise ProjectError(file, "$.format", f"not a vebuild project file: expected \"format\": "
                           f"\"{FORMAT}\", found {found}")
    version = data.get("version")
    if "version" not in data:
        raise ProjectError(file, "$.version",
                           f"no \"version\" key; this vebuild reads format version {VERSION}")
    if type(version) is not int:
        raise ProjectError(file, "$.version", f"expected the format version as a whole number (this vebuild "
                           f"reads version {VERSION}), found {_describe(version)}")
    if version != VERSION:
        hint = "; it was written by a newer vebuild: upgrade vebuild to open it" if version > VERSION else ""
        raise ProjectError(file, "$.version", f"this file is format version {version}, but this vebuild "
                           f"({__version__}) reads format version {VERSION} only{hint}")


def _check_semantics(data: dict[str, Any], file: Any) -> None:
    def unique(items: list[dict[str, Any]], key: str, where: str, what: str) -> None:
        first: dict[str, int] = {}
        for i, item in enumerate(items):
            if item[key] in first:
                raise ProjectError(file, f"{where}[{i}].{key}",
                                   f"the {what} {item[key]!r} is already used by "
                                   f"{where}[{first[item[key]]}]; each {what} must be unique")
            first[item[key]] = i

    def known_marker(name: str, where: str) -> None:
        if name not in markers:
            raise ProjectError(file, where, f"names the marker {name!r}, but $.markers has no marker of that "
                               f"name (the markers are: {_listing(markers)})")

    markers = [m["name"] for m in data["markers"]]
    unique(data["photos"], "id", "$.photos", "photo id")
    unique(data["markers"], "name", "$.markers", "marker name")
    sizes = {}
    for i, photo in enumerate(data["photos"]):
        where = f"$.photos[{i}]"
        _check_relative_path(photo["file"], file, f"{where}.file")
        _check_pixel_count(photo["width"], photo["height"], file, f"{where}.width", "a photo")
        sizes[photo["id"]] = size = (photo["width"], photo["height"])
        for name, uv in photo.get("marker_observations", {}).items():
            known_marker(name, f"{where}.marker_observations{_key(name)}")
            _check_on_photo(uv, size, file, f"{where}.marker_observations{_key(name)}")
        for axis, segments in (photo.get("vanishing_segments") or {}).items():
            for k, seg in enumerate(segments):
                _check_on_photo(seg[:2], size, file, f"{where}.vanishing_segments.{axis}[{k}]")
                _check_on_photo(seg[2:], size, file, f"{where}.vanishing_segments.{axis}[{k}]")
                _check_segment_length(seg, file, f"{where}.vanishing_segments.{axis}[{k}]", photo["id"], axis, k)
        if "principal_point" in photo:
            _check_on_photo(photo["principal_point"]["value"], size, file, f"{where}.principal_point.value")
    model = data.get("model") or {}
    nodes = [n["name"] for n in model.get("nodes", [])]
    photo_ids = [p["id"] for p in data["photos"]]

    def known_point(name: str, where: str) -> None:
        # A reference distance may end on a marker or on a model handle written 'node:handle'.
        if ":" in name:
            node = name.split(":", 1)[0]
            if node not in nodes:
                raise ProjectError(file, where, f"names the handle {name!r} of node {node!r}, but $.model.nodes has "
                                   f"no node of that name (the nodes are: {_listing(nodes)})")
        else:
            known_marker(name, where)

    for i, ref in enumerate(data["reference_distances"]):
        known_point(ref["a"], f"$.reference_distances[{i}].a")
        known_point(ref["b"], f"$.reference_distances[{i}].b")
        if ref["a"] == ref["b"]:
            raise ProjectError(file, f"$.reference_distances[{i}]",
                               f"runs from the marker {ref['a']!r} to itself; expected two different markers")
    if "origin_marker" in data:
        known_marker(data["origin_marker"], "$.origin_marker")
    unique(model.get("nodes", []), "name", "$.model.nodes", "node name")
    for key in ("pins", "edge_observations"):
        for i, obs in enumerate(model.get(key, [])):
            if obs["photo"] not in photo_ids:
                raise ProjectError(file, f"$.model.{key}[{i}].photo", f"names the photo {obs['photo']!r}, but "
                                   f"$.photos has no photo of that id (the photos are: {_listing(photo_ids)})")
            if obs["node"] not in nodes:
                raise ProjectError(file, f"$.model.{key}[{i}].node", f"names the node {obs['node']!r}, but "
                                   f"$.model.nodes has no node of that name (the nodes are: {_listing(nodes)})")
            for k, uv in enumerate([obs["uv"]] if key == "pins" else obs["points"]):
                _check_on_photo(uv, sizes[obs["photo"]], file,
                                f"$.model.{key}[{i}].uv" if key == "pins" else f"$.model.{key}[{i}].points[{k}]")
    for i, node in enumerate(model.get("nodes", [])):
        _check_joint(node["joint"], file, f"$.model.nodes[{i}].joint")
    for i, hyp in enumerate(data.get("hypotheses", [])):
        for name, joint in hyp["joints"].items():
            _check_joint(joint, file, f"$.hypotheses[{i}].joints{_key(name)}")
    cameras = (data.get("calibration") or {}).get("cameras") or {}
    for pid in cameras:
        if pid not in sizes:
            raise ProjectError(file, f"$.calibration.cameras{_key(pid)}", f"a camera for the photo {pid!r}, but "
                               f"$.photos has no photo of that id (the photos are: {_listing(photo_ids)}); run "
                               "`vebuild calibrate` again, or add the photo back")
    for k, page in enumerate((data.get("textures") or {}).get("pages", [])):
        for key in ("atlas", "coverage"):
            _check_relative_path(page[key], file, f"$.textures.pages[{k}].{key}")
        _check_pixel_count(page["width"], page["height"], file, f"$.textures.pages[{k}].width", "an atlas page")
    pages = (data.get("textures") or {}).get("pages", [])
    for k, face in enumerate((data.get("textures") or {}).get("faces", [])):
        where = f"$.textures.faces[{k}]"
        if face["page"] >= len(pages):
            raise ProjectError(file, f"{where}.page", f"names the atlas page {face['page']}, but $.textures.pages has "
                               f"{len(pages)} page(s) (numbered from 0); run `vebuild texture` again")
        x0, y0, w, h = face["rect"]
        page = pages[face["page"]]
        if x0 + w > page["width"] or y0 + h > page["height"]:
            raise ProjectError(file, f"{where}.rect", f"expected a rectangle inside its {page['width']}×"
                               f"{page['height']} atlas page, found [{x0}, {y0}, {w}, {h}]; run `vebuild texture` "
                               "again")
    views = data.get("views", [])
    unique(views, "name", "$.views", "view name")
    for i, view in enumerate(views):
        _check_view(view, file, f"$.views[{i}]")
    presets = (data.get("lighting") or {}).get("presets", [])
    unique(presets, "name", "$.lighting.presets", "lighting preset name")
    for i, preset in enumerate(presets):
        where = f"$.lighting.presets[{i}]"
        if preset["name"] == AS_PHOTOGRAPHED:
            raise ProjectError(file, f"{where}.name", f"{AS_PHOTOGRAPHED!r} is the built-in preset (the photos' "
                               "own light, unlit textures); choose another name")
        for j, light in enumerate(preset.get("lights", [])):
            _check_light(light, file, f"{where}.lights[{j}]")
    evidence = data.get("evidence_markers", [])
    unique(evidence, "label", "$.evidence_markers", "evidence marker label")
    for i, m in enumerate(evidence):
        if m["node"] not in nodes:
            raise ProjectError(file, f"$.evidence_markers[{i}].node", f"names the node {m['node']!r}, but "
                               f"$.model.nodes has no node of that name (the nodes are: {_listing(nodes)})")
    hypotheses = data.get("hypotheses", [])
    unique(hypotheses, "name", "$.hypotheses", "hypothesis name")
    types = {n["name"]: n["joint"]["type"] for n in model.get("nodes", [])}
    for i, hyp in enumerate(hypotheses):
        for name, joint in hyp["joints"].items():
            where = f"$.hypotheses[{i}].joints{_key(name)}"
            if name not in types:
                raise ProjectError(file, where, f"names the node {name!r}, but $.model.nodes has no node of that "
                                   f"name (the nodes are: {_listing(nodes)})")
            if joint["type"] != types[name]:
                raise ProjectError(file, f"{where}.type", f"expected the node's own joint type "
                                   f"{types[name]!r} (a hypothesis moves objects, it does not re-attach them), "
                                   f"found {joint['type']!r}")


#: The built-in lighting preset: the extracted textures shown as photographed, without lighting.
AS_PHOTOGRAPHED = "as-photographed"


def _nonzero(vector: list[float], file: Any, where: str, what: str) -> None:
    length = math.hypot(*vector)
    if not length >= MIN_DIRECTION_LENGTH:
        found = "[0, 0, 0]" if not any(vector) else f"a vector {length:.3g} long"
        raise ProjectError(file, where, f"expected {what} (a non-zero vector [x, y, z], at least "
                           f"{MIN_DIRECTION_LENGTH:g} long: a shorter one loses its direction to rounding), "
                           f"found {found}")


def _check_joint(joint: dict[str, Any], file: Any, where: str) -> None:
    # What the solver, the renderer and the viewer would otherwise meet as a division by zero or
    # an empty range: a hinge or slider needs an axis, and limits [lo, hi] with lo <= hi.
    if "axis" in joint:
        _nonzero(joint["axis"], file, f"{where}.axis", f"the axis of the {joint['type']} joint")
    for key, unit in (("limits_deg", "°"), ("limits", " m")):
        if key in joint and joint[key][0] > joint[key][1]:
            lo, hi = joint[key]
            raise ProjectError(file, f"{where}.{key}", f"expected limits [lo, hi] with lo no greater than hi, found "
                               f"[{lo}{unit}, {hi}{unit}] (reversed?)")


def _check_segment_length(seg: list[float], file: Any, where: str, photo: str, axis: str, k: int) -> None:
    # The same refusal as calibrate's (vanishing.check_segments), at load, so that check reports it.
    from .calibration.vanishing import MIN_SEGMENT_LENGTH_PX
    length = math.hypot(seg[2] - seg[0], seg[3] - seg[1])
    if length < MIN_SEGMENT_LENGTH_PX:
        raise ProjectError(file, where, f"photo {photo!r}: axis {axis}, segment {k}: its end points are "
                           f"{length:.2f} px apart; expected a segment at least {MIN_SEGMENT_LENGTH_PX:g} px "
                           "long along an edge")


def _check_pixel_count(width: int, height: int, file: Any, where: str, what: str) -> None:
    if width * height > MAX_IMAGE_PIXELS:
        raise ProjectError(file, where, f"expected {what} of at most {MAX_IMAGE_PIXELS / 1e6:g} megapixels (more "
                           f"than any camera takes), found {width}×{height} = {width * height / 1e6:.4g} megapixels")


def _check_on_photo(uv: list[float], size: tuple[int, int], file: Any, where: str) -> None:
    # A mark is made on its photo: a position several image sizes outside it is a typing error (and
    # would outweigh every other observation in a solve).
    for value, side, axis in zip(uv, size, "uv", strict=True):
        if not -PIXEL_MARGIN * side <= value <= (1 + PIXEL_MARGIN) * side:
            raise ProjectError(file, where, f"expected a pixel position within {PIXEL_MARGIN} image sizes of the "
                               f"{size[0]}×{size[1]} photo ({axis} from {-PIXEL_MARGIN * side} to "
                               f"{(1 + PIXEL_MARGIN) * side}), found {axis} = {value!r}")


def _check_view(view: dict[str, Any], file: Any, where: str) -> None:
    aims = [k for k in ("look_at", "direction") if k in view]
    if len(aims) != 1:
        found = "both" if aims else "neither"
        raise ProjectError(file, where, f"expected exactly one of \"look_at\" (a point to look at) or \"direction\" "
                           f"(a look direction), found {found}")
    if "look_at" in view and view["look_at"] == view["position"]:
        raise ProjectError(file, f"{where}.look_at", "expected a point other than the view's position, found the "
                           "position itself")
    if "look_at" in view:
        _nonzero([a - b for a, b in zip(view["look_at"], view["position"], strict=True)], file, f"{where}.look_at",
                 "a point away from the view's position (the look direction look_at − position)")
    if "direction" in view:
        _nonzero(view["direction"], file, f"{where}.direction", "a look direction")
    if "fov_deg" in view and "focal_length_mm" in view:
        raise ProjectError(file, where, "expected at most one of \"fov_deg\" (horizontal field of view) or "
                           "\"focal_length_mm\" (35 mm-equivalent focal length), found both")


def _check_light(light: dict[str, Any], file: Any, where: str) -> None:
    needs = {"directional": ("direction",), "point": ("position",), "spot": ("position", "direction")}[light["type"]]
    for key in needs:
        if key not in light:
            raise ProjectError(file, where, f"a {light['type']} light needs \"{key}\" [x, y, z], which is missing")
    if "direction" in light:
        _nonzero(light["direction"], file, f"{where}.direction", "the direction the light shines in")
    inner, outer = light.get("inner_cone_deg"), light.get("outer_cone_deg")
    if inner is not None and outer is not None and inner > outer:
        raise ProjectError(file, f"{where}.inner_cone_deg", f"expected the inner cone ({inner}°) to be no wider than "
                           f"the outer cone ({outer}°)")


def _check_relative_path(file_field: str, file: Any, where: str) -> None:
    # Photos live in the project folder so that the two move together; an absolute path, a
    # Windows separator or '..' would tie the project to one machine's folders.
    p = PurePosixPath(file_field)
    if "\\" in file_field or p.is_absolute() or ".." in p.parts or re.match(r"^[A-Za-z]:", file_field):
        raise ProjectError(file, where, "expected a path inside the project folder, relative to it and with "
                           f"forward slashes (such as \"photos/door.jpg\"), found {file_field!r}")


class _LongInteger(str):
    """The digits of a whole number too long to be one of the format's (see MAX_INT_DIGITS)."""


def _parse_int(digits: str) -> int | _LongInteger:
    # Keep the digits of a huge number as they are, so that _check_values reports it with its path
    # (int() of more than 4300 digits raises ValueError, and is quadratic in the digits).
    if len(digits.lstrip("-")) > MAX_INT_DIGITS:
        return _LongInteger(digits)
    return int(digits)


def _check_values(data: Any, file: Any) -> None:
    """What every value must be, whatever its place: nested at most MAX_DEPTH deep, a number finite
    and of at most MAX_INT_DIGITS digits, text (and keys) writable as UTF-8. Iterative, so that no
    document can exhaust the stack."""
    stack: list[tuple[Any, tuple[Any, ...], int]] = [(data, (), 1)]
    while stack:
        value, parts, depth = stack.pop()
        if isinstance(value, _LongInteger):
            raise ProjectError(file, json_path(parts), f"expected a number of at most {MAX_INT_DIGITS} digits, found "
                               f"a whole number of {len(value.lstrip('-'))} digits")
        if isinstance(value, str):
            _check_text(value, file, parts)
        elif isinstance(value, float) and not math.isfinite(value):
            # JSON has no NaN or infinity; 1e999 reads as infinity, and a NaN slips through every numeric test.
            raise ProjectError(file, json_path(parts), f"expected a finite number, found {value!r}")
        elif isinstance(value, dict | list):
            if depth > MAX_DEPTH:
                raise ProjectError(file, json_path(parts), f"lists and objects are nested more than {MAX_DEPTH} deep "
                                   "here; a vebuild project nests at most 7 deep")
            if isinstance(value, dict):
                for k, v in value.items():
                    if isinstance(k, str):
                        _check_text(k, file, parts, key=True)
                    stack.append((v, (*parts, k), depth + 1))
            else:
                stack.extend((v, (*parts, i), depth + 1) for i, v in enumerate(value))


def _check_text(text: str, file: Any, parts: tuple[Any, ...], key: bool = False) -> None:
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as e:
        # json reads "\ud800" as a lone surrogate: half of a UTF-16 pair, not a character, so it cannot
        # be saved (UTF-8) or shown; refuse it here rather than when a command saves its results.
        what = "key" if key else "text"
        raise ProjectError(file, json_path(parts), f"expected {what} made of characters that can be written in "
                           f"UTF-8, found the lone surrogate \\u{ord(text[e.start]):04x} (half of a UTF-16 pair) "
                           f"at character {e.start + 1} of {_ascii_describe(text)}") from None


def _ascii_describe(text: str) -> str:
    shown = text if len(text) <= 40 else text[:37] + "..."
    return json.dumps(shown)


def _too_deep(text: str) -> tuple[str, int, int]:
    """Where a JSON text first nests deeper than MAX_DEPTH: (JSON path, line, column)."""
    stack: list[list[Any]] = []  # per open container: [key or index]
    last_string: str | None = None
    for m in re.finditer(r'"(?:[^"\\]|\\.)*"|[\[\]{},:]', text):
        tok = m.group()
        if tok[0] == '"':
            last_string = tok
        elif tok in "[{":
            if len(stack) >= MAX_DEPTH:
                line = text.count("\n", 0, m.start()) + 1
                col = m.start() - text.rfind("\n", 0, m.start())
                return json_path([e[0] for e in stack if e[0] is not None]), line, col
            stack.append([0 if tok == "[" else None, tok])
        elif tok in "]}":
            if stack:
                stack.pop()
        elif tok == "," and stack and stack[-1][1] == "[":
            stack[-1][0] += 1
        elif tok == ":" and stack and last_string is not None:
            with contextlib.suppress(ValueError):
                stack[-1][0] = json.loads(last_string)
    return "", 1, 1


def _schema_error(errors: list[jsonschema.ValidationError], file: Any) -> ProjectError:
    # Report one error: the shallowest (the most is wrong there), and at one level an unexpected
    # key before a missing one, since that is usually the same key misspelt.
    error = min(errors, key=lambda e: (len(e.absolute_path), e.validator != "additionalProperties"))
    return ProjectError(file, json_path(error.absolute_path), _explain(error))


def _explain(error: jsonschema.ValidationError) -> str:
    """What a schema error means, in plain words: expected ..., found ...."""
    v, arg, inst, sch = error.validator, error.validator_value, error.instance, error.schema
    found = _describe(inst)
    about = f" ({sch['description']})" if isinstance(sch, dict) and "description" in sch else ""
    if v == "required":
        missing = [k for k in arg if k not in inst]
        return f"the key {missing[0]!r} is required but missing"
    if v == "additionalProperties":
        allowed = list(sch.get("properties", {}))
        extra = [k for k in inst if k not in allowed]
        close = difflib.get_close_matches(extra[0], allowed, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else f"; the allowed keys are: {', '.join(allowed)}"
        return f"unexpected key {extra[0]!r}{hint}"
    if v == "type":
        types = [arg] if isinstance(arg, str) else arg
        return f"expected {' or '.join(_TYPE_WORDS[t] for t in types)}{about}, found {found}"
    if v in ("minItems", "maxItems"):
        lo, hi = sch.get("minItems"), sch.get("maxItems")
        count = f"exactly {lo}" if lo == hi else f"at least {lo}" if v == "minItems" else f"at most {hi}"
        return f"expected {sch.get('description', 'a list')} with {count} items, found {found}"
    if v in ("minimum", "exclusiveMinimum", "maximum", "exclusiveMaximum"):
        words = {"minimum": "at least", "exclusiveMinimum": "greater than", "maximum": "at most",
                 "exclusiveMaximum": "less than"}
        bounds = [f"{w} {_number(sch[k])}" for k, w in words.items() if isinstance(sch, dict) and k in sch]
        return f"expected a number {' and '.join(bounds)}{about}, found {found}"
    if v in ("const", "enum"):
        values = [arg] if v == "const" else arg
        expected = sch.get("description") or " or ".join(json.dumps(x) for x in values)
        return f"expected {expected}, found {found}"
    if v in ("pattern", "minLength"):
        return f"expected {sch.get('description', 'different text')}, found {found}"
    return error.message  # keywords this schema does not use


def _number(x: float) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


_TYPE_WORDS = {
    "number": "a number", "integer": "a whole number", "string": "text in quotes", "array": "a list [...]",
    "object": "an object {...}", "boolean": "true or false", "null": "null",
}


def _describe(value: Any) -> str:
    """A short description of a JSON value for messages."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, int | float):
        return f"the number {value!r}"
    if isinstance(value, str):
        shown = value if len(value) <= 40 else value[:37] + "..."
        return f"the text {json.dumps(shown, ensure_ascii=False)}"
    if isinstance(value, list):
        return f"a list of {len(value)} item{'s' if len(value) != 1 else ''}"
    if isinstance(value, dict):
        return "an object {...}"
    return f"a {type(value).__name__}"


def json_path(parts: Any) -> str:
    """A JSON path such as ``$.photos[2].vanishing_segments.x[0]`` from path components."""
    return "$" + "".join(f"[{p}]" if isinstance(p, int) else _key(p) for p in parts)


def _key(name: str) -> str:
    if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
        return f".{name}"
    return f"[{json.dumps(name, ensure_ascii=False)}]"


def _listing(names: Any, limit: int = 10) -> str:
    names = list(names)
    if not names:
        return "none"
    shown = ", ".join(repr(n) for n in names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


class _JsonFault(Exception):
    """Raised from the JSON decoder's hooks (which know no position); located afterwards by _locate."""

    def __init__(self, kind: str, name: str) -> None:
        super().__init__(kind, name)
        self.kind = kind   # "duplicate" (a key seen twice in one object) or "constant" (NaN, Infinity)
        self.name = name


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    # json.loads would silently keep the last of two equal keys: a hand edit lost without a word.
    out: dict[str, Any] = {}
    for k, v in pairs:
        if k in out:
            raise _JsonFault("duplicate", k)
        out[k] = v
    return out


def _reject_constant(name: str) -> None:
    raise _JsonFault("constant", name)


def _located(file: Path, text: str, fault: _JsonFault) -> ProjectError:
    """The error for a fault the decoder's hooks found, with its JSON path, line and column."""
    found = _locate(text, fault)
    where, at = "", ""
    if found is not None:
        parts, offset = found
        where = json_path(parts)
        line = text.count("\n", 0, offset) + 1
        at = f" (line {line}, column {offset - text.rfind(chr(10), 0, offset)})"
    if fault.kind == "duplicate":
        return ProjectError(file, where, f"the key {fault.name!r} appears twice in one object{at}; keep only one")
    return ProjectError(file, where, f"not valid JSON: {fault.name} is not a JSON number{at}; "
                                     "expected a finite number")


_JSON_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{},:]|[^\s\[\]{},:"]+')


def _locate(text: str, fault: _JsonFault) -> tuple[list[Any], int] | None:
    """Where in ``text`` (a JSON text that only the hooks refused) the fault first occurs.

    Returns the JSON path of the value (a duplicate key: the second occurrence's own path) and the
    character offset of the offending token, or None if the scan does not find it.
    """
    # One entry per open container: [is_object, current key or index, keys seen, expecting a key].
    stack: list[list[Any]] = []
    for m in _JSON_TOKEN.finditer(text):
        tok = m.group()
        top = stack[-1] if stack else None
        if tok in ("{", "["):
            stack.append([tok == "{", None if tok == "{" else 0, set(), tok == "{"])
        elif tok in ("}", "]"):
            if stack:
                stack.pop()
        elif tok == ",":
            if top is not None:
                if top[0]:
                    top[3] = True
                else:
                    top[1] += 1
        elif tok == ":":
            if top is not None:
                top[3] = False
        elif top is not None and top[0] and top[3] and tok[0] == '"':
            try:
                key = json.loads(tok)
            except ValueError:
                continue
            top[1] = key
            if fault.kind == "duplicate" and key == fault.name and key in top[2]:
                return [e[1] for e in stack], m.start()
            top[2].add(key)
        elif fault.kind == "constant" and tok == fault.name:
            return [e[1] for e in stack], m.start()
    return None


# --------------------------------------------------------------------------------------------------
# Photos


def _verify_photo(project: Project, i: int, photo: dict[str, Any]) -> None:
    where = f"$.photos[{i}]"
    image = project.photo_path(photo)
    if not image.is_file():
        raise ProjectError(project.path, f"{where}.file", f"photo file not found: {photo['file']!r} "
                           f"(looked for {image})")
    found = sha256_file(image)
    if found != photo["sha256"]:
        raise ProjectError(project.path, f"{where}.sha256",
                           f"the photo {photo['file']!r} has changed since it was added to the project: "
                           f"expected SHA-256 {photo['sha256'][:_HASH_SHOWN]}..., found "
                           f"{found[:_HASH_SHOWN]}...; vebuild will not use a changed photo, since the marks "
                           "made on it may no longer fit. Restore the original file, or add the photo again")
    size = _image_size(image, project.path, f"{where}.file")
    if size != (photo["width"], photo["height"]):
        raise ProjectError(project.path, f"{where}.width",
                           f"the photo {photo['file']!r} is {size[0]}×{size[1]} pixels, "
                           f"but the project says {photo['width']}×{photo['height']}")


def _image_size(image: Path, file: Any, where: str) -> tuple[int, int]:
    # The whole image is decoded, so that a truncated or damaged file is refused now rather than
    # when a later stage reads its pixels.
    if not image.is_file():
        raise ProjectError(file, where, f"photo file not found: {image}")
    with open_image(image, file, where, decode=True) as img:
        return img.size


@contextlib.contextmanager
def open_image(image: Path | Any, file: Any, where: str, decode: bool = True,
               max_pixels: int = MAX_IMAGE_PIXELS, label: str | None = None) -> Iterator[Image.Image]:
    """An image opened with Pillow, its size bounded before its pixels are decoded (``decode``:
    decoded whole here, so that a damaged file is refused with a clear message).

    Raises
    ------
    ProjectError naming ``file`` and ``where`` (the JSON path of the field that names the image):
    the image is missing, not an image, damaged or truncated, or larger than ``max_pixels``.
    """
    shown = label or str(image)
    try:
        with warnings.catch_warnings():
            # Pillow warns above 89 MP and refuses above 179 MP; the bound here is checked below.
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            img = Image.open(image)
    except FileNotFoundError:
        raise ProjectError(file, where, f"image file not found: {shown}") from None
    except Image.DecompressionBombError:
        raise ProjectError(file, where, f"the image {shown} has more than {max_pixels / 1e6:g} megapixels, more "
                           "than vebuild reads (a larger one is refused before it is decoded)") from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as e:
        raise ProjectError(file, where, f"cannot open {shown} as an image: {e}") from None
    with img:
        w, h = img.size
        if w * h > max_pixels:
            raise ProjectError(file, where, f"the image {shown} is {w}×{h} = {w * h / 1e6:.4g} megapixels, more than "
                               f"the {max_pixels / 1e6:g} megapixels vebuild reads (refused before decoding it)")
        if decode:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", Image.DecompressionBombWarning)
                    img.load()
            except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as e:
                raise ProjectError(file, where, f"the image {shown} cannot be decoded: it is damaged or truncated "
                                   f"({e})") from None
        yield img


# --------------------------------------------------------------------------------------------------
# Texture pages (FORMAT.md, "Results: textures"): every reader goes through these.


def texture_page_path(project: Project, k: int, key: str = "atlas") -> Path:
    """Where page ``k``'s atlas (``key`` "atlas") or coverage map ("coverage") is.

    The path is confined as a photo's is: relative, inside the project folder, and still inside it
    once symbolic links are resolved, so that no project makes vebuild read or copy another file.
    """
    rel = project.data["textures"]["pages"][k][key]
    where = f"$.textures.pages[{k}].{key}"
    _check_relative_path(rel, project.path, where)
    path = project.folder.joinpath(*PurePosixPath(rel).parts)
    try:
        inside = path.resolve().is_relative_to(project.folder.resolve())
    except (OSError, RuntimeError):  # a loop of symbolic links
        inside = False
    if not inside:
        raise ProjectError(project.path, where, f"expected a file inside the project folder, found {rel!r}, which "
                           "leads outside it through a symbolic link")
    return path


def read_texture_page(project: Project, k: int) -> tuple[Path, bytes, str]:
    """Page ``k``'s atlas: its path, bytes and SHA-256, checked against the recorded hash."""
    page = project.data["textures"]["pages"][k]
    path = texture_page_path(project, k)
    try:
        data = path.read_bytes()
    except OSError as e:
        raise ProjectError(project.path, f"$.textures.pages[{k}].atlas",
                           f"cannot read the atlas page {page['atlas']!r}: {e.strerror or e}") from None
    digest = sha256_bytes(data)
    if digest != page["atlas_sha256"]:
        raise ProjectError(project.path, f"$.textures.pages[{k}].atlas_sha256",
                           f"the atlas page {page['atlas']!r} changed since `vebuild texture` wrote it (its bytes no "
                           f"longer hash to the recorded SHA-256 {page['atlas_sha256'][:_HASH_SHOWN]}…); run "
                           "`vebuild texture` again")
    return path, data, digest


def decode_texture_page(project: Project, k: int, data: bytes) -> Any:
    """The pixels of page ``k``'s atlas (its bytes, from :func:`read_texture_page`) as an
    (h, w, 3) uint8 array; its real size must be the recorded one, checked before decoding."""
    import io

    import numpy as np

    page = project.data["textures"]["pages"][k]
    where = f"$.textures.pages[{k}].atlas"
    with open_image(io.BytesIO(data), project.path, where, decode=False, label=repr(page["atlas"])) as im:
        if im.size != (page["width"], page["height"]):
            raise ProjectError(project.path, f"$.textures.pages[{k}]", f"expected the atlas page {page['atlas']!r} "
                               f"to be {page['width']}×{page['height']} texels as recorded, found "
                               f"{im.size[0]}×{im.size[1]}")
        try:
            return np.asarray(im.convert("RGB"))
        except (OSError, ValueError, SyntaxError) as e:
            raise ProjectError(project.path, where, f"the atlas page {page['atlas']!r} cannot be decoded: it is "
                               f"damaged or truncated ({e})") from None


def sha256_bytes(data: bytes) -> str:
    """SHA-256 (lowercase hex) of bytes already in memory."""
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | os.PathLike[str]) -> str:
    """SHA-256 (lowercase hex) of a file's bytes, read in 1 MiB chunks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


# EXIF tags (EXIF 2.3): Make and Model in IFD0; the rest in the Exif IFD.
_MAKE, _MODEL, _EXIF_IFD = 0x010F, 0x0110, 0x8769
_FOCAL_LENGTH, _FOCAL_35MM, _FOCAL_PLANE_XRES, _FOCAL_PLANE_UNIT = 37386, 41989, 41486, 41488
#: FocalPlaneResolutionUnit → millimetres per unit (2 inch, the default, 3 cm, 4 mm, 5 µm).
_MM_PER_UNIT = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}


def read_exif(path: str | os.PathLike[str]) -> dict[str, Any]:
    """What the camera recorded about a photo's focal length.

    Returns
    -------
    dict with the keys of FORMAT.md's ``exif`` object that the file gives (``{}`` for none):
    make, model, focal_length_mm, focal_length_35mm, focal_plane_x_resolution_per_mm, and the
    derived focal_length_px, preferably f_mm × resolution, else from the 35 mm equivalent over the
    image diagonal. The focal-plane resolution is taken to refer to the image as stored.
    """
    with Image.open(path) as img:
        width, height = img.size
        try:
            exif = img.getexif()
            sub = exif.get_ifd(_EXIF_IFD)
        except Exception:  # noqa: BLE001 -- EXIF is advisory: a damaged block must not stop the photo
            return {}
    out: dict[str, Any] = {}
    for key, tag in (("make", _MAKE), ("model", _MODEL)):
        if text := _text(exif.get(tag)):
            out[key] = text
    # EXIF writes 0 for "unknown"; only positive values are kept.
    if (f_mm := _positive(sub.get(_FOCAL_LENGTH))) is not None:
        out["focal_length_mm"] = f_mm
    if (f_35 := _positive(sub.get(_FOCAL_35MM))) is not None:
        out["focal_length_35mm"] = f_35
    res = _positive(sub.get(_FOCAL_PLANE_XRES))
    mm_per_unit = _MM_PER_UNIT.get(sub.get(_FOCAL_PLANE_UNIT, 2))
    if res is not None and mm_per_unit is not None:
        out["focal_plane_x_resolution_per_mm"] = res / mm_per_unit
    if f_mm is not None and "focal_plane_x_resolution_per_mm" in out:
        out["focal_length_px"] = f_mm * out["focal_plane_x_resolution_per_mm"]
    elif f_35 is not None:
        # The 35 mm equivalent matches the diagonals of the image and of a 36 × 24 mm frame.
        out["focal_length_px"] = f_35 * math.hypot(width, height) / math.hypot(36.0, 24.0)
    return out


def _positive(value: Any) -> float | None:
    try:
        x = float(value)  # IFDRational and int alike; a 0/0 rational gives nan
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return x if math.isfinite(x) and x > 0 else None


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    return value.strip("\x00 ") if isinstance(value, str) else ""


def new_photo_entry(project_folder: str | os.PathLike[str], image_path: str | os.PathLike[str],
                    photo_id: str | None = None) -> dict[str, Any]:
    """A photo object for an image inside the project folder, with no marks yet.

    Parameters
    ----------
    project_folder : the folder of the project file.
    image_path : the image (relative paths are taken from the current directory).
    photo_id : default the file's stem, with characters other than ``[A-Za-z0-9_.-]`` made ``_``.

    Raises
    ------
    ProjectError : the image lies outside the project folder or cannot be opened as an image.
    """
    # abspath, not resolve: a symbolic link inside the project folder stays inside it.
    folder = Path(os.path.abspath(project_folder))
    image = Path(os.path.abspath(image_path))
    if not image.is_relative_to(folder):
        raise ProjectError(image, "", f"the photo lies outside the project folder {folder}; copy it into "
                           "that folder (or a folder inside it) so that the project and its photos move "
                           "together")
    if photo_id is None:
        photo_id = _ID_UNSAFE.sub("_", image.stem) or "photo"
    elif not re.fullmatch(r"[A-Za-z0-9_.-]+", photo_id):
        raise ProjectError(image, "", f"expected a photo id made of letters, digits, '_', '.' and '-' only, "
                           f"found {photo_id!r}")
    width, height = _image_size(image, image, "")
    entry: dict[str, Any] = {
        "id": photo_id,
        "file": image.relative_to(folder).as_posix(),
        "width": width,
        "height": height,
        "sha256": sha256_file(image),
    }
    if exif := read_exif(image):
        entry["exif"] = exif
    entry["vanishing_segments"] = {}
    entry["marker_observations"] = {}
    return entry

