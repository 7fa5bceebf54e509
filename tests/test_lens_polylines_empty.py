"""vebuild.model.drag.lens_polylines of no segments through a distorting lens is no curves (the
overlay of a primitive none of whose edges is in front of a photo's camera)."""

import numpy as np

from vebuild.camera import Lens
from vebuild.model.drag import lens_polylines


def test_no_segments_give_no_curves_through_a_lens():
    K = np.array([[1000.0, 0, 800], [0, 1000.0, 600], [0, 0, 1]])
    assert lens_polylines(K, Lens(-0.05), np.zeros((0, 2)), np.zeros((0, 2))) == []
    assert len(lens_polylines(K, Lens(-0.05), [[10.0, 10.0]], [[500.0, 20.0]])) == 1
