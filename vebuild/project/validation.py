"""Validation of the project document (layer 3): the schema, the physical bounds, what a schema
cannot say (unique names, references, finite numbers, relative paths), and reading the JSON text
with its faults located (duplicate keys, NaN, huge numbers, deep nesting), each a
:class:`~vebuild.errors.ProjectError` naming the file, the JSON path and what was expected.

The format is specified in ``scenes/FORMAT.md`` ("Bounds" states each bound and its reason).
"""

from __future__ import annotations

import contextlib
import difflib
import json
import math
import os
import re
from pathlib import Path, PurePosixPath
from typing import TYPE_CHECKING, Any

from vebuild import __version__
from vebuild.errors import ProjectError
from vebuild.lighting import AS_PHOTOGRAPHED

from .camera_groups import check_camera_groups
from .images import MAX_IMAGE_PIXELS
from .json_paths import field_words, json_key, json_path, listing
from .schema_match import new_items, schema_errors

if TYPE_CHECKING:
    import jsonschema

FORMAT = "vebuild-project"
VERSION = 1
#: The deepest nesting of lists and objects a project file may have. The deepest the format uses is 7
#: (``model_solution.nodes.N.handles.H.value``); the bound keeps every reader far from Python's
#: recursion limit, which a hand-made file nested 1000 deep would otherwise hit.
MAX_DEPTH = 32
#: The most digits a whole number in a project file may have: the largest the format holds is a
#: 64-bit count (20 digits); Python refuses to read more than 4300 digits, and any bound of the
#: format is far below 10^20.
MAX_INT_DIGITS = 20
#: How far outside its photo a pixel position may lie, in image sizes: a mark is placed on the
#: photo, a vanishing segment or a principal point a little beyond its edge at most.
PIXEL_MARGIN = 4
#: The shortest direction or axis vector accepted: any length gives the same direction, but the
#: components of a shorter one lose it to rounding.
MIN_DIRECTION_LENGTH = 1e-6
_HASH_SHOWN = 12  # hex digits of a hash quoted in a message: enough to tell two apart


# --------------------------------------------------------------------------------------------------
# Validation


def validate(data: Any, file: str | os.PathLike[str], valid_before: Any = None) -> None:
    """Check a document against format version 1; ProjectError naming ``file`` if it does not match.

    Checked in order: that it is a vebuild project of version 1 (so that a file of another version
    gets that message rather than a list of schema differences), the schema, then what a schema
    cannot say (unique names, names that refer to something, finite numbers, relative paths).
    ``valid_before``, a document that passed this check (the one before an edit), spares the schema
    check and the values' check the items of :data:`.schema_match.ITEM_LISTS` found in its same
    list; all else is checked as without it.
    """
    try:
        _check_format_version(data, file)
        cut = None if valid_before is None else new_items(data, valid_before)
        if cut is None:
            _check_values(data, file)
        else:
            _check_values(cut[0], file, cut[1])
        errors = schema_errors(data, valid_before, cut)
        if errors:
            raise _schema_error(errors, file)
        _check_semantics(data, file)
    except ProjectError as e:
        raise e.named(field_words(e.where, data)) from None


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
                               f"name (the markers are: {listing(markers)})")

    markers = [m["name"] for m in data["markers"]]
    unique(data["photos"], "id", "$.photos", "photo id")
    unique(data["markers"], "name", "$.markers", "marker name")
    sizes = {}
    for i, photo in enumerate(data["photos"]):
        where = f"$.photos[{i}]"
        check_relative_path(photo["file"], file, f"{where}.file")
        _check_pixel_count(photo["width"], photo["height"], file, f"{where}.width", "a photo")
        sizes[photo["id"]] = size = (photo["width"], photo["height"])
        for name, uv in photo.get("marker_observations", {}).items():
            known_marker(name, f"{where}.marker_observations{json_key(name)}")
            _check_on_photo(uv, size, file, f"{where}.marker_observations{json_key(name)}")
        for axis, segments in (photo.get("vanishing_segments") or {}).items():
            for k, seg in enumerate(segments):
                here = f"{where}.vanishing_segments.{axis}[{k}]"
                if len(seg) % 2:
                    raise ProjectError(file, here, f"expected a segment or polyline of (u, v) points [u1, v1, u2, "
                                       f"v2, ...]: an even count of numbers, found {len(seg)}")
                for j in range(0, len(seg), 2):  # every point of a polyline is on the photo
                    _check_on_photo(seg[j:j + 2], size, file, here)
                # The length is that of its end points: a polyline's middle points may bunch.
                _check_segment_length([*seg[:2], *seg[-2:]], file, here, photo["id"], axis, k)
        for axis, sigmas in (photo.get("vanishing_segment_sigmas") or {}).items():
            n_seg = len((photo.get("vanishing_segments") or {}).get(axis) or [])
            if len(sigmas) != n_seg:
                raise ProjectError(file, f"{where}.vanishing_segment_sigmas.{axis}",
                                   f"expected one 1σ (or null) per segment of vanishing_segments.{axis} "
                                   f"({n_seg}), found {len(sigmas)}")
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
                                   f"no node of that name (the nodes are: {listing(nodes)})")
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
    for i, kl in enumerate(data.get("known_lengths", [])):
        where = f"$.known_lengths[{i}]"
        if kl["photo"] not in sizes:
            raise ProjectError(file, f"{where}.photo", f"names the photo {kl['photo']!r}, but $.photos has no photo of "
                               f"that id (the photos are: {listing(list(sizes))})")
        for k, uv in enumerate(kl["ends"]):
            _check_on_photo(uv, sizes[kl["photo"]], file, f"{where}.ends[{k}]")
        from vebuild.calibration.vanishing import MIN_SEGMENT_LENGTH_PX
        (u1, v1), (u2, v2) = kl["ends"]
        if math.hypot(u2 - u1, v2 - v1) < MIN_SEGMENT_LENGTH_PX:
            raise ProjectError(file, f"{where}.ends", f"photo {kl['photo']!r}: the known length's two ends are "
                               f"{math.hypot(u2 - u1, v2 - v1):.2f} px apart; expected its two ends clicked at least "
                               f"{MIN_SEGMENT_LENGTH_PX:g} px apart, one at each end of the length")
    unique(model.get("nodes", []), "name", "$.model.nodes", "node name")
    for key in ("pins", "edge_observations"):
        for i, obs in enumerate(model.get(key, [])):
            if obs["photo"] not in photo_ids:
                raise ProjectError(file, f"$.model.{key}[{i}].photo", f"names the photo {obs['photo']!r}, but "
                                   f"$.photos has no photo of that id (the photos are: {listing(photo_ids)})")
            if obs["node"] not in nodes:
                raise ProjectError(file, f"$.model.{key}[{i}].node", f"names the node {obs['node']!r}, but "
                                   f"$.model.nodes has no node of that name (the nodes are: {listing(nodes)})")
            for k, uv in enumerate([obs["uv"]] if key == "pins" else obs["points"]):
                _check_on_photo(uv, sizes[obs["photo"]], file,
                                f"$.model.{key}[{i}].uv" if key == "pins" else f"$.model.{key}[{i}].points[{k}]")
    for i, node in enumerate(model.get("nodes", [])):
        _check_joint(node["joint"], file, f"$.model.nodes[{i}].joint")
    for i, hyp in enumerate(data.get("hypotheses", [])):
        for name, joint in hyp["joints"].items():
            _check_joint(joint, file, f"$.hypotheses[{i}].joints{json_key(name)}")
    check_camera_groups(data, file)
    cameras = (data.get("calibration") or {}).get("cameras") or {}
    for pid in cameras:
        if pid not in sizes:
            raise ProjectError(file, f"$.calibration.cameras{json_key(pid)}", f"a camera for the photo {pid!r}, but "
                               f"$.photos has no photo of that id (the photos are: {listing(photo_ids)}); run "
                               "`vebuild calibrate` again, or add the photo back")
    for k, page in enumerate((data.get("textures") or {}).get("pages", [])):
        for key in ("atlas", "coverage"):
            check_relative_path(page[key], file, f"$.textures.pages[{k}].{key}")
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
                               f"$.model.nodes has no node of that name (the nodes are: {listing(nodes)})")
    hypotheses = data.get("hypotheses", [])
    unique(hypotheses, "name", "$.hypotheses", "hypothesis name")
    types = {n["name"]: n["joint"]["type"] for n in model.get("nodes", [])}
    for i, hyp in enumerate(hypotheses):
        for name, joint in hyp["joints"].items():
            where = f"$.hypotheses[{i}].joints{json_key(name)}"
            if name not in types:
                raise ProjectError(file, where, f"names the node {name!r}, but $.model.nodes has no node of that "
                                   f"name (the nodes are: {listing(nodes)})")
            if joint["type"] != types[name]:
                raise ProjectError(file, f"{where}.type", f"expected the node's own joint type "
                                   f"{types[name]!r} (a hypothesis moves objects, it does not re-attach them), "
                                   f"found {joint['type']!r}")


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
    from vebuild.calibration.vanishing import MIN_SEGMENT_LENGTH_PX
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


def check_relative_path(file_field: str, file: Any, where: str) -> None:
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


def _check_values(data: Any, file: Any, where: dict[tuple[str, ...], list[int]] | None = None) -> None:
    """What every value must be, whatever its place: nested at most MAX_DEPTH deep, a number finite
    and of at most MAX_INT_DIGITS digits, text (and keys) writable as UTF-8. Iterative, so that no
    document can exhaust the stack. ``where``: for a list of ``data`` cut to some of a document's
    items (:func:`.schema_match.new_items`), the document's index of each, named in errors."""
    where = where or {}
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
                index = where.get(parts) if where else None
                stack.extend((v, (*parts, i if index is None else index[i]), depth + 1) for i, v in enumerate(value))


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


def parse_document(text: str, path: Path) -> Any:
    """The JSON document of a project file's text, every fault located: duplicate keys, NaN or
    Infinity, whole numbers too long, nesting too deep, or JSON that does not parse."""
    try:
        return json.loads(text, object_pairs_hook=_unique_keys, parse_constant=_reject_constant,
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
