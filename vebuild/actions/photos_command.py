"""``vebuild new`` and ``vebuild add``: start a project from photos, or add photos to one; a video
file gives a still of the frame named (vebuild/project/stills.py, docs/video-stills.md).

Everything asked for is decoded and checked first; then the stills' PNGs are written and then the
project file, so that a refused word leaves nothing written.
"""

from __future__ import annotations

import argparse
from typing import Any

from vebuild.errors import ProjectError
from vebuild.project import load_project, new_project, save_project
from vebuild.project.outputs import check_new_project
from vebuild.project.stills import Prepared, fixed_camera_groups, prepare_photos, write_stills

NEW_HELP = "start a project from photos or video stills (records their size, SHA-256 and EXIF or video frame)"
ADD_HELP = "add photos or video stills to a project"
_WORDS_HELP = ("image files inside the project's folder, or video files (MP4, MOV, AVI, MKV, ...) with the frame "
               "to take: CLIP@frame=N (from 0) or CLIP@time=SECONDS, or CLIP with --frame/--time; each still is "
               "written as a lossless PNG beside the video (CLIP.f000123.png)")


def _add_photo_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frame", type=int, action="append", default=[], metavar="N",
                   help="with a video named without @: take its frame N (from 0, in presentation order); repeat "
                        "for more frames")
    p.add_argument("--time", type=float, action="append", default=[], metavar="SECONDS",
                   help="with a video named without @: take the frame shown at this time (its presentation time "
                        "stamp); repeat for more")
    p.add_argument("--field", choices=("top", "bottom"),
                   help="of an interlaced video, keep one field: its rows exactly, the other rows interpolated "
                        "between them (full size, square pixels; half the vertical detail)")


def add_new_parser(sub: Any) -> None:
    """Add ``vebuild new`` to the top-level subparsers ``sub``."""
    p = sub.add_parser("new", help=NEW_HELP)
    p.add_argument("project", help="the project file to create (NAME.vebuild.json), next to the photos")
    p.add_argument("photos", nargs="*", help=_WORDS_HELP + " (or none: add them in `vebuild edit`)")
    _add_photo_arguments(p)
    p.add_argument("--name", help="title of the project (default: from the file name)")
    p.add_argument("--force", action="store_true",
                   help="replace an existing vebuild project file (never another file)")
    p.set_defaults(func=_cmd_new)


def add_add_parser(sub: Any) -> None:
    """Add ``vebuild add`` to the top-level subparsers ``sub``."""
    p = sub.add_parser("add", help=ADD_HELP)
    p.add_argument("project", help="the project file (NAME.vebuild.json)")
    p.add_argument("photos", nargs="+", help=_WORDS_HELP)
    _add_photo_arguments(p)
    p.set_defaults(func=_cmd_add)


def _said(prepared: list[Prepared]) -> str:
    stills = [p for p in prepared if "origin" in p.entry]
    lines = []
    for p in stills:
        o = p.entry["origin"]
        field = "" if o["field"] == "both" else f", {o['field']} field only"
        flag = " (interlaced)" if o["interlaced"] else ""
        lines.append(f"  {p.entry['file']}: frame {o['frame']} at {o['time']:g} s of {o['video']}{flag}{field}")
    return "\n".join(lines)


def _cmd_new(args: argparse.Namespace) -> int:
    path = check_new_project(args.project, args.force)
    prepared = prepare_photos(path.parent, args.photos, args.frame, args.time, args.field)
    data = new_project(args.name or path.name.split(".")[0])
    data["photos"] = [p.entry for p in prepared]
    fixed_camera_groups(data)
    write_stills(prepared)
    save_project(path, data)
    print(f"created {path} with {len(data['photos'])} photo(s)")
    if said := _said(prepared):
        print(said)
    return 0


def _cmd_add(args: argparse.Namespace) -> int:
    project = load_project(args.project, verify_photos=False)
    before = {p["id"] for p in project.data["photos"]}
    files = {p["file"] for p in project.data["photos"]}
    prepared = prepare_photos(project.folder, args.photos, args.frame, args.time, args.field, taken=before)
    for p in prepared:
        if p.entry["file"] in files:
            raise ProjectError(project.path, "$.photos", f"the photo {p.entry['file']!r} is already in the project")
    project.data["photos"].extend(p.entry for p in prepared)
    fixed_camera_groups(project.data)
    write_stills(prepared)
    save_project(project)
    print(f"added {len(prepared)} photo(s) to {project.path}")
    if said := _said(prepared):
        print(said)
    return 0
