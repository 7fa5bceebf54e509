"""The analyses as typed requests: each a dataclass naming what to analyse, with ``run(project)``
returning an :class:`AnalysisResult` (the table to print, the figures for ``--json``, the image
written, if any).

Measurements (distance, height, dimensions, checks) and the lighting comparison are here; sight
lines, viewsheds and trajectories in :mod:`vebuild.analysis.requests_geometry`. A request is made
from the command line or from the words a project records (``analyses``), both through the one
mapping in :mod:`vebuild.analysis.parsers`; :mod:`vebuild.analysis.recorded` parses recorded words.

Adding an analysis: write its request here (or in a module beside it) with ``name`` (the
subcommand), ``run`` and ``with_image``; then its subcommand and mapping in
:func:`vebuild.analysis.parsers.add_analyse_parsers`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

from vebuild.constants import Z95
from vebuild.project.units import RELATIVE, LengthUnit, length_unit

if TYPE_CHECKING:
    from vebuild.project import Project


@dataclass(frozen=True)
class AnalysisResult:
    """What an analysis gives: the readable ``table``, the ``figures`` (units in their keys), and
    the ``image`` it wrote (None when it wrote none)."""

    table: str
    figures: dict[str, Any]
    image: Path | None = None


class Request(Protocol):
    """An analysis to run on a project."""

    name: ClassVar[str]

    def run(self, project: Project) -> AnalysisResult: ...

    def with_image(self, path: str) -> Request | None:
        """The same request writing its image to ``path``; None if it makes no image as asked."""
        ...


# -- measurements --------------------------------------------------------------------------------

def _solved(project: Project) -> tuple[Any, Callable[[str], Any]]:
    from vebuild.project.decode import find_view, photo_camera

    from .points import parse_point
    from .solved import SolvedModel

    solved = SolvedModel.from_project(project)

    def resolve(kind: str, name: str) -> Any:
        return photo_camera(project, name) if kind == "photo" else find_view(project, name)

    return solved, lambda text: parse_point(text, solved, resolve_camera=resolve)


def _solution_figures(project: Project, solved: Any) -> dict[str, Any]:
    from vebuild.project.units import length_unit

    return {"lengths": length_unit(project.data).word,
            "solution": {"recalibrated": solved.recalibrated, "variance_factor": solved.variance_factor}}


def _table(rows: list[Any], unit: LengthUnit) -> str:
    """The measurements, in metres (1σ in mm), or in relative units with a line saying so; the
    "what" column as wide as its longest entry (44 at least), so the figures line up."""
    w = max([44, *(len(m.what) for m in rows)])
    if unit.relative:
        lines = [f"{'quantity':<10} {'what':<{w}} {'value rel.':>10} {'1σ rel.':>8}  {'95 % interval rel.':<21}"]
        for m in rows:
            lo, hi = m.ci95
            lines.append(f"{m.quantity:<10} {m.what:<{w}} {m.value:>10.4f} {m.sigma:>8.4f}  [{lo:.4f}, {hi:.4f}]")
        return "\n".join([*lines, unit.note])
    lines = [f"{'quantity':<10} {'what':<{w}} {'value m':>10} {'1σ mm':>8}  {'95 % interval m':<21}"]
    for m in rows:
        lo, hi = m.ci95
        if getattr(m, "entered_sigma", None) == 0:  # held exactly: entered, not measured
            lines.append(f"{m.quantity:<10} {m.what:<{w}} {m.value:>10.4f} {'entered':>8}  (held as entered, no 1σ)")
            continue
        mark = "  (entered)" if getattr(m, "entered_sigma", None) is not None else ""
        lines.append(f"{m.quantity:<10} {m.what:<{w}} {m.value:>10.4f} {1000 * m.sigma:>8.2f}  [{lo:.4f}, {hi:.4f}]"
                     f"{mark}")
    return "\n".join(lines)


def _rests_on(m: Any) -> str:
    entered = ", ".join(f"{n} ({'exact' if s == 0 else f'± {1000 * s:.1f} mm' if u == 'm' else f'± {s:g}°'})"
                        for n, s, u in getattr(m, "entered", []))
    return (f"rests on nodes {', '.join(m.nodes) or '—'}; markers {', '.join(m.markers) or '—'}; "
            f"photos {', '.join(m.photos) or '—'}" + (f"; entered values {entered}" if entered else ""))


class _NoImage:
    def with_image(self, path: str) -> Request | None:
        return None


@dataclass(frozen=True)
class DistanceRequest(_NoImage):
    """The distance between two points (:data:`vebuild.analysis.points.POINT_SYNTAX`)."""

    name: ClassVar[str] = "distance"
    a: str
    b: str

    def run(self, project: Project) -> AnalysisResult:
        from .measure import distance

        solved, point = _solved(project)
        m = distance(solved, point(self.a), point(self.b))
        unit = length_unit(project.data)
        return AnalysisResult(_table([m], unit) + "\n" + _rests_on(m),
                              {**_solution_figures(project, solved), "measurements": [m.to_json(unit)]})


@dataclass(frozen=True)
class HeightRequest(_NoImage):
    """The height of a point above the floor, or above a flat face ``NODE@FACE``."""

    name: ClassVar[str] = "height"
    point: str
    above: str | None = None

    def run(self, project: Project) -> AnalysisResult:
        from .measure import height
        from .solved import MeasureError

        solved, point = _solved(project)
        above = None
        if self.above:
            node, sep, face = self.above.partition("@")
            if not sep or not face or ":" in face:
                raise MeasureError(f"--above '{self.above}': expected a flat face written NODE@FACE, "
                                   "e.g. table.top@top")
            above = (node, face)
        m = height(solved, point(self.point), above)
        unit = length_unit(project.data)
        return AnalysisResult(_table([m], unit) + "\n" + _rests_on(m),
                              {**_solution_figures(project, solved), "measurements": [m.to_json(unit)]})


@dataclass(frozen=True)
class DimensionsRequest(_NoImage):
    """The dimensions of one or more objects (their primitives' parameters)."""

    name: ClassVar[str] = "dimensions"
    nodes: tuple[str, ...]

    def run(self, project: Project) -> AnalysisResult:
        from .measure import dimensions

        solved, _ = _solved(project)
        rows = [m for node in self.nodes for m in dimensions(solved, node)]
        unit = length_unit(project.data)
        return AnalysisResult(_table(rows, unit), {**_solution_figures(project, solved),
                                                   "measurements": [m.to_json(unit) for m in rows]})


@dataclass(frozen=True)
class ChecksRequest(_NoImage):
    """The check distances (role ``check``): measured against known."""

    name: ClassVar[str] = "checks"

    def run(self, project: Project) -> AnalysisResult:
        from .measure import check_distances

        solved, _ = _solved(project)
        unit = length_unit(project.data)
        checks = check_distances(project, solved)
        if checks and unit.relative:
            # A tape's metres against relative units: no comparison means anything.
            text = (f"the {len(checks)} check distance{'s are' if len(checks) > 1 else ' is'} not compared: "
                    f"{unit.note}")
            return AnalysisResult(text, {**_solution_figures(project, solved), "checks": [],
                                         "not_compared": [{"a": c.a, "b": c.b, "known_m": c.known} for c in checks]})
        if not checks:
            text = "no check distances (add reference_distances with role \"check\" to the project)"
        else:
            lines = [f"{'check':<24} {'known m':>9} {'measured m':>11} {'1σ mm':>7} {'diff mm':>8} {'95 % mm':>8}  "
                     f"{'within':<6} source"]
            for c in checks:
                lines.append(f"{c.a + ' – ' + c.b:<24} {c.known:>9.4f} {c.measured.value:>11.4f} "
                             f"{1000 * c.measured.sigma:>7.2f} {1000 * c.difference:>+8.2f} "
                             f"{1000 * Z95 * c.difference_sigma:>8.2f}  {'yes' if c.within_ci95 else 'NO':<6} "
                             f"{c.measured.source}")
            text = "\n".join(lines)
        return AnalysisResult(text, {**_solution_figures(project, solved), "checks": [c.to_json() for c in checks]})


def single_view_camera(project: Project, photo: str) -> tuple[Any, dict[str, float], bool]:
    """The camera of a calibrated ``photo`` for a single-view measurement, its lens' uncertainty
    (``k1_sigma``, ``k2_sigma``, ``k1_k2_correlation``: the keywords of
    :func:`~vebuild.analysis.single_view.measure_on_photo`), and whether its lengths are relative
    (no scale was given)."""
    from vebuild.project.decode import camera_records, photo_camera

    cam = photo_camera(project, photo)
    cal = camera_records(project.data)[cam.id]  # the final record, as photo_camera's
    distortion = cal.get("distortion") or {}
    k2 = distortion.get("k2") or {}
    lens_sigma = {"k1_sigma": float((distortion.get("k1") or {}).get("sigma") or 0.0),
                  "k2_sigma": float(k2.get("sigma") or 0.0),
                  "k1_k2_correlation": float(k2.get("k1_correlation") or 0.0)}
    return cam, lens_sigma, (cal.get("placement") or {}).get("lengths") == "relative"


@dataclass(frozen=True)
class PhotoHeightRequest(_NoImage):
    """Heights above the floor measured on one calibrated photo (:mod:`vebuild.analysis.single_view`);
    ``pixels``: U1 V1 U2 V2 for each, its foot on the floor then its top. The other single-view
    measurements are this request with another ``name`` (the measurement's kind) and as many
    pixels for each as its clicks (:data:`~vebuild.analysis.single_view.SINGLE_VIEW_CLICKS`)."""

    name: ClassVar[str] = "photo-height"
    photo: str
    pixels: tuple[float, ...]

    def run(self, project: Project) -> AnalysisResult:
        from vebuild.errors import VebuildError

        from .single_view import SINGLE_VIEW_CLICKS, measure_on_photo

        word = self.name
        prompts = SINGLE_VIEW_CLICKS[word]
        each = 2 * len(prompts)
        if not self.pixels or len(self.pixels) % each:
            got = f"got {len(self.pixels)} number{'s' if len(self.pixels) != 1 else ''}"
            if each == 4:
                raise VebuildError(f"{word}: expected pixels in fours, U1 V1 U2 V2 for each measurement "
                                   f"({'foot, then top' if word == 'photo-height' else 'the two floor points'}), "
                                   f"{got}")
            raise VebuildError(f"{word}: expected {each} numbers for each measurement, the pixel U V of each of its "
                               f"{len(prompts)} points in turn ({'; '.join(prompts)}), {got}")
        cam, lens_sigma, relative = single_view_camera(project, self.photo)
        click = project.settings["click_sigma_px"]
        rows = [measure_on_photo(cam, word, [self.pixels[i : i + 2] for i in range(k, k + each, 2)],
                                 click_sigma_px=click, **lens_sigma) for k in range(0, len(self.pixels), each)]
        unit = RELATIVE if relative else length_unit(project.data)
        text = _table(rows, unit)
        against = "the floor (z = 0)" if word in ("photo-height", "floor-distance") else \
            "the floor (z = 0) and the plane its clicks mark"
        text += f"\nmeasured on photo '{cam.id}' alone, against {against}; 1σ from its calibration and " \
                f"the clicks (1σ {click:g} px)"
        return AnalysisResult(text, {"photo": cam.id, "lengths": unit.word, "click_sigma_px": click,
                                     "measurements": [m.to_json(unit) for m in rows]})


@dataclass(frozen=True)
class FloorDistanceRequest(PhotoHeightRequest):
    """Distances between two floor points measured on one calibrated photo; ``pixels``: U1 V1 U2 V2
    for each."""

    name: ClassVar[str] = "floor-distance"


@dataclass(frozen=True)
class WallLengthRequest(PhotoHeightRequest):
    """Lengths on a wall measured on one calibrated photo; ``pixels``: for each, two points where
    the wall meets the floor, then the length's two ends on the wall (8 numbers)."""

    name: ClassVar[str] = "wall-length"


@dataclass(frozen=True)
class RaisedHeightRequest(PhotoHeightRequest):
    """Heights above a raised surface measured on one calibrated photo; ``pixels``: for each, the
    floor below a point of the surface's edge, that point, the foot on the surface, the top (8)."""

    name: ClassVar[str] = "raised-height"


@dataclass(frozen=True)
class PlaneLengthRequest(PhotoHeightRequest):
    """Lengths on a plane marked by three points, measured on one calibrated photo; ``pixels``: for
    each, the floor below each of the three points and the point, then the length's ends (16)."""

    name: ClassVar[str] = "plane-length"


# -- lighting --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class LightingRequest:
    """One view under several lighting presets, with the target's luminance under each; ``out``:
    the views side by side, the target outlined."""

    name: ClassVar[str] = "lighting"
    view: str
    presets: tuple[str, ...]
    target: str
    size: str | None = None  # WxH of each view; None: the view's own
    out: str | None = None
    unobserved: str = "hatch"  # how the strip shows surfaces no photo saw (the luminance never sees it)

    def with_image(self, path: str) -> Request | None:
        return replace(self, out=path)

    def run(self, project: Project) -> AnalysisResult:
        from vebuild.gl import headless_context
        from vebuild.project.decode import find_view
        from vebuild.render.observed import check_mode, finish_image
        from vebuild.render.png import check_output, provenance, write_png
        from vebuild.render.renderer import Renderer, RenderOptions
        from vebuild.render.scene import load_scene
        from vebuild.render.sizes import check_camera, parse_size

        from .lighting import LUMINANCE_WEIGHTS, compare_lighting, side_by_side

        if self.out:
            check_output(Path(self.out), project=project)
        presets = list(self.presets)
        cam = find_view(project, self.view)
        if self.size is not None:
            cam = cam.resized(*parse_size(self.size), source="--size")
        check_camera(cam)
        scene = load_scene(project)
        renderer = Renderer(headless_context(), scene, RenderOptions(unobserved=check_mode(self.unobserved)))
        try:
            results = compare_lighting(project, scene, renderer, cam, presets, self.target)
            mask = renderer.node_mask(cam, self.target)
            marked = renderer.marks_unobserved
        finally:
            renderer.release()
        lines = [f"{self.target} seen from view '{self.view}' ({int(mask.sum())} pixels); relative luminance "
                 "(1 = a white surface under irradiance 1):",
                 f"  {'lighting':<24} {'mean':>8} {'10th pct':>9} {'90th pct':>9}"]
        lines += [f"  {r.preset:<24} {r.luminance:8.4f} {r.luminance_p10:9.4f} {r.luminance_p90:9.4f}"
                  for r in results]
        figures: dict[str, Any] = {
            "view": self.view, "target": self.target, "target_pixels": int(mask.sum()),
            "luminance_weights_rgb": LUMINANCE_WEIGHTS.tolist(),
            "presets": [{"preset": r.preset, "luminance_relative": r.luminance,
                         "luminance_p10_relative": r.luminance_p10, "luminance_p90_relative": r.luminance_p90}
                        for r in results]}
        image = None
        if self.out:
            text = provenance(project, cam, "view", ",".join(presets), None, scene.page_hashes,
                              {"target": self.target, "unobserved": self.unobserved})
            image = Path(self.out)
            write_png(image, finish_image(side_by_side(results, mask), self.unobserved, marked, text,
                                          scene.mask_hashes), text)
            lines.append(f"views side by side written to {self.out}")
            figures["strip_png"] = str(self.out)
        return AnalysisResult("\n".join(lines), figures, image)

