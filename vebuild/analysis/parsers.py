"""The words of ``vebuild analyse PROJECT ANALYSIS …``: the parsers of every analysis, and the
typed request (:mod:`vebuild.analysis.requests`) each one's words make.

One function per subcommand maps its words to its request, given to :func:`_subcommand`; the same
mapping makes the requests of the analyses a project records (:mod:`vebuild.analysis.recorded`),
and :mod:`vebuild.analysis.cli` runs them from the command line. Adding a subcommand: write its
request, then here ``q = _subcommand(asub, "name", "help", lambda a: MyRequest(a.x, …))`` and its
arguments with ``q.add_argument`` (defaults read from the request's fields). ``--json`` and the
project argument come with it.
"""


from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

from vebuild.render.observed import add_option as add_unobserved_option

from .requests import (
    ChecksRequest,
    DimensionsRequest,
    DistanceRequest,
    FloorDistanceRequest,
    HeightRequest,
    LightingRequest,
    PhotoHeightRequest,
    PlaneLengthRequest,
    RaisedHeightRequest,
    Request,
    WallLengthRequest,
)
from .requests_geometry import SightlineRequest, TrajectoryRequest, ViewshedRequest
from .requests_person import PERSON_HELP, add_person_arguments, person_request
from .sightline import SITTING_EYE_M, STANDING_EYE_M

ToRequest = Callable[[argparse.Namespace], Request]


def add_analyse_parsers(sub: Any) -> Any:
    """Add the ``analyse`` command group to the top-level subparsers ``sub``; its subparsers."""
    from .points import POINT_SYNTAX

    p = sub.add_parser("analyse", help="forensic analyses of a solved project: measurements with uncertainty, "
                       "check distances (…; --json OUT writes the figures)",
                       description="Forensic analyses of a solved project (paper §5.1). A point is written "
                       f"{POINT_SYNTAX}.")
    p.add_argument("project", help="the project file (NAME.vebuild.json), calibrated and solved")
    asub = p.add_subparsers(dest="analysis", required=True, metavar="ANALYSIS")

    q = _subcommand(asub, "distance", "distance between two points, with 1σ and 95 %% interval",
                    lambda a: DistanceRequest(a.a, a.b))
    q.add_argument("a", help="the first point")
    q.add_argument("b", help="the second point")
    q = _subcommand(asub, "height", "height of a point above the floor (z = 0) or above a flat face",
                    lambda a: HeightRequest(a.point, a.above))
    q.add_argument("point", help="the point")
    q.add_argument("--above", metavar="NODE@FACE", help="a flat face, e.g. table.top@top (default: the floor)")
    q = _subcommand(asub, "dimensions", "an object's dimensions (its primitive's parameters)",
                    lambda a: DimensionsRequest(tuple(a.nodes)))
    q.add_argument("nodes", nargs="+", metavar="NODE", help="one or more nodes of the model")
    _subcommand(asub, "checks", "check distances (role 'check'): measured vs known, the independent accuracy check",
                lambda a: ChecksRequest())
    for word, what, request, pixels in (
            ("photo-height", "heights above the floor measured on one calibrated photo: for each, the foot on the "
             "floor then the top (U1 V1 U2 V2)", PhotoHeightRequest, "four"),
            ("floor-distance", "distances between two floor points measured on one calibrated photo (U1 V1 U2 V2 "
             "each)", FloorDistanceRequest, "four"),
            ("wall-length", "lengths on a wall measured on one calibrated photo: for each, two points where the wall "
             "meets the floor, then the length's two ends on the wall (U1 V1 … U4 V4)", WallLengthRequest, "eight"),
            ("raised-height", "heights above a raised surface (a table top, a kerb) measured on one calibrated "
             "photo: for each, the floor just below a point of the surface's edge, that point, the foot on the "
             "surface, the top (U1 V1 … U4 V4)", RaisedHeightRequest, "eight"),
            ("plane-length", "lengths on a plane marked by three points, measured on one calibrated photo: for each, "
             "the floor below the plane's first point and the point (the same pixel twice for a point on the "
             "floor), the same for its second and third points, then the length's two ends on the plane "
             "(U1 V1 … U8 V8)", PlaneLengthRequest, "sixteen")):
        q = _subcommand(asub, word, what + "; no model needed", _single_view(request))
        q.add_argument("--photo", required=True, metavar="ID", help="the calibrated photo")
        q.add_argument("pixels", nargs="+", type=float, metavar="U V",
                       help=f"pixel coordinates, {pixels} per measurement")
    _add_person(asub)
    _add_geometry(asub)
    q = _subcommand(asub, "lighting", "one view under several lighting presets side by side, with the target's "
                    "luminance under each",
                    lambda a: LightingRequest(a.view, tuple(a.presets), a.target, a.size, a.out, a.unobserved))
    q.add_argument("--view", required=True, metavar="NAME", help="a named view")
    q.add_argument("--preset", dest="presets", action="append", required=True, metavar="NAME",
                   help="a lighting preset, once per preset (as-photographed is the photos' own light)")
    q.add_argument("--target", required=True, metavar="NODE", help="the object whose luminance is compared")
    q.add_argument("--size", metavar="WxH", help="size of each view (default: the view's)")
    q.add_argument("--out", metavar="STRIP.png", help="write the views side by side, the target outlined")
    add_unobserved_option(q)
    return asub


def _single_view(request: type[PhotoHeightRequest]) -> ToRequest:
    def to_request(a: argparse.Namespace) -> Request:
        return request(a.photo, tuple(a.pixels))

    return to_request


def _add_person(asub: Any) -> None:
    """person-height (:mod:`vebuild.analysis.requests_person`)."""
    q = _subcommand(asub, "person-height", PERSON_HELP, person_request)
    add_person_arguments(q)


def _add_geometry(asub: Any) -> None:
    """sightline, viewshed, trajectory (:mod:`vebuild.analysis.requests_geometry`)."""
    S, V = SightlineRequest, ViewshedRequest
    q = _subcommand(asub, "sightline", "could a witness see a point or an object? visible share, what blocks it, "
                    "and the witness's view (--out)",
                    lambda a: S(a.eye, a.standing, a.sitting, a.target, a.object, a.out, a.fov, a.size, a.lighting,
                                a.samples, a.hypothesis, a.unobserved))
    eye = q.add_mutually_exclusive_group(required=True)
    eye.add_argument("--eye", metavar="X,Y,Z", help="the eye point (metres)")
    eye.add_argument("--standing", metavar="X,Y",
                     help=f"a person standing at this floor spot (eyes at {STANDING_EYE_M:g} m)")
    eye.add_argument("--sitting", metavar="X,Y",
                     help=f"a person sitting at this floor spot (eyes at {SITTING_EYE_M:g} m)")
    _target_args(q)
    q.add_argument("--out", metavar="VIEW.png", help="render the witness's view, the target highlighted")
    q.add_argument("--fov", type=float, default=S.fov, metavar="DEG",
                   help="horizontal field of view of the rendered view (default: %(default)g)")
    q.add_argument("--size", default=S.size, metavar="WxH", help="size of the rendered view (default: %(default)s)")
    q.add_argument("--lighting", metavar="PRESET", help="lighting of the rendered view (default: as photographed)")
    add_unobserved_option(q)
    _common(q, S.samples)

    q = _subcommand(asub, "viewshed", "a floor map of the places from which a point or an object can be seen",
                    lambda a: V(a.out, a.target, a.object, a.height, a.cell, a.samples, a.hypothesis))
    _target_args(q)
    q.add_argument("--height", type=float, default=V.height, metavar="M",
                   help=f"eye height above the floor (default: %(default)g; sitting: {SITTING_EYE_M:g})")
    q.add_argument("--cell", type=float, default=V.cell, metavar="M", help="grid cell size (default: %(default)g)")
    q.add_argument("--out", required=True, metavar="MAP.png", help="the map to write (a top view)")
    _common(q, V.samples)

    q = _subcommand(asub, "trajectory", "a bullet's path: the surfaces it passes and hits, with an uncertainty cone",
                    lambda a: TrajectoryRequest(a.start, a.to, a.azimuth, a.elevation, a.sigma, a.cone, a.view,
                                                a.out, a.lighting, a.hypothesis, a.unobserved))
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
    add_unobserved_option(q)


def _target_args(q: argparse.ArgumentParser) -> None:
    t = q.add_mutually_exclusive_group(required=True)
    t.add_argument("--target", metavar="X,Y,Z", help="the target point (metres)")
    t.add_argument("--object", metavar="NODE", help="the target object: a node of the model (and its parts)")


def _common(q: argparse.ArgumentParser, samples: int) -> None:
    q.add_argument("--samples", type=int, default=samples, metavar="N",
                   help="points sampled on an object's surface (default: %(default)s)")
    q.add_argument("--hypothesis", metavar="NAME", help="the objects arranged as in this hypothesis")


def _subcommand(asub: Any, name: str, help: str, to_request: ToRequest) -> argparse.ArgumentParser:
    q = asub.add_parser(name, help=help, description=help)
    q.add_argument("--json", metavar="OUT", help="write the figures to OUT as JSON")
    q.add_argument("--save", metavar="NAME", help="also save it among the project's analyses under NAME, so that "
                   "the report states it (as the screens' measuring tools save theirs)")
    q.set_defaults(to_request=to_request, analysis_name=name)
    return q


def request_from_args(args: argparse.Namespace) -> Request:
    """The typed request that parsed ``vebuild analyse`` arguments describe."""
    request: Request = args.to_request(args)
    return request
