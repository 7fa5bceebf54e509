"""``vebuild analyse PROJECT sightline | viewshed | trajectory``: the command-line faces of
:mod:`vebuild.analysis.sightline` and :mod:`vebuild.analysis.trajectory` (thin: parse, call, print).

Registered by :func:`vebuild.analysis.cli.add_analyse_parsers` through :func:`add_parsers`; each
handler returns the table to print and the figures for ``--json``.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from vebuild.errors import VebuildError

Subcommand = Callable[..., argparse.ArgumentParser]


def add_parsers(asub: Any, subcommand: Subcommand) -> None:
    """Add the three subcommands with ``subcommand(asub, name, help, handler)`` (analysis/cli.py's)."""
    q = subcommand(asub, "sightline", "could a witness see a point or an object? visible share, what blocks it, "
                   "and the witness's view (--out)", _sightline)
    eye = q.add_mutually_exclusive_group(required=True)
    eye.add_argument("--eye", metavar="X,Y,Z", help="the eye point (metres)")
    eye.add_argument("--standing", metavar="X,Y", help="a person standing at this floor spot (eyes at 1.6 m)")
    eye.add_argument("--sitting", metavar="X,Y", help="a person sitting at this floor spot (eyes at 1.2 m)")
    _target_args(q)
    q.add_argument("--out", metavar="VIEW.png", help="render the witness's view, the target highlighted")
    q.add_argument("--fov", type=float, default=60.0, metavar="DEG",
                   help="horizontal field of view of the rendered view (default: %(default)g)")
    q.add_argument("--size", default="1280x720", metavar="WxH", help="size of the rendered view (default: %(default)s)")
    q.add_argument("--lighting", metavar="PRESET", help="lighting of the rendered view (default: as photographed)")
    _common(q, 4000)

    q = subcommand(asub, "viewshed", "a floor map of the places from which a point or an object can be seen",
                   _viewshed)
    _target_args(q)
    q.add_argument("--height", type=float, default=1.6, metavar="M",
                   help="eye height above the floor (default: %(default)g; sitting: 1.2)")
    q.add_argument("--cell", type=float, default=0.1, metavar="M", help="grid cell size (default: %(default)g)")
    q.add_argument("--out", required=True, metavar="MAP.png", help="the map to write (a top view)")
    _common(q, 256)

    q = subcommand(asub, "trajectory", "a bullet's path: the surfaces it passes and hits, with an uncertainty cone",
                   _trajectory)
    q.add_argument("--from", dest="start", required=True, metavar="POINT",
                   help="the entry hole: X,Y,Z (metres) or node:handle")
    q.add_argument("--to", metavar="POINT", help="the exit hole: X,Y,Z or node:handle")
    q.add_argument("--azimuth", type=float, metavar="DEG", help="instead of --to: direction, counter-clockwise "
                   "from +X about +Z")
    q.add_argument("--elevation", type=float, metavar="DEG", help="with --azimuth: degrees above the horizontal")
    cone = q.add_mutually_exclusive_group()
    cone.add_argument("--sigma", metavar="M[,M]", help="1σ position error of the holes (one for both, or entry,exit)")
    cone.add_argument("--cone", type=float, metavar="DEG", help="the uncertainty cone's half-angle")
    q.add_argument("--view", metavar="NAME", help="with --out: the named view to draw the trajectory in")
    q.add_argument("--out", metavar="FILE.png", help="with --view: the image to write")
    q.add_argument("--lighting", metavar="PRESET", help="lighting of the view (default: as photographed)")
    q.add_argument("--hypothesis", metavar="NAME", help="the objects arranged as in this hypothesis")


def _target_args(q: argparse.ArgumentParser) -> None:
    t = q.add_mutually_exclusive_group(required=True)
    t.add_argument("--target", metavar="X,Y,Z", help="the target point (metres)")
    t.add_argument("--object", metavar="NODE", help="the target object: a node of the model (and its parts)")


def _common(q: argparse.ArgumentParser, samples: int) -> None:
    q.add_argument("--samples", type=int, default=samples, metavar="N",
                   help="points sampled on an object's surface (default: %(default)s)")
    q.add_argument("--hypothesis", metavar="NAME", help="the objects arranged as in this hypothesis")


def _scene(project: Any, hypothesis: str | None) -> Any:
    from vebuild.render.scene import load_scene

    scene = load_scene(project)
    if hypothesis is not None:
        from vebuild.actions.hypothesis import hypothesis_model

        scene = scene.with_model(hypothesis_model(project, scene.model, hypothesis))
    return scene


def _target(occ: Any, args: argparse.Namespace) -> Any:
    from .sightline import parse_floats, target_object, target_point

    if args.object is not None:
        return target_object(occ, args.object)
    return target_point(occ, parse_floats(args.target, 3, "--target"))


def _samples(n: int) -> int:
    if n < 1:
        raise VebuildError(f"--samples: expected 1 or more, got {n}")
    return n


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def _sightline(args: argparse.Namespace, project: Any) -> tuple[str, dict[str, Any]]:
    from vebuild.actions.render import check_output, parse_size

    from .rays import Occluders
    from .sightline import Eye, parse_floats, render_witness_view, sight_line

    if args.out:
        check_output(Path(args.out), project=project)
    size = parse_size(args.size)
    scene = _scene(project, args.hypothesis)
    occ = Occluders(scene)
    if args.eye:
        eye = Eye(parse_floats(args.eye, 3, "--eye"))
    else:
        posture = "standing" if args.standing else "sitting"
        x, y = parse_floats(args.standing or args.sitting, 2, f"--{posture}")
        eye = Eye.person(x, y, posture)
    res = sight_line(occ, eye, _target(occ, args), samples=_samples(args.samples))
    e = eye.position
    lines = [f"{'eye':<16} " + (f"{eye.kind} at ({eye.spot[0]:.3f}, {eye.spot[1]:.3f}), eyes {eye.height:g} m "
                                f"above the floor: " if eye.spot else "")
             + f"({e[0]:.3f}, {e[1]:.3f}, {e[2]:.3f})"]
    t = res.target
    if t.node is not None:
        lines.append(f"{'target':<16} object '{t.node}'" + (f" ({', '.join(t.nodes)})" if t.nodes != (t.node,) else ""))
        lo, hi = res.share_ci95
        lines.append(f"{'visible':<16} {'yes' if res.visible else 'NO'}: {_pct(res.visible_share)} of its surface "
                     f"(95 %: {_pct(lo)} – {_pct(hi)}; {res.samples} samples; {_pct(res.facing_share)} faces the eye)")
        lines.append(f"{'distance':<16} {res.distance_m:.3f} m (to the centre of its surface)")
        if res.blocked_by:
            lines.append(f"{'hidden by':<16} " + ", ".join(f"{k} {_pct(v)}" for k, v in res.blocked_by.items())
                         + " of its surface")
    else:
        p = t.point
        lines.append(f"{'target':<16} point ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})")
        lines.append(f"{'visible':<16} {'yes' if res.visible else 'NO'}")
        lines.append(f"{'distance':<16} {res.distance_m:.3f} m")
    if res.blocker:
        b = res.blocker
        lines.append(f"{'nearest blocker':<16} {b['node']} ({b['face']} face) at {b['distance_from_eye_m']:.3f} m "
                     f"from the eye, at ({', '.join(f'{v:.3f}' for v in b['point_m'])})")
    figures: dict[str, Any] = {"sightline": res.record(), "view_png": None}
    if args.out:
        render_witness_view(project, scene, res, Path(args.out), args.fov, size, args.lighting)
        lines.append(f"{'view':<16} written to {args.out} ({args.fov:g}° field of view, the target highlighted)")
        figures["view_png"] = str(args.out)
        figures["view_fov_deg"] = args.fov
    lines += [f"warning: {w}" for w in scene.warnings]
    return "\n".join(lines), figures


def _viewshed(args: argparse.Namespace, project: Any) -> tuple[str, dict[str, Any]]:
    import numpy as np

    from vebuild.actions.render import check_output

    from .rays import Occluders
    from .sightline import PLACE, viewshed, write_viewshed_png

    check_output(Path(args.out), project=project)
    scene = _scene(project, args.hypothesis)
    occ = Occluders(scene)
    vs = viewshed(occ, _target(occ, args), args.height, args.cell, samples=_samples(args.samples))
    write_viewshed_png(project, vs, occ, Path(args.out))
    f = vs.figures()
    g = f["grid"]
    lines = [f"{'target':<18} {vs.target.label}",
             f"{'eye height':<18} {vs.eye_height:g} m; grid {g['nx']}×{g['ny']} cells of {vs.cell:g} m from "
             f"({g['origin_m'][0]:.3f}, {g['origin_m'][1]:.3f})",
             f"{'floor':<18} {f['floor_area_m2']:.2f} m², of which {f['occupied_area_m2']:.2f} m² occupied "
             f"(no place to stand)",
             f"{'sees the target':<18} {f['seeing_area_m2']:.2f} m² = "
             + ("—" if f["seeing_share_of_place_area"] is None else _pct(f["seeing_share_of_place_area"]))
             + " of the floor where one can stand"]
    if vs.target.node is not None and f.get("mean_visible_share") is not None:
        lines.append(f"{'mean visible share':<18} {_pct(f['mean_visible_share'])} of its surface "
                     f"({vs.samples} samples per cell)")
    lines.append(f"{'map':<18} written to {args.out}")
    lines += [f"warning: {w}" for w in scene.warnings]
    share = np.where(vs.states == PLACE, np.round(vs.share, 4), np.nan)[::-1]
    f["share_rows_top_to_bottom"] = [[None if np.isnan(v) else float(v) for v in row] for row in share]
    f["map_png"] = str(args.out)
    return "\n".join(lines), {"viewshed": f}


def trajectory_from_args(args: argparse.Namespace, occ: Any) -> Any:
    """The trajectory that ``vebuild analyse … trajectory`` arguments describe, against ``occ``
    (also used by the viewer to draw the trajectories a project records)."""
    from .sightline import parse_floats
    from .trajectory import direction_from_angles, parse_point, trajectory

    if (args.to is None) == (args.azimuth is None):
        raise VebuildError("trajectory: give the exit hole (--to) or a direction (--azimuth and --elevation), "
                           "not both")
    if args.azimuth is not None and args.elevation is None:
        raise VebuildError("trajectory: --azimuth needs --elevation (degrees above the horizontal)")
    A = parse_point(occ, args.start, "--from")
    sigma = None
    if args.sigma is not None:
        parts = args.sigma.split(",")
        s = parse_floats(args.sigma, len(parts), "--sigma") if len(parts) in (1, 2) else None
        if s is None:
            raise VebuildError(f"--sigma: expected one or two position errors in metres (such as 0.005 or "
                               f"0.005,0.01), got {args.sigma!r}")
        sigma = (float(s[0]), float(s[-1]))
    if args.to is not None:
        return trajectory(occ, A, parse_point(occ, args.to, "--to"), sigma=sigma, cone_deg=args.cone)
    return trajectory(occ, A, direction=direction_from_angles(args.azimuth, args.elevation), sigma=sigma,
                      cone_deg=args.cone)


def _trajectory(args: argparse.Namespace, project: Any) -> tuple[str, dict[str, Any]]:
    from vebuild.actions.render import check_output
    from vebuild.project.decode import find_view
    from vebuild.render.sizes import check_camera

    from .rays import Occluders
    from .trajectory import render_trajectory_view

    if (args.view is None) != (args.out is None):
        raise VebuildError("trajectory: --view NAME and --out FILE.png go together (the view to draw it in)")
    cam = None
    if args.out:
        check_output(Path(args.out), project=project)
        cam = find_view(project, args.view)
        check_camera(cam)
    scene = _scene(project, args.hypothesis)
    occ = Occluders(scene)
    tr = trajectory_from_args(args, occ)
    rec = tr.record()
    lines = [f"path: from ({', '.join(f'{v:.3f}' for v in tr.entry)})"
             + (f" to ({', '.join(f'{v:.3f}' for v in tr.exit)}), {tr.length:.3f} m apart" if tr.length else "")
             + f"; azimuth {tr.azimuth_deg:.2f}°, elevation {tr.elevation_deg:.2f}°"]
    if tr.cone_deg is not None:
        how = f"from σ {tr.sigma[0] * 1000:g} mm, {tr.sigma[1] * 1000:g} mm" if tr.sigma else "given"
        lines.append(f"uncertainty cone (95 %): half-angle {tr.cone_deg:.3f}° ({how})")
    lines.append(f"\n{'distance m':>11}  {'where':<13} {'surface':<28} {'angle°':>7} {'cone r m':>9}")
    for h in rec["surfaces"]:
        lines.append(f"{h['distance_m']:>11.3f}  {h['where']:<13} {h['node'] + ' (' + h['face'] + ')':<28} "
                     f"{h['angle_to_surface_deg']:>7.2f} {h['cone_radius_95_m']:>9.3f}")
    lines.append("")
    if tr.stop is not None:
        lines.append(f"stops at: {tr.stop.node} ({tr.stop.face}) {tr.stop.t:.3f} m from the entry, "
                     f"{tr.stop.t - tr.length:.3f} m beyond the exit")
    else:
        lines.append("stops at: nothing — the path leaves the scene at ("
                     + ", ".join(f"{v:.3f}" for v in tr.leaves_at) + ")")
    if tr.source is not None:
        lines.append(f"toward the shooter: {tr.source.node} ({tr.source.face}) {-tr.source.t:.3f} m behind the entry")
    else:
        lines.append("toward the shooter: nothing — the line leaves the scene at ("
                     + ", ".join(f"{v:.3f}" for v in tr.leaves_behind_at) + ")")
    if tr.cone_deg:
        lines.append("within the cone, beyond the exit: "
                     + ", ".join(f"{k} {_pct(v)}" for k, v in tr.cone_stop_nodes.items()) + " of its lines")
        lines.append("within the cone, behind the entry: "
                     + ", ".join(f"{k} {_pct(v)}" for k, v in tr.cone_source_nodes.items()) + " of its lines")
    figures: dict[str, Any] = {"trajectory": rec, "view_png": None}
    if cam is not None:
        render_trajectory_view(project, scene, tr, cam, Path(args.out), args.lighting)
        lines.append(f"view '{args.view}' with the trajectory written to {args.out}")
        figures["view_png"] = str(args.out)
    lines += [f"warning: {w}" for w in scene.warnings]
    return "\n".join(lines), figures
