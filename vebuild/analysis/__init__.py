"""Forensic analysis of a solved model (paper §5.1): answers an investigator can defend.

Modules:

- :mod:`vebuild.analysis.measure` — points on surfaces, distances, heights, an object's dimensions
  and check distances, each with 1σ and a 95 % interval propagated from the solve's covariance.
- :mod:`vebuild.analysis.sightline` — sight lines and viewsheds (witness statement evaluation).
- :mod:`vebuild.analysis.trajectory` — trajectories with uncertainty cones, and what they hit.
- :mod:`vebuild.analysis.cli` — the ``vebuild analyse PROJECT …`` command group (readable tables
  and ``--json OUT``); each analysis adds its subcommands there.

Layer 6 of DESIGN.md: thin over the model and solver; numpy only (no GL) unless a module says so.
"""
