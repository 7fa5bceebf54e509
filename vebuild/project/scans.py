"""Laser scans: point clouds read from E57, PLY, LAS and LAZ files, hashed and recorded in the
project (FORMAT.md, "Laser scans: `scans`").

A scan file is evidence like a photo: vebuild reads it, hashes its bytes (SHA-256) when it is
added and checks the hash each time it reads it again; it never writes to it. Readers:

- E57 (ASTM E2807) through pye57 (libE57Format): every scan in the file, each put in the file's
  frame by its own pose; Cartesian coordinates (or spherical ones converted), colours if given;
- PLY through trimesh: the vertices (a mesh's or a point cloud's) and their colours;
- LAS and LAZ through laspy (LAZ decompressed by its lazrs backend): the scaled coordinates, and
  the 16-bit colours of point formats that have them.

Each file's header is checked against its body first (:mod:`.scan_headers`): one that disagrees
is refused. Points with a non-finite coordinate are dropped and counted, up to
:data:`MAX_NON_FINITE_SHARE` of the scan's; E57 returns flagged invalid are dropped and counted.

Targets given on the command line (``NAME=X,Y,Z:POINT``) or in a CSV file (columns ``name, x, y,
z, point``) are parsed here; the project point they name is resolved against the model in
:mod:`vebuild.analysis.scans`.

Layer 3 of DESIGN.md: file I/O and records, no GL.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.errors import ProjectError, VebuildError

from .images import sha256_file
from .scan_headers import declared_points
from .validation import check_relative_path

Array = NDArray[np.float64]

#: File endings and the format each is read as.
FORMATS = {".e57": "e57", ".ply": "ply", ".las": "las", ".laz": "laz"}
#: Largest number of points read from one file (about 2.4 GB of float64 coordinates).
MAX_POINTS = 100_000_000
#: The largest share of a scan's points that may have a non-finite coordinate (NaN, ±inf): they
#: are dropped and counted. A scanner marks a return it could not measure with a flag (E57's
#: ``cartesianInvalidState``, dropped and counted apart), not with NaN; a few non-finite points are
#: a converter's way of writing the same (an organised cloud's empty cells); more than 1 % says the
#: values are damaged or read as the wrong type, and then the finite ones cannot be trusted either.
MAX_NON_FINITE_SHARE = 0.01
#: Default 1σ of one scan point along the surface normal, metres (a phase-based scanner at a few
#: metres: a few millimetres), when the scan entry gives no ``point_sigma_m``.
DEFAULT_POINT_SIGMA_M = 0.005


@dataclass(frozen=True)
class PointCloud:
    """Points (n, 3) in the scan's own frame, metres; colours (n, 3) uint8 sRGB or None."""

    points: Array
    colours: NDArray[np.uint8] | None
    format: str
    #: Points of the file dropped for a non-finite coordinate (NaN, ±inf).
    non_finite: int = 0
    #: E57 returns the scanner flagged invalid (``cartesianInvalidState`` not 0), dropped.
    invalid: int = 0


@dataclass(frozen=True)
class Target:
    """A target seen in the scan at ``scan_xyz`` (scan frame) that is the project point ``point``."""

    name: str
    scan_xyz: tuple[float, float, float]
    point: str


def scan_format(path: str | os.PathLike[str], where: str = "") -> str:
    """The format of a scan file, told by its ending; a ProjectError for any other ending."""
    ending = Path(path).suffix.lower()
    if ending not in FORMATS:
        raise ProjectError(path, where, f"a scan file ending in {ending or '(nothing)'!r}; expected one of "
                           f"{', '.join(sorted(FORMATS))} (E57, PLY, LAS, LAZ)")
    return FORMATS[ending]


def read_point_cloud(path: str | os.PathLike[str], fmt: str | None = None, where: str = "") -> PointCloud:
    """The points of a scan file (module docstring), once its header is found to agree with its body
    (:mod:`.scan_headers`). Points with a non-finite coordinate are dropped and counted, up to
    :data:`MAX_NON_FINITE_SHARE` of the file's; E57 returns flagged invalid are dropped and counted.
    Any failure is a ProjectError naming the file."""
    path = Path(path)
    fmt = fmt or scan_format(path, where)
    if fmt not in ("e57", "ply", "las", "laz"):
        raise ProjectError(path, where, f"unknown scan format {fmt!r}; expected e57, ply, las or laz")
    if not path.is_file():
        raise ProjectError(path, where, "the scan file is missing (expected a file at this path)")
    declared = None
    try:
        declared = declared_points(path, fmt, where)
        if declared > MAX_POINTS:
            raise ProjectError(path, where, f"its header declares {declared} points; vebuild reads at most "
                               f"{MAX_POINTS}")
        cloud = {"e57": _read_e57, "ply": _read_ply, "las": _read_las, "laz": _read_las}[fmt](path)
    except VebuildError:
        raise
    except MemoryError:
        raise ProjectError(path, where, "the scan is too large to read into memory") from None
    except Exception as e:  # each library has its own exceptions for a damaged file
        said = "" if declared is None else f" (its header declares {declared} points)"
        raise ProjectError(path, where, f"cannot read it as {fmt.upper()}{said}: {type(e).__name__}: {e}") from None
    P = cloud.points
    if P.ndim != 2 or P.shape[1] != 3 or len(P) + cloud.invalid != declared:
        raise ProjectError(path, where, f"its header declares {declared} points; {len(P) + cloud.invalid} were read")
    if len(P) == 0:
        raise ProjectError(path, where, f"the {fmt.upper()} file holds no points")
    finite = np.all(np.isfinite(P), axis=1)
    dropped = int(len(P) - np.count_nonzero(finite))
    if dropped > MAX_NON_FINITE_SHARE * len(P):
        raise ProjectError(path, where, f"{dropped} of its {len(P)} points ({100 * dropped / len(P):.2f} %) have a "
                           f"non-finite coordinate (NaN or infinite); vebuild drops such points up to "
                           f"{100 * MAX_NON_FINITE_SHARE:g} % of a scan's and refuses a scan with more (its values "
                           "are likely misread or damaged); remove them from the scan and add it again")
    if dropped:
        cloud = PointCloud(P[finite], None if cloud.colours is None else cloud.colours[finite], fmt,
                           non_finite=dropped, invalid=cloud.invalid)
    return cloud


def _read_e57(path: Path) -> PointCloud:
    import pye57  # type: ignore[import-untyped]

    e57 = pye57.E57(str(path), mode="r")
    try:
        pts, cols, invalid = [], [], 0
        for i in range(e57.scan_count):
            header = e57.get_header(i)
            fields = set(header.point_fields)
            data = e57.read_scan(i, ignore_missing_fields=True, intensity=False,
                                 colors={"colorRed", "colorGreen", "colorBlue"} <= fields,
                                 row_column=False, transform=True)
            # pye57 drops the returns flagged invalid (cartesianInvalidState or sphericalInvalidState not 0)
            xyz = np.column_stack([data["cartesianX"], data["cartesianY"], data["cartesianZ"]]).astype(float)
            pts.append(xyz)
            invalid += int(header.point_count) - len(xyz)
            if "colorRed" in data:
                cols.append(np.column_stack([data[k] for k in ("colorRed", "colorGreen", "colorBlue")]))
        colours = np.clip(np.concatenate(cols), 0, 255).astype(np.uint8) if cols and len(cols) == len(pts) else None
        return PointCloud(np.concatenate(pts) if pts else np.zeros((0, 3)), colours, "e57", invalid=invalid)
    finally:
        e57.close()


def _read_ply(path: Path) -> PointCloud:
    import trimesh

    loaded: Any = trimesh.load(str(path), file_type="ply", process=False)
    P = np.asarray(loaded.vertices, dtype=np.float64)
    colours = None
    if isinstance(loaded, trimesh.PointCloud):
        c = np.asarray(loaded.colors)
        if c.shape == (len(P), 4) and loaded.metadata.get("_ply_raw", {}).get("vertex", {}).get("data") is not None:
            names = loaded.metadata["_ply_raw"]["vertex"]["data"].dtype.names or ()
            if "red" in names:
                colours = c[:, :3].astype(np.uint8)
    else:
        vc = getattr(loaded.visual, "vertex_colors", None)
        if loaded.visual.kind == "vertex" and vc is not None and len(vc) == len(P):
            colours = np.asarray(vc)[:, :3].astype(np.uint8)
    return PointCloud(P, colours, "ply")


def _read_las(path: Path) -> PointCloud:
    import laspy  # type: ignore[import-untyped]

    las = laspy.read(str(path))
    P = np.column_stack([np.asarray(las.x, float), np.asarray(las.y, float), np.asarray(las.z, float)])
    colours = None
    dims = set(las.point_format.dimension_names)
    if {"red", "green", "blue"} <= dims:
        rgb = np.column_stack([np.asarray(las.red), np.asarray(las.green), np.asarray(las.blue)]).astype(np.uint32)
        colours = (rgb >> 8 if rgb.max(initial=0) > 255 else rgb).astype(np.uint8)
    return PointCloud(P, colours, "laz" if path.suffix.lower() == ".laz" else "las")


# ----------------------------------------------------------------------------------------------
# The project's scans


def scan_path(project: Any, index: int) -> Path:
    """The scan file of ``$.scans[index]``, confined to the project folder."""
    entry = project.data["scans"][index]
    where = f"$.scans[{index}].file"
    check_relative_path(entry["file"], project.path, where)
    path = (project.folder / entry["file"])
    try:
        inside = path.resolve().is_relative_to(project.folder.resolve())
    except OSError:
        inside = False
    if not inside:
        raise ProjectError(project.path, where, f"the scan {entry['file']!r} lies outside the project folder once "
                           "links are resolved; keep scans inside it")
    return path


def load_point_cloud(project: Any, index: int) -> PointCloud:
    """The points of ``$.scans[index]`` in the scan's frame, after checking the file's SHA-256."""
    scans = project.data.get("scans") or []
    if not 0 <= index < len(scans):
        raise VebuildError(f"{project.path}: $.scans: no scan {index} (the project has {len(scans)})")
    entry = scans[index]
    path = scan_path(project, index)
    if not path.is_file():
        raise ProjectError(path, f"$.scans[{index}].file", "the scan file is missing (the project records it "
                           f"with SHA-256 {entry['sha256'][:12]}…); put it back in the project folder")
    digest = sha256_file(path)
    if digest != entry["sha256"]:
        raise ProjectError(path, f"$.scans[{index}].sha256", f"the scan file's SHA-256 is {digest}, the project "
                           f"records {entry['sha256']}: the file was changed or replaced since it was added")
    cloud = read_point_cloud(path, entry["format"], f"$.scans[{index}].file")
    if len(cloud.points) != entry["point_count"]:
        raise ProjectError(path, f"$.scans[{index}].point_count", f"the file holds {len(cloud.points)} points, the "
                           f"project records {entry['point_count']}")
    for key, n, what in (("non_finite_dropped", cloud.non_finite, "with a non-finite coordinate"),
                         ("invalid_dropped", cloud.invalid, "flagged invalid")):
        if entry.get(key, n) != n:
            raise ProjectError(path, f"$.scans[{index}].{key}", f"the file has {n} points {what}, the project "
                               f"records {entry[key]}")
    return cloud


def dropped_words(entry: Mapping[str, Any]) -> str:
    """What was dropped from a scan's file as it was read (its entry's counts), or ''."""
    parts = [f"{entry[k]} {what}" for k, what in (("non_finite_dropped", "with a non-finite coordinate"),
                                                  ("invalid_dropped", "flagged invalid by the scanner"))
             if entry.get(k)]
    return f"points dropped: {' and '.join(parts)}" if parts else ""


def relative_file(project: Any, scan_file: str | os.PathLike[str]) -> str:
    """The scan's path relative to the project folder (forward slashes); a ProjectError outside it."""
    p = Path(scan_file)
    try:
        rel = p.resolve().relative_to(project.folder.resolve())
    except ValueError:
        raise ProjectError(p, "", f"the scan lies outside the project folder {project.folder}; copy it into that "
                           "folder (scans move with the project, as photos do)") from None
    return rel.as_posix()


def parse_target(text: str, where: str = "--target") -> Target:
    """``NAME=X,Y,Z:POINT``: the target NAME seen at X, Y, Z in the scan's frame is the project point
    POINT (a marker, ``node:handle``, ``node@face:s,t``: the syntax of ``vebuild analyse``)."""
    name, eq, rest = text.partition("=")
    xyz, colon, point = rest.partition(":")
    if not eq or not colon or not name.strip() or not point.strip():
        raise VebuildError(f"{where} {text!r}: expected NAME=X,Y,Z:POINT (the scan coordinates of the target, then "
                           "the project point it is: a marker, node:handle or node@face:s,t)")
    return Target(name.strip(), _xyz(xyz, f"{where} {text!r}"), point.strip())


def _xyz(text: str, where: str) -> tuple[float, float, float]:
    try:
        v = tuple(float(c) for c in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(np.isfinite(v)):
        raise VebuildError(f"{where}: expected the scan coordinates as three finite numbers X,Y,Z, got {text!r}")
    return (v[0], v[1], v[2])


def read_targets_csv(path: str | os.PathLike[str]) -> list[Target]:
    """Targets from a CSV file with a header row ``name,x,y,z,point`` (any order; extra columns ignored)."""
    path = Path(path)
    if not path.is_file():
        raise VebuildError(f"{path}: the targets file is missing")
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            rows = list(csv.DictReader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise VebuildError(f"{path}: cannot read it as a CSV file of targets: {e}") from None
    need = ("name", "x", "y", "z", "point")
    header = {k.strip().lower(): k for k in (rows[0].keys() if rows else ()) if k is not None}
    if not rows or any(k not in header for k in need):
        raise VebuildError(f"{path}: expected a header row with the columns {', '.join(need)} and a row per "
                           f"target; found columns {', '.join(header) or 'none'}")
    out = []
    for i, row in enumerate(rows, start=2):
        where = f"{path}: line {i}"
        name, point = (row[header["name"]] or "").strip(), (row[header["point"]] or "").strip()
        if not name or not point:
            raise VebuildError(f"{where}: a target needs a name and a project point")
        out.append(Target(name, _xyz(",".join(row[header[c]] or "" for c in "xyz"), where), point))
    return out


def check_target_names(targets: Sequence[Target], where: str) -> None:
    seen: set[str] = set()
    for t in targets:
        if t.name in seen:
            raise VebuildError(f"{where}: the target name {t.name!r} is given twice")
        seen.add(t.name)


def new_scan_entry(project: Any, scan_file: str | os.PathLike[str], cloud: PointCloud,
                   registration: Mapping[str, Any], use_in_solve: bool = False,
                   point_sigma_m: float | None = None) -> dict[str, Any]:
    """The ``$.scans[]`` entry of a scan file (its hash, format and point count, the registration)."""
    entry: dict[str, Any] = {"file": relative_file(project, scan_file), "sha256": sha256_file(scan_file),
                             "format": cloud.format, "point_count": int(len(cloud.points)),
                             "non_finite_dropped": cloud.non_finite, "invalid_dropped": cloud.invalid,
                             "registration": dict(registration), "use_in_solve": bool(use_in_solve)}
    if point_sigma_m is not None:
        entry["point_sigma_m"] = float(point_sigma_m)
    return entry
