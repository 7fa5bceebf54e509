"""vebuild: interactive reconstruction of measurable virtual environments from photographs.

The method is that of Gibson & Howard (VRST 2000). Conventions (world frame, pixels, camera model,
directed vanishing lines) are fixed once in ``docs``/DESIGN and implemented in
:mod:`vebuild.camera`; every other module uses them from there.
"""

__version__ = "0.1.0"
