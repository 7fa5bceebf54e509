"""``vebuild analyse PROJECT ANALYSIS …``: the forensic analyses on the command line.

Every subcommand prints a readable table and, with ``--json OUT``, writes its figures as JSON
(atomically): every number's unit is in its key (``value_m``, ``sigma_m``, ``ci95_m``). The JSON
document is ``{"software", "project", "analysis", ...the analysis' own keys}``.

Adding a subcommand (sight lines, trajectories, …): write ``def _my_thing(args, project) -> tuple[str,
dict]`` returning the table to print and the figures for ``--json``, then in
``add_analyse_parsers`` add ``p = _subcommand(asub, "name", "help", _my_thing)`` and its own
arguments with ``p.add_argument``. ``--json`` and the project argument come with it; errors are
raised as :class:`~vebuild.errors.VebuildError` and printed by ``vebuild``'s main.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .. import __version__

Handler = Callable[[argparse.Namespace, Any], tuple[str, dict[str, Any]]]


def add_analyse_parsers(sub: Any) -> None:
    """Add the ``analyse`` command group to the top-level subparsers ``sub``."""
    from .measure import POINT_SYNTAX

    p = sub.add_parser("analyse", help="forensic analyses of a solved project: measurements with uncertainty, "
                       "check distances (…; --json OUT writes the figures)",
                       description="Forensic analyses of a solved project (paper §5.1). A point is written "
                       f"{POINT_SYNTAX}.")
    p.add_argument("project", help="the project file (NAME.vebuild.json), calibrated and solved")
    asub = p.add_subparsers(dest="analysis", required=True, metavar="ANALYSIS")

    q = _subcommand(asub, "distance", "distance between two points, with 1σ and 95 %% interval", _distance)
    q.add_argument("a", help="the first point")
    q.add_argument("b", help="the second point")
    q = _subcommand(asub, "height", "height of a point above the floor (z = 0) or above a flat face", _height)
    q.add_argument("point", help="the point")
    q.add_argument("--above", metavar="NODE@FACE", help="a flat face, e.g. table.top@top (default: the floor)")
    q = _subcommand(asub, "dimensions", "an object's dimensions (its primitive's parameters)", _dimensions)
    q.add_argument("nodes", nargs="+", metavar="NODE", help="one or more nodes of the model")
    _subcommand(asub, "checks", "check distances (role 'check'): measured vs known, the independent accuracy check",
                _checks)

    from .cli_geometry import add_parsers as add_geometry_parsers

    add_geometry_parsers(asub, _subcommand)  # sightline, viewshed, trajectory

    q = _subcommand(asub, "lighting", "one view under several lighting presets side by side, with the target's "
                    "luminance under each", _lighting)
    q.add_argument("--view", required=True, metavar="NAME", help="a named view")
    q.add_argument("--preset", dest="presets", action="append", required=True, metavar="NAME",
                   help="a lighting preset, once per preset (as-photographed is the photos' own light)")
    q.add_argument("--target", required=True, metavar="NODE", help="the object whose luminance is compared")
    q.add_argument("--size", metavar="WxH", help="size of each view (default: the view's)")
    q.add_argument("--out", metavar="STRIP.png", help="write the views side by side, the target outlined")


def _subcommand(asub: Any, name: str, help: str, handler: Handler) -> argparse.ArgumentParser:
    q = asub.add_parser(name, help=help, description=help)
    q.add_argument("--json", metavar="OUT", help="write the figures to OUT as JSON")
    q.set_defaults(func=lambda args: _run(args, name, handler), handler=handler, analysis_name=name)
    return q


def _run(args: argparse.Namespace, name: str, handler: Handler) -> int:
    from ..project import load_project

    project = load_project(args.project)
    if args.json:
        from ..project.outputs import check_file

        check_file(project, Path(args.json), "figures")
    text, figures = handler(args, project)
    print(text)
    if args.json:
        write_json(Path(args.json), {"software": f"vebuild {__version__}", "project": str(project.path),
                                     "analysis": name, **figures})
        print(f"figures written to {args.json}")
    return 0


def write_json(path: Path, doc: dict[str, Any]) -> None:
    """Write ``doc`` to ``path`` atomically (:mod:`vebuild.project.atomic`)."""
    from ..errors import VebuildError
    from ..project.atomic import write_text

    try:
        write_text(path, json.dumps(doc, indent=2, allow_nan=False) + "\n")
    except OSError as e:
        raise VebuildError(f"{path}: cannot write the figures ({e.strerror or e})") from None


# -- measurements --------------------------------------------------------------------------------

def _solved(project: Any) -> tuple[Any, Callable[[str], Any]]:
    from ..project.decode import find_view, photo_camera
    from .measure import SolvedModel, parse_point

    solved = SolvedModel.from_project(project)

    def resolve(kind: str, name: str) -> Any:
        return photo_camera(project, name) if kind == "photo" else find_view(project, name)

    return solved, lambda text: parse_point(text, solved, resolve_camera=resolve)


def _solution_figures(solved: Any) -> dict[str, Any]:
    return {"solution": {"recalibrated": solved.recalibrated, "variance_factor": solved.variance_factor}}


def _table(rows: list[Any]) -> str:
    lines = [f"{'quantity':<10} {'what':<44} {'value m':>10} {'1σ mm':>8}  {'95 % interval m':<21}"]
    for m in rows:
        lo, hi = m.ci95
        lines.append(f"{m.quantity:<10} {m.what:<44} {m.value:>10.4f} {1000 * m.sigma:>8.2f}  [{lo:.4f}, {hi:.4f}]")
    return "\n".join(lines)


def _rests_on(m: Any) -> str:
    return (f"rests on nodes {', '.join(m.nodes) or '—'}; markers {', '.join(m.markers) or '—'}; "
            f"photos {', '.join(m.photos) or '—'}")


def _distance(args: argparse.Namespace, project: Any) -> tuple[str, dict[str, Any]]:
    from .measure import distance

    solved, point = _solved(project)
    m = distance(solved, point(args.a), point(args.b))
    return _table([m]) + "\n" + _rests_on(m), {**_solution_figures(solved), "measurements": [m.to_json()]}


def _height(args: argparse.Namespace, project: Any) -> tuple[str, dict[str, Any]]:
    from .measure import MeasureError, height

    solved, point = _solved(project)
    above = None
    if args.above:
        node, sep, face = args.above.partition("@")
        if not sep or not face or ":" in face:
            raise MeasureError(f"--above '{args.above}': expected a flat face written NODE@FACE, e.g. table.top@top")
        above = (node, face)
    m = height(solved, point(args.point), above)
    return _table([m]) + "\n" + _rests_on(m), {**_solution_figures(solved), "measurements": [m.to_json()]}


def _dimensions(args: argparse.Namespace, project: Any) -> tuple[str, dict[str, Any]]:
    from .measure import dimensions

    solved, _ = _solved(project)
    rows = [m for node in args.nodes for m in dimensions(solved, node)]
    return _table(rows), {**_solution_figures(solved), "measurements": [m.to_json() for m in rows]}


def _checks(args: argparse.Namespace, project: Any) -> tuple[str, dict[str, Any]]:
    from .measure import check_distances

    solved, _ = _solved(project)
    checks = check_distances(project, solved)
    if not checks:
        text = "no check distances (add reference_distances with role \"check\" to the project)"
    else:
        lines = [f"{'check':<24} {'known m':>9} {'measured m':>11} {'1σ mm':>7} {'diff mm':>8} {'95 % mm':>8}  "
                 f"{'within':<6} source"]
        for c in checks:
            lines.append(f"{c.a + ' – ' + c.b:<24} {c.known:>9.4f} {c.measured.value:>11.4f} "
                         f"{1000 * c.measured.sigma:>7.2f} {1000 * c.difference:>+8.2f} "
                         f"{1000 * 1.959964 * c.difference_sigma:>8.2f}  {'yes' if c.within_ci95 else 'NO':<6} "
                         f"{c.measured.source}")
        text = "\n".join(lines)
    return text, {**_solution_figures(solved), "checks": [c.to_json() for c in checks]}


def _lighting(args: argparse.Namespace, project: Any) -> tuple[str, dict[str, Any]]:
    from ..actions.render import check_output, parse_size, provenance, write_png
    from ..gl import headless_context
    from ..project.decode import find_view
    from ..render.renderer import Renderer
    from ..render.scene import load_scene
    from ..render.sizes import check_camera
    from .lighting import LUMINANCE_WEIGHTS, compare_lighting, side_by_side

    if args.out:
        check_output(Path(args.out), project=project)
    presets = list(args.presets)
    cam = find_view(project, args.view)
    if args.size is not None:
        cam = cam.resized(*parse_size(args.size), source="--size")
    check_camera(cam)
    scene = load_scene(project)
    renderer = Renderer(headless_context(), scene)
    try:
        results = compare_lighting(project, scene, renderer, cam, presets, args.target)
        mask = renderer.node_mask(cam, args.target)
    finally:
        renderer.release()
    lines = [f"{args.target} seen from view '{args.view}' ({int(mask.sum())} pixels); relative luminance "
             "(1 = a white surface under irradiance 1):",
             f"  {'lighting':<24} {'mean':>8} {'10th pct':>9} {'90th pct':>9}"]
    lines += [f"  {r.preset:<24} {r.luminance:8.4f} {r.luminance_p10:9.4f} {r.luminance_p90:9.4f}" for r in results]
    figures: dict[str, Any] = {
        "view": args.view, "target": args.target, "target_pixels": int(mask.sum()),
        "luminance_weights_rgb": LUMINANCE_WEIGHTS.tolist(),
        "presets": [{"preset": r.preset, "luminance_relative": r.luminance, "luminance_p10_relative": r.luminance_p10,
                     "luminance_p90_relative": r.luminance_p90} for r in results]}
    if args.out:
        text = provenance(project, cam, "view", ",".join(presets), None, scene.page_hashes, {"target": args.target})
        write_png(Path(args.out), side_by_side(results, mask), text)
        lines.append(f"views side by side written to {args.out}")
        figures["strip_png"] = str(args.out)
    return "\n".join(lines), figures
