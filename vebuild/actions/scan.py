"""``vebuild scan add`` and ``vebuild scan check``: laser scans into the project, and the model
checked against them (docs/scans.md; FORMAT.md "Laser scans: `scans`").

``scan add PROJECT SCANFILE --target NAME=X,Y,Z:POINT …`` (or ``--targets FILE.csv``) reads the
scan, hashes it, registers it into the project frame from the targets (a similarity fitted by
Umeyama's method, :mod:`vebuild.calibration.similarity`) and records it in ``$.scans``; adding
a file already recorded replaces its entry (registered again). ``scan check PROJECT`` prints,
per face of the model, how far the scan's points lie from it.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from vebuild import __version__
from vebuild.analysis.project_check import load_checked
from vebuild.analysis.scans import CHECK_POINTS, MAX_DISTANCE_M, deviation_table, face_deviations, register_scan
from vebuild.errors import VebuildError
from vebuild.project import Project, save_project
from vebuild.project.scans import (
    Target,
    dropped_words,
    new_scan_entry,
    parse_target,
    read_point_cloud,
    read_targets_csv,
    relative_file,
    scan_format,
)


def add_scan(project: Project, scan_file: str | Path, targets: list[Target], use_in_solve: bool = False,
             point_sigma_m: float | None = None) -> tuple[int, dict[str, Any]]:
    """Register ``scan_file`` from ``targets`` and record it in ``project.data["scans"]`` (not saved).
    Returns its index and entry."""
    scan_file = Path(scan_file)
    fmt = scan_format(scan_file, "SCANFILE")
    rel = relative_file(project, scan_file)
    if point_sigma_m is not None and not 1e-6 <= point_sigma_m <= 1e4:
        raise VebuildError(f"--point-sigma: expected a 1σ in metres from 1e-6 to 1e4, got {point_sigma_m!r}")
    cloud = read_point_cloud(scan_file, fmt, "SCANFILE")
    registration = register_scan(project, targets)
    entry = new_scan_entry(project, scan_file, cloud, registration, use_in_solve, point_sigma_m)
    scans = project.data.setdefault("scans", [])
    for i, old in enumerate(scans):
        if old["file"] == rel:
            scans[i] = entry
            return i, entry
    scans.append(entry)
    return len(scans) - 1, entry


def _cmd_add(args: argparse.Namespace) -> int:
    project = load_checked(args.project, "scan add")
    targets = [parse_target(t) for t in args.target or ()]
    if args.targets:
        targets += read_targets_csv(args.targets)
    index, entry = add_scan(project, args.scan, targets, args.use_in_solve, args.point_sigma)
    save_project(project)
    reg = entry["registration"]
    print(f"scan {index}: {entry['file']} ({entry['format'].upper()}, {entry['point_count']} points, SHA-256 "
          f"{entry['sha256'][:12]}…) registered from {len(reg['targets'])} targets: scale "
          f"{reg['similarity']['scale']:.6f}, rms {reg['rms_m'] * 1000:.1f} mm")
    for r in reg["residuals"]:
        print(f"  {r['name']:<16} residual {r['distance_m'] * 1000:7.1f} mm")
    print(f"  {dropped_words(entry) or 'points dropped: none (every point of the file is finite and valid)'}")
    print(f"written to {project.path}")
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    project = load_checked(args.project, "scan check")
    scans = project.data.get("scans") or []
    if not scans:
        raise VebuildError(f"{project.path}: $.scans: the project has no laser scans; add one with `vebuild scan add`")
    which = range(len(scans)) if args.scan is None else [args.scan]
    if args.max_points < 1:
        raise VebuildError(f"--max-points: expected a whole number of points ≥ 1, got {args.max_points}")
    if args.json:
        from vebuild.project.outputs import check_file

        check_file(project, Path(args.json), "figures")
    results = []
    for i in which:
        if not 0 <= i < len(scans):
            raise VebuildError(f"--scan {i}: the project has {len(scans)} scan(s), numbered from 0")
        r = face_deviations(project, i, args.max_distance, args.max_points)
        print(deviation_table(r))
        results.append({k: v for k, v in r.items() if k not in ("world", "signed")})
    if args.json:
        from vebuild.project.atomic import write_text
        from vebuild.project.provenance import inputs_sha256

        doc = {"software": f"vebuild {__version__}", "project": project.path.name,
               "inputs_sha256": inputs_sha256(project.data), "analysis": "scan check",
               "scans": results}
        write_text(Path(args.json), json.dumps(doc, indent=2, allow_nan=False) + "\n")
        print(f"figures written to {args.json}")
    return 0


def add_scan_parsers(sub: Any) -> None:
    """Add ``vebuild scan add`` and ``vebuild scan check`` to the top-level subparsers ``sub``."""
    p = sub.add_parser("scan", help="laser scans (E57, PLY, LAS, LAZ): register one from targets; check the model "
                       "against them")
    ssub = p.add_subparsers(dest="scan_command", required=True, metavar="ACTION")
    q = ssub.add_parser("add", help="register a scan into the project frame from targets and record it",
                        description="Register a laser scan (E57, PLY, LAS, LAZ) into the project frame by a "
                        "similarity (scale, rotation, translation) fitted to targets seen in both. A target is "
                        "NAME=X,Y,Z:POINT: its scan coordinates, then the project point it is (a marker, "
                        "node:handle, or node@face:s,t as `vebuild analyse` writes points).")
    q.add_argument("project", help="the project file (NAME.vebuild.json)")
    q.add_argument("scan", help="the scan file, inside the project's folder (never written to)")
    q.add_argument("--target", action="append", metavar="NAME=X,Y,Z:POINT",
                   help="a target: e.g. T1=1.204,3.551,0.102:cabinet:v4 (repeat; at least 3 in all)")
    q.add_argument("--targets", metavar="CSV", help="targets from a CSV file with the columns name,x,y,z,point")
    q.add_argument("--use-in-solve", action="store_true", help="use the scan's points as observations of the "
                   "model's faces in `vebuild solve` (default: a check only)")
    q.add_argument("--point-sigma", type=float, metavar="M", help="1σ of one scan point, metres (default 0.005)")
    q.set_defaults(func=_cmd_add)
    q = ssub.add_parser("check", help="per face of the model: the scan points' distance from it (median, p95)")
    q.add_argument("project", help="the project file, with scans")
    q.add_argument("--scan", type=int, metavar="N", help="only scan N (from 0; default: every scan)")
    q.add_argument("--max-distance", type=float, default=MAX_DISTANCE_M, metavar="M",
                   help=f"points farther than this from every face are not the model's (default {MAX_DISTANCE_M} m)")
    q.add_argument("--max-points", type=int, default=CHECK_POINTS, metavar="N",
                   help=f"compare a regular subsample of at most N points of each scan (default {CHECK_POINTS})")
    q.add_argument("--json", metavar="OUT", help="write the figures to OUT as JSON")
    q.set_defaults(func=_cmd_check)
