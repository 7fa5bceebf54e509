"""The tolerances of the texture tests, each with the figure it was chosen from (measured on the
example room, true model and cameras, llvmpipe / LLVM 15) and the reason for its size: the CPU
reference of texture extraction against the example room's ray caster, and the GPU path against
the reference (tests/test_texture_reference.py, tests/test_distortion_gl.py)."""

#: Share of the pixels where the generator sees a model face (an object or the floor) on which the
#: ID buffer must name that face. Measured: 100 % (every pixel of p1 and p4 at full resolution;
#: both sample the ray through the pixel centre); only a centre within rounding of an edge between
#: two faces could differ.
MIN_ID_AGREEMENT = 0.999
#: Relative difference of the ID buffer's depth from the ray caster's hit distance along the
#: camera axis (both float64; measured ≤ 1e-12: perspective-correct interpolation is exact).
TRUTH_DEPTH_RTOL = 1e-9
#: GPU vs CPU ID buffer without erosion: share of pixels whose id differs. Measured 9.1e-5 (p1),
#: 6.6e-5 (p2), all on an edge between two faces: there the faces' depths tie and the GPU's
#: 24-bit depth buffer (near plane 1 mm: ~1.5 mm of depth resolution at 5 m) picks either.
ID_MISMATCH = 1e-3
#: GPU (float32) vs CPU (float64) depth where both name the same face. Measured ≤ 1.0e-6: a few
#: float32 roundings in the transform and the interpolation.
ID_DEPTH_RTOL = 1e-5
#: GPU vs CPU ID buffer with erosion 2 px: share of pixels whose id differs. Measured 2.1e-3
#: (p1), 1.1e-3 (p2): the GPU draws edges as bands r px either side of the line, the reference
#: erodes r px from the pixel centres across an id change (about ½ px less), and the GPU's band is
#: not drawn on a face that is steep in depth next to its own silhouette (see
#: vebuild.texture.reference.rasterise_ids). Every difference lies within r + 1 px of an id
#: change (measured ≤ 2.24 px for r = 2), away from the image border (where the GPU also erodes
#: for edges just outside the image).
ERODED_ID_MISMATCH = 0.01
#: Texels whose seen flag differs, as a share of the texels either sees, without erosion. Measured
#: ≤ 9.5e-5 (p1..p5): the ID-buffer ties above, and float32 projection putting p or a footprint
#: corner in the neighbouring pixel.
SEEN_MISMATCH = 1e-3
#: The same with erosion 2 px. Measured 8.7e-3 (p1), 1.6e-2 (p4, the largest of the five): the
#: two erosions differ near silhouettes (see ERODED_ID_MISMATCH); mostly the GPU sees texels at
#: the near side of a silhouette that the reference erodes.
SEEN_MISMATCH_ERODED = 0.03
#: Every texel whose seen flag differs projects within its footprint's reach (|a| + |b|) plus the
#: erosion radius plus this many pixels of an id change (measured: reach + r + 0.26 at most).
SEEN_MISMATCH_REACH_PX = 1.5
#: |GPU − CPU| of a seen texel's colour c and low band l (linear RGB, 0..1). Measured max 1.8e-3
#: (c), 2.0e-3 (l); median 6.8e-4. Almost all of it is llvmpipe's sRGB decoding, an approximation
#: off by up to 1.2e-3 (2.5 % at code 5) from the exact formula; with the GPU's decoding table
#: substituted the rest is ≤ 6.8e-4 (c) / 1.05e-3 (l): the pyramid's half-float storage (2^-11
#: relative per level) and 8-bit bilinear weights.
COLOUR_ATOL = 3e-3
#: |GPU − CPU| / CPU of a seen texel's weight. Measured ≤ 2e-6: float32 projection and Jacobian.
WEIGHT_RTOL = 1e-5
#: Merged colour (low/low.a + detail/detail.a) over the five photos, on texels both kept views of
#: with the same numbers of kept and dropped views: |GPU − CPU| ≤ MERGED_ATOL except on a share
#: MERGED_OUTLIERS. Measured: 99.98 % within 1.8e-3 (the colour tolerance carries over to a
#: weighted mean); the rest (1.6e-4) are texels at a face border where the two erosions let
#: different photos see the texel (same counts, other views), differing by up to 0.07.
MERGED_ATOL = 3e-3
MERGED_OUTLIERS = 1e-3
#: Share of the texels kept by either whose numbers of kept and dropped views differ. Measured
#: 1.4 % (erosion 2 px; 1.7e-4 without erosion): the erosions differ in which photos see a texel
#: near a silhouette, in the main pass and in the half-resolution best-weight pre-pass.
COUNT_MISMATCH = 0.03
#: Geometry: GPU (float32) vs CPU texel positions in metres (measured ≤ 1.0e-6 on a 5 m room) and
#: unit normals (measured ≤ 3e-8).
POSITION_ATOL = 1e-5
NORMAL_ATOL = 1e-6
