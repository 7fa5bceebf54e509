"""The interactive modelling screen (`vebuild edit`): its edit logic (session), what it draws over
a photo (overlay) and its window (screen)."""
