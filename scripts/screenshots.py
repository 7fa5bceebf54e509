"""Screenshots of vebuild's screens for the README, made from the bundled example room so that
they stay current: ``python3 scripts/screenshots.py [--out docs/images]``.

The example is copied to a temporary folder, calibrated, solved and textured there (as `vebuild
demo` does); then each screen is opened in a real window and its frame saved:

- ``edit-photo.png``: the modelling screen with a photo and its marks (segments, markers, the model
  over the photo);
- ``edit-proposals.png``: the same photo with the detected edges proposed as segments (D);
- ``view-panel.png``: the walk-through with its panel, the door opened by a drag (a hypothesis);
- ``view-present.png``: the same in presentation mode (Tab; F11 is the same full screen): the panel
  hidden, the legend (hypothesis, unobserved surfaces, scale bar) in its place;
- ``report-pages.png``: the report's first two pages side by side (needs pypdfium2; left out, and
  said, without it);
- ``one-photo-measure.png``: the modelling screen on a project of one generated photo (the example's
  p3 alone, as `vebuild new` makes it): its detected lines accepted, the door's height as the known
  length, calibrated, and two measurements made on the photo alone (the Measure tool, T): the box's
  height and a distance on the floor.
- ``one-photo-view.png``: the walk-through (`vebuild view`) on that project, which has no model: the
  photo at its camera with the floor grid and the axes over it, and the box's height measured on the
  photo alone (T, two clicks).

- ``demo-summary.png``: the last screen of `vebuild demo` (its check distance explained, its
  five-line summary), drawn as a terminal shows it.

``--only NAME`` (repeatable) makes only those images, e.g. ``--only one-photo-measure.png``.

Windows need a display: without one the script runs itself again under ``xvfb-run`` (Debian's
xvfb). Each image is downscaled to :data:`SHOTS`' width and saved with a 256-colour palette, so
that the committed files stay small.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "scenes" / "room"
#: Each image: the window it is taken from (width, height) and the width it is saved at.
SHOTS = {
    "edit-photo.png": ((1280, 800), 960),
    "edit-proposals.png": ((1280, 800), 960),
    "view-panel.png": ((1280, 720), 960),
    "view-present.png": ((1280, 720), 960),
    "report-pages.png": (None, 960),
    "one-photo-measure.png": ((1280, 800), 960),
    "one-photo-view.png": ((1280, 960), 960),
    "demo-summary.png": (None, 960),
}
#: The demo's last screen is drawn as a terminal of this many columns shows it.
TERMINAL_COLUMNS, TERMINAL_ROWS = 110, 30
#: The photo shown in the modelling screen, and the view and door opening in the walk-through.
PHOTO = "p3"
VIEW = "overview"
#: The door is opened this much further than measured (a hypothesis), in its hinge's sense.
DOOR_TURN_DEG = 30.0
XVFB_SCREEN = "1600x1200x24"


def save(img: np.ndarray | Image.Image, path: Path, width: int,
         method: Image.Quantize = Image.Quantize.MEDIANCUT) -> Path:
    """Downscale to ``width`` (keeping the shape) and write a palette PNG, atomically (``method``:
    how the 256 colours are chosen; the octree keeps a few thin lines' colour that median cut merges
    into larger areas of a near one)."""
    im = img if isinstance(img, Image.Image) else Image.fromarray(np.ascontiguousarray(img))
    im = im.convert("RGB")
    if im.width != width:
        im = im.resize((width, round(im.height * width / im.width)), Image.Resampling.LANCZOS)
    im = im.quantize(colors=256, method=method, dither=Image.Dither.FLOYDSTEINBERG)
    tmp = path.with_name(path.name + ".part")
    im.save(tmp, format="PNG", optimize=True)
    os.replace(tmp, path)
    return path


def prepare(folder: Path) -> Path:
    """The example copied into ``folder``, calibrated, solved and textured; its project file."""
    from vebuild.cli import main

    shutil.copytree(EXAMPLE, folder / "room")
    project = folder / "room" / "room.vebuild.json"
    for argv in (["calibrate", str(project), "--quiet"], ["solve", str(project)],
                 ["texture", str(project), "--density", "100", "--quiet"]):
        with open(os.devnull, "w") as null:
            old, sys.stdout = sys.stdout, null
            try:
                rc = main(argv)
            finally:
                sys.stdout = old
        if rc != 0:
            raise SystemExit(f"screenshots: `vebuild {' '.join(argv[:1])}` failed on the example ({rc})")
    return project


def shoot_editor(project: Path, out: Path) -> list[Path]:
    import glfw

    from vebuild.edit.screen import Editor
    from vebuild.edit.session import EditSession
    from vebuild.gl.surface import WindowSurface
    from vebuild.gl.window import Window

    (w, h), width = SHOTS["edit-photo.png"]
    written = []
    with Window(w, h, "vebuild edit — screenshots", visible=True) as window:
        session = EditSession.open(project, recover=False)
        editor = Editor(session, WindowSurface(window))
        try:
            editor.set_photo(PHOTO)
            for _ in range(len(session.photo_ids) + 4):  # the thumbnails come one a frame
                editor.frame()
            editor.draw()
            written.append(save(editor.surface.read(), out / "edit-photo.png", width))
            editor.key_pressed(glfw.KEY_D, 0)  # D: the photo's edges proposed as segments
            for _ in range(3):
                editor.frame()
            editor.draw()
            written.append(save(editor.surface.read(), out / "edit-proposals.png", width))
        finally:
            editor.close()
    return written


def _open_door(viewer: object) -> None:
    """Open the door DOOR_TURN_DEG further as a drag would (one undoable move), and say it."""
    from vebuild.viewer.moves import moved_line

    v = viewer
    mover = v.mover  # type: ignore[attr-defined]
    j = mover.model.node("door").joint
    q = j.values().copy()
    q[0] += math.radians(DOOR_TURN_DEG)
    before = mover._snapshot()
    mover._set_limited("door", j.clip(q))
    mover._push(before)
    v._model_changed()  # type: ignore[attr-defined]
    v.select("door")  # type: ignore[attr-defined]
    v.say(moved_line(mover, "door"))  # type: ignore[attr-defined]


def shoot_viewer(project: Path, out: Path) -> list[Path]:
    import glfw

    from vebuild.gl.window import Window
    from vebuild.project import load_project
    from vebuild.render.renderer import RenderOptions
    from vebuild.viewer.app import Viewer

    (w, h), width = SHOTS["view-panel.png"]
    written = []
    with Window(w, h, "vebuild view — screenshots", visible=True) as window:
        viewer = Viewer(load_project(project), window, RenderOptions.interactive(), view=VIEW)
        viewer.enable_gui()
        try:
            _open_door(viewer)

            def grab(name: str) -> Path:
                for _ in range(3):
                    viewer.frame()
                viewer.draw()
                fw, fh = window.framebuffer_size()
                data = window.ctx.screen.read(viewport=(0, 0, fw, fh), components=3, alignment=1)
                return save(np.frombuffer(data, np.uint8).reshape(fh, fw, 3)[::-1], out / name, width)

            written.append(grab("view-panel.png"))
            viewer.key_pressed(glfw.KEY_TAB, 0)  # presentation in the window (F11: the same, full screen)
            written.append(grab("view-present.png"))
        finally:
            viewer.close()
    return written


def shoot_report(project: Path, out: Path) -> list[Path]:
    try:
        import pypdfium2 as pdfium
    except ImportError:
        print("screenshots: report-pages.png left out (it needs pypdfium2: pip install pypdfium2)", file=sys.stderr)
        return []
    from vebuild.cli import main

    folder = project.parent / "report"
    # What an examiner records before the report: the case, its question and the measurements that
    # answer it (saved by the screens' measuring tools; written here as their words).
    data = json.loads(project.read_text())
    data["analyses"] = [
        {"name": "cabinet to table", "command": ["distance", "cabinet:v4", "table.top:v6"]},
        {"name": "table height", "command": ["height", "table.top:v6"]},
        {"name": "the box from the doorway", "command": ["sightline", "--standing", "3.7,0.4", "--object", "box"]}]
    project.write_text(json.dumps(data, indent=1))
    with open(os.devnull, "w") as null:
        old, sys.stdout = sys.stdout, null
        try:
            rc = main(["case", str(project), "--number", "2026/0417", "--examiner", "A. N. Examiner",
                       "--question", "How far is the cabinet from the table, how tall is the table, and could "
                       "someone standing in the doorway see the box?"])
            rc = rc or main(["report", str(project), "--out", str(folder)])
        finally:
            sys.stdout = old
    if rc != 0:
        raise SystemExit(f"screenshots: `vebuild report` failed on the example ({rc})")
    _, width = SHOTS["report-pages.png"]
    pdf = pdfium.PdfDocument(str(folder / "report.pdf"))
    try:
        pages = [pdf[i].render(scale=width / pdf[i].get_width()).to_pil().convert("RGB") for i in range(2)]
    finally:
        pdf.close()
    gap = width // 40
    sheet = Image.new("RGB", (sum(p.width for p in pages) + 3 * gap, max(p.height for p in pages) + 2 * gap),
                      (128, 128, 128))  # the pages on grey, as a PDF reader shows them
    x = gap
    for p in pages:
        sheet.paste(p, (x, gap))
        x += p.width + gap
    return [save(sheet, out / "report-pages.png", width)]


def shoot_demo(folder: Path, out: Path) -> list[Path]:
    """`vebuild demo` run into ``folder``; its last screen (the last :data:`TERMINAL_ROWS` lines, wrapped
    at :data:`TERMINAL_COLUMNS`) drawn as white text on a dark terminal."""
    import contextlib
    import io
    import textwrap

    from PIL import ImageDraw, ImageFont

    from vebuild.cli import main

    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        rc = main(["demo", "--out", str(folder / "demo"), "--quiet"])
    if rc != 0:
        raise SystemExit(f"screenshots: `vebuild demo` failed ({rc})")
    text = printed.getvalue().replace(str(folder / "demo"), "vebuild-demo").splitlines()
    lines = [w for line in text for w in (textwrap.wrap(line, TERMINAL_COLUMNS, subsequent_indent="    ")
                                          or [""])][-TERMINAL_ROWS:]
    font = ImageFont.truetype("DejaVuSansMono.ttf", 18)
    cw, ch = font.getbbox("M")[2], 24
    img = Image.new("RGB", (cw * TERMINAL_COLUMNS + 40, ch * len(lines) + 40), (30, 30, 30))
    draw = ImageDraw.Draw(img)
    for k, line in enumerate(lines):
        draw.text((20, 20 + k * ch), line, font=font, fill=(235, 235, 235))
    _, width = SHOTS["demo-summary.png"]
    return [save(img, out / "demo-summary.png", width)]


def _one_photo_project(folder: Path) -> tuple[Path, dict]:
    """A project of the example's photo PHOTO alone, its lines detected and accepted, the door's
    height (2.045 m, the hinge edge from the floor to its top) as its known length, calibrated;
    its project file and the example's ground truth."""
    import json

    from vebuild.camera import project as project_points
    from vebuild.cli import main
    from vebuild.edit.session import EditSession

    (folder / "photos").mkdir(parents=True)
    shutil.copy(EXAMPLE / "photos" / f"{PHOTO}.jpg", folder / "photos")
    path = folder / "one-photo.vebuild.json"
    with open(os.devnull, "w") as null:
        old, sys.stdout = sys.stdout, null
        try:
            rc = main(["new", str(path), str(folder / "photos" / f"{PHOTO}.jpg")])
        finally:
            sys.stdout = old
    if rc != 0:
        raise SystemExit(f"screenshots: `vebuild new` failed on the example's photo {PHOTO} ({rc})")
    truth = json.loads((EXAMPLE / "ground_truth.json").read_text())
    t = truth["photos"][PHOTO]
    K, R, C = (np.asarray(t[k], float) for k in ("K", "R", "C"))
    session = EditSession.open(path, recover=False)
    session.detect_lines(PHOTO)
    session.accept_all(PHOTO)
    hinge = np.array([4.2, 0.0, 0.0])
    session.add_known_length(PHOTO, "z", [project_points(K, R, C, hinge + [0, 0, z]) for z in (0.0, 2.045)], 2.045,
                             description="the door's top above the floor")
    session.calibrate()
    session.save()
    return path, {"K": K, "R": R, "C": C, "truth": truth}


def shoot_one_photo(folder: Path, out: Path) -> list[Path]:
    """The modelling screen on one calibrated photo with two single-view measurements drawn."""
    from vebuild.camera import project as project_points
    from vebuild.edit.screen import Editor
    from vebuild.edit.session import EditSession
    from vebuild.gl.surface import WindowSurface
    from vebuild.gl.window import Window

    path, t = _one_photo_project(folder)
    box = next(o for o in t["truth"]["objects"] if o["name"] == "box")
    c, (sx, sy, sz), a = np.asarray(box["centre"], float), box["size"], math.radians(box["yaw_deg"])
    turn = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    feet = [np.r_[c[:2] + turn @ [i * sx / 2, j * sy / 2], 0.0] for i in (-1, 1) for j in (-1, 1)]
    foot = min(feet, key=lambda X: float(np.linalg.norm(X - t["C"])))  # the box's edge nearest the camera

    def pixel(X: np.ndarray) -> np.ndarray:
        return project_points(t["K"], t["R"], t["C"], np.asarray(X, float))

    (w, h), width = SHOTS["one-photo-measure.png"]
    with Window(w, h, "vebuild edit — one photo", visible=True) as window:
        session = EditSession.open(path, recover=False)
        editor = Editor(session, WindowSurface(window))
        try:
            editor.set_photo(PHOTO)
            editor.layer_shown["vanishing points"] = False  # the measurements, not the calibration's rays
            for _ in range(4):
                editor.frame()
            editor.set_view(0.7, (840.0, 830.0))  # the lower part of the room, where the box and the door stand
            editor.measure_cycle()  # T: a height on the photo alone
            for X in (foot, foot + [0.0, 0.0, sz]):
                editor.measure_release(*editor.image_to_window(None, pixel(X)))
            editor.measure_cycle()  # T again: a distance on the floor
            for X in (foot, np.array([4.2, 0.0, 0.0])):  # to the door's hinge on the floor
                editor.measure_release(*editor.image_to_window(None, pixel(X)))
            editor.message_clock = lambda: math.inf  # the messages gone, as a few seconds later
            for _ in range(3):
                editor.frame()
            editor.draw()
            return [save(editor.surface.read(), out / "one-photo-measure.png", width, Image.Quantize.FASTOCTREE)]
        finally:
            editor.close()


def shoot_one_photo_view(folder: Path, out: Path) -> list[Path]:
    """The walk-through on the one-photo project (no model): the photo, the floor grid, the axes,
    and the box's height measured on the photo alone."""
    import glfw

    from vebuild.camera import project as project_points
    from vebuild.gl.window import Window
    from vebuild.project import load_project
    from vebuild.render.renderer import RenderOptions
    from vebuild.viewer.app import Viewer

    path, t = _one_photo_project(folder)
    box = next(o for o in t["truth"]["objects"] if o["name"] == "box")
    c, (sx, sy, sz), a = np.asarray(box["centre"], float), box["size"], math.radians(box["yaw_deg"])
    turn = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    feet = [np.r_[c[:2] + turn @ [i * sx / 2, j * sy / 2], 0.0] for i in (-1, 1) for j in (-1, 1)]
    foot = min(feet, key=lambda X: float(np.linalg.norm(X - t["C"])))
    (w, h), width = SHOTS["one-photo-view.png"]
    with Window(w, h, "vebuild view — one photo", visible=True) as window:
        viewer = Viewer(load_project(path), window, RenderOptions.interactive())
        viewer.enable_gui()
        try:
            viewer.measure_cycle()  # T: a height on the photo alone
            for X in (foot, foot + [0.0, 0.0, sz]):
                vx, vy, vw, vh = viewer.viewport()
                u, v = project_points(t["K"], t["R"], t["C"], X) * vw / viewer.project.photo(PHOTO)["width"]
                fw, fh = window.framebuffer_size()
                ww, wh = glfw.get_window_size(window.handle)
                viewer._cursor = ((vx + u) * ww / fw, (fh - vy - vh + v) * wh / fh)
                viewer.measure_click()
            for _ in range(3):
                viewer.frame()
            viewer.draw()
            fw, fh = window.framebuffer_size()
            data = window.ctx.screen.read(viewport=(0, 0, fw, fh), components=3, alignment=1)
            return [save(np.frombuffer(data, np.uint8).reshape(fh, fw, 3)[::-1], out / "one-photo-view.png", width,
                         Image.Quantize.FASTOCTREE)]
        finally:
            viewer.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "images", help="where the PNGs go")
    parser.add_argument("--no-report", action="store_true", help="leave out the report's first page")
    parser.add_argument("--only", action="append", choices=sorted(SHOTS), metavar="NAME",
                        help=f"make only this image (repeatable): {', '.join(SHOTS)}")
    args = parser.parse_args(argv)
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        xvfb = shutil.which("xvfb-run")
        if xvfb is None:
            print("screenshots: the windows need a display; none here and no xvfb-run (apt-get install xvfb)",
                  file=sys.stderr)
            return 2
        return subprocess.call([xvfb, "-a", "-s", f"-screen 0 {XVFB_SCREEN}", sys.executable, __file__,
                                *(argv if argv is not None else sys.argv[1:])])
    args.out.mkdir(parents=True, exist_ok=True)
    want = set(args.only or SHOTS) - ({"report-pages.png"} if args.no_report else set())
    with tempfile.TemporaryDirectory(prefix="vebuild-screenshots-") as tmp:
        written = []
        if want & {"edit-photo.png", "edit-proposals.png", "view-panel.png", "view-present.png", "report-pages.png"}:
            project = prepare(Path(tmp))
            written += shoot_editor(project, args.out) + shoot_viewer(project, args.out)
            if "report-pages.png" in want:
                written += shoot_report(project, args.out)
        if "one-photo-measure.png" in want:
            written += shoot_one_photo(Path(tmp) / "one-photo", args.out)
        if "demo-summary.png" in want:
            written += shoot_demo(Path(tmp), args.out)
        if "one-photo-view.png" in want:
            written += shoot_one_photo_view(Path(tmp) / "one-photo-view", args.out)
    for p in written:
        print(f"{p}  {Image.open(p).size[0]}×{Image.open(p).size[1]}  {p.stat().st_size // 1024} KiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
