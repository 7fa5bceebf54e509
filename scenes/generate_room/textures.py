"""Colour (sRGB ↔ linear) and the procedural textures: functions of surface coordinates (s, t) in metres."""

from __future__ import annotations

import numpy as np


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


