"""``vebuild calibrate``: its words on the command line and what it prints (paper §2).

The calibration itself is :mod:`.calibrate`; this module is the command's face: the arguments
(camera groups made or released before calibrating), the progress bar, the table printed, and the
exit status: 0, or 1 where the calibration is written but fails its checks (a check distance
beyond its limit: ``calibration.failed_checks``); refusals are errors (status 2, vebuild.cli).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from vebuild.analysis.project_check import load_checked
    from vebuild.console.bars import Bar
    from vebuild.console.tables import calibration_table, failed_check_words
    from vebuild.project import save_project
    from vebuild.project.outputs import begin_stage

    from .calibrate import calibrate_project

    project = load_checked(args.project, "calibrate")
    if args.group or args.release:
        from .camera_group_records import apply_group_options

        apply_group_options(project.data, project.path, args.group or [], args.release or [])
    begin_stage(project)
    bars = not args.quiet and sys.stderr.isatty()
    result = calibrate_project(project, progress=lambda it: Bar(it, desc="calibrating", unit="photo",
                                                                disable=not bars))
    save_project(project)
    print(calibration_table(result))
    print(f"\ncameras written to {project.path}")
    if result.get("failed_checks"):  # exit status 1: written, but the calibration fails its checks
        for c in result["failed_checks"]:
            print(f"vebuild calibrate: check failed: {failed_check_words(c)}: the cameras disagree with the tape; "
                  "the calibration is written, marked as failing (calibration.failed_checks)", file=sys.stderr)
        return 1
    return 0


def add_calibrate_parser(sub: Any) -> None:
    """Add ``vebuild calibrate`` to the top-level subparsers ``sub``."""
    p = sub.add_parser("calibrate", help="calibrate every photo and place the cameras (paper §2)")
    p.add_argument("project", help="the project file (NAME.vebuild.json)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--group", action="append", metavar="ID=PHOTO,PHOTO",
                   help="photos taken with one camera, which share its focal length, principal point and lens "
                        "distortion (saved in the project's camera_groups; repeatable)")
    p.add_argument("--release", action="append", metavar="PHOTO",
                   help="release a photo from its camera group: its intrinsics are its own (saved as its "
                        "own_camera; repeatable)")
    p.set_defaults(func=_cmd_calibrate)
