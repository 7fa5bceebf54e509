"""The project file: load, validate, save; photos verified, texture pages read (layer 3, project I/O).

Validation (the schema, the bounds, the JSON text's faults) is in :mod:`vebuild.project.validation`; opening,
hashing and reading the EXIF of image files in :mod:`vebuild.project.images`.

The format is specified in ``scenes/FORMAT.md`` and, for machines, in the JSON Schema shipped as
``vebuild/schema/project-v1.schema.json``. Every problem with the file or a photo it names is a
:class:`~vebuild.errors.ProjectError` that says where (JSON path), what was expected and what was
found, in words meant for the person who made the project rather than for a programmer.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from typing import Any

from vebuild.calibration.priors import PRINCIPAL_POINT_SIGMA_REL
from vebuild.errors import ProjectError
from vebuild.lighting import AS_PHOTOGRAPHED

from .images import MAX_IMAGE_PIXELS, decoded_size, open_image, read_exif, sha256_bytes, sha256_file
from .json_paths import json_path, listing
from .pixels import rgb_image
from .provenance import audit_entry, current_command, document_sha256
from .schema_match import schema
from .validation import FORMAT, VERSION, check_relative_path, parse_document, validate

__all__ = [  # what other modules take from here; validation and image files have modules of their own
    "AS_PHOTOGRAPHED", "DEFAULT_SETTINGS", "FORMAT", "MAX_IMAGE_PIXELS", "RESULT_KEYS", "VERSION", "Project",
    "autosave_path", "canonical_input_hash", "decode_texture_page", "json_path", "load_project",
    "new_photo_entry", "new_project", "open_image", "read_exif", "read_texture_page", "save_project",
    "schema", "sha256_bytes", "sha256_file", "texture_page_path", "validate",
]

#: Values of ``settings`` that a project does not give (FORMAT.md, "settings").
DEFAULT_SETTINGS: dict[str, float] = {
    "click_sigma_px": 1.0,
    # 3 % of the longer side: real cameras' principal points lie a few per cent off centre
    # (calibration.priors.PRINCIPAL_POINT_SIGMA_REL says what was measured).
    "principal_point_sigma_rel": PRINCIPAL_POINT_SIGMA_REL,
    "exif_focal_sigma_rel": 0.03,  # vebuild.calibration.exif.NOMINAL_FOCAL_SIGMA_REL: EXIF is nominal
}
#: Top-level keys written by vebuild's stages; they are not input, so the input hash skips them. The
#: audit trail (``audit``, vebuild.project.provenance) is written with every save and is no input either.
RESULT_KEYS = ("calibration", "model_solution", "textures", "audit")


_ID_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]+")
_HASH_SHOWN = 12  # hex digits of a hash quoted in a message: enough to tell two apart


@dataclass
class Project:
    """A loaded project file.

    Attributes
    ----------
    path : the project file.
    data : the JSON document, as plain dicts and lists.
    loaded_sha256 : :func:`vebuild.project.provenance.document_sha256` of the document as loaded (or
        last saved): the ``before_sha256`` of the audit entry the next save appends.
    """

    path: Path
    data: dict[str, Any]
    loaded_sha256: str | None = field(default=None, compare=False)

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
        known = listing(p["id"] for p in self.data["photos"])
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
    data = parse_document(text, path)
    validate(data, path)
    project = Project(path, data, document_sha256(data))
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
        before = project_or_path.loaded_sha256
    else:
        path = Path(project_or_path)
        if data is None:
            raise TypeError("save_project(path, data): data is required when a path is given")
        before = None
    if not validated:
        validate(data, path)
    trail = data.get("audit")
    after = _append_audit(path, data, before)  # an entry valid by construction (provenance.audit_entry)
    try:
        _write_document(path, data)
    except BaseException:
        if after is not None:  # the entry is taken back: the document is as it was given
            if trail is None:
                del data["audit"]
            else:
                data["audit"] = trail
        raise
    if isinstance(project_or_path, Project) and after is not None:
        project_or_path.loaded_sha256 = after
    return path


def _append_audit(path: Path, data: dict[str, Any], before: str | None) -> str | None:
    """Append the running command's audit entry (vebuild.project.provenance) to ``data`` when a
    command is running (``vebuild.cli``) and this is the project file itself, not its autosave
    side file, and the document changed; the document's hash after, or None."""
    running = current_command()
    if running is None or path.name.endswith(".autosave"):
        return None
    after = document_sha256(data)
    if after == before and data.get("audit"):
        return None
    data["audit"] = [*(data.get("audit") or []), audit_entry(running[0], running[1], before, after, path)]
    return after


def _refuse_links(path: Path) -> None:
    """A project file (or autosave) is saved by writing a new file in its place: refused where
    that would replace a symbolic link, or part one name from a file that has others."""
    import stat

    try:
        st = os.lstat(path)
    except OSError:
        return
    if stat.S_ISLNK(st.st_mode):
        to = os.readlink(path)
        raise ProjectError(path, "", f"is a symbolic link (to {to}); saving writes a new file in its place, which "
                           "would replace the link, not the file it leads to; vebuild does not replace links; open "
                           "the file it leads to instead")
    if stat.S_ISREG(st.st_mode) and st.st_nlink > 1:
        raise ProjectError(path, "", f"is a hard link (the file has {st.st_nlink} names); saving writes a new file "
                           "in its place, which its other names would not see; vebuild replaces only a file that "
                           "has no other name; copy it to a file of its own and open the copy")


def _write_document(path: Path, data: dict[str, Any]) -> None:
    import io

    _refuse_links(path)

    from .atomic import write_with  # beside the target, fsync'ed, renamed over it (vebuild/project/atomic.py)

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


def autosave_path(project_path: str | os.PathLike[str]) -> Path:
    """The modelling screen's side file of a project (``NAME.vebuild.json.autosave``, FORMAT.md)."""
    path = Path(project_path)
    return path.with_name(path.name + ".autosave")


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
    size = decoded_size(image, found, project.path, f"{where}.file")
    if size != (photo["width"], photo["height"]):
        turned = ""
        if size == (photo["height"], photo["width"]):
            # A project made before vebuild turned photos by their EXIF orientation: its marks
            # were placed on the photo as stored, not as the camera meant it to be shown.
            turned = (": the photo's EXIF orientation turns it a quarter, and vebuild shows (and marks) photos as "
                      "the camera meant them, turned; the project's size is the photo as stored, so its marks do "
                      "not fit the photo as shown. Add the photo again and mark it again")
        raise ProjectError(project.path, f"{where}.width",
                           f"the photo {photo['file']!r} is {size[0]}×{size[1]} pixels, "
                           f"but the project says {photo['width']}×{photo['height']}{turned}")


# --------------------------------------------------------------------------------------------------
# Texture pages (FORMAT.md, "Results: textures"): every reader goes through these.


def texture_page_path(project: Project, k: int, key: str = "atlas") -> Path:
    """Where page ``k``'s atlas (``key`` "atlas") or coverage map ("coverage") is.

    The path is confined as a photo's is: relative, inside the project folder, and still inside it
    once symbolic links are resolved, so that no project makes vebuild read or copy another file.
    """
    rel = project.data["textures"]["pages"][k][key]
    where = f"$.textures.pages[{k}].{key}"
    check_relative_path(rel, project.path, where)
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
            im.load()
            pixels = rgb_image(im, project.path, where, repr(page["atlas"]), noun="atlas page", head=data[:32])
            return np.asarray(pixels)
        except (OSError, ValueError, SyntaxError) as e:
            raise ProjectError(project.path, where, f"the atlas page {page['atlas']!r} cannot be decoded: it is "
                               f"damaged or truncated ({e})") from None


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
    if not image.is_file():
        raise ProjectError(image, "", f"photo file not found: {image}")
    sha256 = sha256_file(image)
    width, height = decoded_size(image, sha256, image, "")
    entry: dict[str, Any] = {
        "id": photo_id,
        "file": image.relative_to(folder).as_posix(),
        "width": width,
        "height": height,
        "sha256": sha256,
    }
    if exif := read_exif(image):
        entry["exif"] = exif
    entry["vanishing_segments"] = {}
    entry["marker_observations"] = {}
    return entry
