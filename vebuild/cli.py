"""The ``vebuild`` command line: thin shells over the library's actions.

Every command loads what it needs, calls one library function, and prints. Errors caused by the
input (:class:`~vebuild.errors.VebuildError`) are printed as one clear message and exit status 2,
never as a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from . import __version__
from .console.terminal import escaped_output, shown
from .errors import VebuildError

if TYPE_CHECKING:
    from .project import Project


def _warn_stale(project: Project, command: str) -> None:
    """Name each stale result the command reads (vebuild.project.provenance.READS), on stderr."""
    from .project.provenance import stale_warnings

    for line in stale_warnings(project, command):
        print(line, file=sys.stderr)


def _cmd_solve(args: argparse.Namespace) -> int:
    from .actions.solve import solve_project
    from .analysis.project_check import load_checked
    from .console.tables import model_table
    from .project import save_project
    from .project.outputs import begin_stage

    project = load_checked(args.project, "solve")
    _warn_stale(project, "solve")
    begin_stage(project)
    result = solve_project(project, recalibrate=args.recalibrate, refine_intrinsics=not args.fixed_intrinsics)
    save_project(project)
    print(model_table(result))
    print(f"\nmodel written to {project.path}")
    return 0


def _cmd_view(args: argparse.Namespace) -> int:
    from .analysis.project_check import load_checked
    from .render.sizes import parse_size
    from .viewer.app import run_viewer

    project = load_checked(args.project, "view")
    _warn_stale(project, "view")
    run_viewer(project, parse_size(args.size), hypothesis=args.hypothesis, view=args.view, samples=args.samples,
               quad_stereo=args.quad_stereo)
    return 0


def _cmd_edit(args: argparse.Namespace) -> int:
    from .edit.screen import run_editor
    from .render.sizes import parse_size

    recover = True if args.recover else (False if args.discard_autosave else None)
    if not Path(args.project).exists():
        raise VebuildError(f"{args.project}: no such project file; start one from photos with "
                           f"`vebuild new {args.project} PHOTO…` (or with no photos, to add them on the screen)")
    run_editor(args.project, parse_size(args.size), recover=recover, add_photos=args.add_photo or ())
    return 0


def _cmd_mark(args: argparse.Namespace) -> int:
    from .analysis.markers import add_marker, place_marker
    from .analysis.project_check import load_checked
    from .project import save_project

    project = load_checked(args.project, "mark")
    markers = project.data.get("evidence_markers", [])
    if args.remove:
        if args.label not in [m["label"] for m in markers]:
            raise VebuildError(f"{project.path}: $.evidence_markers: no marker is labelled {args.label!r}")
        project.data["evidence_markers"] = [m for m in markers if m["label"] != args.label]
        save_project(project)
        print(f"evidence marker {args.label!r} removed from {project.path}")
        return 0
    if not args.at:
        raise VebuildError("mark: --at is required (X,Y,Z, photo:ID@u,v or view:NAME@u,v), or --remove")
    rec = place_marker(project, args.label, args.at, args.description or "")
    add_marker(project, rec)
    save_project(project)
    from .project.units import length_unit

    x, y, z = rec["position"]
    at = length_unit(project.data).after(f"({x:.3f}, {y:.3f}, {z:.3f})")
    print(f"evidence marker {args.label!r} on {rec['node']!r} at {at}, written to {project.path}")
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from .analysis.project_check import load_checked
    from .console.bars import Bar
    from .report.write import SECTIONS, write_report

    project = load_checked(args.project, "report")
    _warn_stale(project, "report")
    bar = Bar(total=SECTIONS + int(not args.no_pdf), desc="report", unit="section", disable=not _progress_wanted(args))

    def step(what: str) -> None:
        bar.set_postfix_str(shown(what))
        bar.update(1)
    try:
        page = write_report(project, Path(args.out), pdf=not args.no_pdf, progress=step, summary=args.summary,
                            paper=args.paper)
    finally:
        bar.close()
    print(f"report written to {page}" + ("" if args.no_pdf else f" and {page.with_suffix('.pdf')}"))
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    from .actions.render import RenderRequest, render_evidence
    from .analysis.project_check import load_checked
    from .project.decode import preset_names
    from .render.sizes import parse_size

    project = load_checked(args.project, "render")
    if args.list:
        views = project.data.get("views", [])
        print("views:" + ("" if views else " none (add them under \"views\" in the project file)"))
        for v in views:
            print(f"  {v['name']:<24} {v['width']}×{v['height']}  {v.get('description', '')}")
        print("photos: " + ", ".join(p["id"] for p in project.data["photos"]))
        print("lighting presets: " + ", ".join(preset_names(project)))
        return 0
    if not args.out:
        raise VebuildError("render: --out FILE.png is required (or --list to see the views and presets)")
    _warn_stale(project, "render")
    req = RenderRequest(out=Path(args.out), view=args.view, photo=args.photo,
                        size=parse_size(args.size) if args.size is not None else None, lighting=args.lighting,
                        stereo=args.stereo, eye_separation=args.eye_separation, convergence=args.convergence,
                        samples=args.samples, shadows=not args.no_shadows, validate=args.validate,
                        hypothesis=args.hypothesis, unobserved=args.unobserved)
    result = render_evidence(project, req)
    for w in result.warnings:
        print(f"warning: {w}")
    what = f"view '{args.view}'" if args.view else f"photo '{result.camera.id}'"
    print(f"{what}, lighting '{result.lighting}', {result.size[0]}×{result.size[1]} written to {result.out}")
    if result.overlay is not None:
        assert result.covered_fraction is not None and result.rms_colour_difference is not None
        print(f"overlay of the photo written to {result.overlay}")
        print(f"RMS colour difference over the {100 * result.covered_fraction:.1f} % of pixels the model covers: "
              f"{result.rms_colour_difference:.1f} sRGB levels (after an exposure gain of {result.exposure_gain:.3f})")
    return 0


def _cmd_texture(args: argparse.Namespace) -> int:
    from .actions.texture import texture_project
    from .analysis.project_check import load_checked
    from .console.progress import progress_bar
    from .console.tables import texture_table
    from .texture.options import Options

    project = load_checked(args.project, "texture")
    try:
        options = Options(texels_per_metre=args.density, max_face_texels=args.max_face_texels, mode=args.mode,
                          fill=args.fill, erode_px=0.0 if args.no_erode else args.erode_px,
                          drop_ratio=0.0 if args.no_drop else args.drop_ratio,
                          detail_sharpness=1.0 if args.no_detail else Options.detail_sharpness,
                          exposure=not args.no_exposure)
    except VebuildError as e:
        raise VebuildError(f"{project.path}: {e}") from None
    _warn_stale(project, "texture")
    with progress_bar(_progress_wanted(args)) as progress:
        record, _ = texture_project(project, options, progress)  # pages, then the project, then old pages
    from .project.units import length_unit

    print(texture_table(record, length_unit(project.data)))
    print(f"\ntextures written to {project.folder / 'textures'}; recorded in {project.path}")
    return 0


def _cmd_video(args: argparse.Namespace) -> int:
    from .analysis.project_check import load_checked
    from .console.progress import progress_bar
    from .project.units import length_unit
    from .render.sizes import parse_size
    from .render.video import DEFAULT_SPEED, Timing, VideoRequest, parse_views, render_video

    project = load_checked(args.project, "video")
    _warn_stale(project, "video")
    unit = length_unit(project.data)
    if args.seconds is None:
        unit.refuse(f"video: the walking speed ({args.speed or DEFAULT_SPEED:g} m/s; give --seconds per segment "
                    "instead)")
    timing = Timing(fps=args.fps, speed=args.speed, seconds=args.seconds, hold=args.hold,
                    turn_rate_deg=args.turn_rate)
    size = parse_size(args.size) if args.size is not None else None
    request = VideoRequest(parse_views(args.views), Path(args.out) if args.out else None,
                           size, timing, args.lighting, args.stereo, args.crf, unobserved=args.unobserved)
    with progress_bar(_progress_wanted(args), desc="video", unit="frame") as progress:
        r = render_video(project, request, progress)
    for w in r.warnings:
        print(f"warning: {w}")
    print(f"wrote {r.out} (H.264 {r.encoder}, {r.width}×{r.height}, {r.fps:g} fps, {r.frames} frames, "
          f"{r.duration:.1f} s, {r.bytes / 1e6:.2f} MB)")
    print(f"  {unit.length(r.length, 2)} of path, lighting {r.lighting}; "
          f"{r.render_seconds / r.frames:.3f} s per frame rendered and encoded")
    print("  views at frames: " + ", ".join(f"{name} {k}" for name, k in r.keyframes))
    return 0


def _cmd_register(args: argparse.Namespace) -> int:
    from .actions.register import register_photos
    from .analysis.project_check import load_checked
    from .console.tables import calibration_table
    from .project import save_project

    project = load_checked(args.project, "register")
    _warn_stale(project, "register")
    done = register_photos(project, args.photos or None)
    save_project(project)
    cal = project.data["calibration"]
    print(calibration_table({**cal, "cameras": {pid: cal["cameras"][pid] for pid in done},
                             "markers": {}, "reference_distances": [], "warnings": []}))
    print(f"{len(done)} photo(s) registered in {project.path}")
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from .analysis.project_check import load_checked
    from .render.export import export_model

    project = load_checked(args.project, "export")
    _warn_stale(project, "export")
    if args.html is not None:
        from .actions.export_html import export_html

        h = export_html(project, args.html, photo=args.camera)
        print(f"wrote the viewer {h.folder}/index.html ({len(h.files)} files; open it in a browser, no network needed)")
        print(f"  {len(h.cameras)} camera(s), {h.photos} photo(s), {h.markers} evidence marker(s), "
              f"{h.analyses} analysis item(s), {h.hypotheses} hypothesis(es)")
        for w in h.warnings:
            print(f"warning: {w}")
        if args.out is None:
            return 0
    if args.out is None:
        raise VebuildError("export: give --out FILE.glb|FILE.obj, --html DIR, or both")
    if args.camera is not None or not (project.data.get("model") or {}).get("nodes"):
        from .actions.handoff import export_camera_command

        return export_camera_command(project, args.camera, args.out)
    r = export_model(project, args.out)
    what = {"glb": "glTF 2.0 binary", "obj": "Wavefront OBJ + MTL"}[r.format]
    size = sum(f.stat().st_size for f in r.files)
    print(f"wrote {r.path} ({what}, {size / 1e6:.2f} MB)")
    print(f"  {r.nodes} node(s), {r.meshes} mesh(es) in {r.primitives} primitive(s), {r.triangles} triangles")
    if r.format == "glb":
        print(f"  {len(r.cameras)} camera(s)" + (f": {', '.join(r.cameras)}" if r.cameras else ""))
    if r.textured:
        how = "embedded" if r.format == "glb" else "copied next to it"
        print(f"  {len(r.pages)} texture page(s), {how}: {', '.join(str(p) for p in r.pages)}")
    else:
        print("  untextured (face colours)")
    if len(r.files) > 1:
        print("  files: " + ", ".join(str(f) for f in r.files))
    for w in r.warnings:
        print(f"warning: {w}")
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    from .actions.check import check_project, project_status
    from .project import load_project

    project = load_project(args.project)
    details = check_project(project)
    photos = project.data["photos"]
    status = project_status(project)
    from .project.stills import check_videos

    videos, video_changed = check_videos(project)
    outside = "; changed outside vebuild (see the audit trail below)" if status.audit else ""
    print(f"{project.path}: {'stale' if status.stale else 'valid'} vebuild project (format version "
          f"{project.data['version']}), {len(photos)} photo(s), hashes verified{outside}")
    for p in photos:
        n_seg = sum(len(v) for v in (p.get("vanishing_segments") or {}).values())
        print(f"  {p['id']:<10} {p['file']:<28} {p['width']}×{p['height']}  sha256 {p['sha256'][:16]}…  "
              f"{n_seg} segments, {len(p.get('marker_observations') or {})} markers")
    for line in details + videos + status.lines:
        print(f"  {line}")
    return 0 if status.clean and not video_changed else 1


def _cmd_demo(args: argparse.Namespace) -> int:
    from .actions.demo import run_demo

    return run_demo(Path(args.out), progress=_progress_wanted(args))


def _cmd_bench(args: argparse.Namespace) -> int:
    from .bench import run_bench
    from .project.atomic import write_text
    from .project.outputs import check_file

    if args.json:
        check_file(None, Path(args.json), "figures")
    figures, text = run_bench(args.name, quick=args.quick, progress=_progress_wanted(args), data=args.data)
    print(text)
    if args.json:
        out = Path(args.json)
        try:  # "software" marks the file as vebuild's (vebuild/project/outputs.py)
            write_text(out, json.dumps({"software": f"vebuild {__version__}", **figures}, indent=2) + "\n")
        except OSError as e:
            raise VebuildError(f"{out}: cannot write the figures ({e.strerror or e})") from None
        print(f"figures written to {out}")
    return 0


def _progress_wanted(args: argparse.Namespace) -> bool:
    return not getattr(args, "quiet", False) and sys.stderr.isatty()


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The command line's parser; with ``command``, one that adds that command's arguments only.

    Every command is named, with its line of help, so that ``vebuild --help`` lists them all and a
    mistyped one gets "did you mean"; but only the command being run gets its arguments, whose
    defaults and choices come from the modules that run it: ``vebuild check`` imports no renderer
    (docs/start-up.md). ``command=None``: every command's arguments; ``""``: none.
    """
    from .console.arguments import SuggestingParser

    parser = SuggestingParser(prog="vebuild", description="Rebuild a real place as a measurable virtual environment "
                              "from a few photographs.")
    parser.add_argument("--version", action="version", version=f"vebuild {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command_parser(name: str, help: str) -> argparse.ArgumentParser | None:
        """Name the command; its parser, to add its arguments to, if it is the one being run."""
        p: argparse.ArgumentParser = sub.add_parser(name, help=help)
        return p if command in (None, name) else None

    if p := command_parser("demo", help="run the whole pipeline on the bundled example room"):
        p.add_argument("--out", default="vebuild-demo", help="folder to copy the example into (default: %(default)s)")
        p.add_argument("--quiet", action="store_true", help="no progress bars")
        p.set_defaults(func=_cmd_demo)

    if p := command_parser("solve", help="fit the model's primitives to the pins (paper §3.1); --recalibrate: §3.2"):
        p.add_argument("project")
        p.add_argument("--recalibrate", action="store_true",
                       help="solve cameras and markers jointly with the model (robust; cameras held by their "
                            "calibration)")
        p.add_argument("--fixed-intrinsics", action="store_true",
                       help="with --recalibrate: keep focal lengths and principal points as calibrated")
        p.set_defaults(func=_cmd_solve)

    if p := command_parser("render", help="render an evidence view or a photo's camera to a PNG with its provenance"):
        from .actions.render import RenderRequest
        from .render.observed import add_option as add_unobserved_option

        p.add_argument("project")
        which = p.add_mutually_exclusive_group()
        which.add_argument("--view", metavar="NAME", help="a named view of the project")
        which.add_argument("--photo", metavar="ID", help="a photo's calibrated camera (its id, or its number from 1)")
        which.add_argument("--list", action="store_true", help="list the views, photos and lighting presets")
        p.add_argument("--out", metavar="FILE.png", help="the image to write")
        p.add_argument("--size", metavar="WxH", help="image size in pixels (default: the view's or photo's)")
        p.add_argument("--lighting", metavar="PRESET",
                       help="a lighting preset of the project (default: as-photographed, the textures unlit)")
        p.add_argument("--stereo", choices=("sbs", "tb", "anaglyph"),
                       help="a stereo pair: side by side, top and bottom, or red-cyan anaglyph")
        p.add_argument("--eye-separation", type=float, default=RenderRequest.eye_separation, metavar="M",
                       help="distance between the eyes in metres (default: %(default)s)")
        p.add_argument("--convergence", type=float, metavar="M",
                       help="distance of the screen plane (zero parallax) in metres (default: the scene's centre)")
        p.add_argument("--samples", type=int, default=RenderRequest.samples, metavar="N",
                       help="anti-aliasing samples (default: %(default)s)")
        p.add_argument("--no-shadows", action="store_true", help="lights cast no shadows")
        p.add_argument("--hypothesis", metavar="NAME",
                       help="the objects arranged as in this hypothesis (the image is labelled as one)")
        add_unobserved_option(p)
        p.add_argument("--validate", action="store_true",
                       help="with --photo: also write the photo overlaid on the render and print the RMS colour "
                            "difference")
        p.set_defaults(func=_cmd_render)

    if p := command_parser("view", help="walk through the scene in a window, move objects as their joints allow"):
        p.add_argument("project")
        p.add_argument("--size", default="1280x720", metavar="WxH", help="window size (default: %(default)s)")
        p.add_argument("--view", metavar="NAME", help="start at this named view (default: the first)")
        p.add_argument("--hypothesis", metavar="NAME", help="start with the objects arranged as in this hypothesis")
        p.add_argument("--samples", type=int, default=1, metavar="N",
                       help="anti-aliasing samples (default: %(default)s; more cost frame rate without a GPU)")
        p.add_argument("--quad-stereo", action="store_true",
                       help="ask the display for quad-buffered stereo (shutter glasses; B switches to it if given)")
        p.set_defaults(func=_cmd_view)

    if p := command_parser("edit", help="the modelling screen: mark the photos, calibrate, build and solve the "
                           "model (paper §2-3)"):
        p.add_argument("project", help="the project file (NAME.vebuild.json; `vebuild new` starts one)")
        p.add_argument("--size", default="1400x860", metavar="WxH", help="window size (default: %(default)s)")
        rec = p.add_mutually_exclusive_group()
        rec.add_argument("--recover", action="store_true",
                         help="take the edits an earlier session left in the side file PROJECT.autosave")
        rec.add_argument("--discard-autosave", action="store_true", help="discard the autosave side file's edits")
        p.add_argument("--add-photo", action="append", metavar="FILE",
                       help="add this image (in the project's folder) to the project first, or a video's frame as "
                            "CLIP@frame=N or CLIP@time=SECONDS; repeat for more")
        p.set_defaults(func=_cmd_edit)

    if p := command_parser("mark", help="place (or remove) a labelled evidence marker on a surface of the model"):
        p.add_argument("project")
        p.add_argument("label", help="the marker's label, such as A or \"cartridge case\"")
        p.add_argument("--at", metavar="WHERE", help="X,Y,Z (a point on a surface, metres), photo:ID@u,v or "
                       "view:NAME@u,v (the surface seen at that pixel)")
        p.add_argument("--description", help="what the marker marks")
        p.add_argument("--remove", action="store_true", help="remove the marker with this label")
        p.set_defaults(func=_cmd_mark)

    if p := command_parser("report", help="an HTML (and PDF) report another examiner can reproduce from the project"):
        p.add_argument("project")
        p.add_argument("--out", required=True, metavar="DIR",
                       help="the folder to write: new, empty, or an earlier report (replaced); never the project's "
                            "folder")
        p.add_argument("--no-pdf", action="store_true", help="only the HTML and its images")
        p.add_argument("--summary", action="store_true",
                       help="a short report for a briefing (at most 4 pages): the case, the question, the answers, "
                            "the plan, the evidence views and the limitations; no annex")
        p.add_argument("--paper", choices=("A4", "letter"), default="A4", help="the PDF's paper size (default A4)")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
        p.set_defaults(func=_cmd_report)

    if p := command_parser("texture", help="extract textures from the photos onto the model (paper §4)"):
        from .texture.options import FILLS, MODES, Options

        p.add_argument("project")
        p.add_argument("--density", type=float, default=Options.texels_per_metre, metavar="T",
                       help="texels per metre on every face (default: %(default)s)")
        p.add_argument("--max-face-texels", type=int, default=Options.max_face_texels, metavar="N",
                       help="at most N texels along a face's side (default: %(default)s)")
        p.add_argument("--mode", choices=MODES, default=Options.mode,
                       help="'average': one colour per face (paper Figure 9, middle)")
        p.add_argument("--fill", choices=FILLS, default=Options.fill,
                       help="how texels no photo saw are filled: smoothly from the seen ones, or with "
                            "the face's average colour (the paper)")
        p.add_argument("--erode-px", type=float, default=Options.erode_px, metavar="PX",
                       help="keep texels this far from occluding edges (default: %(default)s)")
        p.add_argument("--drop-ratio", type=float, default=Options.drop_ratio, metavar="R",
                       help="ignore a view where it is R times worse than the texel's best (default: %(default)s)")
        p.add_argument("--no-erode", action="store_true", help="take texels right up to occluding edges")
        p.add_argument("--no-drop", action="store_true", help="average every view, however poor")
        p.add_argument("--no-detail", action="store_true",
                       help="plain weighted average (the paper) instead of detail from the best view")
        p.add_argument("--no-exposure", action="store_true", help="do not compensate exposure between photos")
        p.add_argument("--quiet", action="store_true", help="no progress bars")
        p.set_defaults(func=_cmd_texture)

    if p := command_parser("video", help="render a walk-through through named views to an MP4 (H.264)"):
        from .render.observed import add_option as add_unobserved_option
        from .render.video import Timing, VideoRequest

        p.add_argument("project")
        p.add_argument("--views", required=True, metavar="A,B,C",
                       help="the views to walk through, in order, by name (at least two)")
        p.add_argument("--out", metavar="FILE.mp4", help="the video (default: videos/<views>.mp4 beside the project)")
        p.add_argument("--size", metavar="WxH", help="image size, even (default: the first view's)")
        p.add_argument("--fps", type=float, default=Timing.fps, help="frames per second (default: %(default)g)")
        how = p.add_mutually_exclusive_group()
        how.add_argument("--speed", type=float, metavar="M_PER_S", help="walking speed (default: 1 m/s)")
        how.add_argument("--seconds", type=float, metavar="S",
                         help="seconds for each segment between two views, whatever its length")
        p.add_argument("--hold", type=float, default=Timing.hold, metavar="S",
                       help="seconds to stay at each view (default: %(default)g)")
        p.add_argument("--turn-rate", type=float, default=Timing.turn_rate_deg, metavar="DEG_PER_S",
                       help="fastest turn (or zoom), which sets the time of segments that turn more than they "
                            "move (default: %(default)g)")
        p.add_argument("--lighting", metavar="PRESET", help="a lighting preset (default: as photographed)")
        p.add_argument("--stereo", choices=("sbs", "tb", "anaglyph"), help="stereo: side by side, top and bottom, "
                       "or red-cyan anaglyph")
        p.add_argument("--crf", type=int, default=VideoRequest.crf,
                       help="x264 quality, 0 (best) to 51 (default: %(default)s)")
        add_unobserved_option(p)
        p.add_argument("--quiet", action="store_true", help="no progress bars")
        p.set_defaults(func=_cmd_video)

    if p := command_parser("register", help="place further photos from known points (paper §3.2)"):
        p.add_argument("project")
        p.add_argument("photos", nargs="*", help="photo ids (default: every photo without a camera)")
        p.set_defaults(func=_cmd_register)

    if p := command_parser("export", help="write the textured model as glTF 2.0 binary (.glb) or OBJ + MTL (.obj)"):
        p.add_argument("project")
        p.add_argument("--out", metavar="FILE",
                       help="FILE.glb (model, textures, views and photo cameras) or FILE.obj (model and textures)")
        p.add_argument("--html", metavar="DIR", help="a folder with a web viewer (index.html, the .glb, the photos, "
                       "markers, analyses and hypotheses) that opens in a browser with no network "
                       "(docs/html-viewer.md)")
        p.add_argument("--camera", metavar="PHOTO", help="hand on one calibrated photo with no model: --out FILE.glb "
                       "(its camera, the photo as a plane at the camera's frustum, the floor grid, the axes and its "
                       "measurements), --out FILE.fspy (an fSpy project for fSpy and its Blender add-on), --html DIR "
                       "(the viewer of that photo); the only calibrated photo where the project has one "
                       "(docs/export.md)")
        p.set_defaults(func=_cmd_export)

    if p := command_parser("check", help="validate a project file, verify its photos' hashes and audit trail, and "
                           "say which results are stale (exit status 1 if any is, or if the file was changed outside "
                           "vebuild)"):
        p.add_argument("project")
        p.set_defaults(func=_cmd_check)

    if p := command_parser("bench", help="measure accuracy and speed (prints a table; --json writes the figures)"):
        from .bench import BENCHES

        p.add_argument("name", choices=sorted(BENCHES))
        p.add_argument("--quick", action="store_true", help="a smaller run, for a quick look")
        p.add_argument("--json", metavar="OUT", help="write the figures to OUT as JSON")
        p.add_argument("--data", metavar="DIR", help="bench real: the photo sets with surveyed cameras")
        p.add_argument("--quiet", action="store_true", help="no progress bars")
        p.set_defaults(func=_cmd_bench)

    for name, help, module, adder in _PARSERS_BESIDE_ACTIONS:
        if command in (None, name):
            getattr(importlib.import_module(module, __package__), adder)(sub)
        else:
            sub.add_parser(name, help=help)
    return parser


#: The commands whose parsers are made beside their actions: name, help (as their parsers say it,
#: tests/test_cli_start.py), module and function, imported only to run that command.
_PARSERS_BESIDE_ACTIONS = (
    ("calibrate", "calibrate every photo and place the cameras (paper §2)", ".actions.calibrate_command",
     "add_calibrate_parser"),
    ("analyse", "forensic analyses of a solved project: measurements with uncertainty, check distances (…; --json "
     "OUT writes the figures)", ".analysis.cli", "add_analyse_parsers"),
    ("import", "import an fSpy project (.fspy) as a new project folder, calibrate it and compare fSpy's camera with "
     "vebuild's", ".actions.fspy_command", "add_import_parser"),
    ("detect", "detect straight edges, group them by vanishing point and add them to the photos as vanishing "
     "segments (then calibrate)", ".actions.detect", "add_detect_parser"),
    ("scan", "laser scans (E57, PLY, LAS, LAZ): register one from targets; check the model against them",
     ".actions.scan", "add_scan_parsers"),
    ("case", "set (or show) the case details on the report's title page", ".actions.case", "add_case_parser"),
    ("new", "start a project from photos or video stills (records their size, SHA-256 and EXIF or video frame)",
     ".actions.photos_command", "add_new_parser"),
    ("add", "add photos or video stills to a project", ".actions.photos_command", "add_add_parser"),
)


@escaped_output()  # every text printed shows its control characters rather than sends them (console/terminal.py)
def main(argv: Sequence[str] | None = None) -> int:
    words = list(sys.argv[1:] if argv is None else argv)
    # The command is the first word that is not an option (`vebuild --version` has none).
    args = build_parser(next((w for w in words if not w.startswith("-")), "")).parse_args(words)
    try:
        from .determinism import fixed_threads

        arguments = words[words.index(args.command) + 1:] if args.command in words else words
        with fixed_threads():  # before numpy loads, so that its BLAS starts on one thread
            from .console.arguments import path_words
            from .project.provenance import command_context

            # Every save of the project file while the command runs appends its audit entry (project/file.py).
            with command_context(args.command, arguments, path_words(args)):
                return int(args.func(args))
    except VebuildError as e:
        from .console.messages import error_in_words

        print(f"vebuild {args.command}: error: {error_in_words(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
