"""Forensic analysis of a solved model (paper §5.1): answers an investigator can defend.

Modules:

- :mod:`vebuild.analysis.solved` — the solved model with its parameters' covariance, and points
  tied to it.
- :mod:`vebuild.analysis.points` — points written as text (handles, face points, pixels,
  markers) and picked in a photo or a view.
- :mod:`vebuild.analysis.measure` — distances, heights, an object's dimensions and check
  distances, each with 1σ and a 95 % interval propagated from the solve's covariance.
- :mod:`vebuild.analysis.sightline` — sight lines and viewsheds (witness statement evaluation).
- :mod:`vebuild.analysis.trajectory` — trajectories with uncertainty cones, and what they hit.
- :mod:`vebuild.analysis.lighting` — one view under several lighting presets.
- :mod:`vebuild.analysis.single_view` — heights above the floor and distances on it, lengths on a
  wall or on a plane marked by three points, heights above a raised surface, measured on one
  calibrated photo (single-view metrology), no model needed; ``recorded.measure_clicked`` runs a clicked
  one as the command line runs its saved words.
- :mod:`vebuild.analysis.requests` and :mod:`vebuild.analysis.requests_geometry` — each analysis
  as a typed request whose ``run(project)`` gives its table, figures and image: what the command
  line, the report and the viewer run.
- :mod:`vebuild.analysis.parsers` — the subcommands' words and the one mapping from them to the
  requests (the command line's and the recorded analyses').
- :mod:`vebuild.analysis.cli` — the ``vebuild analyse PROJECT …`` command group: each request run
  on the checked project, a readable table and ``--json OUT``.
- :mod:`vebuild.analysis.recorded` — the analyses a project records, parsed into requests.

Layer 6 of DESIGN.md: thin over the model and solver; numpy only (no GL) unless a module says so.
"""
