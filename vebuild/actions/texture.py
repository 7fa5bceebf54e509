"""``vebuild texture``: extract the model's textures from the photos and record them in the project.

Writes ``textures/atlas_K_HASH.png`` (sRGB) and ``textures/coverage_K_HASH.png`` (RGBA, see
:mod:`vebuild.texture.merge`) next to the project file, one pair per atlas page (HASH: the first 12
hex digits of the file's SHA-256), and the ``textures`` record (FORMAT.md).

The stage commits its pages and the project together, in an order that a failure or a kill at any
moment leaves the last good state whole: the new pages are written under fresh names (atomically,
:mod:`vebuild.project.atomic`), then the project is saved pointing at them, then the old pages are deleted,
each only if its bytes still hash to the SHA-256 the old record gives (a user's file is never
deleted). Pages that no record refers to (left by a kill) are removed at the next run, only if their
name is of the pattern above and their bytes match the hash in it.
"""

from __future__ import annotations

import io
import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, PngImagePlugin

from vebuild import __version__
from vebuild.errors import VebuildError
from vebuild.project import Project, autosave_path, canonical_input_hash, load_project, save_project, sha256_file
from vebuild.project.atomic import write_bytes
from vebuild.project.decode import cameras as final_cameras
from vebuild.project.decode import load_model
from vebuild.project.outputs import begin_stage, check_no_links
from vebuild.project.provenance import stamp
from vebuild.texture.extract import PhotoSource, TextureResult, extract
from vebuild.texture.merge import linear_to_srgb8
from vebuild.texture.options import Options
from vebuild.texture.timings import Timings

TEXTURE_DIR = "textures"
#: The name of a page vebuild writes: kind, page number, the first 12 hex digits of its SHA-256.
PAGE_NAME = re.compile(r"^(atlas|coverage)_(\d+)_([0-9a-f]{12})\.png$")


def texture_project(project: Project, options: Options | None = None,
                    progress: Callable[[int, int, str], None] | None = None,
                    timings: Timings | None = None, save: bool = True) -> tuple[dict[str, Any], TextureResult]:
    """Extract, write the PNGs, set ``project.data['textures']`` and (``save``) save the project,
    then delete the old pages; returns (record, result).

    With ``save`` False (the modelling screen, whose project is saved when the user says so) the
    new pages are written and recorded in ``project.data`` only; the old pages stay, as the project
    file on disk still refers to them, and are removed by a later run once no record names them.
    """
    options = options or Options()  # checked when made (and frozen)
    folder = texture_folder(project)
    begin_stage(project)
    data = project.data
    cams = final_cameras(project)  # the final ones: re-calibrated where the solution has them
    model, _, _ = load_model(project)
    if not any(n.primitive is not None for n in model.nodes):
        raise VebuildError(f"{project.path}: $.model.nodes: the model has no primitives to texture")
    cameras, sources = [], {}
    for i, p in enumerate(data["photos"]):
        if p["id"] not in cams:
            continue
        cameras.append(cams[p["id"]])
        sources[p["id"]] = PhotoSource(p["id"], project.photo_path(p), p["sha256"], f"$.photos[{i}]", str(project.path))
    result = extract(model, cameras, sources, options, progress, timings)
    old = data.get("textures")
    folder = texture_folder(project, make=True)
    record = _write(project, result, options, folder)
    data["textures"] = record
    stamp(data, "textures")  # what it was computed from (vebuild.project.provenance)
    if not save:
        return record, result
    try:
        save_project(project)
    except BaseException:
        data["textures"] = old
        remove_unrecorded_pages(project, folder)  # the new pages: nothing refers to them
        raise
    _remove_old_pages(project, folder, old, record)
    remove_unrecorded_pages(project, folder)
    return record, result


def texture_folder(project: Project, make: bool = False) -> Path:
    """The project's textures/ folder (``make``: made if missing); refused if it is a link, leads
    outside the project's folder or holds a link or a file with other names."""
    folder = project.folder / TEXTURE_DIR
    if folder.is_symlink():
        raise VebuildError(f"{folder}: is a symbolic link (to {os.readlink(folder)}); vebuild writes textures only "
                           "inside the project's folder; replace the link with a real folder (or remove it)")
    real, home = os.path.realpath(folder), os.path.realpath(project.folder)
    if os.path.dirname(real) != home:
        raise VebuildError(f"{folder}: leads outside the project's folder {project.folder} (to {real}); vebuild "
                           "writes textures only inside it; replace it with a real folder")
    if folder.exists() and not folder.is_dir():
        raise VebuildError(f"{folder}: is a file; vebuild keeps the textures in a folder of that name; move it away")
    # Pages are written, replaced and deleted there: never through a link, nor one name of a file with others.
    check_no_links(folder, "keep in textures/ only the pages `vebuild texture` writes")
    if make:
        try:
            folder.mkdir(exist_ok=True)
        except OSError as e:
            raise VebuildError(f"{folder}: cannot make the textures folder ({e.strerror or e})") from None
    return folder


def _recorded_names(record: dict[str, Any] | None) -> dict[str, str]:
    """The page files a textures record names (file name → recorded SHA-256)."""
    out: dict[str, str] = {}
    for page in (record or {}).get("pages", []):
        for key in ("atlas", "coverage"):
            if page.get(key):
                out[Path(str(page[key])).name] = str(page.get(f"{key}_sha256", ""))
    return out


def _names_recorded_on_disk(project: Project, autosave_only: bool = False) -> set[str] | None:
    """The page files the project file on disk (unless ``autosave_only``) and its autosave name;
    None if one of them cannot be read (then nothing may be deleted)."""
    names: set[str] = set()
    files = [autosave_path(project.path)] + ([] if autosave_only else [project.path])
    for path in files:
        if path.exists():
            try:
                names |= set(_recorded_names(load_project(path, verify_photos=False).data.get("textures")))
            except VebuildError:
                return None
    return names


def _remove_old_pages(project: Project, folder: Path, old: dict[str, Any] | None, new: dict[str, Any]) -> None:
    """Delete the pages of the old record that the new one (and an open modelling session's
    autosave) does not name, each only if its bytes still hash to the old record's SHA-256."""
    keep = _names_recorded_on_disk(project, autosave_only=True)
    if keep is None:
        return  # cannot tell what the autosave refers to: touch nothing
    keep |= set(_recorded_names(new))
    for name, digest in _recorded_names(old).items():
        path = folder / name
        if name in keep or path.is_symlink() or not path.is_file():
            continue
        try:
            if sha256_file(path) == digest:
                path.unlink()
        except OSError:
            pass  # left for the next run


def remove_unrecorded_pages(project: Project, folder: Path) -> list[Path]:
    """Delete pages vebuild wrote that no record refers to (a run killed before or after its
    save): names of :data:`PAGE_NAME` whose bytes match the hash in the name, named neither by
    the project in memory, nor by the project file on disk, nor by its autosave."""
    names = _names_recorded_on_disk(project)
    if names is None:
        return []  # cannot tell what they refer to: touch nothing
    names |= set(_recorded_names(project.data.get("textures")))
    removed = []
    for path in sorted(folder.iterdir()):
        m = PAGE_NAME.match(path.name)
        if m is None or path.name in names or path.is_symlink() or not path.is_file():
            continue
        try:
            if sha256_file(path).startswith(m[3]):
                path.unlink()
                removed.append(path)
        except OSError:
            pass
    return removed


def _png(img: np.ndarray, mode: str) -> bytes:
    info = PngImagePlugin.PngInfo()
    info.add_text("Software", f"vebuild {__version__}")
    buf = io.BytesIO()
    Image.fromarray(img, mode).save(buf, format="PNG", optimize=False, pnginfo=info)
    return buf.getvalue()


def _write(project: Project, result: TextureResult, options: Options, folder: Path) -> dict[str, Any]:
    """Write the pages under fresh names (atomically); returns the record naming them. On an
    error the pages written so far are removed (nothing refers to them) and nothing else changes."""
    import hashlib

    old_names = set(_recorded_names(project.data.get("textures")))
    pages = []
    try:
        for k, (atlas, cov) in enumerate(zip(result.atlases, result.coverage, strict=True)):
            entry: dict[str, Any] = {"width": int(atlas.shape[1]), "height": int(atlas.shape[0])}
            for key, img, mode in (("atlas", atlas, "RGB"), ("coverage", cov, "RGBA")):
                data = _png(img, mode)
                digest = hashlib.sha256(data).hexdigest()
                final = folder / f"{key}_{k}_{digest[:12]}.png"
                if not (final.name in old_names and final.is_file() and sha256_file(final) == digest):
                    write_bytes(final, data)
                entry[key] = f"{TEXTURE_DIR}/{final.name}"
                entry[f"{key}_sha256"] = digest
            pages.append(entry)
    except OSError as e:
        remove_unrecorded_pages(project, folder)  # those written so far: nothing refers to them
        raise VebuildError(f"{folder}: cannot write the textures: {e.strerror or e}") from None
    except BaseException:
        remove_unrecorded_pages(project, folder)
        raise
    faces = []
    for f in result.faces:
        st = result.face_stats[f.id]
        mean = st.mean_linear
        faces.append({
            "id": f.id, "node": f.node, "face": f.name, "page": f.page, "rect": list(f.rect),
            "size_m": [round(v, 6) for v in f.size_m],
            "texels_per_metre": [round(v, 3) for v in f.texels_per_metre],
            "seen_fraction": round(st.seen_fraction, 6),
            "photos": result.face_photos[f.id],
            "average_colour_srgb": [int(v) for v in linear_to_srgb8(mean)] if np.isfinite(mean).all() else None,
        })
    photos = [{"id": pid, "sha256": project.photo(pid)["sha256"], "order": k,
               "gain": [round(float(g), 6) for g in result.gains[pid]], "overlap_texels": result.overlap.get(pid, 0)}
              for k, pid in enumerate(result.order)]
    unseen = [f"{f.node}.{f.name}" for f in result.unseen_faces]
    warnings = [f"{len(unseen)} face(s) seen by no photo, filled with their node's average colour: "
                + ", ".join(unseen)] if unseen else []
    warnings += [f"photo {p['id']}: too little overlap with the photos before it to compensate its exposure"
                 for p in photos[1:] if options.exposure and p["overlap_texels"] < 64]
    return {
        "software": f"vebuild {__version__}",
        "input_hash": canonical_input_hash(project.data),
        "options": options.as_dict(),
        "page_size_limit": result.page_size,
        "exposure_scale": round(result.exposure_scale, 6),
        "pages": pages,
        "photos": photos,
        "faces": faces,
        "warnings": warnings,
    }
