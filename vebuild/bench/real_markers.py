"""The markers of ``vebuild bench real``: the bench's stand-in for a user's clicks.

The sets have no surveyed points, so the markers are made from the photos themselves: SIFT
features (OpenCV) matched between every two photos of a group (Lowe's ratio test, 0.75), kept
where the match lies within :data:`EPIPOLAR_PX` of its epipolar line under the TRUE cameras,
chained into tracks, each track triangulated with the true cameras (linear, then kept where it
reprojects within :data:`REPROJECTION_PX` in every photo of the track, in front of each). Of those,
:func:`choose_markers` keeps up to :data:`MAX_MARKERS` well-spread ones seen in several photos; a
marker is "clicked" in each photo of its track at its true projection plus Gaussian noise of
:data:`CLICK_NOISE_PX` (seeded), so a click is where a careful user would put it, on a point the
photo really shows. The triangulated points stand for the surveyed truth of the markers (their
distances give the scale and the check distance).

Tracks are cached per group under ``~/.cache/vebuild/bench-real`` (``VEBUILD_CACHE`` overrides
``~/.cache/vebuild``), keyed by the photos' and cameras' SHA-256: SIFT on a 6 MP photo takes
seconds.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vebuild.project.atomic import write_bytes
from vebuild.resources import cache_dir

from .real_layout import SurveyedPhoto

Array = NDArray[np.float64]

#: Bump when the tracks change: old caches are then not reused.
VERSION = 1
SIFT_FEATURES = 6000
RATIO = 0.75
EPIPOLAR_PX = 2.0
REPROJECTION_PX = 1.5
#: A user clicks 8–18 markers; the bench at most this many per group.
MAX_MARKERS = 18
MIN_MARKERS = 8
#: A marker is seen in this many photos at least: two views triangulate any match along its
#: epipolar line, so only a third checks it.
MIN_VIEWS = 3
MIN_SEPARATION_PX = 20.0
CLICK_NOISE_PX = 1.0


@dataclass(frozen=True)
class Track:
    X: Array                      # the triangulated point, world (the set's frame), metres
    photos: tuple[str, ...]       # the photos that show it


def _P(ph: SurveyedPhoto) -> Array:
    return ph.K @ np.hstack([ph.R, (-ph.R @ ph.C)[:, None]])


def _fundamental(a: SurveyedPhoto, b: SurveyedPhoto) -> Array:
    """F with x_bᵀ F x_a = 0 from the two true cameras."""
    R = b.R @ a.R.T
    t = b.R @ (a.C - b.C)
    tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
    return np.linalg.inv(b.K).T @ tx @ R @ np.linalg.inv(a.K)


def _features(ph: SurveyedPhoto) -> tuple[Array, np.ndarray]:
    import cv2

    from vebuild.project.images import decode_photo

    pixels = decode_photo(ph.image.read_bytes(), ph.image.name, ph.image, "")
    grey = cv2.cvtColor(pixels, cv2.COLOR_RGB2GRAY) if pixels.ndim == 3 else pixels
    sift = cv2.SIFT_create(nfeatures=SIFT_FEATURES)  # type: ignore[attr-defined]
    kp, des = sift.detectAndCompute(np.ascontiguousarray(grey, np.uint8), None)
    # OpenCV's key points are at pixel centres = integers; vebuild's pixel centres are at +0.5.
    uv = np.array([k.pt for k in kp], float).reshape(-1, 2) + 0.5
    return uv, (des if des is not None else np.zeros((0, 128), np.float32))


def _matches(ua: Array, da: np.ndarray, ub: Array, db: np.ndarray, F: Array) -> list[tuple[int, int]]:
    import cv2

    if len(da) < 2 or len(db) < 2:
        return []
    pairs = [(p[0].queryIdx, p[0].trainIdx) for p in cv2.BFMatcher(cv2.NORM_L2).knnMatch(da, db, k=2)
             if len(p) == 2 and p[0].distance < RATIO * p[1].distance]
    if not pairs:
        return []
    i, j = np.array(pairs).T
    lines = np.hstack([ua[i], np.ones((len(i), 1))]) @ F.T
    d = np.abs(np.sum(lines * np.hstack([ub[j], np.ones((len(j), 1))]), axis=1))
    d /= np.maximum(np.hypot(lines[:, 0], lines[:, 1]), 1e-12)
    return [(int(a), int(b)) for a, b, ok in zip(i, j, d < EPIPOLAR_PX, strict=True) if ok]


def triangulate(photos: Sequence[SurveyedPhoto], uv: Sequence[Array]) -> Array:
    """The linear (DLT) point seen at ``uv`` in ``photos``."""
    rows = []
    for ph, p in zip(photos, uv, strict=True):
        P = _P(ph)
        rows += [p[0] * P[2] - P[0], p[1] * P[2] - P[1]]
    _, _, Vt = np.linalg.svd(np.array(rows))
    return Vt[-1, :3] / Vt[-1, 3]


def true_projection(ph: SurveyedPhoto, X: Array) -> Array | None:
    """Where the true camera sees X (pixels), or None behind it."""
    x = ph.K @ (ph.R @ (X - ph.C))
    return None if x[2] <= 0 else x[:2] / x[2]


def find_tracks(photos: Sequence[SurveyedPhoto]) -> list[Track]:
    """Tracks over the photos (every pair matched), triangulated and checked with the true cameras."""
    feats = [_features(ph) for ph in photos]
    parent: dict[tuple[int, int], tuple[int, int]] = {}

    def root(n: tuple[int, int]) -> tuple[int, int]:
        while parent.setdefault(n, n) != n:
            parent[n] = parent[parent[n]]
            n = parent[n]
        return n

    for a in range(len(photos)):
        for b in range(a + 1, len(photos)):
            F = _fundamental(photos[a], photos[b])
            for i, j in _matches(*feats[a], *feats[b], F):
                ra, rb = root((a, i)), root((b, j))
                if ra != rb:
                    parent[ra] = rb
    groups: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for n in list(parent):
        groups.setdefault(root(n), []).append(n)
    tracks = []
    for members in groups.values():
        views = sorted({a for a, _ in members})
        if len(views) != len(members) or len(views) < 2:  # two features of one photo: ambiguous
            continue
        members.sort()
        uv = [feats[a][0][i] for a, i in members]
        X = triangulate([photos[a] for a in views], uv)
        ok = True
        for a, p in zip(views, uv, strict=True):
            q = true_projection(photos[a], X)
            if q is None or np.linalg.norm(q - p) > REPROJECTION_PX:
                ok = False
                break
        if ok:
            tracks.append(Track(X, tuple(photos[a].id for a in views)))
    return tracks


def _cache_key(photos: Sequence[SurveyedPhoto]) -> str:
    h = hashlib.sha256(f"v{VERSION} {SIFT_FEATURES} {RATIO} {EPIPOLAR_PX} {REPROJECTION_PX}".encode())
    for ph in photos:
        h.update(ph.id.encode())
        h.update(hashlib.sha256(ph.image.read_bytes()).digest())
        h.update(np.concatenate([ph.K.ravel(), ph.R.ravel(), ph.C]).tobytes())
    return h.hexdigest()[:24]


def cached_tracks(photos: Sequence[SurveyedPhoto]) -> list[Track]:
    """:func:`find_tracks`, cached by the photos' and cameras' contents."""
    path = cache_dir() / "bench-real" / f"v{VERSION}" / f"{_cache_key(photos)}.json"
    if path.is_file():
        try:
            rows = json.loads(path.read_text())
            return [Track(np.array(r["X"], float), tuple(r["photos"])) for r in rows]
        except (ValueError, KeyError, TypeError):
            pass  # a damaged cache is made again
    tracks = find_tracks(photos)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_bytes(path, json.dumps([{"X": t.X.tolist(), "photos": list(t.photos)} for t in tracks]).encode())
    return tracks


def choose_markers(tracks: Sequence[Track], photos: Sequence[SurveyedPhoto], n_max: int = MAX_MARKERS) -> list[Track]:
    """Up to ``n_max`` tracks of :data:`MIN_VIEWS` photos or more as markers: each pick the one that
    most raises the fewest markers any photo has, then that is seen in the most photos (up to 4),
    then that lies farthest from those chosen (a user marks well-spread points, and enough in every
    photo to tie it to the others), never within :data:`MIN_SEPARATION_PX` of one chosen in a photo
    both show (SIFT finds one corner several times)."""
    by_id = {ph.id: ph for ph in photos}
    left = [t for t in tracks if len(t.photos) >= MIN_VIEWS]
    chosen: list[Track] = []
    count = {ph.id: 0 for ph in photos}

    def apart(t: Track, c: Track) -> bool:
        for p in set(t.photos) & set(c.photos) & set(by_id):
            a, b = true_projection(by_id[p], t.X), true_projection(by_id[p], c.X)
            if a is not None and b is not None and np.linalg.norm(a - b) < MIN_SEPARATION_PX:
                return False
        return True

    while left and len(chosen) < n_max:
        least = min(count.values())
        scores = [(sum(1 for p in t.photos if count.get(p, least + 1) == least), min(len(t.photos), 4),
                   min((float(np.linalg.norm(t.X - c.X)) for c in chosen), default=0.0)) for t in left]
        best = left.pop(max(range(len(left)), key=lambda i: scores[i]))
        chosen.append(best)
        left = [t for t in left if apart(t, best)]
        for p in best.photos:
            if p in count:
                count[p] += 1
    return chosen
