"""The model solver (paper §3.1) and re-calibration (§3.2): the least-squares problem.

The unknowns are the joints' degrees of freedom and the primitives' parameters of the nodes being
solved; with ``recalibrate`` also every camera's rotation and position (and focal length and
principal point if asked, and, with them, the lens distortion k1 of each photo whose calibration
gives k1 a finite 1σ) and every free marker's position, each camera held by a prior equal to its
calibration and covariance, as in :mod:`vebuild.calibration.positions`, its k1 by its own prior.
Every projection goes through each photo's lens (:attr:`~vebuild.camera.ImageCamera.lens`). Their layout in the
vector is a :class:`~vebuild.model.layout.ParameterLayout`; the residuals and their Jacobian are
in :mod:`.residuals`, the iteration in :mod:`.lm`, what a solve found in :mod:`.solution`.

Relations between nodes (``model.relations``) are taken from the model: an ``equal`` group is one
unknown, a ``flush`` or ``aligned`` relation hard rows (:mod:`.constraints`).

Vertex fixing (paper Figure 7) emerges from two ingredients rather than from a hand-made choice
of parameters: fixed vertices are pins that stay in the problem, and every parameter is pulled
gently toward its value before the solve, more gently for a joint's position than for a size.
With nothing fixed, the cheapest way to follow the mouse is to move the whole primitive; with a
vertex fixed, only a change of size or turn keeps it in place; directions that no observation
determines stay where they were.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from vebuild.calibration.lm import LMResult, levenberg_marquardt
from vebuild.calibration.lsq import is_numeric_failure
from vebuild.calibration.positions import ReferenceDistance
from vebuild.camera import ImageCamera
from vebuild.determinism import deterministic

from .camera_blocks import SharedIntrinsics, group_prior, shared_cameras, whitening
from .constraints import hard_relations, restore, tie_equal
from .layout import ParameterLayout
from .residuals import EdgeObservation, MarkerObservation, Pin, Residuals
from .scene import Model

Array = NDArray[np.float64]

#: 1σ of the pull toward the value before a drag, per kind of parameter: metres for positions,
#: radians for angles, metres for sizes. A position is 10× freer than a size and, at a lever arm
#: of half a metre, 3× freer than a turn, so a lone drag moves the primitive rather than
#: stretching or turning it (paper Figure 7a); the pull also keeps each step of a drag local.
PRIOR_SIGMA = {"position": 1.0, "angle": 0.3, "size": 0.1}
#: In a final solve the pull only keeps undetermined directions in place: 10⁵ times weaker.
FINAL_PRIOR_SCALE = 1e5


@dataclass(frozen=True)
class ProblemOptions:
    """How a problem is posed.

    click_sigma_px : the click noise (1σ, pixels) that whitens every image residual.
    prior_scale : the pull toward the values before the solve is PRIOR_SIGMA × this
        (FINAL_PRIOR_SCALE in a final solve).
    free_nodes : the nodes whose parameters are solved (default: every node with ``solve``).
    held : ``node.param`` names held at their values besides the nodes' own ``hold``.
    recalibrate : solve the cameras (and the free markers) too (paper §3.2).
    refine_intrinsics : with ``recalibrate``, each camera's f and principal point as well.
    k1_sigma : with ``recalibrate`` and ``refine_intrinsics``, photo id → the 1σ of its lens
        distortion's prior (the calibration record's ``distortion.k1.sigma``): that photo's k1 is
        refined, held by a Gaussian prior at its calibrated value with this 1σ. A photo absent, or
        with a 1σ of 0 or not finite, keeps its k1 as calibrated.
    camera_groups : with ``recalibrate`` and ``refine_intrinsics``, camera group id → its photos'
        shared intrinsics (:class:`~vebuild.model.camera_blocks.SharedIntrinsics`): one (f, cx, cy[,
        k1]) for all of them, held once by the group's prior (a group's photos' own k1_sigma unused).
    """

    click_sigma_px: float = 1.0
    prior_scale: float = 1.0
    free_nodes: Sequence[str] | None = None
    held: Collection[str] = ()
    recalibrate: bool = False
    refine_intrinsics: bool = False
    k1_sigma: Mapping[str, float] = field(default_factory=dict)
    camera_groups: Mapping[str, SharedIntrinsics] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("click_sigma_px", "prior_scale"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        for photo, v in self.k1_sigma.items():
            if not v >= 0:
                raise ValueError(f"photo '{photo}': the 1σ of k1 must be ≥ 0, got {v!r}")

    def refines_k1(self, photo: str) -> bool:
        """Whether the solve refines this photo's lens distortion."""
        v = self.k1_sigma.get(photo, 0.0)
        return self.recalibrate and self.refine_intrinsics and bool(np.isfinite(v) and v > 0)


@dataclass(frozen=True)
class MarkerData:
    """The markers a problem sees: calibrated positions, those held fixed when re-calibrating (the
    origin, surveyed ones), their sightings in the photos, and the reference distances."""

    positions: Mapping[str, Array] = field(default_factory=dict)
    fixed: Sequence[str] = ()
    observations: Sequence[MarkerObservation] = ()
    distances: Sequence[ReferenceDistance] = ()


class Problem(Residuals):
    """One least-squares problem over a model (and optionally cameras and markers).

    Built once per drag or solve: everything that does not change between evaluations (which
    parameters are free, which observations each one moves, camera matrices) is set up here.
    """

    def __init__(self, model: Model, cameras: Mapping[str, ImageCamera], pins: Sequence[Pin] = (),
                 edges: Sequence[EdgeObservation] = (), *, options: ProblemOptions | None = None,
                 markers: MarkerData | None = None) -> None:
        options = ProblemOptions() if options is None else options
        markers = MarkerData() if markers is None else markers
        self.options = options
        self.model = model
        self.cam_ids = list(cameras)
        shared = options.camera_groups if options.recalibrate and options.refine_intrinsics else {}
        shared = {g: s for g, s in shared.items() if all(c in cameras for c in s.photos)}
        self.cameras = shared_cameras(cameras, shared)
        self.sigma = options.click_sigma_px
        self.pins = [p for p in pins if p.photo in self.cameras]
        for p in self.pins:
            if np.shape(p.uv) != (2,) or not np.all(np.isfinite(p.uv)):
                raise ValueError(f"pin {p.node}:{p.handle} in photo '{p.photo}': expected a finite pixel (u, v), "
                                 f"got {p.uv}")
        self.edges = [e for e in edges if e.photo in self.cameras]
        self.x_model0 = model.vector()
        free = {n.name for n in model.nodes if n.solve} if options.free_nodes is None else set(options.free_nodes)
        free_idx: list[int] = []
        owner: list[str] = []
        for n in model.nodes:
            if n.name in free:
                sq, sp = model.slices[n.name]
                names_n = list(n.joint.dof_names) + list(n.primitive.PARAMS if n.primitive is not None else ())
                idx = list(range(sq.start, sq.stop)) + list(range(sp.start, sp.stop))
                keep = [i for i, nm in zip(idx, names_n, strict=True)
                        if nm not in n.hold and f"{n.name}.{nm}" not in options.held]
                free_idx += keep
                owner += [n.name] * len(keep)  # the node each parameter moves (with its subtree)
        # Equal relations: one unknown per group (or the group held at its held member's value).
        ties = tie_equal(model, self.x_model0, np.array(free_idx, dtype=np.intp), owner)
        self.x_model0, self.free_idx, self.owner = ties.x_model0, ties.free_idx, ties.owner
        self.tie_src, self.tie_dst, self.also, self.alias = ties.src, ties.dst, ties.also, ties.alias
        owner = self.owner
        names, kinds = model.parameter_names(), model.parameter_kinds()
        lo, _ = model.bounds()
        self._least = np.where(np.array(kinds)[self.free_idx] == "size", lo[self.free_idx], -np.inf) \
            if len(self.free_idx) else np.zeros(0)
        # Free nodes whose joints have limits: each clips its own degrees of freedom in a step.
        movers = set(owner).union(*self.also.values())
        self._limited = [(n.joint, model.slices[n.name][0]) for n in model.nodes
                         if n.name in movers and np.isfinite(np.r_[n.joint.bounds()]).any()]

        self.recalibrate = options.recalibrate
        self.refine_intrinsics = options.refine_intrinsics
        self.markers0 = {k: np.asarray(v, float) for k, v in markers.positions.items()}
        self.marker_obs = [m for m in markers.observations if m.photo in self.cameras and m.marker in self.markers0]
        fixed = set(markers.fixed)
        self.free_markers = [k for k in sorted(self.markers0) if k not in fixed] if self.recalibrate else []
        self.distances = list(markers.distances)
        self.layout = ParameterLayout([names[i] for i in self.free_idx], [kinds[i] for i in self.free_idx],
                                      self.cam_ids if self.recalibrate else (),
                                      self.recalibrate and self.refine_intrinsics, self.free_markers,
                                      [c for c in self.cam_ids if options.refines_k1(c)],
                                      {g: (s.photos, s.refine_k1) for g, s in shared.items()})
        self.names = list(self.layout.model.names)
        self.n_model = len(self.layout.model)
        self.n = self.layout.n
        self.prior_sigma = np.array([PRIOR_SIGMA[k] for k in self.layout.model.kinds]) * options.prior_scale
        self._prior_L, self._prior_at = {}, {}
        for cid, blk in self.layout.cameras.items():
            cam = self.cameras[cid]
            keep = list(blk.calibration_index)
            # Block-diagonal: the calibration's covariance over (f, cx, cy, ω, C), then k1's 1σ.
            L = np.zeros((len(blk), len(blk)))
            if cam.covariance is not None:  # a group's photo: its pose's marginal (the group holds K)
                L[: len(keep), : len(keep)] = whitening(np.asarray(cam.covariance, float)[np.ix_(keep, keep)])
            at = np.zeros(len(blk))  # the prior is 0 at the calibration: no turn, no change of K
            o = blk.pose_start + 3 - blk.start  # the centre C follows the turn ω
            at[o : o + 3] = cam.C
            if blk.distortion:  # its own k1 (a group's photo's is the group's)
                L[-1, -1] = 1.0 / options.k1_sigma[cid]
                at[-1] = cam.lens.k1
            self._prior_L[cid], self._prior_at[cid] = L, at
        self._group_L, self._group_at = {}, {}
        for gid, blk in self.layout.groups.items():
            self._group_L[gid] = group_prior(len(blk), shared[gid].covariance)
            self._group_at[gid] = np.r_[0.0, 0.0, 0.0, [shared[gid].k1] if blk.k1_index is not None else []]
        # Only the subtrees of nodes with a free parameter move (during a drag, one object of the
        # scene): every other node's transform and handles are computed once, here.
        moving: set[str] = set()
        for name in movers:
            moving.update(model.subtree(name))
        self._moving = None if len(moving) == len(model.nodes) else sorted(moving, key=model.index.__getitem__)
        self.hard = hard_relations(model, moving)
        self._build_dependencies()
        self._T0 = model.world_transforms(self.x_model0)
        self._H0 = self.handle_positions(self.x_model0, self._T0)

    # -- the unknowns ------------------------------------------------------------------------
    def x0(self) -> Array:
        """The starting vector: the model's values, each camera as calibrated, the markers' positions."""
        x = np.zeros(self.layout.n)
        x[self.layout.model.slice] = self.x_model0[self.free_idx]
        for cid, blk in self.layout.cameras.items():
            x[blk.slice] = self._prior_at[cid]  # as calibrated: no turn, no change of K
        for gid, blk in self.layout.groups.items():
            x[blk.slice] = self._group_at[gid]
        for k, blk in self.layout.markers.items():
            x[blk.slice] = self.markers0[k]
        return x

    def bounds(self) -> tuple[Array, Array]:
        """Lower and upper bounds of every unknown (the joints' limits, the primitives' least sizes)."""
        lo, hi = self.model.bounds()
        extra = self.layout.n - len(self.layout.model)
        return np.r_[lo[self.free_idx], np.full(extra, -np.inf)], np.r_[hi[self.free_idx], np.full(extra, np.inf)]

    def clip(self, x: Array) -> Array:
        """x with every joint's degrees of freedom clipped by the joint to its limits and every size
        at least its primitive's least; within a solve, brought back onto its flush and aligned
        relations (:func:`~vebuild.model.constraints.restore`)."""
        x = np.array(x, float)
        m = self.layout.model.slice
        if self._limited:
            xm = self.model_vector(x)
            for joint, sq in self._limited:
                xm[sq] = joint.clip(xm[sq])
            x[m] = xm[self.free_idx]
        x[m] = np.maximum(x[m], self._least)
        if self._hard_J is not None:  # a step of the solve: back onto the relations (constraints.py)
            x = restore(self, x, self._hard_J)
            x[m] = np.maximum(x[m], self._least)
        return x

    # -- solving -----------------------------------------------------------------------------
    @deterministic
    def solve(self, x0: Array | None = None, robust: bool = False, max_iterations: int = 100,
              tol: float = 1e-10, damping: float = 1e-4) -> LMResult:
        """Bounded Levenberg–Marquardt (:mod:`.lm`) from x0 (default: the model's values).

        The normal equations JᵀJ are solved directly (sparse when large); a robust fit uses the
        soft-L1 loss on the observation rows (not on the priors).
        """
        x0 = self.x0() if x0 is None else x0
        # A robust fit reweights from the first iteration, so that a wrong mark is discounted
        # before it can drag the model (or the cameras) toward it.
        robust_rows = self.n_data + len(self.distances) if robust else 0
        return levenberg_marquardt(self.residuals, self.jacobian, self.clip(x0), self.clip, max_iterations,
                                   tol=tol, damping=damping, robust_rows=robust_rows)

    def plausible(self, result: LMResult) -> bool:
        """Whether a solve from the first guess plainly found the minimum, so that no staged start
        (:func:`staged_start`) is needed: it converged, every pinned handle and sighted marker lies
        in front of its camera (an edge's ends may lie behind: its line is what is observed), the
        median of the observations' whitened residuals (per pin, edge or sighting, the norm of its
        two rows) is at most PLAUSIBLE_MEDIAN_SIGMAS, and no node's pins and edges have a median
        above PLAUSIBLE_NODE_SIGMAS (a piece of furniture turned the wrong way among hundreds
        that fit would not move the overall median)."""
        if not result.converged or not np.all(np.isfinite(result.x)):
            return False
        x = result.x
        _, H = self._posed(self.model_vector(x))
        Ks, Rs, Cs, _k1 = self._camera_arrays(x)
        M = self._marker_array(x)
        for cam, X in ((self.pin_cam, H[self.pin_row]), (self.mo_cam, M[self.mo_marker])):
            if len(cam) and np.any(np.einsum("nj,nj->n", Rs[cam, 2], X - Cs[cam]) <= 0.0):
                return False
        r = result.residuals
        rows = np.concatenate([self.rows_pin, self.rows_edge, self.rows_marker])
        norms = np.hypot(r[rows[:, 0]], r[rows[:, 1]])
        if len(rows) and np.median(norms) > PLAUSIBLE_MEDIAN_SIGMAS:
            return False
        nodes = [p.node for p in self.pins] + [e.node for e in self.edges]
        of_node: dict[str, list[float]] = {}
        for node, e in zip(nodes, norms[: len(nodes)].tolist(), strict=True):
            of_node.setdefault(node, []).append(e)
        return all(float(np.median(v)) <= PLAUSIBLE_NODE_SIGMAS for v in of_node.values())


#: A solve from the first guess is kept (:meth:`Problem.plausible`) where the median of its
#: observations' whitened residuals is at most this. On the generated rooms of `vebuild bench rooms`
#: (clicks at their stated σ) a solve that found the minimum has a median of 0.7–1.1; the one that
#: did not (seed 6: 100 iterations, two pinned handles behind a camera) 3.6. Clicks twice as
#: scattered as the stated σ take the staged start, as every solve did before.
PLAUSIBLE_MEDIAN_SIGMAS = 2.0
#: ... and where no node's pins and edges have a median whitened residual above this: a pin at
#: the stated click noise lies this far out with a chance of e^(-12.5), 4e-6, so a node of a
#: right minimum stays below it; a node in a wrong one is off by tens of σ (seed 6: the tenth
#: of the pins farthest out at 60σ and more).
PLAUSIBLE_NODE_SIGMAS = 5.0

#: A stage of :func:`staged_start` stops once a step lowers its cost by less than this share: it
#: only gives the final solve its start. On the generated house a stage's cost is within 0.1 % of
#: its minimum after a few steps, and a tolerance of 1e-10 spent 30–90 more Jacobians on its tail.
STAGE_TOL = 1e-6


def staged_start(model: Model, cameras: Mapping[str, ImageCamera], pins: Sequence[Pin],
                 edges: Sequence[EdgeObservation], click_sigma_px: float) -> int:
    """Move ``model`` to a start for its final solve, down the scene graph a level at a time: the
    free nodes at the top level first (a room, from its own pins and edges), then those one level
    down with them, and so on to the level above the last, each with the cameras held as given and
    only the pins, edges and relations of the nodes solved so far. Returns the stages solved.

    From a first guess 10–25 % off, a solve of everything at once can be led by the children's
    pins, whose positions follow their parent's wrong size, into a minimum that turns the room and
    puts pinned vertices behind a camera (seeds 6 and 8 of tests/test_room_scenes.py did); a parent
    solved first from its own observations gives its children a start near theirs. The final
    solve, from here, is the same least-squares problem as before: only where it starts changes.
    A stage that fails numerically (a degenerate sub-problem) puts the model back where it was
    before the first and stops: the final solve then starts from the guess and says what fails.

    `vebuild solve` first solves the whole problem from the guess and comes here only where that
    did not plainly find the minimum (:meth:`Problem.plausible`): on the generated house, whose
    calibrated cameras stand decimetres off in the far rooms, stages that hold the cameras as
    calibrated led the final solve into 100 iterations that did not converge, where the solve from
    the guess converged in 9.
    """
    depth: dict[str, int] = {}
    for n in model.nodes:  # parents before children
        depth[n.name] = 0 if n.parent is None else depth[n.parent] + 1
    free = [n.name for n in model.nodes if n.solve]
    levels = sorted({depth[n] for n in free})
    every, guess = model.relations, model.vector()
    for level in levels[:-1]:
        names = {n for n in free if depth[n] <= level}
        # A relation to a node not yet solved would hold the solved ones to that node's guess.
        model.relations = [r for r in every if set(r.nodes()) <= names]
        try:
            problem = Problem(model, cameras, [p for p in pins if p.node in names],
                              [e for e in edges if e.node in names],
                              options=ProblemOptions(click_sigma_px=click_sigma_px, prior_scale=FINAL_PRIOR_SCALE,
                                                     free_nodes=sorted(names)))
            if problem.n_model and problem.n_data:
                x = problem.model_vector(problem.solve(problem.x0(), robust=True, tol=STAGE_TOL).x)
                if np.all(np.isfinite(x)):  # else the final solve starts from where this stage did, and says why
                    model.set_vector(x)
        except (ValueError, np.linalg.LinAlgError) as e:
            if not is_numeric_failure(e):
                raise
            model.set_vector(guess)
            return 0
        finally:
            model.relations = every
    return max(len(levels) - 1, 0)
