"""Bad inputs, section 11: links below an output folder (cases of tests/bad_inputs_corpus.py, which
imports this module once its own cases are made; run by tests/test_bad_inputs.py).

A writer never writes through a symbolic link below its output folder (a subfolder or a file), nor
replaces one name of a file that has others (a hard link): each outside target is under the test's
folder, so that the snapshot sees it untouched. The earlier outputs carry vebuild's mark, so that only
the link is refused.
"""

from __future__ import annotations

import hashlib
import json
import os
import struct
from collections.abc import Callable
from pathlib import Path

from bad_inputs_corpus import CMDS, PROJECT, Ctx, P, _atlas_file, case


def _elsewhere(ctx: Ctx) -> Path:
    """A folder outside every output folder and the project (still watched)."""
    folder = ctx.out.parent / "elsewhere"
    folder.mkdir(exist_ok=True)
    (folder / "keep.txt").write_text("someone else's\n")
    return folder


def _earlier_html(ctx: Ctx) -> Path:
    """An earlier `export --html` folder, as its manifest marks it."""
    viewer = ctx.out / "viewer"
    viewer.mkdir()
    files = ["index.html", "scene.glb", "photos/p1.jpg", "photos/p2.jpg"]
    (viewer / "vebuild-html.json").write_text(json.dumps({"software": "vebuild 0", "project": PROJECT,
                                                          "files": files}))
    (viewer / "index.html").write_text("<!doctype html>\n")
    return viewer


def _earlier_report(ctx: Ctx, *, linked: str = "") -> Path:
    """An earlier report folder whose manifest lists its report.html (``linked``: made a link)."""
    report = ctx.out / "report"
    report.mkdir()
    text = b"<!doctype html>\n"
    if linked == "symbolic":
        (_elsewhere(ctx) / "report.html").write_bytes(text)
        (report / "report.html").symlink_to(ctx.out.parent / "elsewhere" / "report.html")
    elif linked == "hard":
        (_elsewhere(ctx) / "report.html").write_bytes(text)
        os.link(ctx.out.parent / "elsewhere" / "report.html", report / "report.html")
    else:
        (report / "report.html").write_bytes(text)
    (report / ".vebuild-output.json").write_text(json.dumps({
        "software": "vebuild 0", "kind": "report", "project": PROJECT,
        "files": {"report.html": hashlib.sha256(text).hexdigest()}}))
    return report


def _html_photos_link(ctx: Ctx) -> None:
    photos = _elsewhere(ctx) / "photos"
    photos.mkdir()
    (_earlier_html(ctx) / "photos").symlink_to(photos, target_is_directory=True)


def _html_file_link(ctx: Ctx) -> None:
    (_earlier_html(ctx) / "notes.txt").symlink_to(_elsewhere(ctx) / "keep.txt")


def _html_hard_link(ctx: Ctx) -> None:
    os.link(_elsewhere(ctx) / "keep.txt", _earlier_html(ctx) / "scene.glb")


def _report_images_link(ctx: Ctx) -> None:
    (_earlier_report(ctx) / "images").symlink_to(_elsewhere(ctx), target_is_directory=True)


def _textures_sub_link(ctx: Ctx) -> None:
    (ctx.folder / "textures" / "more").symlink_to(_elsewhere(ctx), target_is_directory=True)


def _textures_file_link(ctx: Ctx) -> None:
    (ctx.folder / "textures" / "notes.txt").symlink_to(_elsewhere(ctx) / "keep.txt")


def _textures_hard_link(ctx: Ctx) -> None:
    os.link(_atlas_file(ctx), _elsewhere(ctx) / "atlas.png")


def _vebuild_png(path: Path) -> None:
    from PIL import Image, PngImagePlugin

    info = PngImagePlugin.PngInfo()
    info.add_text("Software", "vebuild 0 (an earlier render)")
    Image.new("RGB", (4, 4)).save(path, pnginfo=info)


def _vebuild_glb(path: Path) -> None:
    doc = json.dumps({"asset": {"version": "2.0", "generator": "vebuild 0"}}).encode()
    doc += b" " * (-len(doc) % 4)
    path.write_bytes(b"glTF" + struct.pack("<II", 2, 20 + len(doc)) + struct.pack("<II", len(doc), 0x4E4F534A) + doc)


def _vebuild_mp4(path: Path) -> None:
    import av
    import numpy as np

    with av.open(str(path), "w", format="mp4") as c:
        c.metadata["description"] = "vebuild 0"
        s = c.add_stream("mpeg4", rate=1)
        s.width, s.height, s.pix_fmt = 16, 16, "yuv420p"
        for packet in [*s.encode(av.VideoFrame.from_ndarray(np.zeros((16, 16, 3), np.uint8), format="rgb24")),
                       *s.encode()]:
            c.mux(packet)


def _hard_linked_output(name: str, make: Callable[[Path], None]) -> Callable[[Ctx], None]:
    """{OUT}/name: a file vebuild wrote (its mark) that has a second name outside."""
    def mutate(ctx: Ctx) -> None:
        outside = _elsewhere(ctx) / name
        make(outside)
        os.link(outside, ctx.out / name)
    return mutate


def _project_hard_link(ctx: Ctx) -> None:
    ctx.project.write_text(json.dumps(ctx.doc, indent=2, ensure_ascii=False) + "\n")
    ctx.write = False
    os.link(ctx.project, _elsewhere(ctx) / PROJECT)


def _project_symlink(ctx: Ctx) -> None:
    kept = _elsewhere(ctx) / PROJECT
    kept.write_text(json.dumps(ctx.doc, indent=2, ensure_ascii=False) + "\n")
    ctx.project.unlink()
    ctx.project.symlink_to(kept)
    ctx.write = False


HTML = ["export", P, "--html", "{OUT}/viewer"]
REPORT = ["report", P, "--out", "{OUT}/report", "--no-pdf", "--quiet"]
LINK_WORDS = ("symbolic link", "hard link")
case("output-html-photos-symlink", _html_photos_link, [HTML], ["{OUT}/viewer/photos"], any_of=list(LINK_WORDS))
case("output-html-file-symlink", _html_file_link, [HTML], ["{OUT}/viewer/notes.txt"], any_of=list(LINK_WORDS))
case("output-html-hard-link", _html_hard_link, [HTML], ["{OUT}/viewer/scene.glb"], any_of=list(LINK_WORDS))
case("output-report-images-symlink", _report_images_link, [REPORT], ["{OUT}/report/images"],
     any_of=list(LINK_WORDS))
case("output-report-file-symlink", lambda ctx: _earlier_report(ctx, linked="symbolic"), [REPORT],
     ["{OUT}/report", "report.html"])
case("output-report-hard-link", lambda ctx: _earlier_report(ctx, linked="hard"), [REPORT],
     ["{OUT}/report/report.html"], any_of=list(LINK_WORDS))
case("output-textures-subfolder-symlink", _textures_sub_link, ["texture"], ["{D}/textures/more"],
     any_of=list(LINK_WORDS))
case("output-textures-file-symlink", _textures_file_link, ["texture"], ["{D}/textures/notes.txt"],
     any_of=list(LINK_WORDS))
case("output-textures-hard-link", _textures_hard_link, ["texture"], ["{D}/{ATLAS}"], any_of=list(LINK_WORDS))
case("output-render-hard-link", _hard_linked_output("v.png", _vebuild_png), ["render-view"], ["{OUT}/v.png"],
     any_of=list(LINK_WORDS))
case("output-export-hard-link", _hard_linked_output("m.glb", _vebuild_glb), ["export"], ["{OUT}/m.glb"],
     any_of=list(LINK_WORDS))
case("output-export-obj-mtl-hard-link", _hard_linked_output("m.mtl", lambda p: p.write_text("# vebuild 0\n")),
     ["export-obj"], ["{OUT}/m.mtl"], any_of=list(LINK_WORDS))
case("output-video-hard-link", _hard_linked_output("w.mp4", _vebuild_mp4), ["video"], ["{OUT}/w.mp4"],
     any_of=list(LINK_WORDS))
case("output-figures-hard-link",
     _hard_linked_output("f.json", lambda p: p.write_text(json.dumps({"software": "vebuild 0"}))),
     [[*CMDS["analyse"], "--json", "{OUT}/f.json"]], ["{OUT}/f.json"], any_of=list(LINK_WORDS))
case("output-project-hard-link", _project_hard_link, [["case", P, "--number", "2026/17"], CMDS["mark"]], [P],
     any_of=list(LINK_WORDS))
case("output-project-symlink", _project_symlink, [["case", P, "--number", "2026/17"], CMDS["mark"]], [P],
     any_of=list(LINK_WORDS))
