"""Sight lines, viewsheds and trajectories as typed requests (:mod:`vebuild.analysis.requests`):
each ``run(project)`` loads the scene (arranged as a hypothesis, if one is named), computes, and
returns the table, the figures and the image it wrote."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from vebuild.errors import VebuildError
from vebuild.project.units import length_unit

from .requests import AnalysisResult, Request
from .sightline import DEFAULT_FOV_DEG, OBJECT_SAMPLES, STANDING_EYE_M
from .viewshed import VIEWSHED_OBJECT_SAMPLES

if TYPE_CHECKING:
    from vebuild.project import Project


#: The witness's view's size when none is given (WxH).
DEFAULT_VIEW_SIZE = "1280x720"
#: The viewshed's grid cell (metres) when none is given.
DEFAULT_CELL_M = 0.1


def _scene(project: Project, hypothesis: str | None) -> Any:
    from vebuild.render.scene import load_scene

    scene = load_scene(project)
    if hypothesis is not None:
        from vebuild.project.hypotheses import hypothesis_model

        scene = scene.with_model(hypothesis_model(project, scene.model, hypothesis))
    return scene


def _target(occ: Any, target: str | None, node: str | None) -> Any:
    from .sightline import parse_floats, target_object, target_point

    if node is not None:
        return target_object(occ, node)
    if target is None:
        raise VebuildError("expected a target: --target X,Y,Z or --object NODE")
    return target_point(occ, tuple(parse_floats(target, 3, "--target")))


def _samples(n: int) -> int:
    if n < 1:
        raise VebuildError(f"--samples: expected 1 or more, got {n}")
    return n


def _pct(x: float | None) -> str:
    return "—" if x is None else f"{100 * x:.1f} %"


@dataclass(frozen=True)
class SightlineRequest:
    """Could a witness at ``eye`` (X,Y,Z), or a person ``standing`` or ``sitting`` at a floor spot
    (X,Y), see the ``target`` point (X,Y,Z) or ``object`` (a node)? ``out``: the witness's view."""

    name: ClassVar[str] = "sightline"
    eye: str | None = None
    standing: str | None = None
    sitting: str | None = None
    target: str | None = None
    object: str | None = None
    out: str | None = None
    fov: float = DEFAULT_FOV_DEG
    size: str = DEFAULT_VIEW_SIZE
    lighting: str | None = None
    samples: int = OBJECT_SAMPLES
    hypothesis: str | None = None
    unobserved: str = "hatch"  # how the witness's view shows surfaces no photo saw

    def with_image(self, path: str) -> Request | None:
        return replace(self, out=path)

    def aim(self, occ: Any) -> tuple[Any, Any]:
        """The eye and the target, read against the occluders ``occ`` (their unit, their model):
        what the run looks from and for (also what ``vebuild check`` reads of a recorded one)."""
        from .sightline import Eye, parse_floats

        if not self.eye:
            occ.unit.refuse(f"sightline --{'standing' if self.standing else 'sitting'}: a person's eye height")
            posture = "standing" if self.standing else "sitting"
            spot = self.standing or self.sitting
            if spot is None:
                raise VebuildError("sightline: expected an eye: --eye X,Y,Z, --standing X,Y or --sitting X,Y")
            x, y = parse_floats(spot, 2, f"--{posture}")
            eye = Eye.person(x, y, posture)
        else:
            eye = Eye(parse_floats(self.eye, 3, "--eye"))
        return eye, _target(occ, self.target, self.object)

    def run(self, project: Project) -> AnalysisResult:
        from vebuild.render.observed import check_mode
        from vebuild.render.png import check_output
        from vebuild.render.sizes import parse_size

        check_mode(self.unobserved)

        from .rays import Occluders
        from .sightline import render_witness_view, sight_line

        if self.out:
            check_output(Path(self.out), project=project)
        size = parse_size(self.size)
        unit = length_unit(project.data)
        scene = _scene(project, self.hypothesis)
        occ = Occluders(scene, unit)
        eye, target = self.aim(occ)
        res = sight_line(occ, eye, target, samples=_samples(self.samples))
        e = eye.position
        u = unit.symbol
        lines = [f"{'eye':<16} " + (f"{eye.kind} at ({eye.spot[0]:.3f}, {eye.spot[1]:.3f}), eyes {eye.height:g} m "
                                    f"above the floor: " if eye.spot else "")
                 + f"({e[0]:.3f}, {e[1]:.3f}, {e[2]:.3f})"]
        t = res.target
        if t.node is not None:
            lines.append(f"{'target':<16} object '{t.node}'"
                         + (f" ({', '.join(t.nodes)})" if t.nodes != (t.node,) else ""))
            assert res.share_ci95 is not None  # set for an object target
            lo, hi = res.share_ci95
            lines.append(f"{'visible':<16} {'yes' if res.visible else 'NO'}: {_pct(res.visible_share)} of its "
                         f"surface (95 %: {_pct(lo)} – {_pct(hi)}; {res.samples} samples; {_pct(res.facing_share)} "
                         "faces the eye)")
            lines.append(f"{'distance':<16} {res.distance_m:.3f} {u} (to the centre of its surface)")
            if res.blocked_by:
                lines.append(f"{'hidden by':<16} " + ", ".join(f"{k} {_pct(v)}" for k, v in res.blocked_by.items())
                             + " of its surface")
            un = res.unobserved
            lines.append(f"{'unobserved':<16} " + ("unknown (no coverage maps: run `vebuild texture`)" if un is None
                         else f"{_pct(un['rests_on_unobserved_share'])} of the answer rests on surfaces no photo "
                         f"saw: {_pct(un['visible_on_unobserved_share'])} of its surface seen where no photo saw "
                         f"it, {_pct(un['hidden_by_unobserved_share'])} hidden by surfaces no photo saw"))
        else:
            p = t.point
            assert p is not None  # a point target
            lines.append(f"{'target':<16} point ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})")
            lines.append(f"{'visible':<16} {'yes' if res.visible else 'NO'}")
            lines.append(f"{'distance':<16} {res.distance_m:.3f} {u}")
        if res.blocker:
            b = res.blocker
            lines.append(f"{'nearest blocker':<16} {b['node']} ({b['face']} face) at "
                         f"{b['distance_from_eye_m']:.3f} {u} from the eye, at "
                         f"({', '.join(f'{v:.3f}' for v in b['point_m'])})"
                         + {True: "; a surface no photo saw (inferred, not observed)", False: "; observed by a photo",
                            None: ""}[b.get("unobserved")])
        if unit.relative:
            lines.append(unit.note)
        figures: dict[str, Any] = {"lengths": unit.word, "sightline": unit.keyed(res.record()), "view_png": None}
        image = None
        if self.out:
            image = Path(self.out)
            render_witness_view(project, scene, res, image, self.fov, size, self.lighting, unobserved=self.unobserved)
            lines.append(f"{'view':<16} written to {self.out} ({self.fov:g}° field of view, the target highlighted)")
            figures["view_png"] = str(self.out)
            figures["view_fov_deg"] = self.fov
        lines += [f"warning: {w}" for w in scene.warnings]
        return AnalysisResult("\n".join(lines), figures, image)


@dataclass(frozen=True)
class ViewshedRequest:
    """A floor map (``out``, a top view) of the places from which the ``target`` point or
    ``object`` can be seen, with eyes ``height`` above the floor."""

    name: ClassVar[str] = "viewshed"
    out: str
    target: str | None = None
    object: str | None = None
    height: float = STANDING_EYE_M
    cell: float = DEFAULT_CELL_M
    samples: int = VIEWSHED_OBJECT_SAMPLES
    hypothesis: str | None = None

    def with_image(self, path: str) -> Request | None:
        return replace(self, out=path)

    def aim(self, occ: Any) -> Any:
        """The target, read against the occluders ``occ`` (also what ``vebuild check`` reads)."""
        return _target(occ, self.target, self.object)

    def run(self, project: Project) -> AnalysisResult:
        import numpy as np

        from vebuild.render.png import check_output

        from .rays import Occluders
        from .viewshed import PLACE, viewshed, write_viewshed_png

        length_unit(project.data).refuse(f"viewshed: the eye height ({self.height:g}) and the grid's cell "
                                         f"({self.cell:g})")
        check_output(Path(self.out), project=project)
        scene = _scene(project, self.hypothesis)
        occ = Occluders(scene)
        vs = viewshed(occ, self.aim(occ), self.height, self.cell, samples=_samples(self.samples))
        write_viewshed_png(project, vs, occ, Path(self.out))
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
        un = f["unobserved"]
        lines.append(f"{'unobserved':<18} " + ("unknown (no coverage maps: run `vebuild texture`)"
                                                 if un["seeing_area_resting_on_unobserved_m2"] is None else
                     f"{un['seeing_area_resting_on_unobserved_m2']:.2f} m² of the seeing area ("
                     + _pct(un["seeing_share_resting_on_unobserved"]) + f") and "
                     f"{un['hidden_area_resting_on_unobserved_m2']:.2f} m² of the hidden area ("
                     + _pct(un["hidden_share_resting_on_unobserved"]) + ") rest on surfaces no photo saw"))
        lines.append(f"{'map':<18} written to {self.out}")
        lines += [f"warning: {w}" for w in scene.warnings]
        share = np.where(vs.states == PLACE, np.round(vs.share, 4), np.nan)[::-1]
        f["share_rows_top_to_bottom"] = [[None if np.isnan(v) else float(v) for v in row] for row in share]
        f["map_png"] = str(self.out)
        return AnalysisResult("\n".join(lines), {"viewshed": f}, Path(self.out))


@dataclass(frozen=True)
class TrajectoryRequest:
    """A bullet's path from the entry hole ``start`` to the exit hole ``to`` (X,Y,Z or
    node:handle), or in the direction ``azimuth``/``elevation`` (degrees), with its uncertainty
    cone (``sigma``: the holes' 1σ position error, or ``cone``: the half-angle); ``view`` and
    ``out``: the image of the named view with the trajectory drawn in."""

    name: ClassVar[str] = "trajectory"
    start: str
    to: str | None = None
    azimuth: float | None = None
    elevation: float | None = None
    sigma: str | None = None
    cone: float | None = None
    view: str | None = None
    out: str | None = None
    lighting: str | None = None
    hypothesis: str | None = None
    unobserved: str = "hatch"  # how the view shows surfaces no photo saw

    def with_image(self, path: str) -> Request | None:
        return replace(self, out=path) if self.view else None

    def trajectory(self, occ: Any) -> Any:
        """The trajectory against the occluders ``occ`` (also how the viewer draws the
        trajectories a project records)."""
        from .sightline import parse_floats
        from .trajectory import direction_from_angles, parse_point, trajectory

        if (self.to is None) == (self.azimuth is None):
            raise VebuildError("trajectory: give the exit hole (--to) or a direction (--azimuth and --elevation), "
                               "not both")
        if self.azimuth is not None and self.elevation is None:
            raise VebuildError("trajectory: --azimuth needs --elevation (degrees above the horizontal)")
        A = parse_point(occ, self.start, "--from")
        sigma = None
        if self.sigma is not None:
            parts = self.sigma.split(",")
            s = parse_floats(self.sigma, len(parts), "--sigma") if len(parts) in (1, 2) else None
            if s is None:
                raise VebuildError(f"--sigma: expected one or two position errors in metres (such as 0.005 or "
                                   f"0.005,0.01), got {self.sigma!r}")
            sigma = (float(s[0]), float(s[-1]))
        if self.to is not None:
            return trajectory(occ, A, parse_point(occ, self.to, "--to"), sigma=sigma, cone_deg=self.cone)
        assert self.azimuth is not None and self.elevation is not None
        return trajectory(occ, A, direction=direction_from_angles(self.azimuth, self.elevation), sigma=sigma,
                          cone_deg=self.cone)

    def run(self, project: Project) -> AnalysisResult:
        from vebuild.project.decode import find_view
        from vebuild.render.png import check_output
        from vebuild.render.sizes import check_camera

        from .rays import Occluders
        from .trajectory import render_trajectory_view

        if (self.view is None) != (self.out is None):
            raise VebuildError("trajectory: --view NAME and --out FILE.png go together (the view to draw it in)")
        cam = None
        if self.out and self.view:
            check_output(Path(self.out), project=project)
            cam = find_view(project, self.view)
            check_camera(cam)
        unit = length_unit(project.data)
        if self.sigma is not None:
            unit.refuse(f"trajectory --sigma {self.sigma}: the holes' position error (give the cone's half-angle, "
                        "--cone DEG, instead)")
        u = unit.symbol
        scene = _scene(project, self.hypothesis)
        occ = Occluders(scene, unit)
        tr = self.trajectory(occ)
        rec = tr.record()
        lines = [f"path: from ({', '.join(f'{v:.3f}' for v in tr.entry)})"
                 + (f" to ({', '.join(f'{v:.3f}' for v in tr.exit)}), {tr.length:.3f} {u} apart" if tr.length else "")
                 + f"; azimuth {tr.azimuth_deg:.2f}°, elevation {tr.elevation_deg:.2f}°"]
        if tr.cone_deg is not None:
            how = f"from σ {tr.sigma[0] * 1000:g} mm, {tr.sigma[1] * 1000:g} mm" if tr.sigma else "given"
            lines.append(f"uncertainty cone (95 %): half-angle {tr.cone_deg:.3f}° ({how})")
        lines.append(f"\n{'distance ' + u:>11}  {'where':<13} {'surface':<28} {'angle°':>7} {'cone r ' + u:>9}")
        for h in rec["surfaces"]:
            lines.append(f"{h['distance_m']:>11.3f}  {h['where']:<13} {h['node'] + ' (' + h['face'] + ')':<28} "
                         f"{h['angle_to_surface_deg']:>7.2f} {h['cone_radius_95_m']:>9.3f}")
        lines.append("")
        if tr.stop is not None:
            lines.append(f"stops at: {tr.stop.node} ({tr.stop.face}) {tr.stop.t:.3f} {u} from the entry, "
                         f"{tr.stop.t - tr.length:.3f} {u} beyond the exit")
        else:
            lines.append("stops at: nothing — the path leaves the scene at ("
                         + ", ".join(f"{v:.3f}" for v in tr.leaves_at) + ")")
        if tr.source is not None:
            lines.append(f"toward the shooter: {tr.source.node} ({tr.source.face}) {-tr.source.t:.3f} {u} behind "
                         "the entry")
        else:
            lines.append("toward the shooter: nothing — the line leaves the scene at ("
                         + ", ".join(f"{v:.3f}" for v in tr.leaves_behind_at) + ")")
        if tr.cone_deg:
            lines.append("within the cone, beyond the exit: "
                         + ", ".join(f"{k} {_pct(v)}" for k, v in tr.cone_stop_nodes.items()) + " of its lines")
            lines.append("within the cone, behind the entry: "
                         + ", ".join(f"{k} {_pct(v)}" for k, v in tr.cone_source_nodes.items()) + " of its lines")
        if unit.relative:
            lines.append(unit.note)
        figures: dict[str, Any] = {"lengths": unit.word, "trajectory": unit.keyed(rec), "view_png": None}
        image = None
        if cam is not None and self.out is not None:
            image = Path(self.out)
            render_trajectory_view(project, scene, tr, cam, image, self.lighting, unobserved=self.unobserved)
            lines.append(f"view '{self.view}' with the trajectory written to {self.out}")
            figures["view_png"] = str(self.out)
        lines += [f"warning: {w}" for w in scene.warnings]
        return AnalysisResult("\n".join(lines), figures, image)
