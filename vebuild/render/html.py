"""The model as a self-contained web page (``vebuild export PROJECT --html DIR``; docs/html-viewer.md).

The folder written holds everything the page needs, so that it opens from ``file://`` or any plain
web server with no network:

- ``index.html``: the page (its Content-Security-Policy allows nothing outside the folder);
- ``scene.glb``: the glTF export of :mod:`vebuild.render.export` (model, textures, coverage maps,
  view and photo cameras, their ``extras``), for other tools; ``scene.js``: the same bytes as
  base64 in a classic script (``window.VEBUILD_SCENE``), since a page opened from ``file://``
  may not ``fetch()`` a file beside it;
- ``data.js``: what the glTF does not hold (``window.VEBUILD_DATA``): the evidence markers, the
  recorded analyses with their figures and uncertainty (computed by the caller, who may run them:
  this layer does not), the hypotheses as node transforms, the photos' files, the units;
- ``photos/ID.jpg``: each calibrated photo downscaled (the originals are only read);
- ``viewer.js`` and ``three-bundle.min.js`` (three.js, bundled once by ``web/build.sh`` into one
  classic script) and ``THREE-LICENSE``;
- ``vebuild-html.json``: the manifest (vebuild's mark: a folder holding one may be written again;
  any other non-empty folder is refused, so that nothing vebuild did not write is replaced).

Every file goes to a temporary name first and is renamed only when all were written. A symbolic
link or a file with other names anywhere in the folder is refused (nothing is written through a
link), and the folders below it are opened without following links as the files are written.
"""

from __future__ import annotations

import base64
import io
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vebuild import __version__
from vebuild.errors import VebuildError
from vebuild.project import Project
from vebuild.project.outputs import begin_stage, check_file, check_no_links
from vebuild.project.stills import origin_summary
from vebuild.render.export import ROOT_NAME, _collect, glb_bytes, gltf_document

#: The folder of the viewer's committed web files (three.js bundle, viewer script, page template).
WEB = Path(__file__).with_name("web")
#: Files copied from :data:`WEB` as they are.
STATIC = ("three-bundle.min.js", "viewer.js", "THREE-LICENSE")
#: The manifest: vebuild's mark on a folder it wrote.
MANIFEST = "vebuild-html.json"
#: Longest side of the photos' copies, pixels, and their JPEG quality.
PHOTO_MAX_PX = 1280
PHOTO_QUALITY = 85
#: The page's Content-Security-Policy: nothing from outside the folder (scripts from it, the
#: textures as blob: URLs made by the glTF loader, inline style for the labels).
CSP = ("default-src 'self' data: blob: 'unsafe-inline'; script-src 'self' 'unsafe-inline'; "
       "img-src 'self' data: blob:; connect-src 'self' data: blob:; style-src 'self' 'unsafe-inline'")


@dataclass
class HtmlResult:
    """What was written, for the command line to print."""

    folder: Path
    files: list[Path]
    cameras: list[str]  # the page's camera ids (``#camera=ID``)
    markers: int
    analyses: int
    hypotheses: int
    photos: int
    textured: bool
    warnings: list[str] = field(default_factory=list)


def camera_id(name: str, kind: str) -> str:
    """The page's id of an exported camera (``#camera=ID``): ``photo-ID`` or ``view-NAME``."""
    return f"photo-{name[len('photo '):]}" if kind == "photo" else f"view-{name}"


def _js_string(value: Any) -> str:
    """JSON safe inside a classic script (no ``</script>``, no U+2028/9 line breaks)."""
    text = json.dumps(value, ensure_ascii=True, allow_nan=False, separators=(",", ":"))
    return text.replace("</", "<\\/")


def _hypotheses(contents: Any, index: dict[str, int]) -> tuple[list[dict[str, Any]], list[str]]:
    """Each hypothesis as the glTF local matrix (column-major) of every node it places otherwise."""
    from vebuild.project.hypotheses import applied_hypothesis, label

    project = contents.project
    out, warnings = [], []
    base = {n.name: n.local for n in contents.nodes}
    for i, rec in enumerate(project.data.get("hypotheses") or []):
        try:
            model = applied_hypothesis(project, contents.scene.model, i)
        except VebuildError as e:
            warnings.append(f"hypothesis {rec['name']!r} left out: {e}")
            continue
        world = model.world_transforms()
        moved = {}
        for node in model.nodes:
            T = world[node.name]
            local = T if node.parent is None else np.linalg.inv(world[node.parent]) @ T
            if node.name in base and not np.allclose(local, base[node.name], atol=1e-12):
                moved[str(index[node.name])] = [float(v) for v in local.T.ravel()]
        out.append({"name": rec["name"], "description": rec.get("description", ""), "label": label(rec["name"]),
                    "joints": rec.get("joints", {}), "nodes": moved})
    return out, warnings


def _photo_copy(project: Project, photo: dict[str, Any], max_px: int) -> tuple[bytes, tuple[int, int]]:
    """A downscaled JPEG of a photo as displayed (EXIF orientation applied); the original is only read."""
    from PIL import Image

    from vebuild.project.images import decode_photo

    path = project.photo_path(photo)
    where = f"$.photos[{project.data['photos'].index(photo)}].file"
    try:
        data = path.read_bytes()
    except OSError as e:
        raise VebuildError(f"{project.path}: {where}: cannot read the photo {path} ({e.strerror or e})") from None
    img = Image.fromarray(decode_photo(data, path.name, project.path, where, label=str(path)))
    scale = min(1.0, max_px / max(img.size))
    if scale < 1.0:
        size = (max(1, round(img.width * scale)), max(1, round(img.height * scale)))
        img = img.resize(size, Image.Resampling.LANCZOS)
    buf = io.BytesIO()
    img.save(buf, "JPEG", quality=PHOTO_QUALITY, optimize=True)
    return buf.getvalue(), img.size


def _check_folder(project: Project, folder: Path) -> set[str]:
    """Refuse a folder the export may not write into; the files an earlier export listed there."""
    if folder.exists() and not folder.is_dir():
        raise VebuildError(f"{folder}: is not a folder; give a folder for the HTML export (it is created if missing)")
    if folder.is_symlink():
        raise VebuildError(f"{folder}: is a symbolic link; vebuild does not write through links; choose a new folder")
    parent = folder.parent
    if not parent.is_dir():
        raise VebuildError(f"{folder}: the folder above it, {parent}, does not exist; create it first")
    if not os.access(parent if not folder.exists() else folder, os.W_OK):
        raise VebuildError(f"{folder}: cannot be written (permission denied)")
    if folder.resolve() == project.folder.resolve():
        raise VebuildError(f"{folder}: is the project's own folder; the HTML export needs a folder of its own, "
                           f"such as {project.folder / 'viewer'}")
    if folder.is_dir() and any(folder.iterdir()):
        manifest = folder / MANIFEST
        listed: Any = None
        try:
            record = json.loads(manifest.read_text("utf-8"))
            if str(record.get("software", "")).startswith("vebuild"):
                listed = record.get("files")
        except (OSError, ValueError, AttributeError):
            listed = None
        if not isinstance(listed, list):
            raise VebuildError(f"{folder}: is not empty and holds no {MANIFEST} (the mark of a folder vebuild's HTML "
                               "export wrote); vebuild replaces only its own outputs; choose a new or empty folder")
        check_no_links(folder, "choose a new or empty folder")  # nothing is written through a link
        return {str(f) for f in listed} | {MANIFEST}
    return set()


def write_html(project: Project, folder: str | os.PathLike[str], analyses: list[dict[str, Any]] | None = None,
               photo_max_px: int = PHOTO_MAX_PX, warnings: list[str] | None = None,
               extra_files: list[tuple[str, bytes]] | None = None,
               camera_only: tuple[dict[str, Any], bytes, Any] | None = None) -> HtmlResult:
    """Write the viewer folder for ``project`` (see the module's docstring).

    ``analyses``: the recorded analyses as the page draws them, each a dict with ``name``,
    ``description``, ``kind``, ``label`` (the figures and uncertainty, in words), ``table``,
    ``command``, ``anchor`` (a world point for the label, or None), ``paths`` and ``cone``
    (world polylines: the measured segment or trajectory, and its uncertainty region), and
    ``image`` (a path in the folder, or None). ``extra_files``: (path in the folder, bytes) written
    with the rest, such as the analyses' images. ``camera_only``: a project with no model, shown as
    one calibrated photo: the glTF document and binary chunk of
    :func:`vebuild.render.export_camera.camera_document` and the photo's camera.
    """
    folder = Path(folder)
    ours = _check_folder(project, folder)
    for name in STATIC:
        if not (WEB / name).is_file():
            raise VebuildError(f"{WEB / name}: the HTML viewer's file is missing from the installation; reinstall "
                               "vebuild (or rebuild the bundle with vebuild/render/web/build.sh)")
    if camera_only is None:
        contents = _collect(project)
        doc, binary = gltf_document(contents)
        index = {n.name: i + 1 for i, n in enumerate(contents.nodes)}  # as gltf_document numbers them
        hypotheses, hw = _hypotheses(contents, index)
        out_warnings = list(contents.warnings) + list(warnings or []) + hw
        scene_cameras, textured = contents.cameras, contents.scene.textured
    else:
        doc, binary, only = camera_only
        hypotheses, out_warnings = [], list(warnings or [])
        scene_cameras, textured = [(f"photo {only.id}", "photo", only)], True
    glb = glb_bytes(doc, binary)

    files: list[tuple[Path, bytes]] = []
    photos: dict[str, Any] = {}
    cameras = []
    for name, kind, cam in scene_cameras:
        cid = camera_id(name, kind)
        cameras.append(cid)
        if kind == "photo":
            pid = name[len("photo "):]
            photo = project.photo(pid)
            data, size = _photo_copy(project, photo, photo_max_px)
            rel = f"photos/{pid}.jpg"
            files.append((folder / "photos" / f"{pid}.jpg", data))
            photos[cid] = {"id": pid, "file": rel, "source": photo["file"], "sha256": photo.get("sha256"),
                           "width": size[0], "height": size[1], "camera_width": int(cam.width),
                           "camera_height": int(cam.height)}
            if (video := origin_summary(photo)) is not None:  # a still: its video, hash, frame, time, field
                photos[cid]["video"] = video

    from vebuild.project.units import length_unit

    unit = length_unit(project.data)
    title = str(project.data.get("name") or project.path.stem)
    markers = [{"label": m["label"], "position": [float(v) for v in m["position"]], "node": m.get("node"),
                "description": m.get("description", "")} for m in project.data.get("evidence_markers") or []]
    data_js: dict[str, Any] = {
        "software": f"vebuild {__version__}",
        "project": project.path.name,
        "name": title,
        "units": "relative" if unit.relative else "metres",
        "units_note": unit.note if unit.relative else "",
        "root": ROOT_NAME,
        "textured": textured,
        "single_photo": camera_only is not None,
        "markers": markers,
        "analyses": analyses or [],
        "hypotheses": hypotheses,
        "photos": photos,
        "cameras": cameras,
        "unobserved": _unobserved(),
        "warnings": out_warnings,
    }
    for rel, blob in extra_files or []:
        files.append((folder.joinpath(*Path(rel).parts), blob))
    files.append((folder / "scene.glb", glb))
    files.append((folder / "scene.js", b"window.VEBUILD_SCENE = \"" + base64.b64encode(glb) + b"\";\n"))
    files.append((folder / "data.js", ("window.VEBUILD_DATA = " + _js_string(data_js) + ";\n").encode("utf-8")))
    for name in STATIC:
        files.append((folder / name, (WEB / name).read_bytes()))
    page = (WEB / "index.html").read_text("utf-8")
    page = page.replace("{{CSP}}", CSP).replace("{{TITLE}}", _html_escape(title))
    page = page.replace("{{VERSION}}", _html_escape(__version__))
    files.append((folder / "index.html", page.encode("utf-8")))
    from vebuild.project.provenance import inputs_sha256

    manifest = {"software": f"vebuild {__version__}", "project": project.path.name,
                "inputs_sha256": inputs_sha256(project.data),  # FORMAT.md "Inputs digest"
                "files": sorted(str(p.relative_to(folder).as_posix()) for p, _ in files)}
    files.append((folder / MANIFEST, (json.dumps(manifest, indent=2) + "\n").encode("utf-8")))

    for path, _ in files:
        if path.is_dir():
            raise VebuildError(f"{path}: is a folder; the HTML export needs to write a file there; nothing was written")
        if path.is_symlink() or path.relative_to(folder).as_posix() not in ours:
            check_file(project, path, "HTML export")  # a file the earlier export did not write: vebuild's own only
        elif path.exists() and not path.is_file():
            raise VebuildError(f"{path}: is not a regular file; nothing was written")
    check_no_links(folder, "choose a new or empty folder")  # again: none was put there meanwhile
    subfolders = sorted({p.parent for p, _ in files})
    for sub in subfolders:
        sub.mkdir(parents=True, exist_ok=True)
    begin_stage(project, *subfolders)
    from vebuild.project.atomic import write_many

    try:
        write_many(files, within=folder)  # no folder below ``folder`` is gone through if it is a link
    except OSError as e:
        raise VebuildError(f"{folder}: cannot write {e.filename or folder} ({e.strerror or e})") from None
    return HtmlResult(folder, [p for p, _ in files], cameras, len(markers), len(analyses or []),
                      len(hypotheses), len(photos), textured, out_warnings)


def _unobserved() -> dict[str, Any]:
    """How the page marks the surfaces no photo saw: the renders' hatch (:mod:`vebuild.render.observed`)."""
    from vebuild.render.observed import HATCH_DUTY, HATCH_PERIOD_M, HATCH_STRENGTH, LEGEND_TEXT, UNOBSERVED_SRGB

    return {"mode": "hatch", "colour_srgb": list(UNOBSERVED_SRGB), "strength": HATCH_STRENGTH,
            "period_m": HATCH_PERIOD_M, "duty": HATCH_DUTY, "legend": LEGEND_TEXT["hatch"]}


def _html_escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")
