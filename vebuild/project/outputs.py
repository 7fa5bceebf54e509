"""Where vebuild may write an output, and where never (scenes/FORMAT.md, "What vebuild writes and
what it never touches").

An output *file* (a render, an export, a video, a figures JSON) may be written only where nothing
is, or over a file vebuild wrote, recognised by what vebuild puts in it:

========== ===========================================================================
PNG        a text chunk ``Software`` that starts with ``vebuild``
.glb       the glTF JSON's ``asset.generator`` starts with ``vebuild``
.obj .mtl  the first line starts with ``# vebuild``
.mp4       the container's ``description`` metadata starts with ``vebuild``
.json      a top-level object whose ``software`` starts with ``vebuild``
========== ===========================================================================

and never over the project file or its autosave, a photo of the project, anything inside the
project's ``textures/`` folder, or a symbolic link. An output *folder* (the report) must be new,
empty, or carry vebuild's manifest (:data:`MANIFEST`, naming every file vebuild wrote there with
its SHA-256) and hold nothing else; it is never the project's folder nor a folder that holds the
project file or a photo. Nothing below an output folder may be a symbolic link or a file with other
names (a hard link), nor may an output file have other names (:func:`check_no_links`): vebuild
never writes through a link nor parts one name from a file kept under another. Every refusal is a
:class:`VebuildError` that says what is there and what to do instead.

Layer: project I/O (reads the project's data, never GL).
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import struct
from pathlib import Path
from typing import TYPE_CHECKING, Any

from vebuild import __version__
from vebuild.errors import VebuildError
from vebuild.project.atomic import MANIFEST, clean_stale, is_temp_name, write_text
from vebuild.project.file import autosave_path

if TYPE_CHECKING:
    from .file import Project


#: The marker vebuild's own files carry (see the table above).
SOFTWARE = f"vebuild {__version__}"


# -- what belongs to the project -------------------------------------------------------------------


def _key(path: Path) -> tuple[str, tuple[int, int] | None]:
    real = os.path.realpath(path)
    try:
        st = os.stat(real)
        return real, (st.st_dev, st.st_ino)
    except OSError:
        return real, None


def protected(project: Project | None) -> dict[str, str]:
    """The project's own files, by real path: what each is, for the refusal's message."""
    if project is None:
        return {}
    out: dict[str, str] = {}
    path = Path(project.path)
    out[os.path.realpath(path)] = f"the project file {path.name}"
    auto = autosave_path(path)
    out[os.path.realpath(auto)] = f"the project's autosave {auto.name}"
    for p in project.data.get("photos", []):
        out[os.path.realpath(project.photo_path(p))] = f"the project's photo {p['file']}"
    for page in (project.data.get("textures") or {}).get("pages", []):
        for key in ("atlas", "coverage"):
            if page.get(key):
                out[os.path.realpath(project.folder / page[key])] = f"the project's texture page {page[key]}"
    return out


def _owner(project: Project | None, path: Path) -> str | None:
    """What of the project ``path`` is (by real path or, for an existing file, by inode), or None."""
    if project is None:
        return None
    prot = protected(project)
    real, ino = _key(path)
    if real in prot:
        return prot[real]
    if ino is not None:
        for p, what in prot.items():
            if _key(Path(p))[1] == ino:
                return what + " (another name for it)"
    textures = os.path.realpath(project.folder / "textures")
    if real == textures or real.startswith(textures + os.sep):
        return "inside the project's textures/ folder, which `vebuild texture` keeps"
    return None


# -- recognising vebuild's own files ---------------------------------------------------------------


def _png_software(path: Path) -> str:
    from PIL import Image

    with Image.open(path) as im:
        if im.format != "PNG":
            return ""
        return str(im.info.get("Software", ""))


def _glb_generator(path: Path) -> str:
    with open(path, "rb") as f:
        head = f.read(20)
        if len(head) < 20 or head[:4] != b"glTF":
            return ""
        length, kind = struct.unpack("<II", head[12:20])
        if kind != 0x4E4F534A or length > 64 << 20:
            return ""
        doc = json.loads(f.read(length))
    return str((doc.get("asset") or {}).get("generator", ""))


def _first_line(path: Path) -> str:
    with open(path, "rb") as f:
        return f.readline(200).decode("utf-8", "replace")


def _mp4_description(path: Path) -> str:
    import av

    with av.open(str(path)) as c:
        return str(c.metadata.get("description", ""))


def _json_software(path: Path) -> str:
    if path.stat().st_size > 64 << 20:
        return ""
    doc = json.loads(path.read_bytes())
    return str(doc.get("software", "")) if isinstance(doc, dict) else ""


_RECOGNISE = {".png": _png_software, ".glb": _glb_generator, ".obj": _first_line, ".mtl": _first_line,
              ".mp4": _mp4_description, ".json": _json_software}


def written_by_vebuild(path: Path) -> bool:
    """Whether the existing file ``path`` carries vebuild's mark (see the module's table)."""
    how = _RECOGNISE.get(path.suffix.lower())
    if how is None:
        return False
    try:
        mark = how(path)
    except Exception:  # unreadable, not of its kind: not ours
        return False
    return mark.startswith("# vebuild") if path.suffix.lower() in (".obj", ".mtl") else mark.startswith("vebuild")


# -- files -----------------------------------------------------------------------------------------


def _copy_of_a_page(project: Project | None, path: Path) -> bool:
    """A PNG byte-identical to one of the project's recorded atlas pages (an OBJ export's copy of a
    page textured by a vebuild older than the ``Software`` mark)."""
    if project is None or path.suffix.lower() != ".png":
        return False
    hashes = {p.get("atlas_sha256") for p in (project.data.get("textures") or {}).get("pages", [])}
    try:
        return sha256_of(path) in hashes
    except OSError:
        return False


def check_file(project: Project | None, path: str | os.PathLike[str], what: str = "output",
               suffix: str | None = None) -> Path:
    """Refuse (VebuildError) to write the output file ``path`` unless the policy above allows it
    (``suffix``: the kind of file wanted, for the message's example name)."""
    path = Path(path)
    stem = path.stem.split(".")[0] or "output"
    example = f"a new file name such as {Path('renders') / (stem + (suffix or path.suffix))}"
    if path.is_symlink():
        raise VebuildError(f"{path}: is a symbolic link (to {os.readlink(path)}); vebuild does not write over links; "
                           f"choose {example}")
    owner = _owner(project, path)
    if owner is not None:
        raise VebuildError(f"{path}: is {owner}; vebuild never writes its {what} over the project's own files; "
                           f"choose {example}")
    _refuse_other_names(path, f"choose {example}")
    if path.exists() and not path.is_dir():  # a folder: each command says so in its own words
        if not path.is_file():
            raise VebuildError(f"{path}: is not a regular file; choose {example}")
        if not (written_by_vebuild(path) or _copy_of_a_page(project, path)):
            raise VebuildError(f"{path}: already exists and is not a file vebuild wrote (it carries no vebuild "
                               f"mark); vebuild replaces only its own outputs; move it away or choose {example}")
    return path


def is_project_file(path: Path) -> bool:
    """Whether the existing file ``path`` is a vebuild project file: a JSON object whose ``format``
    is ``vebuild-project`` (of any version)."""
    from vebuild.project.validation import FORMAT

    try:
        if path.is_symlink() or not path.is_file() or path.stat().st_size > 256 << 20:
            return False
        doc = json.loads(path.read_bytes())
    except Exception:  # unreadable, not JSON: not a project file
        return False
    return isinstance(doc, dict) and doc.get("format") == FORMAT


def check_new_project(path: str | os.PathLike[str], force: bool) -> Path:
    """Refuse (VebuildError) to write a new project file at ``path`` over anything but, with
    ``force``, an existing vebuild project file (never over a photo, a render or a link)."""
    path = Path(path)
    example = f"a new file name such as {path.parent / 'room.vebuild.json'}"
    if path.is_symlink():
        raise VebuildError(f"{path}: is a symbolic link (to {os.readlink(path)}); vebuild does not write over links; "
                           f"choose {example}")
    if not path.exists():
        return path
    if path.is_dir():
        raise VebuildError(f"{path}: is a folder; choose {example}")
    if not is_project_file(path):
        raise VebuildError(f"{path}: already exists and is not a vebuild project file; `vebuild new` (even with "
                           f"--force) replaces only a project file; move it away or choose {example}")
    if not force:
        raise VebuildError(f"{path}: already exists; choose another name or pass --force to replace it")
    return path


# -- links -----------------------------------------------------------------------------------------


def _refuse_other_names(path: Path, advice: str) -> None:
    """Refuse a regular file that has other names (a hard link): replacing it would part one name
    from a file someone keeps under another."""
    try:
        st = os.lstat(path)
    except OSError:
        return
    if stat.S_ISREG(st.st_mode) and st.st_nlink > 1:
        raise VebuildError(f"{path}: is a hard link (the file has {st.st_nlink} names); vebuild replaces only a "
                           f"file that has no other name; move it away or {advice}")


def check_no_links(folder: str | os.PathLike[str], advice: str, itself: bool = False) -> None:
    """Refuse (VebuildError) anything below the output folder ``folder`` that writing there could
    go through or part: a symbolic link (to a file or a folder, or to nothing), a file with other
    names (a hard link), anything but a file or a folder. ``folder`` itself is the caller's to
    check, unless ``itself``: then a link there is refused too. ``advice``: what to do instead
    ("choose a new folder such as …")."""
    folder = Path(folder)
    if itself and folder.is_symlink():
        raise VebuildError(f"{folder}: is a symbolic link (to {os.readlink(folder)}); vebuild never writes through a "
                           f"link; {advice}")
    if folder.is_symlink() or not folder.is_dir():
        return

    def unreadable(e: OSError) -> None:
        raise VebuildError(f"{e.filename or folder}: cannot be read ({e.strerror or e}); vebuild checks every entry "
                           f"of its output folder before it writes there; {advice}")

    for root, dirs, files in os.walk(folder, onerror=unreadable, followlinks=False):
        for name in sorted(dirs + files):
            path = Path(root) / name
            try:
                st = os.lstat(path)
            except OSError as e:
                unreadable(e)
                continue
            if stat.S_ISLNK(st.st_mode):
                raise VebuildError(f"{path}: is a symbolic link (to {os.readlink(path)}) inside the output folder "
                                   f"{folder}; vebuild never writes through a link nor replaces one; move the link "
                                   f"away or {advice}")
            if stat.S_ISDIR(st.st_mode):
                continue
            if not stat.S_ISREG(st.st_mode):
                raise VebuildError(f"{path}: is not a regular file nor a folder (inside the output folder {folder}); "
                                   f"move it away or {advice}")
            _refuse_other_names(path, advice)


# -- folders ---------------------------------------------------------------------------------------


def sha256_of(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def read_manifest(folder: Path) -> dict[str, Any] | None:
    try:
        doc = json.loads((folder / MANIFEST).read_bytes())
    except (OSError, ValueError):
        return None
    if not (isinstance(doc, dict) and str(doc.get("software", "")).startswith("vebuild")
            and isinstance(doc.get("files"), dict)):
        return None
    return doc


def write_manifest(folder: Path, kind: str, project: Project | None = None) -> None:
    """Name every file under ``folder`` (vebuild just wrote them) with its SHA-256."""
    files = {}
    for p in sorted(folder.rglob("*")):
        if p.is_file() and p.name != MANIFEST:
            files[p.relative_to(folder).as_posix()] = sha256_of(p)
    doc = {"software": SOFTWARE, "kind": kind, "project": None if project is None else Path(project.path).name,
           "files": files}
    write_text(folder / MANIFEST, json.dumps(doc, indent=2, sort_keys=True) + "\n")


def check_folder(project: Project | None, out: str | os.PathLike[str], what: str = "report") -> Path:
    """Refuse (VebuildError) an output folder the policy does not allow; returns ``out``."""
    out = Path(out)
    example = f"a new folder such as {what}/"
    if out.is_symlink():
        raise VebuildError(f"{out}: is a symbolic link (to {os.readlink(out)}); choose {example}")
    if out.exists() and not out.is_dir():
        raise VebuildError(f"{out}: is a file; expected a folder for the {what}; choose {example}")
    owner = _owner(project, out)
    if owner is not None:
        raise VebuildError(f"{out}: is {owner}; choose {example}")
    real = os.path.realpath(out)
    cwd = os.path.realpath(os.getcwd())
    if project is not None and real == os.path.realpath(project.folder):
        pass  # said below, more precisely
    elif real == cwd or cwd.startswith(real + os.sep):
        raise VebuildError(f"{out}: is the folder you are working in (or holds it); vebuild replaces its output "
                           f"folder as a whole; choose {example}")
    if project is not None:
        if real == os.path.realpath(project.folder):
            raise VebuildError(f"{out}: is the project's folder (it holds {Path(project.path).name} and its "
                               f"photos); choose {example}")
        for own, owner in protected(project).items():
            if own.startswith(real + os.sep) and os.path.lexists(own):
                raise VebuildError(f"{out}: holds {owner}; vebuild never replaces a folder with the project's own "
                                   f"files; choose {example}")
    if not out.exists():
        return out
    entries = sorted(p for p in out.rglob("*") if p.name != MANIFEST and not p.is_dir())
    if not entries and not any(out.iterdir()):
        return out
    manifest = read_manifest(out)
    if manifest is None:
        shown = ", ".join(p.relative_to(out).as_posix() for p in entries[:3]) or "folders"
        raise VebuildError(f"{out}: is not empty (it holds {shown}) and is not a folder vebuild wrote (no "
                           f"{MANIFEST}); choose {example} or empty it yourself")
    check_no_links(out, f"choose {example}")
    listed = manifest["files"]
    for p in entries:
        rel = p.relative_to(out).as_posix()
        if p.is_symlink() or rel not in listed or sha256_of(p) != listed[rel]:
            raise VebuildError(f"{out}: holds {rel}, which vebuild did not write there (or which changed since); "
                               f"move it away or choose {example}")
    return out


def begin_stage(project: Project | None, *folders: str | os.PathLike[str]) -> None:
    """At the start of a stage that writes: remove vebuild's stale temporaries (from a process
    that was killed) in the project's folder, its textures/ folder and the given folders."""
    places = [] if project is None else [project.folder, project.folder / "textures"]
    for f in [*places, *map(Path, folders)]:
        if Path(f).is_dir() and not Path(f).is_symlink():
            clean_stale(f)


def temporaries(folder: Path) -> list[Path]:
    """vebuild temporary files or folders under ``folder`` (for tests and checks)."""
    return [p for p in Path(folder).rglob("*") if is_temp_name(p.name)]
