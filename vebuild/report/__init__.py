"""The report (``vebuild report``): everything another examiner needs to check and reproduce the
work, as an HTML page with its images (and a PDF of it).

The report is made from the project file alone: the photos with their SHA-256, the calibration
and its residuals (a project of calibrated photos with no model has a report too), the model and
its solve, the check distances, the evidence views (with the
evidence markers), each photo's camera against its photo, the analyses the project records
(``analyses``: measurements, sight lines, viewsheds, trajectories, lighting comparisons, each
re-computed), and the hypotheses, each clearly labelled as one. It carries no time stamp: running
it twice on the same project gives the same HTML and the same images, byte for byte.

Modules (imports point one way: write → findings, sections → analyses → page):

- :mod:`vebuild.report.page` — the HTML pieces, the report being built, the page.
- :mod:`vebuild.report.findings` — the first page: the case, the question, the answers in words, the plan.
- :mod:`vebuild.report.sections` — the sections (their order: :func:`vebuild.report.write.report_steps`).
- :mod:`vebuild.report.glossary` — the annex's technical terms in plain words.
- :mod:`vebuild.report.analyses` — the recorded analyses, each re-run as its typed request.
- :mod:`vebuild.report.single_view` — the measurements made on single photos, drawn on their photo
  and tabled with their intervals.
- :mod:`vebuild.report.without_model` — the report of calibrated photos with no model: the sections
  that need one left out with a line saying why, and what a project lacks before any report.
- :mod:`vebuild.report.write` — :func:`~vebuild.report.write.write_report`, whole or not at all, and
  the digest that shows two runs gave the same report.
- :mod:`vebuild.console.tables` — the plain-text tables the command line prints.
"""
