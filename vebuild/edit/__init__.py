"""The interactive modelling screen (`vebuild edit`).

Its edit logic, without a window: :mod:`.session` (:class:`~.session.EditSession`) made of
:mod:`.history` (the edit transaction, undo, autosave), :mod:`.marks` (segments, markers,
distances, edge observations), :mod:`.modelling` (primitives, joints, drags, fixes) and
:mod:`.photo_overlay` (what is drawn over a photo, as the plain data of :mod:`.overlay`).
Its window: :mod:`.screen` (:class:`~.screen.Editor`) made of :mod:`.tools`, :mod:`.photo_view`,
:mod:`.bars` and :mod:`.preview` over :mod:`.layout`, with :mod:`.panels` as a component; its
keys are one table, :mod:`.keys`."""
