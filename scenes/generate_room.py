"""Generate the example project ``scenes/room``: a furnished room photographed five times.

    python scenes/generate_room.py [--out scenes/room] [--scale 1.0] [--supersample 2]

Everything here is written independently of the ``vebuild`` package on purpose: the photographs,
the "user's" clicks and the ground truth come from this file's own geometry, projection and ray
caster, so a convention slip in vebuild (an axis flip, a half-pixel offset) cannot cancel against
the same slip in its test data. Only numpy and Pillow are used; hashes and JSON are written here.

Conventions are those of ``shared/DESIGN.md`` (restated where they are used):

- world: right-handed, metres, +Z up, floor z = 0; the room spans x∈[0, 5], y∈[0, 4], z∈[0, 2.6];
- pixels (u, v): origin at the top-left *corner* of the image, so pixel column i, row j has its
  centre at (i + 0.5, j + 0.5);
- camera: ``x_cam = R (X − C)``, ``u ~ K x_cam``, K = [[f, 0, cx], [0, f, cy], [0, 0, 1]], the camera
  looks along +z_cam, v grows along +y_cam;
- yaw / pitch / roll as defined at the end of ``scenes/FORMAT.md``;
- a directed vanishing segment runs from p1 to p2 in the positive sense of its world axis.

Every surface is a planar rectangle ("quad": a corner and two edge vectors); its outward normal is
``edge1 × edge2``. Shading is Lambertian with one directional light and an ambient term, so each
quad has one constant shade factor (no shadows); each photo has its own exposure gain. Albedo is
defined in sRGB, shading happens in linear light and the result is encoded back to 8-bit sRGB.

The annotations (vanishing segments, marker clicks) depend on geometry only, never on the
rendered pixels, so they are the same at any rendering quality and cheap to regenerate in tests.

The modelling stage (paper §3) is simulated too: ``ground_truth.json`` holds the room's true scene
graph in the project format (``model``) and the world position of every primitive handle it implies
(``model_handles``, from this file's own forward kinematics, which the tests hold to the rendered
corners); the project holds the rough model a user has after dropping primitives onto the photos,
the handles a careful user pins to visible corners, and a few edge observations. The walls are in
the model too, as boxes a measured thickness thick behind the rendered wall planes, with the
doorway left open; the user places them from measurements taken in the room, not from the photos.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import time
from fractions import Fraction
from pathlib import Path

import numpy as np
from PIL import Image
from PIL.TiffImagePlugin import IFDRational

# The one seed. Photo k's clicks use default_rng([SEED, k]) and its pins default_rng([SEED, 1, k]);
# edge observations default_rng([SEED, 2]); the rough model default_rng([SEED, 3]).
SEED = 20000
BASE_WIDTH, BASE_HEIGHT = 1600, 1200  # photo size at --scale 1
ROOM = (5.0, 4.0, 2.6)  # x, y, z extent of the room, metres
CLICK_SIGMA_PX = 0.7  # 1σ of a simulated click, per coordinate, at scale 1
PIXEL_PITCH_MM = 0.0015  # simulated sensor pixel pitch at scale 1 (a small phone sensor)
JPEG_QUALITY = 92
SEGMENT_MIN_PX = 80.0  # shortest vanishing segment a careful user would mark, at scale 1
IMAGE_MARGIN_PX = 5.0  # clicks stay this far inside the image, at scale 1
EDGE_SAMPLES = 200  # points sampled along a 3D edge to find its longest visible run
VISIBILITY_EPS_M = 1e-3  # an occluder must lie this much nearer than the point to hide it

AMBIENT = 0.42  # shade = AMBIENT + DIFFUSE · max(0, n·L)
DIFFUSE = 0.58
LIGHT_DIR = np.array([0.55, 0.35, 0.76]) / np.linalg.norm([0.55, 0.35, 0.76])  # toward the light

# Door opening in the south wall (y = 0): x∈[DOOR_X0, DOOR_X1], z∈[0, DOOR_H]; hinge on the east
# jamb, the panel swung DOOR_AJAR_DEG into the room.
DOOR_X0, DOOR_X1, DOOR_H = 3.30, 4.20, 2.05
DOOR_AJAR_DEG = 25.0
# The walls as the model has them (the renderer draws them as the planes below, which is all a
# photo from inside shows): boxes WALL_THICK thick standing outside the room, each inner face a
# rendered wall plane, so that neighbouring walls meet along the room's corner lines. The square
# column outside each corner is left out: nothing inside reaches it, and walls run on into it
# would hide edges just behind the visible corners. The south wall is three pieces around the doorway.
WALL_THICK = 0.10
TABLE_CENTRE, TABLE_SIZE, TABLE_TOP_Z = (2.20, 2.70), (1.40, 0.80), 0.76
TABLE_TOP_THICK, TABLE_LEG, TABLE_LEG_INSET = 0.04, 0.06, 0.06
CABINET_Y = (1.50, 2.50)  # against the west wall, x∈[0, CABINET_DEPTH]
CABINET_DEPTH, CABINET_H = 0.50, 1.90
BOX_CENTRE, BOX_SIZE, BOX_YAW_DEG = (2.90, 1.00), (0.60, 0.45, 0.40), 30.0


# ---------------------------------------------------------------------------------------------
# Colour
# ---------------------------------------------------------------------------------------------


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 decoding, c in [0, 1]."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 encoding, c clipped to [0, 1]."""
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1.0 / 2.4) - 0.055)


def to_8bit(c_linear: np.ndarray) -> np.ndarray:
    """Linear light → 8-bit sRGB, rounded to nearest."""
    return np.round(linear_to_srgb(c_linear) * 255.0).astype(np.uint8)


# ---------------------------------------------------------------------------------------------
# Procedural textures: functions of surface coordinates (s, t) in metres
# ---------------------------------------------------------------------------------------------


def _hash(ix: np.ndarray, iy: np.ndarray, seed: int) -> np.ndarray:
    """A well-mixed pseudo-random value in [0, 1) per integer lattice point (ix, iy)."""
    h = (ix.astype(np.int64).astype(np.uint64) * np.uint64(0x9E3779B1)
         + iy.astype(np.int64).astype(np.uint64) * np.uint64(0x85EBCA77)
         + np.uint64(seed) * np.uint64(0xC2B2AE3D))
    h ^= h >> np.uint64(15)
    h *= np.uint64(0x2C1B3C6D)
    h ^= h >> np.uint64(12)
    h *= np.uint64(0x297A2D39)
    h ^= h >> np.uint64(15)
    return (h & np.uint64(0xFFFFFF)).astype(np.float64) / float(0x1000000)


def value_noise(x: np.ndarray, y: np.ndarray, seed: int) -> np.ndarray:
    """Smooth value noise in [0, 1] with unit lattice spacing."""
    ix, iy = np.floor(x), np.floor(y)
    fx, fy = x - ix, y - iy
    fx, fy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
    a, b = _hash(ix, iy, seed), _hash(ix + 1, iy, seed)
    c, d = _hash(ix, iy + 1, seed), _hash(ix + 1, iy + 1, seed)
    return (a + (b - a) * fx) * (1 - fy) + (c + (d - c) * fx) * fy


def fbm(x: np.ndarray, y: np.ndarray, seed: int, octaves: int = 3) -> np.ndarray:
    """Fractal sum of value noise, in about [0, 1]."""
    total, amp, norm = np.zeros_like(x), 1.0, 0.0
    for k in range(octaves):
        total += amp * value_noise(x * 2.0**k, y * 2.0**k, seed + 17 * k)
        norm += amp
        amp *= 0.5
    return total / norm


def _rgb(*c: float) -> np.ndarray:
    return np.array(c, dtype=np.float64) / 255.0


def _mix(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per-sample blend of colours a, b (each (3,) or (n, 3)) by weights w (n,)."""
    w = np.asarray(w)[:, None]
    return a * (1 - w) + b * w


def _fill(s: np.ndarray, colour: np.ndarray) -> np.ndarray:
    return np.broadcast_to(colour, (len(s), 3)).copy()


def _rect_mask(s, t, s0, s1, t0, t1):
    return (s >= s0) & (s <= s1) & (t >= t0) & (t <= t1)


def _frame_mask(s, t, s0, s1, t0, t1, w):
    """A rectangular outline of line width w."""
    outer = _rect_mask(s, t, s0, s1, t0, t1)
    inner = _rect_mask(s, t, s0 + w, s1 - w, t0 + w, t1 - w)
    return outer & ~inner


def tex_floor_tiles(s, t, W, H):
    """Ceramic tiles 0.5 m square on the world x/y grid, 8 mm grout joints, per-tile shade."""
    size, half_joint = 0.5, 0.004
    i, j = np.floor(s / size), np.floor(t / size)
    fs, ft = s - i * size, t - j * size
    d = np.minimum(np.minimum(fs, size - fs), np.minimum(ft, size - ft))
    var = _hash(i, j, 11)
    mottle = fbm(s * 6.0, t * 6.0, 12)
    base = _mix(_rgb(214, 170, 128), _rgb(190, 140, 100), var)
    base = base * (0.93 + 0.14 * mottle)[:, None]
    return np.where((d < half_joint)[:, None], _rgb(92, 84, 76), base)


def _wallpaper(a, b, pin):
    def tex(s, t, W, H):
        """Vertical stripes (period 0.24 m) with a pinstripe, and a white skirting board."""
        p = np.mod(s, 0.24)
        col = np.where((p < 0.15)[:, None], a, b)
        col = np.where((np.abs(p - 0.195) < 0.005)[:, None], pin, col)
        col = col * (0.96 + 0.08 * fbm(s * 8.0, t * 8.0, 21))[:, None]
        skirting = np.where((t > 0.092)[:, None], _rgb(170, 170, 165), _rgb(236, 234, 228))
        return np.where((t < 0.10)[:, None], skirting, col)

    return tex


def tex_ceiling(s, t, W, H):
    """Off-white ceiling panels on a 0.6 m grid."""
    fs, ft = np.mod(s, 0.6), np.mod(t, 0.6)
    line = (np.minimum(fs, 0.6 - fs) < 0.004) | (np.minimum(ft, 0.6 - ft) < 0.004)
    base = _fill(s, _rgb(238, 238, 230)) * (0.97 + 0.05 * fbm(s * 10, t * 10, 31))[:, None]
    return np.where(line[:, None], _rgb(180, 180, 172), base)


def tex_oak(s, t, W, H):
    """Oak planks 0.2 m wide running along s, with grain rings and dark plank joints."""
    plank = np.floor(t / 0.2)
    ft = t - plank * 0.2
    warp = fbm(s * 1.2 + plank * 7.3, t * 6.0, 41)
    rings = np.mod(t * 38.0 + 4.0 * warp + plank * 0.37, 1.0)
    w = np.clip(np.abs(rings - 0.5) * 2.0, 0, 1) ** 3
    col = _mix(_rgb(206, 148, 84), _rgb(150, 92, 44), w)
    col = col * (0.92 + 0.12 * _hash(plank, plank * 0 + 3, 43))[:, None]
    joint = np.minimum(ft, 0.2 - ft) < 0.0025
    return np.where(joint[:, None], _rgb(80, 50, 25), col)


def tex_oak_edge(s, t, W, H):
    """End grain / edge of the table top: darker oak with fine streaks along s."""
    n = fbm(s * 3.0, t * 200.0, 47)
    return _mix(_rgb(156, 100, 52), _rgb(120, 72, 34), n)


def tex_walnut(s, t, W, H):
    """Dark walnut legs, grain along t (vertical)."""
    n = fbm(s * 150.0, t * 4.0, 51)
    return _mix(_rgb(88, 56, 34), _rgb(58, 36, 22), n)


def tex_cabinet_front(s, t, W, H):
    """Blue painted cabinet front: two doors with inset panel mouldings and brass knobs."""
    col = _fill(s, _rgb(52, 98, 150)) * (0.97 + 0.05 * fbm(s * 12, t * 12, 61))[:, None]
    gap = np.abs(s - W / 2) < 0.004  # the split between the two doors
    gap |= (t < 0.08) | (np.abs(t - 0.08) < 0.004)  # plinth
    col = np.where((t < 0.08)[:, None], _rgb(30, 58, 92), col)
    mould = np.zeros(len(s), dtype=bool)
    for s0 in (0.08, W / 2 + 0.08):
        mould |= _frame_mask(s, t, s0, s0 + W / 2 - 0.16, 0.22, H - 0.16, 0.018)
    col = np.where(mould[:, None], _rgb(32, 66, 108), col)
    col = np.where(gap[:, None], _rgb(18, 30, 45), col)
    for sk in (W / 2 - 0.05, W / 2 + 0.05):
        knob = (s - sk) ** 2 + (t - 1.05) ** 2 < 0.018**2
        col = np.where(knob[:, None], _rgb(214, 176, 80), col)
    return col


def tex_cabinet_side(s, t, W, H):
    """Blue paint, a shade lighter than the front, with faint brush streaks."""
    return _fill(s, _rgb(64, 112, 164)) * (0.95 + 0.08 * fbm(s * 40, t * 3, 63))[:, None]


def _door_face(handle_at_high_s):
    def tex(s, t, W, H):
        """Light grey painted door: six raised panels (2 × 3), a dark handle near the free edge."""
        return _door_texture(s, t, W, H, handle_at_high_s)

    return tex


def _door_texture(s, t, W, H, handle_at_high_s):
    col = _fill(s, _rgb(200, 203, 206)) * (0.97 + 0.04 * fbm(s * 15, t * 15, 71))[:, None]
    mould = np.zeros(len(s), dtype=bool)
    cols = [(0.10, W / 2 - 0.05), (W / 2 + 0.05, W - 0.10)]
    rows = [(0.12, 0.72), (0.82, 1.42), (1.52, H - 0.12)]
    for s0, s1 in cols:
        for t0, t1 in rows:
            mould |= _frame_mask(s, t, s0, s1, t0, t1, 0.02)
    col = np.where(mould[:, None], _rgb(140, 144, 150), col)
    sh = W - 0.08 if handle_at_high_s else 0.08
    handle = (np.abs(s - sh) < 0.04) & (np.abs(t - 1.015) < 0.015) | ((s - sh) ** 2 + (t - 1.015) ** 2 < 0.03**2)
    return np.where(handle[:, None], _rgb(60, 60, 66), col)


def tex_door_edge(s, t, W, H):
    return _fill(s, _rgb(176, 180, 184))


def tex_box_side(s, t, W, H):
    """Kraft cardboard with a printed white label: bars of 'text' and a red band."""
    col = _fill(s, _rgb(176, 132, 78)) * (0.94 + 0.10 * fbm(s * 20, t * 5, 81))[:, None]
    lw, lh = min(0.26, 0.6 * W), 0.16
    s0, t0 = (W - lw) / 2, (H - lh) / 2
    label = _rect_mask(s, t, s0, s0 + lw, t0, t0 + lh)
    col = np.where(label[:, None], _rgb(245, 245, 240), col)
    band = _rect_mask(s, t, s0, s0 + lw, t0 + lh - 0.04, t0 + lh - 0.01)
    col = np.where(band[:, None], _rgb(200, 30, 36), col)
    # three lines of "text": black bars with hashed word lengths
    text = np.zeros(len(s), dtype=bool)
    for k, tl in enumerate((t0 + 0.085, t0 + 0.055, t0 + 0.025)):
        row = (t >= tl) & (t <= tl + 0.014)
        word = np.floor((s - s0 - 0.02) / 0.045)
        inword = np.mod(s - s0 - 0.02, 0.045) < 0.015 + 0.025 * _hash(word, word * 0 + k, 83)
        text |= row & inword & (s > s0 + 0.02) & (s < s0 + lw - 0.02)
    return np.where(text[:, None], _rgb(20, 20, 20), col)


def tex_box_top(s, t, W, H):
    """Kraft cardboard top: the seam between the flaps under a strip of tan tape."""
    col = _fill(s, _rgb(170, 126, 72)) * (0.94 + 0.10 * fbm(s * 20, t * 5, 85))[:, None]
    tape = np.abs(t - H / 2) < 0.025
    col = np.where(tape[:, None], _rgb(214, 186, 130), col)
    seam = np.abs(t - H / 2) < 0.002
    return np.where(seam[:, None], _rgb(100, 72, 40), col)


def tex_corridor(s, t, W, H):
    """The dim space seen through the door opening."""
    return _fill(s, _rgb(60, 56, 52)) * (0.92 + 0.16 * fbm(s * 4, t * 4, 91))[:, None]


TEXTURES = {
    "floor_tiles": tex_floor_tiles,
    "ceiling_panels": tex_ceiling,
    "wallpaper_cream": _wallpaper(_rgb(236, 222, 170), _rgb(214, 190, 120), _rgb(160, 120, 60)),
    "wallpaper_sage": _wallpaper(_rgb(186, 208, 170), _rgb(150, 180, 136), _rgb(90, 120, 80)),
    "wallpaper_blue": _wallpaper(_rgb(176, 196, 222), _rgb(140, 166, 200), _rgb(70, 90, 140)),
    "wallpaper_rose": _wallpaper(_rgb(232, 196, 196), _rgb(210, 160, 164), _rgb(150, 80, 90)),
    "oak_top": tex_oak,
    "oak_edge": tex_oak_edge,
    "walnut_leg": tex_walnut,
    "cabinet_front": tex_cabinet_front,
    "cabinet_paint": tex_cabinet_side,
    # On the room-side face (−y local) edge1 runs from the hinge to the free edge; on the other
    # face it runs back, so the handle sits at the other end of s.
    "door_face": _door_face(True),
    "door_face_back": _door_face(False),
    "door_edge": tex_door_edge,
    "cardboard_side": tex_box_side,
    "cardboard_top": tex_box_top,
    "corridor": tex_corridor,
}


# ---------------------------------------------------------------------------------------------
# Scene
# ---------------------------------------------------------------------------------------------


def _quad(name, obj, corner, e1, e2, texture, frame=None):
    """A rectangle corner + a·e1 + b·e2 (a, b ∈ [0, 1]) whose outward normal is e1 × e2.

    frame (origin, u, v, W, H) places the texture; by default it is the quad's own (corner,
    e1/|e1|, e2/|e2|, |e1|, |e2|). Pieces of one wall share the wall's frame, so the wallpaper
    runs on across them.
    """
    corner, e1, e2 = (np.asarray(v, dtype=np.float64) for v in (corner, e1, e2))
    if abs(float(e1 @ e2)) > 1e-9 * (e1 @ e1 + e2 @ e2):
        raise ValueError(f"quad {name}: edges must be perpendicular")
    if frame is None:
        frame = (corner, e1 / np.linalg.norm(e1), e2 / np.linalg.norm(e2),
                 float(np.linalg.norm(e1)), float(np.linalg.norm(e2)))
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n)
    shade = AMBIENT + DIFFUSE * max(0.0, float(n @ LIGHT_DIR))
    return {"name": name, "object": obj, "corner": corner, "edge1": e1, "edge2": e2,
            "texture": texture, "normal": n, "shade": shade,
            "tex_origin": np.asarray(frame[0], dtype=np.float64), "tex_u": frame[1], "tex_v": frame[2],
            "tex_size": (frame[3], frame[4])}


def _box_axes(yaw_deg):
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return np.array([c, s, 0.0]), np.array([-s, c, 0.0]), np.array([0.0, 0.0, 1.0])


def _box_quads(name, obj, centre, size, yaw_deg, textures, skip=()):
    """The faces of a box (centre, full size along its local axes, turned yaw_deg about +Z).

    textures maps face (+x, −x, +y, −y, +z, −z) to a texture name; edge1 × edge2 points outward
    and, on vertical faces, edge2 points up.
    """
    ux, uy, uz = _box_axes(yaw_deg)
    c = np.asarray(centre, dtype=np.float64)
    hx, hy, hz = (0.5 * v for v in size)
    faces = {
        "+x": (c + hx * ux - hy * uy - hz * uz, 2 * hy * uy, 2 * hz * uz),
        "-x": (c - hx * ux + hy * uy - hz * uz, -2 * hy * uy, 2 * hz * uz),
        "+y": (c + hy * uy + hx * ux - hz * uz, -2 * hx * ux, 2 * hz * uz),
        "-y": (c - hy * uy - hx * ux - hz * uz, 2 * hx * ux, 2 * hz * uz),
        "+z": (c + hz * uz - hx * ux - hy * uy, 2 * hx * ux, 2 * hy * uy),
        "-z": (c - hz * uz - hx * ux + hy * uy, 2 * hx * ux, -2 * hy * uy),
    }
    return [_quad(f"{name}.{f}", obj, *faces[f], textures.get(f, textures["*"]))
            for f in faces if f not in skip]


def _box_vertical_edges(name, centre, size, yaw_deg):
    """The four vertical edges of a box, bottom → top (the +Z sense)."""
    ux, uy, _ = _box_axes(yaw_deg)
    c = np.asarray(centre, dtype=np.float64)
    hx, hy, hz = (0.5 * v for v in size)
    out = []
    for sx, sy, tag in ((1, 1, "pp"), (1, -1, "pm"), (-1, 1, "mp"), (-1, -1, "mm")):
        p = c + sx * hx * ux + sy * hy * uy
        out.append((f"{name}.vert_{tag}", p + [0, 0, -hz], p + [0, 0, hz]))
    return out


def _aligned_box_edges(name, lo, hi):
    """The 12 edges of an axis-aligned box [lo, hi], grouped by world axis, low → high end."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    out = {"x": [], "y": [], "z": []}
    for k, axis in enumerate("xyz"):
        o1, o2 = [m for m in range(3) if m != k]
        for a in (lo[o1], hi[o1]):
            for b in (lo[o2], hi[o2]):
                p, q = np.empty(3), np.empty(3)
                p[o1] = q[o1] = a
                p[o2] = q[o2] = b
                p[k], q[k] = lo[k], hi[k]
                tag = f"{'xyz'[o1]}{'lo' if a == lo[o1] else 'hi'}_{'xyz'[o2]}{'lo' if b == lo[o2] else 'hi'}"
                out[axis].append((f"{name}.{axis}_{tag}", p, q))
    return out


def build_scene() -> dict:
    """The room, its furniture, markers and the straight 3D edges a user could mark.

    Returns a dict: quads (list), objects (parametric boxes), markers (name → (position,
    description)), edges (axis → list of (name, start, end), end − start along +axis), light.
    """
    X, Y, Z = ROOM
    quads: list[dict] = []
    # --- the room shell; normals point into the room -------------------------------------------
    quads.append(_quad("floor", "room", (0, 0, 0), (X, 0, 0), (0, Y, 0), "floor_tiles"))
    quads.append(_quad("ceiling", "room", (0, 0, Z), (0, Y, 0), (X, 0, 0), "ceiling_panels"))
    quads.append(_quad("wall_west", "room", (0, 0, 0), (0, Y, 0), (0, 0, Z), "wallpaper_sage"))
    quads.append(_quad("wall_north", "room", (0, Y, 0), (X, 0, 0), (0, 0, Z), "wallpaper_blue"))
    quads.append(_quad("wall_east", "room", (X, Y, 0), (0, -Y, 0), (0, 0, Z), "wallpaper_rose"))
    # The south wall (y = 0) has the door opening: three pieces sharing one texture frame.
    south = (np.array([X, 0, 0.0]), np.array([-1.0, 0, 0]), np.array([0, 0, 1.0]), X, Z)
    quads.append(_quad("wall_south.west", "room", (DOOR_X0, 0, 0), (-DOOR_X0, 0, 0), (0, 0, Z),
                       "wallpaper_cream", south))
    quads.append(_quad("wall_south.east", "room", (X, 0, 0), (DOOR_X1 - X, 0, 0), (0, 0, Z),
                       "wallpaper_cream", south))
    quads.append(_quad("wall_south.lintel", "room", (DOOR_X1, 0, DOOR_H), (DOOR_X0 - DOOR_X1, 0, 0),
                       (0, 0, Z - DOOR_H), "wallpaper_cream", south))
    # --- a closed dark recess behind the opening, so every ray hits something ------------------
    cx0, cx1, cy0, cz1 = DOOR_X0 - 0.1, DOOR_X1 + 0.1, -0.8, DOOR_H + 0.1
    quads += [
        _quad("corridor.floor", "corridor", (cx0, cy0, 0), (cx1 - cx0, 0, 0), (0, -cy0, 0), "corridor"),
        _quad("corridor.ceiling", "corridor", (cx0, cy0, cz1), (0, -cy0, 0), (cx1 - cx0, 0, 0), "corridor"),
        _quad("corridor.back", "corridor", (cx1, cy0, 0), (cx0 - cx1, 0, 0), (0, 0, cz1), "corridor"),
        _quad("corridor.west", "corridor", (cx0, cy0, 0), (0, -cy0, 0), (0, 0, cz1), "corridor"),
        _quad("corridor.east", "corridor", (cx1, 0, 0), (0, cy0, 0), (0, 0, cz1), "corridor"),
    ]
    objects = [{"name": "room", "centre": [X / 2, Y / 2, Z / 2], "size": [X, Y, Z], "yaw_deg": 0.0}]

    # --- table: a top slab on four legs -------------------------------------------------------
    tx, ty = TABLE_CENTRE
    tw, td = TABLE_SIZE
    top_c = (tx, ty, TABLE_TOP_Z - TABLE_TOP_THICK / 2)
    top_s = (tw, td, TABLE_TOP_THICK)
    quads += _box_quads("table.top", "table", top_c, top_s, 0.0, {"+z": "oak_top", "*": "oak_edge"})
    objects.append({"name": "table.top", "parent": "table", "centre": list(top_c), "size": list(top_s),
                    "yaw_deg": 0.0})
    leg_h = TABLE_TOP_Z - TABLE_TOP_THICK
    legs = []
    for k, (sx, sy) in enumerate(((-1, -1), (1, -1), (1, 1), (-1, 1)), start=1):
        lc = (tx + sx * (tw / 2 - TABLE_LEG_INSET - TABLE_LEG / 2),
              ty + sy * (td / 2 - TABLE_LEG_INSET - TABLE_LEG / 2), leg_h / 2)
        ls = (TABLE_LEG, TABLE_LEG, leg_h)
        legs.append((f"table.leg{k}", lc, ls))
        quads += _box_quads(f"table.leg{k}", "table", lc, ls, 0.0, {"*": "walnut_leg"}, skip=("+z", "-z"))
        objects.append({"name": f"table.leg{k}", "parent": "table", "centre": list(lc), "size": list(ls),
                        "yaw_deg": 0.0})

    # --- cabinet against the west wall, front facing +x ---------------------------------------
    cab_c = (CABINET_DEPTH / 2, sum(CABINET_Y) / 2, CABINET_H / 2)
    cab_s = (CABINET_DEPTH, CABINET_Y[1] - CABINET_Y[0], CABINET_H)
    quads += _box_quads("cabinet", "cabinet", cab_c, cab_s, 0.0, {"+x": "cabinet_front", "*": "cabinet_paint"},
                        skip=("-x", "-z"))
    objects.append({"name": "cabinet", "centre": list(cab_c), "size": list(cab_s), "yaw_deg": 0.0})

    # --- door panel, hinged on the east jamb and swung into the room ---------------------------
    door_w, door_t, door_h = DOOR_X1 - DOOR_X0 - 0.01, 0.04, DOOR_H - 0.015
    door_yaw = 180.0 - DOOR_AJAR_DEG  # local +x points from the hinge toward the free edge
    door_ux, door_uy, _ = _box_axes(door_yaw)  # −door_uy points into the room
    hinge = np.array([DOOR_X1, 0.0, 0.0])
    door_c = hinge + door_ux * (door_w / 2 + 0.005) - door_uy * (door_t / 2) + [0, 0, 0.01 + door_h / 2]
    door_s = (door_w, door_t, door_h)
    quads += _box_quads("door", "door", door_c, door_s, door_yaw,
                        {"+y": "door_face_back", "-y": "door_face", "*": "door_edge"}, skip=("-z",))
    objects.append({"name": "door", "centre": door_c.tolist(), "size": list(door_s), "yaw_deg": door_yaw,
                    "hinge": hinge.tolist(), "ajar_deg": DOOR_AJAR_DEG})

    # --- cardboard box on the floor, turned about z -------------------------------------------
    box_c = (BOX_CENTRE[0], BOX_CENTRE[1], BOX_SIZE[2] / 2)
    quads += _box_quads("box", "box", box_c, BOX_SIZE, BOX_YAW_DEG, {"+z": "cardboard_top", "*": "cardboard_side"},
                        skip=("-z",))
    objects.append({"name": "box", "centre": list(box_c), "size": list(BOX_SIZE), "yaw_deg": BOX_YAW_DEG})

    names = [q["name"] for q in quads]
    assert len(set(names)) == len(names), "quad names must be unique"

    # --- markers --------------------------------------------------------------------------------
    tl = (tx - tw / 2, ty - td / 2)
    th = (tx + tw / 2, ty + td / 2)
    bx, by, _ = _box_axes(BOX_YAW_DEG)
    bc = np.array([BOX_CENTRE[0], BOX_CENTRE[1], BOX_SIZE[2]])
    markers = {
        "O": ((0, 0, 0), "floor corner, south-west (the origin)"),
        "X5": ((X, 0, 0), "floor corner, south-east"),
        "Y4": ((0, Y, 0), "floor corner, north-west"),
        "T1": ((tl[0], tl[1], TABLE_TOP_Z), "table top corner, south-west"),
        "T2": ((th[0], tl[1], TABLE_TOP_Z), "table top corner, south-east"),
        "T3": ((th[0], th[1], TABLE_TOP_Z), "table top corner, north-east"),
        "T4": ((tl[0], th[1], TABLE_TOP_Z), "table top corner, north-west"),
        "C1": ((CABINET_DEPTH, CABINET_Y[0], CABINET_H), "cabinet top front corner, south"),
        "C2": ((CABINET_DEPTH, CABINET_Y[1], CABINET_H), "cabinet top front corner, north"),
        "B1": (tuple(bc + BOX_SIZE[0] / 2 * bx - BOX_SIZE[1] / 2 * by), "box top corner, toward +x"),
        "B2": (tuple(bc - BOX_SIZE[0] / 2 * bx - BOX_SIZE[1] / 2 * by), "box top corner, toward -y"),
        # the opening's own corners hide behind the ajar panel from most viewpoints
        "D1": (tuple(door_c + door_s[0] / 2 * door_ux - door_s[1] / 2 * door_uy + [0, 0, door_s[2] / 2]),
               "door panel, top corner of the free edge, room side"),
    }
    markers = {k: (np.array(p, dtype=np.float64), d) for k, (p, d) in markers.items()}

    # --- straight 3D edges along the world axes, start → end in the positive sense -------------
    e = {"x": [], "y": [], "z": []}
    for z, zn in ((0.0, "floor"), (Z, "ceiling")):
        e["x"] += [(f"{zn}_south", (0, 0, z), (X, 0, z)), (f"{zn}_north", (0, Y, z), (X, Y, z))]
        e["y"] += [(f"{zn}_west", (0, 0, z), (0, Y, z)), (f"{zn}_east", (X, 0, z), (X, Y, z))]
    for x, y in ((0, 0), (X, 0), (0, Y), (X, Y)):
        e["z"].append((f"corner_{int(x)}_{int(y)}", (x, y, 0), (x, y, Z)))
    for k in range(1, int(round(Y / 0.5))):
        e["x"].append((f"tile_joint_y{0.5 * k:.1f}", (0, 0.5 * k, 0), (X, 0.5 * k, 0)))
    for k in range(1, int(round(X / 0.5))):
        e["y"].append((f"tile_joint_x{0.5 * k:.1f}", (0.5 * k, 0, 0), (0.5 * k, Y, 0)))
    # Wallpaper stripe borders (where the wide band starts, s mod 0.24 = 0) are straight vertical
    # lines a user can click too; a few per wall, away from corners and the door.
    walls = {"wall_west": ((0, 0), (0, 1), (0.72, 1.92, 3.12)),
             "wall_north": ((0, Y), (1, 0), (0.96, 2.40, 3.84)),
             "wall_east": ((X, Y), (0, -1), (0.72, 1.92, 3.12)),
             "wall_south": ((X, 0), (-1, 0), (2.40, 3.84, 4.56))}
    for wall, (o, u, ss) in walls.items():
        for s_ in ss:
            x, y = o[0] + s_ * u[0], o[1] + s_ * u[1]
            e["z"].append((f"{wall}.stripe_{s_:.2f}", (x, y, 0.10), (x, y, Z)))
    e["x"].append(("door_lintel", (DOOR_X0, 0, DOOR_H), (DOOR_X1, 0, DOOR_H)))
    e["z"] += [("door_jamb_west", (DOOR_X0, 0, 0), (DOOR_X0, 0, DOOR_H)),
               ("door_jamb_east", (DOOR_X1, 0, 0), (DOOR_X1, 0, DOOR_H))]
    top_edges = _aligned_box_edges("table.top", (tl[0], tl[1], TABLE_TOP_Z - TABLE_TOP_THICK),
                                   (th[0], th[1], TABLE_TOP_Z))
    e["x"] += top_edges["x"]
    e["y"] += top_edges["y"]
    for name, lc, ls in legs:
        e["z"] += _box_vertical_edges(name, lc, ls, 0.0)
    cab_edges = _aligned_box_edges("cabinet", (0, CABINET_Y[0], 0), (CABINET_DEPTH, CABINET_Y[1], CABINET_H))
    for axis in "xyz":
        e[axis] += cab_edges[axis]
    e["z"] += _box_vertical_edges("door", door_c, door_s, door_yaw)
    e["z"] += _box_vertical_edges("box", box_c, BOX_SIZE, BOX_YAW_DEG)
    edges = {a: [(n, np.asarray(p, dtype=np.float64), np.asarray(q, dtype=np.float64)) for n, p, q in v]
             for a, v in e.items()}
    for a, v in edges.items():
        k = "xyz".index(a)
        for n, p, q in v:
            d = q - p
            assert d[k] > 0 and np.allclose(np.delete(d, k), 0), f"edge {n} is not along +{a}"

    return {"room": ROOM, "quads": quads, "objects": objects, "markers": markers, "edges": edges,
            "light": {"direction": LIGHT_DIR.tolist(), "ambient": AMBIENT, "diffuse": DIFFUSE}}


# ---------------------------------------------------------------------------------------------
# Cameras and projection
# ---------------------------------------------------------------------------------------------

# id, centre C (m), yaw/pitch/roll (deg, FORMAT.md), f (px), principal point offset from the
# image centre (px), exposure gain — all at scale 1 (1600 × 1200).
CAMERA_SPECS = [
    ("p1", (4.50, 3.60, 1.65), 200.0, -17.0, 2.0, 1350.0, (24.0, -18.0), 1.00),
    ("p2", (4.60, 1.90, 1.75), 193.0, -16.0, -2.2, 1700.0, (-27.0, 15.0), 0.93),
    ("p3", (4.65, 3.75, 1.45), 246.0, 0.0, 0.0, 1150.0, (0.0, 0.0), 1.06),
    ("p4", (2.35, 0.40, 1.50), 90.0, 0.0, 0.0, 1000.0, (0.0, 0.0), 0.97),
    ("p5", (1.40, 3.80, 1.70), 285.0, -22.0, 1.8, 1100.0, (12.0, 26.0), 1.03),
]


def rotation_from_ypr(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """World → camera rotation R (rows: the camera's right, down, forward axes in the world).

    forward = (cos p cos y, cos p sin y, sin p); right before roll = (sin y, −cos y, 0) (level);
    down = forward × right; roll turns right toward down (clockwise seen from behind).
    """
    y, p, r = (math.radians(v) for v in (yaw_deg, pitch_deg, roll_deg))
    fwd = np.array([math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), math.sin(p)])
    right0 = np.array([math.sin(y), -math.cos(y), 0.0])
    down0 = np.cross(fwd, right0)
    right = math.cos(r) * right0 + math.sin(r) * down0
    down = -math.sin(r) * right0 + math.cos(r) * down0
    return np.vstack([right, down, fwd])


def cameras(scale: float = 1.0) -> list[dict]:
    """The five cameras, for photos of (1600 × scale) × (1200 × scale) pixels.

    Scaling an image with a corner-origin pixel frame maps u → scale·u exactly, so f, cx and cy
    all scale by the same factor.
    """
    out = []
    for pid, C, yaw, pitch, roll, f, (dx, dy), exposure in CAMERA_SPECS:
        w, h = int(round(BASE_WIDTH * scale)), int(round(BASE_HEIGHT * scale))
        sx, sy = w / BASE_WIDTH, h / BASE_HEIGHT
        if abs(sx - sy) > 1e-12:
            raise ValueError(f"scale {scale} gives non-square pixels ({w} x {h})")
        fs, cx, cy = f * sx, (BASE_WIDTH / 2 + dx) * sx, (BASE_HEIGHT / 2 + dy) * sx
        K = np.array([[fs, 0.0, cx], [0.0, fs, cy], [0.0, 0.0, 1.0]])
        out.append({"id": pid, "width": w, "height": h, "scale": sx, "K": K,
                    "R": rotation_from_ypr(yaw, pitch, roll), "C": np.array(C, dtype=np.float64),
                    "f": fs, "principal_point": (cx, cy), "yaw_deg": yaw, "pitch_deg": pitch,
                    "roll_deg": roll, "exposure": exposure})
    return out


def project(cam: dict, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates (n, 2) and camera depths z_cam (n,) of world points X (n, 3)."""
    x_cam = (np.atleast_2d(X) - cam["C"]) @ cam["R"].T
    z = x_cam[:, 2]
    K = cam["K"]
    u = K[0, 0] * x_cam[:, 0] / z + K[0, 2]
    v = K[1, 1] * x_cam[:, 1] / z + K[1, 2]
    return np.column_stack([u, v]), z


def pixel_rays(cam: dict, uv: np.ndarray) -> np.ndarray:
    """World directions (n, 3) of the rays through pixel positions uv (n, 2) (not normalised)."""
    K = cam["K"]
    d_cam = np.column_stack([(uv[:, 0] - K[0, 2]) / K[0, 0], (uv[:, 1] - K[1, 2]) / K[1, 1],
                             np.ones(len(uv))])
    return d_cam @ cam["R"]  # row-vector form of Rᵀ d_cam


# ---------------------------------------------------------------------------------------------
# Ray casting
# ---------------------------------------------------------------------------------------------


def _geometry(scene: dict) -> dict:
    """Per-quad arrays for the ray caster, cached in the scene."""
    g = scene.get("_geometry")
    if g is None:
        P = np.array([q["corner"] for q in scene["quads"]])
        E1 = np.array([q["edge1"] for q in scene["quads"]])
        E2 = np.array([q["edge2"] for q in scene["quads"]])
        N = np.cross(E1, E2)
        nn = np.sum(N * N, axis=1, keepdims=True)
        G1 = np.cross(E2, N) / nn  # dual basis: (X − P)·G1 = a, (X − P)·G2 = b
        G2 = np.cross(N, E1) / nn
        g = {"P": P, "N": N, "G1": G1, "G2": G2, "M": np.hstack([N.T, G1.T, G2.T])}
        scene["_geometry"] = g
    return g


def trace(scene: dict, origin: np.ndarray, dirs: np.ndarray, t_min: float = 1e-9,
          subset: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hit of rays origin + t·dirs (t > t_min) against the quads (all, or those in subset).

    Returns (index (n,) of the quad hit, −1 for none; t (n,), inf for none). Memory is
    n × (number of quads) × a few float64: callers chunk.
    """
    g = _geometry(scene)
    sel = np.arange(len(g["P"])) if subset is None else np.asarray(subset, dtype=np.int64)
    if len(sel) == 0:
        return np.full(len(dirs), -1), np.full(len(dirs), np.inf)
    Q = len(sel)
    M = g["M"].reshape(3, 3, -1)[:, :, sel].reshape(3, -1)
    DM = dirs @ M
    dn, d1, d2 = DM[:, :Q], DM[:, Q:2 * Q], DM[:, 2 * Q:]
    rel = g["P"][sel] - origin  # (Q, 3)
    cn = np.sum(rel * g["N"][sel], axis=1)
    c1 = -np.sum(rel * g["G1"][sel], axis=1)
    c2 = -np.sum(rel * g["G2"][sel], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = cn / dn
        a = c1 + t * d1
        b = c2 + t * d2
        ok = (t > t_min) & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)
    t = np.where(ok, t, np.inf)
    k = np.argmin(t, axis=1)
    tbest = t[np.arange(len(t)), k]
    idx = sel[k]
    idx[~np.isfinite(tbest)] = -1
    return idx, tbest


def quad_image_bounds(scene: dict, cam: dict, z_near: float = 1e-4) -> np.ndarray:
    """Conservative image bounding boxes (Q, 4) = (u_min, v_min, u_max, v_max) of every quad.

    Each quad is clipped to the half-space z_cam ≥ z_near before projecting (a quad wholly behind
    the camera gets an empty box), so rays of an image tile can only hit quads whose box meets it.
    """
    K = cam["K"]
    out = np.empty((len(scene["quads"]), 4))
    for k, q in enumerate(scene["quads"]):
        corners = q["corner"] + np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) @ np.array([q["edge1"], q["edge2"]])
        xc = (corners - cam["C"]) @ cam["R"].T
        poly = []  # Sutherland–Hodgman against z = z_near
        for i in range(4):
            p, n = xc[i], xc[(i + 1) % 4]
            if p[2] >= z_near:
                poly.append(p)
            if (p[2] >= z_near) != (n[2] >= z_near):
                poly.append(p + (z_near - p[2]) / (n[2] - p[2]) * (n - p))
        if not poly:
            out[k] = (np.inf, np.inf, -np.inf, -np.inf)
            continue
        poly = np.array(poly)
        u = K[0, 0] * poly[:, 0] / poly[:, 2] + K[0, 2]
        v = K[1, 1] * poly[:, 1] / poly[:, 2] + K[1, 2]
        out[k] = (u.min(), v.min(), u.max(), v.max())
    return out


def shade_hits(scene: dict, idx: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Linear-light colour (n, 3) of surface points X (n, 3) on quads idx (n,), before exposure."""
    out = np.zeros((len(idx), 3))
    quads = scene["quads"]
    for q in np.unique(idx):
        if q < 0:
            continue
        sel = idx == q
        quad = quads[q]
        rel = X[sel] - quad["tex_origin"]
        s, t = rel @ quad["tex_u"], rel @ quad["tex_v"]
        albedo = TEXTURES[quad["texture"]](s, t, *quad["tex_size"])
        out[sel] = srgb_to_linear(np.clip(albedo, 0, 1)) * quad["shade"]
    return out


def render_photo(scene: dict, cam: dict, width: int, height: int, supersample: int = 2,
                 return_ids: bool = False, tile: int = 64):
    """Ray-cast the photo: (height, width, 3) uint8 sRGB; with return_ids also the (height,
    width) int array of the quad seen through each pixel centre (−1 for none).

    Pixel (i, j) averages s × s stratified samples at (i + (k + ½)/s, j + (l + ½)/s); for s = 1
    that is the pixel centre (i + ½, j + ½). The image is cast in tiles of tile × tile pixels,
    each against only the quads whose image bounds meet it. cam's K is for cam["width"] ×
    cam["height"]; it is rescaled if width × height differs.
    """
    s = int(supersample)
    if (width, height) != (cam["width"], cam["height"]):
        k = width / cam["width"]
        cam = dict(cam, K=cam["K"] * np.array([[k, 1, k], [1, k, k], [1, 1, 1]]), width=width, height=height)
    bounds = quad_image_bounds(scene, cam)
    img = np.zeros((height, width, 3), dtype=np.float32)
    ids = np.full((height, width), -1, dtype=np.int32) if return_ids else None
    offs = (np.arange(s) + 0.5) / s
    for j0 in range(0, height, tile):
        j1 = min(height, j0 + tile)
        for i0 in range(0, width, tile):
            i1 = min(width, i0 + tile)
            pad = 1.0  # pixels: the boxes are exact up to rounding; a margin costs nothing
            cand = np.flatnonzero((bounds[:, 0] <= i1 + pad) & (bounds[:, 2] >= i0 - pad)
                                  & (bounds[:, 1] <= j1 + pad) & (bounds[:, 3] >= j0 - pad))
            u_s = (np.arange(i0, i1)[:, None] + offs[None, :]).reshape(-1)
            v_s = (np.arange(j0, j1)[:, None] + offs[None, :]).reshape(-1)
            uu, vv = np.meshgrid(u_s, v_s)
            d = pixel_rays(cam, np.column_stack([uu.ravel(), vv.ravel()]))
            idx, t = trace(scene, cam["C"], d, subset=cand)
            X = cam["C"] + np.where(np.isfinite(t), t, 0.0)[:, None] * d
            col = shade_hits(scene, idx, X) * cam["exposure"]
            img[j0:j1, i0:i1] = col.reshape(j1 - j0, s, i1 - i0, s, 3).mean(axis=(1, 3))
            if return_ids:
                if s == 1:
                    ids[j0:j1, i0:i1] = idx.reshape(j1 - j0, i1 - i0)
                else:
                    uc, vc = np.meshgrid(np.arange(i0, i1) + 0.5, np.arange(j0, j1) + 0.5)
                    dc = pixel_rays(cam, np.column_stack([uc.ravel(), vc.ravel()]))
                    ids[j0:j1, i0:i1] = trace(scene, cam["C"], dc, subset=cand)[0].reshape(j1 - j0, i1 - i0)
    out = to_8bit(img)
    return (out, ids) if return_ids else out


def visible(scene: dict, cam: dict, points: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """True where a world point (n, 3) is in front of the camera, projects inside the image
    (at least margin px from its border) and nothing lies between it and the camera centre
    (an occluder must be more than VISIBILITY_EPS_M nearer than the point)."""
    points = np.atleast_2d(np.asarray(points, dtype=np.float64))
    uv, z = project(cam, points)
    inside = ((z > 1e-6) & (uv[:, 0] >= margin) & (uv[:, 0] <= cam["width"] - margin)
              & (uv[:, 1] >= margin) & (uv[:, 1] <= cam["height"] - margin))
    d = points - cam["C"]
    dist = np.linalg.norm(d, axis=1)
    _, t = trace(scene, cam["C"], d)  # t = 1 at the point itself
    return inside & (t * dist >= dist - VISIBILITY_EPS_M)


# ---------------------------------------------------------------------------------------------
# Annotations: what a careful user would click
# ---------------------------------------------------------------------------------------------


def _longest_visible_run(scene, cam, p, q, margin):
    """The longest run of consecutive visible samples along segment p → q, as 3D end points."""
    a = np.linspace(0.0, 1.0, EDGE_SAMPLES)
    X = p + a[:, None] * (q - p)
    vis = visible(scene, cam, X, margin)
    best, start, best_run = 0, None, None
    for k, ok in enumerate(np.append(vis, False)):
        if ok and start is None:
            start = k
        elif not ok and start is not None:
            if k - start > best:
                best, best_run = k - start, (start, k - 1)
            start = None
    if best_run is None or best < 2:
        return None
    return X[best_run[0]], X[best_run[1]]


def _line_distance(p, a, b):
    """Distance of image point p from the infinite line through a, b."""
    d = b - a
    return abs(d[0] * (p[1] - a[1]) - d[1] * (p[0] - a[0])) / np.linalg.norm(d)


def choose_segments(scene: dict, cam: dict, axis: str, n_max: int = 6, n_min: int = 4) -> list[dict]:
    """Pick up to n_max long, well-spread visible runs of the scene's edges along axis.

    Longest first; a run is skipped when it lies on nearly the same image line as one already
    taken, or (in the first pass) when its midpoint crowds one already taken.
    """
    scale = cam["width"] / BASE_WIDTH
    margin, min_len = IMAGE_MARGIN_PX * scale, SEGMENT_MIN_PX * scale
    cands = []
    for name, p, q in scene["edges"][axis]:
        run = _longest_visible_run(scene, cam, p, q, margin)
        if run is None:
            continue
        uv, _ = project(cam, np.array(run))
        length = float(np.linalg.norm(uv[1] - uv[0]))
        if length >= min_len:
            cands.append({"edge": name, "X1": run[0], "X2": run[1], "uv": uv, "length": length})
    cands.sort(key=lambda c: -c["length"])
    spread = 0.12 * math.hypot(cam["width"], cam["height"])
    same_line = 20.0 * scale
    chosen: list[dict] = []
    for crowd in (spread, 0.0):
        for c in cands:
            if len(chosen) >= n_max:
                break
            if any(c is o for o in chosen):
                continue
            mid = c["uv"].mean(axis=0)
            dup = any(max(_line_distance(c["uv"][0], *o["uv"]), _line_distance(c["uv"][1], *o["uv"]))
                      < same_line for o in chosen)
            crowded = any(np.linalg.norm(mid - o["uv"].mean(axis=0)) < crowd for o in chosen)
            if not dup and not crowded:
                chosen.append(c)
        if len(chosen) >= n_min:
            break
    return chosen


def annotate(scene: dict, cam: dict, rng: np.random.Generator) -> dict:
    """The clicks of a careful user on this photo, with N(0, 0.7 px · scale) noise per coordinate.

    Returns {"vanishing_segments": axis → [[u1, v1, u2, v2], ...] (directed along +axis),
    "segments_truth": axis → [{"edge", "X1", "X2"}] (the 3D run each segment was clicked on),
    "marker_observations": name → [u, v]}.
    """
    sigma = CLICK_SIGMA_PX * cam["width"] / BASE_WIDTH
    segs, truth = {}, {}
    for axis in "xyz":
        chosen = choose_segments(scene, cam, axis)
        if not chosen:
            continue
        uv = np.array([c["uv"].reshape(4) for c in chosen])  # X1 → X2 is the +axis sense
        uv = uv + rng.normal(0.0, sigma, uv.shape)
        segs[axis] = uv
        truth[axis] = [{"edge": c["edge"], "X1": c["X1"], "X2": c["X2"]} for c in chosen]
    names = list(scene["markers"])
    P = np.array([scene["markers"][n][0] for n in names])
    vis = visible(scene, cam, P, IMAGE_MARGIN_PX * cam["width"] / BASE_WIDTH)
    uv, _ = project(cam, P)
    uv = uv + rng.normal(0.0, sigma, uv.shape)  # drawn for every marker: stable streams
    obs = {n: uv[k] for k, n in enumerate(names) if vis[k]}
    return {"vanishing_segments": segs, "segments_truth": truth, "marker_observations": obs}


# ---------------------------------------------------------------------------------------------
# The model (paper §3): the true scene graph, its forward kinematics, and what a user would do
# ---------------------------------------------------------------------------------------------
#
# The format is "The model" in scenes/FORMAT.md. A primitive's local frame has its origin at the
# centre of its bottom face, local +z up. A joint gives parent_from_node (4 × 4), written out here
# as this file reads the format (tests/test_example_scene.py writes it out again and holds every
# handle to the corners of the quads rendered above):
#
#   marker    T(marker) · Rz(yaw) · T(−handle)          the handle sits on the marker, turned about +Z
#   rests_on  F · T(s, t, 0) · Rz(yaw)                  F: the parent face's frame (origin, x, y, normal);
#                                                       the world's floor z = 0 without a parent
#   fixed     T(translation) · Rz(rz) · Ry(ry) · Rx(rx)  XYZ Euler angles about the parent's axes
#   hinge     T(p) · Rot(axis, angle) · T(−p) · fixed   p = axis_point; fixed = the pose at angle 0;
#                                                       a positive angle turns counter-clockwise
#                                                       about axis (right-hand rule)

# The door swings into the room about the downward axis (so that opening is a positive angle): 0°
# is shut against the stop in the frame, and at about 153° its free edge would meet the east wall.
DOOR_HINGE_AXIS = (0.0, 0.0, -1.0)
DOOR_LIMITS_DEG = (0.0, 150.0)
# The walls' nodes (true_walls). No photo shows a wall's thickness, its outer faces or (the ajar
# panel hides them) the doorway's corners, so the user places the walls from what was measured in
# the room: its size (5 × 4 m, 2.6 m high), the walls' thickness at the doorway, the doorway's width,
# height and distance from the west wall. In the project they are "solve": false (FORMAT.md) at those
# values; they rest on the floor, so they follow the floor as solved. They take no pins.
WALL_NODES = ("wall_west", "wall_north", "wall_east", "wall_south", "wall_south.west", "wall_south.east",
              "wall_south.lintel")
PIN_PROBE_M = 0.02  # a corner is clicked only where ≥ 2 of its edges are seen this far from it
PIN_MIN_SEP_PX = 8.0  # … and no other seen corner of that primitive lies this near it (scale 1)
ROUGH_SIZE_REL = (0.10, 0.25)  # a dropped primitive's sizes (and position, × its extent) are this far off
ROUGH_YAW_DEG = (5.0, 10.0)
ROUGH_HINGE_DEG = (8.0, 12.0)
# Model edges on which the user draws a red edge observation (each in the photo that shows the
# longest visible run of it).
EDGE_OBSERVATION_CANDIDATES = [
    ("floor", "e1"), ("floor", "e2"), ("cabinet", "e9"), ("cabinet", "e10"), ("cabinet", "e5"),
    ("box", "e8"), ("box", "e9"), ("box", "e10"), ("box", "e11"), ("table.top", "e4"), ("table.top", "e7"),
    ("door", "e9"), ("door", "e4"),
]

_RING = ((-1, -1), (1, -1), (1, 1), (-1, 1))  # v0…v3: counter-clockwise from (−x, −y), seen from +z
QUAD_EDGES = {f"e{k}": (f"v{k}", f"v{(k + 1) % 4}") for k in range(4)}
BOX_EDGES = {**QUAD_EDGES,
             **{f"e{k + 4}": (f"v{k + 4}", f"v{(k + 1) % 4 + 4}") for k in range(4)},
             **{f"e{k + 8}": (f"v{k}", f"v{k + 4}") for k in range(4)}}


def primitive_handles(prim: dict) -> dict[str, np.ndarray]:
    """Handle name → position in the primitive's local frame (quad and box, FORMAT.md)."""
    p = prim["params"]
    w, d = p["width"], p["depth"]
    out = {f"v{k}": np.array([sx * w / 2, sy * d / 2, 0.0]) for k, (sx, sy) in enumerate(_RING)}
    if prim["type"] == "box":
        out.update({f"v{k + 4}": np.array([sx * w / 2, sy * d / 2, p["height"]]) for k, (sx, sy) in enumerate(_RING)})
    elif prim["type"] != "quad":
        raise ValueError(f"primitive type {prim['type']!r}: this generator knows quad and box")
    return out


def primitive_edges(prim: dict) -> dict[str, tuple[str, str]]:
    return BOX_EDGES if prim["type"] == "box" else QUAD_EDGES


def _T(t) -> np.ndarray:
    M = np.eye(4)
    M[:3, 3] = t
    return M


def _R4(R: np.ndarray) -> np.ndarray:
    M = np.eye(4)
    M[:3, :3] = R
    return M


def _axis_rotation(axis, angle_deg: float) -> np.ndarray:
    """Rodrigues: counter-clockwise by angle_deg about the unit vector along axis (right-hand rule)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    a = math.radians(angle_deg)
    Kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(a) * Kx + (1 - math.cos(a)) * (Kx @ Kx)


def _euler_xyz(rotation_deg) -> np.ndarray:
    """XYZ Euler angles about the parent's (fixed) axes: Rz(rz) · Ry(ry) · Rx(rx)."""
    rx, ry, rz = rotation_deg
    return _axis_rotation((0, 0, 1), rz) @ _axis_rotation((0, 1, 0), ry) @ _axis_rotation((1, 0, 0), rx)


def face_frame(prim: dict | None, face: str) -> np.ndarray:
    """primitive_from_face: the face's origin (its centre) and axes (x, y, outward normal)."""
    if prim is None:
        raise ValueError(f"face {face!r} of a group: a group has no faces")
    if face == "top":
        return _T([0.0, 0.0, prim["params"].get("height", 0.0) if prim["type"] == "box" else 0.0])
    if face == "bottom" and prim["type"] == "box":
        return _R4(_axis_rotation((1, 0, 0), 180.0))  # x, −y, −z: right-handed, normal down
    raise ValueError(f"{prim['type']} has no face {face!r}")


def joint_transform(joint: dict, prim: dict | None, parent_prim: dict | None, has_parent: bool,
                    markers: dict[str, np.ndarray]) -> np.ndarray:
    """parent_from_node (4 × 4) of one joint (the table at the top of this section)."""
    kind = joint["type"]
    if kind == "marker":
        h = primitive_handles(prim)[joint["handle"]]
        return _T(markers[joint["marker"]]) @ _R4(_axis_rotation((0, 0, 1), joint["yaw_deg"])) @ _T(-h)
    if kind == "rests_on":
        F = face_frame(parent_prim, joint["face"]) if has_parent else np.eye(4)
        s, t = joint["position"]
        return F @ _T([s, t, 0.0]) @ _R4(_axis_rotation((0, 0, 1), joint["yaw_deg"]))
    pose = _T(joint["translation"]) @ _R4(_euler_xyz(joint["rotation_deg"]))
    if kind in ("fixed", "free"):
        return pose
    if kind == "hinge":
        p = np.asarray(joint["axis_point"], dtype=np.float64)
        return _T(p) @ _R4(_axis_rotation(joint["axis"], joint["angle_deg"])) @ _T(-p) @ pose
    raise ValueError(f"joint type {kind!r}: this generator knows marker, rests_on, fixed, free and hinge")


def model_world_transforms(nodes: list[dict], markers: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Node name → world_from_node, composing joints down the graph (parents listed first)."""
    world: dict[str, np.ndarray] = {}
    prims = {n["name"]: n.get("primitive") for n in nodes}
    for n in nodes:
        parent = n.get("parent")
        if parent is not None and parent not in world:
            raise ValueError(f"node {n['name']!r}: parent {parent!r} must be listed before it")
        T = joint_transform(n["joint"], n.get("primitive"), prims.get(parent), parent is not None, markers)
        world[n["name"]] = T if parent is None else world[parent] @ T
    return world


def model_handles_world(nodes: list[dict], markers: dict[str, np.ndarray]) -> dict[str, dict[str, np.ndarray]]:
    """Primitive node name → handle name → world position (3,)."""
    world = model_world_transforms(nodes, markers)
    out = {}
    for n in nodes:
        if n.get("primitive") is not None:
            T = world[n["name"]]
            out[n["name"]] = {h: T[:3, :3] @ x + T[:3, 3] for h, x in primitive_handles(n["primitive"]).items()}
    return out


def scene_markers(scene: dict) -> dict[str, np.ndarray]:
    return {n: p for n, (p, _) in scene["markers"].items()}


def _c(x) -> list[float] | float:
    """Values rounded to 1e-12 m (or degree): 0.4 rather than 0.3999999999999999 in the files."""
    if np.ndim(x):
        return [_c(v) for v in np.ravel(x)]
    return round(float(x), 12) + 0.0  # + 0.0: no −0.0


def true_model(scene: dict) -> list[dict]:
    """The room's true scene graph (FORMAT.md nodes), read off the objects build_scene rendered.

    Values are rounded to 1e-12 (see _c); the tests hold every handle to its rendered corner within 1e-9.
    """
    X, Y, _ = ROOM
    floor_c = np.array([X / 2, Y / 2, 0.0])  # the floor's top-face frame: its centre, axes +x, +y
    obj = {o["name"]: o for o in scene["objects"]}

    def box(name):
        w, d, h = obj[name]["size"]
        return {"type": "box", "params": {"width": _c(w), "depth": _c(d), "height": _c(h)}}

    def bottom(name):
        return np.array(obj[name]["centre"]) - [0.0, 0.0, obj[name]["size"][2] / 2]

    def on_floor(name):
        b = bottom(name) - floor_c
        assert abs(b[2]) < 1e-12, f"{name} does not stand on the floor"
        return {"type": "rests_on", "face": "top", "position": _c(b[:2]), "yaw_deg": _c(obj[name]["yaw_deg"])}

    table_c = np.array([TABLE_CENTRE[0], TABLE_CENTRE[1], 0.0])
    nodes = [
        {"name": "floor", "primitive": {"type": "quad", "params": {"width": X, "depth": Y}},
         "joint": {"type": "marker", "marker": "O", "handle": "v0", "yaw_deg": 0.0}},
        {"name": "cabinet", "parent": "floor", "primitive": box("cabinet"), "joint": on_floor("cabinet")},
        {"name": "box", "parent": "floor", "primitive": box("box"), "joint": on_floor("box")},
        {"name": "table", "parent": "floor",
         "joint": {"type": "rests_on", "face": "top", "position": _c((table_c - floor_c)[:2]), "yaw_deg": 0.0}},
    ]
    for part in ("table.top", "table.leg1", "table.leg2", "table.leg3", "table.leg4"):
        assert obj[part]["yaw_deg"] == 0.0
        nodes.append({"name": part, "parent": "table", "primitive": box(part),
                      "joint": {"type": "fixed", "translation": _c(bottom(part) - table_c),
                                "rotation_deg": [0.0, 0.0, 0.0]}})
    # The door as rendered is open by ajar_deg; its pose at angle 0 turns it back about the hinge.
    door = obj["door"]
    hinge = np.array(door["hinge"])
    shut = _axis_rotation(DOOR_HINGE_AXIS, -door["ajar_deg"])
    nodes.append({"name": "door", "parent": "floor", "primitive": box("door"),
                  "joint": {"type": "hinge", "axis_point": _c(hinge - floor_c), "axis": list(DOOR_HINGE_AXIS),
                            "translation": _c(hinge + shut @ (bottom("door") - hinge) - floor_c),
                            "rotation_deg": [0.0, 0.0, _c(door["yaw_deg"] + door["ajar_deg"])],
                            "angle_deg": _c(door["ajar_deg"]), "limits_deg": list(DOOR_LIMITS_DEG)}})
    nodes += true_walls(scene)
    return nodes


def true_walls(scene: dict) -> list[dict]:
    """The walls' nodes (WALL_NODES), read off the wall quads build_scene rendered: a box WALL_THICK
    thick behind each, its front face (local −y) the quad itself, toward the room, its local +x left
    to right as seen from the room. The west, north and east walls rest on the floor; the south wall is a group
    resting on the floor (its origin at the floor-level centre line of the whole wall, turned as its
    pieces are) whose pieces beside and above the doorway are fixed in it."""
    X, Y, _ = ROOM
    floor_c = np.array([X / 2, Y / 2, 0.0])
    quads = {q["name"]: q for q in scene["quads"]}

    def wall(name):
        """(primitive, bottom centre, yaw in degrees) of the box behind the quad ``name``."""
        q = quads[name]
        e1, e2, n = q["edge1"], q["edge2"], q["normal"]
        assert abs(e1[2]) < 1e-12 and abs(e2[0]) + abs(e2[1]) < 1e-12 and e2[2] > 0, f"{name} is not upright"
        prim = {"type": "box", "params": {"width": _c(np.linalg.norm(e1)), "depth": WALL_THICK, "height": _c(e2[2])}}
        centre = q["corner"] + e1 / 2 - n * (WALL_THICK / 2)
        yaw = math.degrees(math.atan2(n[0] + 0.0, -n[1] + 0.0))  # turns local −y onto n (+ 0.0: no −0.0)
        return prim, centre, yaw

    nodes = []
    for name in ("wall_west", "wall_north", "wall_east"):
        prim, centre, yaw = wall(name)
        nodes.append({"name": name, "parent": "floor", "primitive": prim,
                      "joint": {"type": "rests_on", "face": "top", "position": _c((centre - floor_c)[:2]),
                                "yaw_deg": _c(yaw)}})
    south, south_yaw = np.array([X / 2, -WALL_THICK / 2, 0.0]), 180.0
    nodes.append({"name": "wall_south", "parent": "floor",
                  "joint": {"type": "rests_on", "face": "top", "position": _c((south - floor_c)[:2]),
                            "yaw_deg": south_yaw}})
    for part in ("west", "east", "lintel"):
        prim, centre, yaw = wall(f"wall_south.{part}")
        assert yaw == south_yaw
        nodes.append({"name": f"wall_south.{part}", "parent": "wall_south", "primitive": prim,
                      "joint": {"type": "fixed", "translation": _c(_axis_rotation((0, 0, 1), -yaw) @ (centre - south)),
                                "rotation_deg": [0.0, 0.0, 0.0]}})
    assert [n["name"] for n in nodes] == list(WALL_NODES)
    return nodes


def rough_model(nodes: list[dict], rng: np.random.Generator) -> list[dict]:
    """The starting values a user has after dropping each primitive onto the photos.

    Sizes are off by 10–25 %, rests_on positions by 10–25 % of the object's extent, yaws by 5–10°
    and the hinge angle by 8–12°, each in a random sense. Fixed joints and a hinge's axis and shut
    pose are kept: they have no degree of freedom, so a wrong value there could never be solved
    away (the user states them as the object's known make-up). Every node draws the same numbers
    whatever its kind, so the streams stay stable. The walls (WALL_NODES) are placed at their
    measured values and marked "solve": false.
    """
    out = json.loads(json.dumps(nodes))
    extent = {n["name"]: max(n["primitive"]["params"]["width"], n["primitive"]["params"]["depth"])
              for n in nodes if n.get("primitive")}
    extent["table"] = extent["table.top"]
    for n in out:
        rel = rng.uniform(*ROUGH_SIZE_REL, 3) * rng.choice([-1.0, 1.0], 3)
        shift, phi = rng.uniform(*ROUGH_SIZE_REL), rng.uniform(0.0, 2 * math.pi)
        dyaw = rng.uniform(*ROUGH_YAW_DEG) * rng.choice([-1.0, 1.0])
        dhinge = rng.uniform(*ROUGH_HINGE_DEG) * rng.choice([-1.0, 1.0])
        if n["name"] in WALL_NODES:
            n["solve"] = False
            continue
        prim, j = n.get("primitive"), n["joint"]
        if prim is not None:
            for k, key in enumerate(prim["params"]):
                prim["params"][key] = round(prim["params"][key] * (1 + rel[k]), 3)
        if j["type"] == "rests_on":
            s, t = j["position"]
            r = shift * extent[n["name"]]
            j["position"] = [round(s + r * math.cos(phi), 3), round(t + r * math.sin(phi), 3)]
        if j["type"] in ("rests_on", "marker"):
            j["yaw_deg"] = round(j["yaw_deg"] + dyaw, 1)
        if j["type"] == "hinge":
            lo, hi = j["limits_deg"]
            j["angle_deg"] = round(min(max(j["angle_deg"] + dhinge, lo), hi), 1)
    # The legs' heights show in no photo (the top hides their upper ends and every camera stands
    # above the table), so the user states what is known: each leg reaches the top, so it holds
    # its height at the top's offset above the floor (a known dimension, not a guess).
    top_z = next(n for n in nodes if n["name"] == "table.top")["joint"]["translation"][2]
    for n in out:
        if n["name"].startswith("table.leg"):
            n["primitive"]["params"]["height"] = top_z
            n["hold"] = ["height"]
    return out


def pinnable(scene: dict, cam: dict, prim: dict, handles: dict[str, np.ndarray]) -> dict[str, bool]:
    """Which handles a careful user would drag onto this photo: the corner is visible (at least
    IMAGE_MARGIN_PX inside the image, nothing more than VISIBILITY_EPS_M nearer on its ray), so
    are points PIN_PROBE_M along at least two of its edges (else the corner cannot be made out),
    and no other such corner of the primitive projects within PIN_MIN_SEP_PX of it (the two ends
    of a thin edge seen end-on cannot be told apart: the door's free edge from p3)."""
    names = list(handles)
    probes, owner = [], []
    for a, b in primitive_edges(prim).values():
        d = handles[b] - handles[a]
        step = min(PIN_PROBE_M, 0.25 * float(np.linalg.norm(d))) * d / np.linalg.norm(d)
        probes += [handles[a] + step, handles[b] - step]
        owner += [a, b]
    pts = np.array([handles[h] for h in names] + probes)
    vis = visible(scene, cam, pts, IMAGE_MARGIN_PX * cam["width"] / BASE_WIDTH)
    seen = dict(zip(names, vis[:len(names)], strict=True))
    n_edges = {h: 0 for h in names}
    for h, ok in zip(owner, vis[len(names):], strict=True):
        n_edges[h] += int(ok)
    ok = {h: bool(seen[h] and n_edges[h] >= 2) for h in names}
    uv, _ = project(cam, pts[:len(names)])
    sep = PIN_MIN_SEP_PX * cam["width"] / BASE_WIDTH
    crowded = {h for i, h in enumerate(names) for j, o in enumerate(names)
               if i != j and ok[h] and ok[o] and np.linalg.norm(uv[i] - uv[j]) < sep}
    return {h: ok[h] and h not in crowded for h in names}


def choose_pins(scene: dict, cams: list[dict], nodes: list[dict]) -> list[dict]:
    """Every handle a careful user would pin, photo k's clicks from the stream default_rng([SEED, 1, k])
    (N(0, 0.7 px · scale) per coordinate, drawn for every handle so that the streams stay stable).
    The walls, placed from measurements, take none (they come last, so no stream moves)."""
    handles = model_handles_world(nodes, scene_markers(scene))
    pins = []
    for k, cam in enumerate(cams):
        rng = np.random.default_rng([SEED, 1, k])
        sigma = CLICK_SIGMA_PX * cam["width"] / BASE_WIDTH
        for n in nodes:
            if n.get("primitive") is None or n["name"] in WALL_NODES:
                continue
            hw = handles[n["name"]]
            uv, _ = project(cam, np.array(list(hw.values())))
            uv = uv + rng.normal(0.0, sigma, uv.shape)
            ok = pinnable(scene, cam, n["primitive"], hw)
            pins += [{"photo": cam["id"], "node": n["name"], "handle": h, "uv": _r(uv[i]), "fixed": True}
                     for i, h in enumerate(hw) if ok[h]]
    return pins


def _segment_distance(p, a, b) -> float:
    """Distance of image point p from the segment a–b."""
    d = b - a
    s = min(max(float((p - a) @ d / (d @ d)), 0.0), 1.0)
    return float(np.linalg.norm(p - (a + s * d)))


def choose_edge_observations(scene: dict, cams: list[dict], nodes: list[dict]) -> list[dict]:
    """For each EDGE_OBSERVATION_CANDIDATES edge, two clicks (at 10 % and 90 % of its longest visible
    run) in the photo where that run is longest, if it is at least SEGMENT_MIN_PX long and no other
    visible edge of the primitive passes within PIN_MIN_SEP_PX of its middle (a thin edge face seen
    obliquely shows two lines a user could not tell apart); noise from the stream
    default_rng([SEED, 2]), drawn for every candidate."""
    handles = model_handles_world(nodes, scene_markers(scene))
    prims = {n["name"]: n.get("primitive") for n in nodes}
    rng = np.random.default_rng([SEED, 2])
    out = []
    for node, edge in EDGE_OBSERVATION_CANDIDATES:
        edges = primitive_edges(prims[node])
        noise = rng.normal(0.0, CLICK_SIGMA_PX, (2, 2))
        best = None
        for cam in cams:
            scale = cam["width"] / BASE_WIDTH
            runs = {e: _longest_visible_run(scene, cam, handles[node][a], handles[node][b], IMAGE_MARGIN_PX * scale)
                    for e, (a, b) in edges.items()}
            if runs[edge] is None:
                continue
            X = np.array([runs[edge][0] + f * (runs[edge][1] - runs[edge][0]) for f in (0.1, 0.5, 0.9)])
            uv, _ = project(cam, X)
            length = float(np.linalg.norm(uv[2] - uv[0]) / 0.8)
            near = [e for e, r in runs.items() if e != edge and r is not None
                    and _segment_distance(uv[1], *project(cam, np.array(r))[0]) < PIN_MIN_SEP_PX * scale]
            if length >= SEGMENT_MIN_PX * scale and not near and (best is None or length > best[0]):
                best = (length, cam, uv[[0, 2]] + noise * scale)
        if best is not None:
            out.append({"photo": best[1]["id"], "node": node, "edge": edge, "points": [_r(x) for x in best[2]]})
    return out


def model_json(scene: dict, cams: list[dict]) -> dict:
    """The project's model: the user's rough nodes, pins and edge observations (FORMAT.md)."""
    truth = true_model(scene)
    return {"nodes": rough_model(truth, np.random.default_rng([SEED, 3])),
            "pins": choose_pins(scene, cams, truth),
            "edge_observations": choose_edge_observations(scene, cams, truth)}


def check_model_coverage(model: dict, truth_nodes: list[dict]) -> None:
    """Every primitive but the legs is pinned in ≥ 2 photos with ≥ 3 distinct handles, spanning
    both signs of local x and y, and a box has a top handle too. At least two legs have ≥ 3 handles
    spanning x and y: their tops hide under the table top, and most photos frame them out, but a
    leg's bottom corners lie on the floor, so one photo places them. The walls, placed from
    measurements ("solve": false), take no pins at all."""
    prims = {n["name"]: n["primitive"] for n in truth_nodes if n.get("primitive") and n["name"] not in WALL_NODES}
    if any(p["node"] in WALL_NODES for p in model["pins"]):
        raise AssertionError("a wall is pinned; the walls are placed from measurements")
    if any(n.get("solve", True) for n in model["nodes"] if n["name"] in WALL_NODES):
        raise AssertionError('every wall node must be "solve": false')
    legs_ok = 0
    for name, prim in prims.items():
        pins = [p for p in model["pins"] if p["node"] == name]
        local = primitive_handles(prim)
        hs = {p["handle"] for p in pins}
        problems = []
        if len({p["photo"] for p in pins}) < (1 if name.startswith("table.leg") else 2) or len(hs) < 3:
            problems.append(f"{len(hs)} handles in {len({p['photo'] for p in pins})} photos")
        for k, axis in ((0, "x"), (1, "y")):
            if len({np.sign(local[h][k]) for h in hs}) < 2:
                problems.append(f"no span along local {axis}")
        if prim["type"] == "box" and not any(local[h][2] > 0 for h in hs) and not name.startswith("table.leg"):
            problems.append("no top handle")
        if name.startswith("table.leg"):
            legs_ok += not problems
        elif problems:
            raise AssertionError(f"model node {name}: " + "; ".join(problems))
    if legs_ok < 2:
        raise AssertionError(f"only {legs_ok} table legs are pinned well enough, expected >= 2")


# ---------------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------------


def exif_values(cam: dict) -> dict:
    """EXIF focal data consistent with f (px): focal_mm × resolution_per_mm = f exactly.

    The focal length in mm is that of the scale-1 camera on a sensor with PIXEL_PITCH_MM pixels;
    a scaled-down photo keeps the lens and gets coarser pixels.
    """
    f_base = Fraction(cam["f"]).limit_denominator(10**6) / Fraction(cam["scale"]).limit_denominator(10**6)
    focal_mm = f_base * Fraction(PIXEL_PITCH_MM).limit_denominator(10**6)
    res = Fraction(cam["f"]).limit_denominator(10**6) / focal_mm
    diag_px = math.hypot(cam["width"], cam["height"])
    f35 = int(round(cam["f"] * math.hypot(36.0, 24.0) / diag_px))
    return {"focal_mm": focal_mm, "res_per_mm": res, "f35": f35}


def write_jpeg(path: Path, rgb: np.ndarray, cam: dict) -> dict:
    """Write the photo with EXIF focal data; return the project's exif object (read back)."""
    ev = exif_values(cam)
    exif = Image.Exif()
    exif[0x010F] = "vebuild"  # Make
    exif[0x0110] = "synthetic"  # Model
    ifd = exif.get_ifd(0x8769)
    fmm, res = (IFDRational(v.numerator, v.denominator) for v in (ev["focal_mm"], ev["res_per_mm"]))
    ifd[0x920A] = fmm  # FocalLength (RATIONAL, exact)
    ifd[0xA20E] = res  # FocalPlaneXResolution (RATIONAL, exact)
    ifd[0xA20F] = res  # FocalPlaneYResolution
    ifd[0xA210] = 4  # FocalPlaneResolutionUnit: 4 = millimetre (an extension used by cameras)
    ifd[0xA405] = ev["f35"]  # FocalLengthIn35mmFilm (SHORT)
    Image.fromarray(rgb).save(path, "JPEG", quality=JPEG_QUALITY, exif=exif.tobytes())
    return read_exif(path)


def read_exif(path: Path) -> dict:
    """The project's exif object, from the file as written."""
    with Image.open(path) as im:
        ex = im.getexif()
        ifd = ex.get_ifd(0x8769)
    focal_mm, res = float(ifd[0x920A]), float(ifd[0xA20E])
    if int(ifd[0xA210]) != 4:
        raise ValueError(f"{path}: FocalPlaneResolutionUnit {ifd[0xA210]}, expected 4 (mm)")
    return {"make": str(ex[0x010F]), "model": str(ex[0x0110]), "focal_length_mm": focal_mm,
            "focal_length_35mm": int(ifd[0xA405]), "focal_plane_x_resolution_per_mm": res,
            "focal_length_px": focal_mm * res}


def sha256_file(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _r(x, nd=3):
    return [round(float(v), nd) for v in np.ravel(x)]


def photo_annotations_json(ann: dict) -> dict:
    """The vanishing_segments and marker_observations of one photo as written to the project."""
    return {"vanishing_segments": {a: [_r(s) for s in v] for a, v in ann["vanishing_segments"].items()},
            "marker_observations": {n: _r(uv) for n, uv in ann["marker_observations"].items()}}


def annotate_all(scene: dict, cams: list[dict]) -> list[dict]:
    """Every photo's annotations, photo k from the noise stream default_rng([SEED, k])."""
    return [annotate(scene, cam, np.random.default_rng([SEED, k])) for k, cam in enumerate(cams)]


def reference_distances(scene: dict) -> list[dict]:
    m = {n: p for n, (p, _) in scene["markers"].items()}
    check = float(np.linalg.norm(m["T2"] - m["C1"]))
    return [
        {"a": "O", "b": "X5", "distance": 5.000, "sigma": 0.002, "role": "scale"},
        {"a": "O", "b": "Y4", "distance": 4.000, "sigma": 0.002, "role": "scale"},
        {"a": "T2", "b": "C1", "distance": round(check, 4), "sigma": 0.002, "role": "check"},
    ]


#: Named evidence views of the example (FORMAT.md, "views"): where a witness stood, with eyes at 1.6 m.
EXAMPLE_VIEWS = [
    {"name": "doorway", "description": "standing in the doorway, looking at the table",
     "position": [3.7, 0.3, 1.6], "look_at": [2.2, 2.7, 0.74], "fov_deg": 65.0, "width": 1280, "height": 720},
    {"name": "by the cabinet", "description": "beside the cabinet, looking across the room to the door",
     "position": [0.8, 1.2, 1.6], "look_at": [3.8, 0.3, 1.0], "fov_deg": 70.0, "width": 1280, "height": 720},
    {"name": "overview", "description": "from the far corner, high",
     "position": [4.8, 3.8, 2.4], "look_at": [2.3, 1.8, 0.3], "focal_length_mm": 24.0, "width": 1280,
     "height": 720},
]
#: Lighting presets of the example (FORMAT.md, "lighting"): irradiance 1 shows a texture as extracted.
EXAMPLE_LIGHTING = {"presets": [
    {"name": "daylight", "description": "sun through the window, as when the photos were taken",
     "ambient": [0.35, 0.35, 0.37],
     "lights": [{"type": "directional", "name": "sun", "direction": (-LIGHT_DIR).round(4).tolist(),
                 "colour": [1.0, 0.97, 0.92], "intensity": 0.9}]},
    {"name": "ceiling lamp", "description": "one bulb under the ceiling's centre, nothing else",
     "ambient": [0.03, 0.03, 0.03],
     "lights": [{"type": "point", "name": "bulb", "position": [2.5, 2.0, 2.5], "colour": [1.0, 0.85, 0.65],
                 "intensity": 4.0}]},
    {"name": "night, torch", "description": "dark room; a torch held in the doorway, aimed at the table",
     "ambient": [0.005, 0.005, 0.006],
     "lights": [{"type": "spot", "name": "torch", "position": [3.7, 0.3, 1.5], "direction": [-1.5, 2.4, -0.76],
                 "inner_cone_deg": 10.0, "outer_cone_deg": 16.0, "intensity": 6.0}]},
]}


def project_json(scene: dict, cams: list[dict], anns: list[dict], photo_files: dict) -> dict:
    """The vebuild project document (scenes/FORMAT.md). photo_files: id → {file, sha256, exif}."""
    seen = {n for a in anns for n in a["marker_observations"]}
    photos = []
    for cam, ann in zip(cams, anns, strict=True):
        pf = photo_files[cam["id"]]
        photos.append({"id": cam["id"], "file": pf["file"], "width": cam["width"], "height": cam["height"],
                       "sha256": pf["sha256"], "exif": pf["exif"], **photo_annotations_json(ann)})
    return {
        "format": "vebuild-project",
        "version": 1,
        "name": "Example room (synthetic, generated by scenes/generate_room.py)",
        "settings": {"click_sigma_px": CLICK_SIGMA_PX * cams[0]["width"] / BASE_WIDTH},
        "photos": photos,
        "markers": [{"name": n, "description": d} for n, (_, d) in scene["markers"].items() if n in seen],
        "origin_marker": "O",
        "reference_distances": reference_distances(scene),
        "model": model_json(scene, cams),
        "views": EXAMPLE_VIEWS,
        "lighting": EXAMPLE_LIGHTING,
    }


def _l(x):
    return np.asarray(x, dtype=np.float64).tolist()


def ground_truth_json(scene: dict, cams: list[dict], anns: list[dict], scale: float, supersample: int) -> dict:
    photos = {}
    for cam, ann in zip(cams, anns, strict=True):
        photos[cam["id"]] = {
            "width": cam["width"], "height": cam["height"], "K": _l(cam["K"]), "R": _l(cam["R"]),
            "C": _l(cam["C"]), "f": cam["f"], "principal_point": list(cam["principal_point"]),
            "yaw_deg": cam["yaw_deg"], "pitch_deg": cam["pitch_deg"], "roll_deg": cam["roll_deg"],
            "exposure": cam["exposure"],
            "segments": {a: [{"edge": s["edge"], "X1": _l(s["X1"]), "X2": _l(s["X2"])} for s in v]
                         for a, v in ann["segments_truth"].items()},
        }
    nodes = true_model(scene)
    return {
        "generator": "scenes/generate_room.py", "seed": SEED, "scale": scale, "supersample": supersample,
        "conventions": "DESIGN.md: world +Z up metres; pixel origin at the top-left corner (pixel centre "
                       "i+0.5); x_cam = R (X - C); u ~ K x_cam",
        "room": list(ROOM),
        "light": scene["light"],
        "photos": photos,
        "markers": {n: _l(p) for n, (p, _) in scene["markers"].items()},
        "objects": scene["objects"],
        "quads": [{"name": q["name"], "object": q["object"], "corner": _l(q["corner"]), "edge1": _l(q["edge1"]),
                   "edge2": _l(q["edge2"]), "texture": q["texture"], "shade": q["shade"]}
                  for q in scene["quads"]],
        # the true scene graph (FORMAT.md "The model") and, from it, every handle's world position
        "model": {"nodes": nodes},
        "model_handles": {n: {h: _l(x) for h, x in hs.items()}
                          for n, hs in model_handles_world(nodes, scene_markers(scene)).items()},
    }


def check_coverage(project: dict) -> None:
    """Marker rules of the example: every marker in ≥ 2 photos; O in p1, p2, p3, p5 and not p4;
    p4 sees ≥ 3 markers that other photos see too."""
    obs = {p["id"]: set(p["marker_observations"]) for p in project["photos"]}
    for m in project["markers"]:
        n = sum(m["name"] in o for o in obs.values())
        if n < 2:
            raise AssertionError(f"marker {m['name']} is seen by {n} photo(s), expected >= 2")
    for pid in ("p1", "p2", "p3", "p5"):
        if "O" not in obs[pid]:
            raise AssertionError(f"origin marker O is not seen by {pid}")
    if "O" in obs["p4"]:
        raise AssertionError("p4 must not see the origin marker O")
    others = set().union(*(o for pid, o in obs.items() if pid != "p4"))
    if len(obs["p4"] & others) < 3:
        raise AssertionError(f"p4 shares only {sorted(obs['p4'] & others)} with the other photos")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "room")
    ap.add_argument("--scale", type=float, default=1.0, help="multiplies the 1600 x 1200 photo size")
    ap.add_argument("--supersample", type=int, default=2, help="s x s samples per pixel")
    args = ap.parse_args(argv)

    t0 = time.perf_counter()
    scene = build_scene()
    cams = cameras(args.scale)
    anns = annotate_all(scene, cams)
    (args.out / "photos").mkdir(parents=True, exist_ok=True)
    files = {}
    for cam in cams:
        t1 = time.perf_counter()
        rgb = render_photo(scene, cam, cam["width"], cam["height"], args.supersample)
        rel = f"photos/{cam['id']}.jpg"
        exif = write_jpeg(args.out / rel, rgb, cam)
        if abs(exif["focal_length_px"] / cam["f"] - 1) > 1e-4:
            raise AssertionError(f"{rel}: EXIF focal {exif['focal_length_px']} px, expected {cam['f']}")
        files[cam["id"]] = {"file": rel, "sha256": sha256_file(args.out / rel), "exif": exif}
        print(f"{rel}: {cam['width']}x{cam['height']}, {time.perf_counter() - t1:.1f} s, "
              f"{(args.out / rel).stat().st_size / 1024:.0f} KiB")
    project = project_json(scene, cams, anns, files)
    check_coverage(project)
    check_model_coverage(project["model"], true_model(scene))
    gt = ground_truth_json(scene, cams, anns, args.scale, args.supersample)
    for name, doc in (("room.vebuild.json", project), ("ground_truth.json", gt)):
        tmp = args.out / (name + ".tmp")
        tmp.write_text(json.dumps(doc, indent=1) + "\n")
        tmp.replace(args.out / name)
    print(f"wrote {args.out} in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
