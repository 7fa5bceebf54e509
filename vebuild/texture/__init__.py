"""Texture extraction (paper §4): ID buffers, texel projection and a weighted merge.

The GPU path (:mod:`vebuild.texture.gpu`) and the CPU reference (:mod:`vebuild.texture.reference`)
implement the same definitions, given here once.

Layout (:mod:`vebuild.texture.layout`)
    Every logical face of every primitive gets a chart of ``nw × nh`` texels,
    ``n = ceil(size_m × texels_per_metre)`` capped at ``max_face_texels``, packed into atlas pages.
    A vertex's atlas position (in texels, on its page) is its chart position scaled to the chart.
    A texel (i, j) of a page has its centre at (i + ½, j + ½); it lies on the face whose triangle
    (in atlas space) contains that centre, at the world point and normal interpolated linearly
    from the triangle's corners. ``e_u``, ``e_v`` are the world steps of one texel along atlas x
    and y (constant per triangle).

Pass 1, the ID buffer (per photo, full resolution)
    At pixel (i, j) the 1-based global id of the face nearest along the ray through the pixel
    centre (i + ½, j + ½), and that face's camera depth z there; 0 and +inf where nothing is seen.
    Erosion (``erode_px`` = r > 0): every pixel within r pixels of a visible face boundary or
    silhouette edge is set to 0 (the edges are drawn r pixels wide, depth-tested with the faces),
    so a texel near the edge of an occluder or of its own face is never taken.

Pass 2, the texels (per photo)
    A texel at world P, normal N projects to p = π(K R (P − C)) with depth z. Its footprint in the
    photo is a = J e_u, b = J e_v with J the 2×3 Jacobian of the projection at P. It is *seen* when
    z > 0, N·(C − P) > 0, p lies in the image, ``id[floor(p)]`` is the texel's face with
    ``z ≤ (1 + DEPTH_TOLERANCE)·depth[floor(p)]``, and the ID buffer holds the same face at the four
    footprint corners p ± a ± b (so the filter's support stays on the face).
    Weight w = sqrt(|a × b|) · cos θ, cos θ = N·(C − P)/|C − P| (paper §4: the projected texel
    size times the cosine).
    Colour: the photo is decoded to linear RGB and box-filtered into a pyramid (level k + 1 texel
    (i, j) is the mean of level k texels {2i, min(2i + 1, W_k − 1)} × {2j, min(2j + 1, H_k − 1)});
    the texel's colour c is the trilinear sample at level λ = log2(max(|a|, |b|)) clamped to the
    pyramid, where level k is sampled bilinearly at p / 2^k (texel centres at half-integers,
    coordinates clamped to the level's centres). Its low band l is the same at λ + ``detail_levels``.

Lens distortion (a photo's ``k1``, the division model of :mod:`vebuild.camera`)
    Pass 1 draws the ID buffer of the photo's pinhole cover (:mod:`vebuild.texture.lens`): the
    pinhole image of the same K over the photo's undistorted bounds, its pixels the pinhole's
    pixels of K shifted by a whole ``origin``. In pass 2 the seen test above is made there, at
    p − origin with the pinhole footprint a, b; then p, a and b are distorted (p_d = c + f·s·x_u,
    s = 2 / (1 + √(1 − 4 k1 |x_u|²)), x_u = (p − c) / f; a_d = J a, b_d = J b with J the Jacobian
    s I + (2 k1 s² / √(1 − 4 k1 |x_u|²)) x_u x_uᵀ), the corners p_d ± a_d ± b_d must lie in the
    photo (as for a pinhole, whose ID buffer ends at the photo's border), and the weight,
    the level of detail and the colour are those of p_d, a_d, b_d: the photo is sampled once,
    where the lens recorded the texel. For k1 = 0 the cover is the photo's frame and nothing is
    distorted.

Merge (over photos)
    With per-photo gain g (exposure compensation, 1 when off), kept views (w ≥ ``drop_ratio`` ×
    the best w any photo has at that texel; all when off) give
    ``colour = Σ w l/g / Σ w + Σ w^s (c − l)/g / Σ w^s`` (s = ``detail_sharpness``; with s = 1
    this is exactly the paper's weighted average Σ w c/g / Σ w). A texel seen only by dropped
    views takes their weighted average. Unseen texels are filled from the seen ones by push-pull
    interpolation within their own face's chart (no hard edge), and charts bleed into their gutter.
"""

#: A texel may lie this much (relative) behind the depth in the ID buffer and still be seen: the
#: buffer's depth is at the pixel centre, the texel up to half a pixel away on a sloping face.
DEPTH_TOLERANCE = 0.02
#: Pyramid levels at most.
MAX_LEVELS = 16
#: Scale of the pre-pass that finds each texel's best weight (its ID buffer is this much smaller).
BEST_WEIGHT_SCALE = 0.5


def pre_pass_erosion(erode_px: float) -> float:
    """Erosion of the best-weight pre-pass: half the main pass's, at least 1 px (0: off)."""
    return max(1.0, erode_px * BEST_WEIGHT_SCALE) if erode_px > 0 else 0.0

