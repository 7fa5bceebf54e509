"""Which horizontal direction is world x in each photo, chosen from the markers the photos share.

A photo's vanishing points fix its rotation up to the choice of world x among the two horizontal
directions: four candidates, rotations of 0/90/180/270° about z of one another. Photos placed
together by markers must agree on it. With every rotation known, a marker seen in two photos
gives two rays that must meet: for two photos sharing n ≥ MIN_SHARED_MARKERS markers, the camera centres and
marker positions are the null vector of a linear system in the ray constraints (one camera at the
origin, up to scale), and the rays' angles to the solved positions say how well the pair agrees.
Of the four candidates for a photo, the one whose rays agree with those of photos already
chosen is taken, if it is clearly the best (:func:`choose_turns`).

A choice is an integer ``k``: the photo's world axes are those of its ``k = 0`` candidate turned
by k·90° about z (``R_k = R_0 · Rz(k·90°)``, R mapping world directions to camera ones).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: Two photos decide a photo's choice when they share this many markers. Two rays per marker over
#: two markers always meet (the two-point epipolar fix); three are the least with redundancy. Measured
#: (``vebuild bench orient``: generated façade pairs, 1 px clicks, 3000 pairs per n and noise level):
#: with rotations off by 0.3° per axis, three let a wrong turn pass the margins below once, four to
#: eight never (0 in 12 000); off by 1° (lines with clutter), three 6 times, four to eight 4 times in
#: 12 000, all with the views 5–20° apart. Four decide 68–75 % of pairs, five 78–83 %, eight 90–95 %
#: (0.3°); docs/detect.md.
MIN_SHARED_MARKERS = 4
#: The markers `vebuild detect` (and the screen's Shift+D) choose a photo's x from, proposing it:
#: three, where a wrong turn passes the margins for 1 pair in 3000 with 0.3° rotation errors and 6
#: with 1° (vebuild bench orient). A proposal, not a placement: `vebuild calibrate` tests every
#: photo's turn again, before placing from MIN_SHARED_MARKERS and after placing from its markers'
#: misses (vebuild.actions.orientation), and leaves a turned photo out; it is never placed.
MIN_SHARED_MARKERS_TO_PROPOSE = 3
#: The chosen candidate's rays agree with the others' within this RMS angle (degrees): a wider
#: miss means the rotations or markers are wrong, not the choice (detected vanishing points are
#: good to a fraction of a degree, markers to a few pixels, an uncorrected lens to ~1.5°).
MAX_AGREEMENT_DEG = 4.0
#: ... and the next best candidate misses by at least this many times as much (and by 0.5° more).
#: Two level views over a few markers can leave a wrong turn within 0.5–2° (tests/test_detect_axes.py,
#: the example room's p2 against p1 alone: 0.2° and 1.5°): the ratio separates it from the true
#: turn's miss, which is the vanishing points' and markers' noise (0.0–0.2° on the example room).
MIN_MARGIN_RATIO = 3.0
MIN_MARGIN_DEG = 0.5


def rz(k: int) -> Array:
    """The rotation by k·90° about z."""
    c, s = [(1, 0), (0, 1), (-1, 0), (0, -1)][k % 4]
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def turn_between(R0: Array, R: Array) -> int:
    """k with R ≈ R0 · Rz(k·90°) (R0, R world→camera rotations sharing z)."""
    M = R0.T @ R
    return int(round(np.degrees(np.arctan2(M[1, 0], M[0, 0])) / 90.0)) % 4


def two_view(R_a: Array, rays_a: Array, R_b: Array, rays_b: Array) -> tuple[float, Array, Array]:
    """Two photos with rotations R (world→camera) seeing the same n markers along camera-frame
    rays (n, 3): the RMS angle (degrees) between each ray and its solved marker, the second camera
    centre (the first at the origin, unit baseline scale) and the markers (n, 3), world axes."""
    n = len(rays_a)
    wa = rays_a @ R_a  # world directions: Rᵀ d, row-wise
    wb = rays_b @ R_b
    wa /= np.linalg.norm(wa, axis=1, keepdims=True)
    wb /= np.linalg.norm(wb, axis=1, keepdims=True)
    A = np.zeros((4 * n, 3 + 3 * n))
    for i in range(n):
        for j, w in enumerate((wa[i], wb[i])):
            P = _perp(w)
            rows = slice(4 * i + 2 * j, 4 * i + 2 * j + 2)
            A[rows, 3 + 3 * i: 6 + 3 * i] = P
            if j == 1:
                A[rows, 0:3] = -P
    v = np.linalg.svd(A)[2][-1]
    C_b, X = v[:3], v[3:].reshape(n, 3)
    if np.sum(np.einsum("ij,ij->i", X, wa)) + np.sum(np.einsum("ij,ij->i", X - C_b, wb)) < 0:
        C_b, X = -C_b, -X  # the markers in front of the cameras
    ang = np.r_[_angles(X, wa), _angles(X - C_b, wb)]
    return float(np.degrees(np.sqrt(np.mean(ang ** 2)))), C_b, X


def _perp(w: Array) -> Array:
    """Two unit rows orthogonal to w."""
    a = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(w, a)
    u /= np.linalg.norm(u)
    return np.vstack([u, np.cross(w, u)])


def _angles(V: Array, W: Array) -> Array:
    n = np.linalg.norm(V, axis=1)
    cos = np.einsum("ij,ij->i", V, W) / np.maximum(n, 1e-300)
    return np.arccos(np.clip(cos, -1.0, 1.0))


@dataclass(frozen=True)
class TurnDecision:
    photo: str
    turn: int | None                 # the chosen k, or None: not decided
    fixed: bool                      # given (the user's choice, or the reference), not decided here
    residual_deg: tuple[float, ...]  # each candidate's RMS miss (k = 0..3), () if not compared
    against: tuple[str, ...]         # the photos it was compared with
    message: str


def choose_turns(rotations: Mapping[str, Array], rays: Mapping[str, Mapping[str, Array]],
                 fixed: Mapping[str, int], *, min_shared: int = MIN_SHARED_MARKERS) -> dict[str, TurnDecision]:
    """Each photo's turn k from its k = 0 rotation (``rotations``, world→camera) and its markers'
    camera-frame rays (``rays``: photo → marker → (3,)), starting from the photos whose turn is
    ``fixed`` (at least one). Greedily, the photo sharing the most markers with decided ones is
    decided next, against every decided photo sharing ≥ ``min_shared`` markers with it (the
    documented MIN_SHARED_MARKERS; another value only to measure the rule, vebuild/bench/orient.py)."""
    if not fixed:
        raise ValueError("choose_turns: at least one photo's turn must be fixed")
    out: dict[str, TurnDecision] = {p: TurnDecision(p, k % 4, True, (), (), "given") for p, k in fixed.items()}
    R = {p: rotations[p] @ rz(k) for p, k in fixed.items()}  # decided photos' rotations
    todo = [p for p in rotations if p not in out]
    tried: dict[str, int] = {}  # a photo left undecided: with how many partners it was tried
    undecided: dict[str, TurnDecision] = {}

    def usable(p: str) -> list[str]:
        return [q for q in R if len(set(rays.get(p, {})) & set(rays.get(q, {}))) >= min_shared]

    while True:
        ready = [p for p in todo if len(usable(p)) > tried.get(p, 0)]
        if not ready:
            break
        p = max(ready, key=lambda p: (len(usable(p)), sum(len(set(rays.get(p, {})) & set(rays.get(q, {})))
                                                           for q in usable(p))))
        partners = usable(p)
        res = _misses(rotations[p], rays, p, partners, R)
        order = np.argsort(res)
        best, second = res[order[0]], res[order[1]]
        where = ", ".join(partners)
        if best > MAX_AGREEMENT_DEG:
            undecided[p] = TurnDecision(p, None, False, tuple(res), tuple(partners),
                                        f"no choice of x makes its markers' rays meet those of {where} (best "
                                        f"RMS miss {best:.1f}°, at most {MAX_AGREEMENT_DEG:.0f}° expected): check "
                                        "its markers and vanishing segments")
            tried[p] = len(partners)
            continue
        if second < max(MIN_MARGIN_RATIO * best, best + MIN_MARGIN_DEG):
            undecided[p] = TurnDecision(p, None, False, tuple(res), tuple(partners),
                                        f"two choices of x agree about equally with {where} (RMS miss "
                                        f"{best:.1f}° and {second:.1f}°)")
            tried[p] = len(partners)
            continue
        todo.remove(p)
        undecided.pop(p, None)
        k = int(order[0])
        R[p] = rotations[p] @ rz(k)
        out[p] = TurnDecision(p, k, False, tuple(res), tuple(partners),
                              f"its markers' rays meet those of {where} within {best:.1f}° RMS")
    # Checked once more against every photo chosen (also those chosen after it).
    for p, d in list(out.items()):
        if d.fixed or d.turn is None:
            continue
        partners = [q for q in R if q != p and len(set(rays[p]) & set(rays[q])) >= min_shared]
        res = _misses(rotations[p], rays, p, partners, R)
        if int(np.argmin(res)) != d.turn:
            out[p] = TurnDecision(p, None, False, tuple(res), tuple(partners),
                                  f"its choice against {', '.join(d.against)} disagrees with {', '.join(partners)} "
                                  f"(RMS miss {min(res):.1f}° at another turn)")
    for p in todo:
        if p in undecided:
            out[p] = undecided[p]
            continue
        shared = {q: len(set(rays.get(p, {})) & set(rays.get(q, {}))) for q in R}
        most = max(shared.values(), default=0)
        out[p] = TurnDecision(p, None, False, (), (),
                              f"it shares at most {most} markers with any photo already oriented "
                              f"({', '.join(R) or 'none'}): {min_shared} are needed to choose its x axis")
    return out


def _misses(R0: Array, rays: Mapping[str, Mapping[str, Array]], p: str, partners: list[str],
            R: Mapping[str, Array]) -> list[float]:
    """Photo p's RMS ray miss (degrees) at each turn k = 0..3 of its rotation R0, over its
    two-view agreements with each partner (decided rotations R)."""
    res = []
    for k in range(4):
        Rk = R0 @ rz(k)
        per = []
        for q in partners:
            names = sorted(set(rays[p]) & set(rays[q]))
            rms, _, _ = two_view(R[q], np.array([rays[q][m] for m in names]), Rk, np.array([rays[p][m] for m in names]))
            per.append(rms)
        res.append(float(np.sqrt(np.mean(np.square(per)))))
    return res


def direction_turn(rotations: Mapping[str, Array], rays: Mapping[str, Mapping[str, Array]],
                   turns: Mapping[str, int], a: str, b: str, *, max_off_deg: float = 20.0) -> int | None:
    """The turn g of every photo's axes that makes the world direction from marker ``a`` to marker
    ``b`` (triangulated from two decided photos seeing both and ≥ MIN_SHARED_MARKERS in all) run
    along +x, or None where no pair sees them or the direction is not within ``max_off_deg`` of a
    horizontal axis."""
    ids = [p for p in turns if a in rays.get(p, {}) and b in rays.get(p, {})]
    best: tuple[float, int] | None = None
    for i, p in enumerate(ids):
        for q in ids[i + 1:]:
            names = sorted(set(rays[p]) & set(rays[q]))
            if len(names) < MIN_SHARED_MARKERS:
                continue
            Rp, Rq = rotations[p] @ rz(turns[p]), rotations[q] @ rz(turns[q])
            rms, _, X = two_view(Rp, np.array([rays[p][m] for m in names]), Rq, np.array([rays[q][m] for m in names]))
            d = X[names.index(b)] - X[names.index(a)]
            if np.hypot(d[0], d[1]) < 0.5 * np.linalg.norm(d):
                continue  # mostly vertical
            ang = np.degrees(np.arctan2(d[1], d[0]))
            g = int(round(ang / 90.0)) % 4
            off = abs((ang - 90.0 * g + 180.0) % 360.0 - 180.0)
            if off <= max_off_deg and (best is None or rms < best[0]):
                best = (rms, g)
    return None if best is None else best[1]
