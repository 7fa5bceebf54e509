"""What the commands print on the terminal: the progress bar (:mod:`.progress`) and the plain-text
tables of calibration, model and texture results (:mod:`.tables`). Used by the command line and by
the actions that report as they go (``vebuild demo``); no logic of the pipeline lives here."""
