"""``vebuild import FILE.fspy --out FOLDER``: its words on the command line and what it prints.

The import itself is :mod:`.fspy`; the comparison of fSpy's camera with vebuild's is
:mod:`.fspy_compare`; this module is the command's face: the arguments and the table printed.
"""

from __future__ import annotations

import argparse
from typing import Any

from .fspy import ImportResult, import_fspy


def comparison_table(result: ImportResult) -> str:
    """The comparison as a small text table: fSpy, vebuild (± 1σ), vebuild − fSpy."""
    def num(v: float | None, w: int = 11) -> str:
        return f"{'—':>{w}}" if v is None else f"{v:>{w}.3f}"

    lines = []
    if not result.fspy_camera:
        lines.append("the fSpy file holds no saved camera (cameraParameters is null): vebuild's calibration only")
    lines.append(f"{'':<30}{'fSpy':>11}{'vebuild':>11}{'± 1σ':>10}{'difference':>12}")
    for r in result.rows:
        sig = "" if r.sigma is None else f"{r.sigma:.3f}"
        lines.append(f"{r.quantity:<30}{num(r.fspy)}{num(r.vebuild)}{sig:>10}{num(r.difference, 12)}")
    return "\n".join(lines)


def _cmd_import(args: argparse.Namespace) -> int:
    r = import_fspy(args.file, args.out, click_sigma_px=args.click_sigma, name=args.name)
    print(f"imported {args.file} ({'one' if r.mode == 'OneVanishingPoint' else 'two'}-vanishing-point fSpy project) "
          f"into {r.project} with the photo {r.photo.name}")
    for note in r.notes:
        print(f"  {note}")
    for w in r.warnings:
        print(f"warning: {w}")
    if r.calibrated:
        print()
        print(comparison_table(r))
    return 0


def add_import_parser(sub: Any) -> None:
    """Add ``vebuild import`` (an fSpy project) to the top-level subparsers ``sub``."""
    p = sub.add_parser("import", help="import an fSpy project (.fspy) as a new project folder, calibrate it and "
                       "compare fSpy's camera with vebuild's")
    p.add_argument("file", help="the fSpy project file (FILE.fspy)")
    p.add_argument("--out", required=True, help="a new (or empty) folder for the project and its photo")
    p.add_argument("--name", help="title of the project (default: from the file name)")
    p.add_argument("--click-sigma", type=float, default=1.0, metavar="PX",
                   help="1σ of one of fSpy's control points, pixels (default: %(default)s)")
    p.set_defaults(func=_cmd_import)
