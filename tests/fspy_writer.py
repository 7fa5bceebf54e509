"""Write fSpy project files (.fspy) for the import tests, from a known camera.

The layout is fSpy's (project_file_format.md in github.com/stuffmatic/fSpy): "fspy", uint32 version,
uint32 state size, uint32 image size (little-endian), the state JSON, the image bytes. The state's
control points are made by projecting known 3-D lines through a known camera, adding Gaussian noise
(pixels) and converting to fSpy's relative coordinates (x / width, y / height, y down). Each
segment's two ends are written in a random order: fSpy's segments carry no direction.

``cameraParameters`` is what fSpy's solver computes from those noisy control points (its equations
re-derived here from Guillou et al., "Using vanishing points for camera calibration and coarse 3D
reconstruction from a single image", as fSpy's solver.ts uses them, in fSpy's image plane
coordinates: origin at the centre, y up, unit half the longer side); only its translation is the
true camera's (in the reference distance's unit), fSpy's own being a scaling of it.
"""

from __future__ import annotations

import io
import json
import struct
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

from vebuild.camera import rotation_from_ypr

GL_TO_CV = np.diag([1.0, -1.0, -1.0])
AXIS_NAMES = {("x", 1): "xPositive", ("x", -1): "xNegative", ("y", 1): "yPositive", ("y", -1): "yNegative",
              ("z", 1): "zPositive", ("z", -1): "zNegative"}


def axis_vec(name: str) -> np.ndarray:
    v = np.zeros(3)
    v["xyz".index(name[0])] = 1.0 if name.endswith("Positive") else -1.0
    return v


def fspy_bytes(state: dict[str, Any] | bytes, image: bytes, version: int = 1, magic: bytes = b"fspy",
               state_size: int | None = None, image_size: int | None = None) -> bytes:
    """The file as fSpy's ``ProjectFile.save`` (src/gui/io/project-file.ts) writes it: the 16-byte
    header, ``JSON.stringify(state)`` (no spaces) as UTF-8, the image's bytes."""
    raw = state if isinstance(state, bytes) else json.dumps(state, separators=(",", ":"),
                                                            ensure_ascii=False).encode("utf-8")
    header = magic + struct.pack("<III", version, len(raw) if state_size is None else state_size,
                                 len(image) if image_size is None else image_size)
    return header + raw + image


#: What each of fSpy's releases saves (github.com/stuffmatic/fSpy at each tag; ``SavedState`` in
#: src/gui/io/saved-state.ts, ``getStateToSave`` in src/gui/io/project-file.ts, the types in
#: src/gui/types/*.ts): whether the state holds ``cameraParameters`` and ``resultDisplaySettings``
#: (saved since v1.0.0-alpha.5), ``cameraData.presetData`` (since v1.0.0), and the reference distance
#: units of ``ReferenceDistanceUnit`` (No unit / Meters / Yards until v1.0.1; eight from v1.0.2 on).
RELEASES: dict[str, dict[str, Any]] = {
    "1.0.0-alpha.1": {"camera": False, "preset_data": False, "units": ("No unit", "Meters", "Yards")},
    "1.0.0-alpha.5": {"camera": True, "preset_data": False, "units": ("No unit", "Meters", "Yards")},
    "1.0.0": {"camera": True, "preset_data": True, "units": ("No unit", "Meters", "Yards")},
    "1.0.2": {"camera": True, "preset_data": True,
              "units": ("No unit", "Millimeters", "Centimeters", "Meters", "Kilometers", "Inches", "Feet", "Miles")},
}
#: Metres per unit of fSpy's ``ReferenceDistanceUnit`` (and the early ``Yards``).
UNIT_M = {"No unit": 1.0, "Millimeters": 0.001, "Centimeters": 0.01, "Meters": 1.0, "Kilometers": 1000.0,
          "Inches": 0.0254, "Feet": 0.3048, "Miles": 1609.344, "Yards": 0.9144}
#: A few of fSpy's camera presets (src/gui/solver/camera-presets.ts): id → (the preset as fSpy
#: stores it in ``presetData``).
PRESETS = {"canon_5d": {"displayName": "Canon 5D", "sensorWidth": 36, "sensorHeight": 24},
           "aps-c": {"displayName": "APS-C DSLR", "sensorWidth": 22.3, "sensorHeight": 14.9},
           "iphone_6s": {"displayName": "iPhone 6S", "sensorWidth": 4.8, "sensorHeight": 3.6, "focalLength": 4.15}}


def as_saved_by(state: dict[str, Any], release: str, horizon_moved: bool = False) -> dict[str, Any]:
    """``state`` (the newest layout) as fSpy ``release`` saves it.

    ``horizon_moved``: the horizon as fSpy saves it once one of its two control points has been
    dragged: fSpy's ``ADJUST_HORIZON`` reducer (src/gui/reducers/control-points-1-vp.ts, every
    release) copies the pair with ``{ ...state.horizon }``, so ``JSON.stringify`` writes an object
    with the keys "0" and "1" instead of a list.
    """
    spec = RELEASES[release]
    out = json.loads(json.dumps(state))
    unit = out["calibrationSettingsBase"]["referenceDistanceUnit"]
    assert unit in spec["units"], f"fSpy {release} has no unit {unit!r}"
    if not spec["camera"]:
        del out["cameraParameters"], out["resultDisplaySettings"]
    if not spec["preset_data"]:
        del out["calibrationSettingsBase"]["cameraData"]["presetData"]
    if horizon_moved:
        h = out["controlPointsState1VP"]["horizon"]
        out["controlPointsState1VP"]["horizon"] = {"0": h[0], "1": h[1]}
    return out


def make_image(width: int, height: int, fmt: str = "JPEG", seed: int = 0) -> bytes:
    """A small picture (grey with a few lines), encoded as ``fmt``."""
    rng = np.random.default_rng(seed)
    img = Image.new("RGB", (width, height), (120, 120, 130))
    d = ImageDraw.Draw(img)
    for _ in range(6):
        d.line([tuple(rng.uniform(0, width, 1)) + tuple(rng.uniform(0, height, 1)),
                tuple(rng.uniform(0, width, 1)) + tuple(rng.uniform(0, height, 1))], fill=(200, 190, 60), width=2)
    buf = io.BytesIO()
    img.save(buf, format=fmt, **({"quality": 90} if fmt == "JPEG" else {}))
    return buf.getvalue()


@dataclass
class KnownCamera:
    """A pinhole camera in vebuild's conventions (K in pixels, R world → camera, C)."""

    width: int
    height: int
    f: float
    c: np.ndarray
    R: np.ndarray
    C: np.ndarray

    @staticmethod
    def looking_at_corner(width: int = 640, height: int = 480, f_rel: float = 0.9, yaw_deg: float = 225.0,
                          pitch_deg: float = -18.0, roll_deg: float = 2.0, height_m: float = 1.6,
                          c_offset: tuple[float, float] = (0.0, 0.0)) -> KnownCamera:
        """A camera 1.6 m above the floor at (3, 2.5), looking back toward the origin's corner."""
        R = rotation_from_ypr(np.radians(yaw_deg), np.radians(pitch_deg), np.radians(roll_deg))
        f = f_rel * max(width, height)
        c = np.array([width / 2 + c_offset[0], height / 2 + c_offset[1]])
        return KnownCamera(width, height, f, c, R, np.array([3.0, 2.5, height_m]))

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.f, 0, self.c[0]], [0, self.f, self.c[1]], [0, 0, 1.0]])

    def project(self, X: np.ndarray) -> np.ndarray:
        x = self.K @ (self.R @ (np.asarray(X, float) - self.C))
        assert x[2] > 0, "a point behind the camera"
        return x[:2] / x[2]


@dataclass
class StateBuilder:
    """Builds an fSpy state from a known camera."""

    cam: KnownCamera
    rng: np.random.Generator
    noise_px: float = 0.5
    # The default camera looks toward −x and −y: those axes point toward its vanishing points.
    first_axis: str = "xNegative"
    second_axis: str = "yNegative"
    mode: str = "TwoVanishingPoints"
    quad: bool = False
    principal_point_mode: str = "Default"
    reference_axis: str | None = "zPositive"
    reference_unit: str = "Meters"
    with_camera: bool = True
    sensor_mm: tuple[float, float] = (36.0, 24.0)
    preset: str | None = None  # one of PRESETS: its sensor instead of sensor_mm
    shuffle: bool = True
    truth: dict[str, Any] = field(default_factory=dict)

    @property
    def sensor(self) -> tuple[float, float]:
        if self.preset:
            return (float(PRESETS[self.preset]["sensorWidth"]), float(PRESETS[self.preset]["sensorHeight"]))
        return self.sensor_mm

    # -- coordinates --------------------------------------------------------------------------------

    def rel(self, uv: np.ndarray, noisy: bool = True) -> dict[str, float]:
        uv = np.asarray(uv, float) + (self.rng.normal(0.0, self.noise_px, 2) if noisy and self.noise_px else 0.0)
        return {"x": float(uv[0] / self.cam.width), "y": float(uv[1] / self.cam.height)}

    def plane(self, p: dict[str, float]) -> np.ndarray:
        """fSpy's relative → image plane coordinates (relativeToImagePlane)."""
        W, H = self.cam.width, self.cam.height
        a = W / H
        if a <= 1:
            return np.array([(-1 + 2 * p["x"]) * a, 1 - 2 * p["y"]])
        return np.array([-1 + 2 * p["x"], (1 - 2 * p["y"]) / a])

    def segment(self, X0: np.ndarray, X1: np.ndarray) -> list[dict[str, float]]:
        pts = [self.rel(self.cam.project(X0)), self.rel(self.cam.project(X1))]
        if self.shuffle and self.rng.random() < 0.5:
            pts.reverse()
        return pts

    def lines_along(self, axis: str, starts: list[np.ndarray], length: float = 1.2) -> dict[str, Any]:
        e = np.abs(axis_vec(axis))
        return {"lineSegments": [self.segment(s, s + length * e) for s in starts]}

    # -- the state ---------------------------------------------------------------------------------

    def starts(self, axis: str) -> list[np.ndarray]:
        """Two starting points of lines along ``axis`` in view of the camera (a room corner at the origin)."""
        letter = axis[0]
        return {"x": [np.array([0.3, 0.0, 0.0]), np.array([0.3, 0.0, 1.2])],
                "y": [np.array([0.0, 0.3, 0.0]), np.array([0.0, 0.3, 1.4])],
                "z": [np.array([0.4, 0.0, 0.1]), np.array([0.0, 0.6, 0.1])]}[letter]

    def build(self) -> dict[str, Any]:
        W, H = self.cam.width, self.cam.height
        first, second = self.first_axis, self.second_axis
        third_vec = np.cross(axis_vec(first), axis_vec(second))
        third = AXIS_NAMES[("xyz"[int(np.argmax(np.abs(third_vec)))], int(np.sign(third_vec.max() + third_vec.min())))]
        if self.quad:
            e1, e2 = np.abs(axis_vec(first)), np.abs(axis_vec(second))
            P = np.array([0.3, 0.3, 0.0])
            q = [P, P + 1.5 * e1, P + 1.5 * e1 + 1.2 * e2, P + 1.2 * e2]
            uv = [self.rel(self.cam.project(X)) for X in q]
            vp1 = {"lineSegments": [[uv[0], uv[1]], [uv[3], uv[2]]]}
            vp2 = {"lineSegments": [[uv[0], uv[3]], [uv[1], uv[2]]]}  # unused by fSpy in quad mode
        else:
            vp1 = self.lines_along(first, self.starts(first))
            vp2 = self.lines_along(second, self.starts(second))
        vp3 = self.lines_along(third, self.starts(third))
        origin = self.rel(self.cam.project(np.zeros(3)))
        # The reference distance: along its axis from an anchor in the plane through the origin at
        # right angles to it (for z, the floor), handles 0.3 m and 1.8 m along.
        ref_axis = self.reference_axis or "zPositive"
        A = {"z": np.array([0.8, 0.9, 0.0]), "x": np.array([0.0, 0.9, 0.7]),
             "y": np.array([0.9, 0.0, 0.7])}[ref_axis[0]]
        z0, z1 = 0.3, 1.8
        anchor_uv = self.cam.project(A)
        anchor = self.rel(anchor_uv)
        w = axis_vec(ref_axis)
        vz = self.cam.K @ self.cam.R @ w
        vz_rel = np.array([vz[0] / vz[2] / W, vz[1] / vz[2] / H])
        a_rel = np.array([anchor["x"], anchor["y"]])
        d = (vz_rel - a_rel) / np.linalg.norm(vz_rel - a_rel)
        offsets = []
        for z in (z0, z1):
            h = self.cam.project(A + z * w)
            h_rel = np.array([h[0] / W, h[1] / H]) + self.rng.normal(0, self.noise_px, 2) / np.array([W, H])
            offsets.append(float((h_rel - a_rel) @ d))
        pp_rel = self.rel(self.cam.c, noisy=False)
        # Horizon (one vanishing point): two points along the line through the first and second
        # vanishing points, at the image's centre height.
        v1 = self.cam.K @ self.cam.R @ axis_vec(first)
        v2 = self.cam.K @ self.cam.R @ axis_vec(second)
        hline = np.cross(v1, v2)
        hd = np.array([hline[1], -hline[0]])
        hd /= np.linalg.norm(hd)
        # A point on the horizon line nearest the image centre.
        m = np.array([W / 2, H / 2])
        n = hline[:2] / np.linalg.norm(hline[:2])
        m = m - (hline @ np.array([m[0], m[1], 1.0])) / np.linalg.norm(hline[:2]) * n
        horizon = [self.rel(m - 0.3 * W * hd), self.rel(m + 0.3 * W * hd)]
        f_rel_true = self.cam.f / (max(W, H) / 2)
        sw, sh = self.sensor
        focal_mm = f_rel_true * (sw if sw / sh > 1 else sh) / 2
        state: dict[str, Any] = {
            "globalSettings": {"calibrationMode": self.mode, "overlay3DGuide": "XYGridFloor", "imageOpacity": 1},
            "calibrationSettingsBase": {
                "referenceDistanceUnit": self.reference_unit,
                "referenceDistance": (z1 - z0) / UNIT_M[self.reference_unit],
                "referenceDistanceAxis": self.reference_axis,
                "cameraData": {"presetId": self.preset, "presetData": PRESETS[self.preset] if self.preset else None,
                               "customSensorWidth": 36 if self.preset else sw,
                               "customSensorHeight": 24 if self.preset else sh},
                "firstVanishingPointAxis": first,
                "secondVanishingPointAxis": second,
            },
            "calibrationSettings1VP": {"principalPointMode": "Manual" if (self.mode == "OneVanishingPoint" and
                                                                          self.principal_point_mode == "Manual")
                                       else "Default", "absoluteFocalLength": focal_mm},
            "calibrationSettings2VP": {"principalPointMode": self.principal_point_mode, "quadModeEnabled": self.quad},
            "controlPointsStateBase": {
                "principalPoint": pp_rel, "origin": origin, "referenceDistanceAnchor": anchor,
                "firstVanishingPoint": vp1, "referenceDistanceHandleOffsets": offsets,
            },
            "controlPointsState1VP": {"horizon": horizon},
            "controlPointsState2VP": {"secondVanishingPoint": vp2, "thirdVanishingPoint": vp3},
            "cameraParameters": None,
            "resultDisplaySettings": {"projectionMode": "None"},
        }
        if self.with_camera:
            state["cameraParameters"] = self.solve(state)
        self.truth = {"focal_mm": focal_mm, "reference_m": z1 - z0}
        return state

    # -- fSpy's solver, re-derived ----------------------------------------------------------------

    def _vp(self, vp: dict[str, Any]) -> np.ndarray:
        (a, b), (c, d) = [[self.plane(p) for p in s] for s in vp["lineSegments"]]
        v = np.cross(np.cross([*a, 1], [*b, 1]), np.cross([*c, 1], [*d, 1]))
        return v[:2] / v[2]

    def solve(self, state: dict[str, Any]) -> dict[str, Any]:
        W, H = self.cam.width, self.cam.height
        base = state["controlPointsStateBase"]
        s2 = state["controlPointsState2VP"]
        Fu = self._vp(base["firstVanishingPoint"])
        P = np.zeros(2)
        if state["globalSettings"]["calibrationMode"] == "OneVanishingPoint":
            if state["calibrationSettings1VP"]["principalPointMode"] == "Manual":
                P = self.plane(base["principalPoint"])
            sw, sh = self.sensor
            f = 2 * state["calibrationSettings1VP"]["absoluteFocalLength"] / (sw if sw / sh > 1 else sh)
            h0, h1 = (self.plane(p) for p in state["controlPointsState1VP"]["horizon"])
            hd = (h1 - h0) / np.linalg.norm(h1 - h0)
            Fup = Fu - P
            k = -(Fup @ Fup + f * f) / (Fup @ hd)
            Fv = Fu + k * hd
        else:
            if self.quad:
                ls = base["firstVanishingPoint"]["lineSegments"]
                Fv = self._vp({"lineSegments": [[ls[0][0], ls[1][0]], [ls[0][1], ls[1][1]]]})
            else:
                Fv = self._vp(s2["secondVanishingPoint"])
            mode = state["calibrationSettings2VP"]["principalPointMode"]
            if mode == "Manual":
                P = self.plane(base["principalPoint"])
            elif mode == "FromThirdVanishingPoint":
                F3 = self._vp(s2["thirdVanishingPoint"])
                Mx = np.array([Fv - F3, Fu - F3])
                P = np.linalg.solve(Mx, np.array([Fu @ (Fv - F3), Fv @ (Fu - F3)]))
            d = (Fu - Fv) / np.linalg.norm(Fu - Fv)
            Puv = (P - Fv) @ d * d + Fv
            f = float(np.sqrt(np.linalg.norm(Fv - Puv) * np.linalg.norm(Fu - Puv) - np.linalg.norm(P - Puv) ** 2))
        u = np.array([*(Fu - P), -f])
        v = np.array([*(Fv - P), -f])
        u /= np.linalg.norm(u)
        v /= np.linalg.norm(v)
        M = np.column_stack([u, v, np.cross(u, v)])
        first = state["calibrationSettingsBase"]["firstVanishingPointAxis"]
        second = state["calibrationSettingsBase"]["secondVanishingPointAxis"]
        r3 = np.cross(axis_vec(first), axis_vec(second))
        A = np.vstack([axis_vec(first), axis_vec(second), r3])
        Rgl = M @ A
        unit = UNIT_M[self.reference_unit]
        t = -Rgl @ self.cam.C / unit
        view = np.eye(4)
        view[:3, :3] = Rgl
        view[:3, 3] = t
        third_dir = M[:, 2]
        F3p = P + f * third_dir[:2] / -third_dir[2]
        third = AXIS_NAMES[("xyz"[int(np.argmax(np.abs(r3)))], int(np.sign(r3.max() + r3.min())))]
        a = W / H
        return {
            "principalPoint": {"x": float(P[0]), "y": float(P[1])},
            "viewTransform": {"rows": view.tolist()},
            "cameraTransform": {"rows": np.linalg.inv(view).tolist()},
            "horizontalFieldOfView": float(2 * np.arctan(1 / f)),
            "verticalFieldOfView": float(2 * np.arctan((1 / a) / f)),
            "vanishingPoints": [{"x": float(p[0]), "y": float(p[1])} for p in (Fu, Fv, F3p)],
            "vanishingPointAxes": [first, second, third],
            "relativeFocalLength": float(f),
            "imageWidth": W,
            "imageHeight": H,
        }
