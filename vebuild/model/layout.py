"""The solver's unknowns, laid out as blocks: the model's free parameters, then each camera's, then
each free marker's.

A block knows its slice of the vector, its parameters' names, kinds (DOF_KINDS, plus ``pixel``
for a camera's intrinsics) and units, how the solve holds it (its prior), and how its values are
written in the project file (angles in degrees, under a ``_deg`` name). Nothing else computes an
offset into the vector or decides from a name whether a parameter is an angle.

Camera block: with intrinsics, (δf, δcx, δcy) in pixels; then a small turn ω (radians, left-
multiplied: R' = exp([ω]×) R) and the centre C (metres), in the order of the calibration's
(9, 9) covariance over (f, cx, cy, ω, C); last, where the photo's lens distortion is refined, its
k1 (the division model of vebuild/camera.py, dimensionless), held by its own prior (the k1 and 1σ
of the calibration's ``distortion`` record). Marker block: the position (metres).

Camera group block (photos of one camera, scenes/FORMAT.md "Camera groups"): where intrinsics are
refined, a group's photos share one (δf, δcx, δcy[, k1]), held once by the group's joint prior; each
of its photos' camera blocks then holds only its pose (ω, C) and points at the group's block.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: The unit of each kind of parameter in the solver (radians for angles: DESIGN.md).
UNITS = {"position": "m", "angle": "rad", "size": "m", "pixel": "px", "coefficient": "1"}
#: A calibrated camera's parameters in the order of its (9, 9) covariance.
CAMERA_PARAMS = ("f", "cx", "cy", "wx", "wy", "wz", "x", "y", "z")
CAMERA_KINDS = ("pixel",) * 3 + ("angle",) * 3 + ("position",) * 3
#: A camera's lens distortion, after its calibration parameters where it is refined.
DISTORTION_PARAM, DISTORTION_KIND = "k1", "coefficient"
#: How a block is held besides by the observations: ``pull`` toward its value before the solve
#: (the model: PRIOR_SIGMA by kind), ``calibration`` by the camera's calibration covariance,
#: ``none`` (a marker: its sightings and distances alone place it).
PRIORS = ("pull", "calibration", "none")


@dataclass(frozen=True)
class Block:
    """One block of the solver's vector: ``what`` (model, camera, marker) and ``key`` (the photo id
    or the marker name; "" for the model)."""

    what: str
    key: str
    start: int
    names: tuple[str, ...]  # full names: "box0.yaw", "camera:p1.wx", "marker:M1.x"
    kinds: tuple[str, ...]
    prior: str
    #: A camera block's parameters' places in CAMERA_PARAMS (its calibration covariance's rows).
    calibration_index: tuple[int, ...] = ()
    #: A camera block whose last parameter is the lens distortion k1.
    distortion: bool = False
    #: A camera block of a camera group's photo: where the group's (δf, δcx, δcy) are, and its k1.
    shared_at: int | None = None
    shared_k1: int | None = None

    def __len__(self) -> int:
        return len(self.names)

    @property
    def stop(self) -> int:
        return self.start + len(self.names)

    @property
    def slice(self) -> slice:
        return slice(self.start, self.stop)

    @property
    def indices(self) -> NDArray[np.intp]:
        return np.arange(self.start, self.stop)

    @property
    def units(self) -> tuple[str, ...]:
        return tuple(UNITS[k] for k in self.kinds)

    @property
    def own_intrinsics(self) -> bool:
        """A camera block with its own (δf, δcx, δcy) ahead of its pose."""
        return self.what == "camera" and len(self.calibration_index) == 9

    @property
    def intrinsics(self) -> bool:
        """A camera block whose (δf, δcx, δcy) are refined: its own, or its camera group's."""
        return self.own_intrinsics or self.shared_at is not None

    @property
    def intrinsics_start(self) -> int:
        """Where a camera block's (δf, δcx, δcy) are: in it, or in its camera group's block."""
        return self.start if self.shared_at is None else self.shared_at

    @property
    def pose_start(self) -> int:
        """Where a camera block's turn ω begins (its centre follows at + 3)."""
        return self.start + (3 if self.own_intrinsics else 0)

    @property
    def k1_index(self) -> int | None:
        """Where a camera block's lens distortion k1 is (None where it is not refined)."""
        return self.stop - 1 if self.distortion else self.shared_k1

    @property
    def columns(self) -> NDArray[np.intp]:
        """Every unknown that moves this camera: its own and its camera group's."""
        if self.shared_at is None:
            return self.indices
        shared = [*range(self.shared_at, self.shared_at + 3), *([self.shared_k1] if self.shared_k1 is not None else [])]
        return np.r_[np.array(shared, dtype=np.intp), self.indices].astype(np.intp)

    def camera_columns(self) -> tuple[list[int], NDArray[np.intp]]:
        """The camera's refined (f, cx, cy, ω, C) as places in CAMERA_PARAMS and their columns."""
        if self.shared_at is None:
            return list(self.calibration_index), self.start + np.arange(len(self.calibration_index))
        return [0, 1, 2, *self.calibration_index], np.r_[np.arange(self.shared_at, self.shared_at + 3),
                                                          np.arange(self.start, self.start + 6)].astype(np.intp)

    def file_names(self) -> list[str]:
        """The names in the project file's units: an angle's name gains ``_deg``."""
        return [f"{n}_deg" if k == "angle" else n for n, k in zip(self.names, self.kinds, strict=True)]

    def file_scale(self) -> Array:
        """Multiply solver values (and 1σ) by this to get file units (degrees for angles)."""
        return np.array([np.degrees(1.0) if k == "angle" else 1.0 for k in self.kinds])


class ParameterLayout:
    """The blocks of one solve, in vector order: the model, each camera (when re-calibrating),
    each free marker. ``distortion``: the cameras (of ``cameras``) whose lens distortion k1 is
    refined too."""

    def __init__(self, model_names: Sequence[str], model_kinds: Sequence[str], cameras: Sequence[str] = (),
                 intrinsics: bool = False, markers: Sequence[str] = (), distortion: Collection[str] = (),
                 groups: Mapping[str, tuple[Sequence[str], bool]] | None = None) -> None:
        """groups : with ``intrinsics``, camera group id → (its photos, whether its k1 is refined):
        one block of intrinsics per group, after the cameras' (module docstring)."""
        if len(model_names) != len(model_kinds):
            raise ValueError(f"{len(model_names)} model parameter names for {len(model_kinds)} kinds")
        self.model = Block("model", "", 0, tuple(model_names), tuple(model_kinds), "pull")
        k = self.model.stop
        params = CAMERA_PARAMS if intrinsics else CAMERA_PARAMS[3:]
        index = tuple(CAMERA_PARAMS.index(p) for p in params)
        group_of = {c: g for g, (members, _) in (groups or {}).items() for c in members} if intrinsics else {}
        self.cameras: dict[str, Block] = {}
        for cid in [c for c in cameras if c not in group_of]:
            lens = cid in distortion
            names = tuple(f"camera:{cid}.{p}" for p in params) + ((f"camera:{cid}.{DISTORTION_PARAM}",) if lens else ())
            kinds = tuple(CAMERA_KINDS[i] for i in index) + ((DISTORTION_KIND,) if lens else ())
            self.cameras[cid] = Block("camera", cid, k, names, kinds, "calibration", index, lens)
            k += len(names)
        self.groups: dict[str, Block] = {}
        for gid, (members, lens) in (groups or {}).items() if intrinsics else ():
            names = tuple(f"camera_group:{gid}.{p}" for p in CAMERA_PARAMS[:3]) + \
                ((f"camera_group:{gid}.{DISTORTION_PARAM}",) if lens else ())
            kinds = CAMERA_KINDS[:3] + ((DISTORTION_KIND,) if lens else ())
            self.groups[gid] = blk = Block("camera_group", gid, k, names, kinds, "calibration", (0, 1, 2), lens)
            k += len(names)
            for cid in members:
                self.cameras[cid] = Block("camera", cid, k, tuple(f"camera:{cid}.{p}" for p in CAMERA_PARAMS[3:]),
                                          CAMERA_KINDS[3:], "calibration", tuple(range(3, 9)),
                                          shared_at=blk.start, shared_k1=blk.k1_index)
                k += 6
        self.cameras = {c: self.cameras[c] for c in cameras}  # in the photos' order
        self.markers: dict[str, Block] = {}
        for m in markers:
            self.markers[m] = Block("marker", m, k, tuple(f"marker:{m}.{c}" for c in "xyz"), ("position",) * 3, "none")
            k += 3
        self.n = k

    @property
    def blocks(self) -> list[Block]:
        return sorted([self.model, *self.cameras.values(), *self.groups.values(), *self.markers.values()],
                      key=lambda b: b.start)

    @property
    def names(self) -> list[str]:
        return [n for b in self.blocks for n in b.names]

    @property
    def kinds(self) -> list[str]:
        return [k for b in self.blocks for k in b.kinds]

    def model_and_markers(self) -> NDArray[np.intp]:
        """Indices of the model's and the markers' parameters: what a point of the model moves
        with (the cameras left out)."""
        return np.concatenate([self.model.indices, *[b.indices for b in self.markers.values()]]).astype(np.intp)

    def file_names(self, blocks: Sequence[Block]) -> list[str]:
        return [n for b in blocks for n in b.file_names()]

    def file_scale(self, blocks: Sequence[Block]) -> Array:
        return np.concatenate([b.file_scale() for b in blocks] or [np.zeros(0)])

    def block_of(self, index: int) -> Block:
        """The block holding parameter ``index``."""
        for b in self.blocks:
            if b.start <= index < b.stop:
                return b
        raise IndexError(f"parameter {index} is outside the layout's {self.n}")
