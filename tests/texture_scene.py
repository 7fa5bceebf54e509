"""The example room's ground truth for texture tests: see vebuild.bench.example_truth."""

from vebuild.bench.example_truth import (  # noqa: F401
    TRUTH_SUPERSAMPLE,
    generator,
    ground_truth,
    photo_path,
    psnr,
    texture_psnr,
    true_cameras,
    true_model,
    truth_texels,
)
