"""The example room's fixed numbers: the seed, the room and its furniture, the light, the clicks."""

from __future__ import annotations

import numpy as np

# The one seed. Photo k's clicks use default_rng([SEED, k]) and its pins default_rng([SEED, 1, k]);
# edge observations default_rng([SEED, 2]); the rough model default_rng([SEED, 3]).
SEED = 20000
BASE_WIDTH, BASE_HEIGHT = 1600, 1200  # photo size at --scale 1
ROOM = (5.0, 4.0, 2.6)  # x, y, z extent of the room, metres
CLICK_SIGMA_PX = 0.7  # 1σ of a simulated click, per coordinate, at scale 1
PIXEL_PITCH_MM = 0.0015  # simulated sensor pixel pitch at scale 1 (a small phone sensor)
JPEG_QUALITY = 92
SEGMENT_MIN_PX = 80.0  # shortest vanishing segment a careful user would mark, at scale 1
#: A segment on a photo whose lens bends lines is clicked as a polyline of this many points at
#: least and at most, one more per POLYLINE_STEP_PX (scale 1) of its image length: 3 up to 250 px,
#: 4 up to 500 px, 5 beyond.
POLYLINE_POINTS = (3, 5)
POLYLINE_STEP_PX = 250.0
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


