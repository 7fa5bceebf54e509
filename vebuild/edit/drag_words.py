"""A refused drag in words (the modelling screen's message line): what holds the corner and the one
change in the window that lets it go there, with no names from the project file, for the first line
of the message that :meth:`vebuild.edit.modelling.Modelling.drag_to` gives."""

from __future__ import annotations

from typing import Any


def stuck_words(j: Any, n_fixed: int, on_marker: bool, at_limit: bool) -> str:
    """A refused drag in words (no names from the project file): what holds the corner and the one
    change in the window that lets it move there (``on_marker``: the corner is the one on the marker;
    ``at_limit``: a hinge or slider at the end of its travel)."""
    if on_marker:
        return (f"This corner sits on marker {getattr(j, 'marker', '?')} and cannot leave it. Choose the joint "
                "\"rests_on\" in the Model tab (joint) to move the object off the marker.")
    if n_fixed:
        many = f"{n_fixed} fixed corners hold" if n_fixed > 1 else "a fixed corner holds"
        them = "them" if n_fixed > 1 else "it"
        return (f"This corner cannot go there: {many} the object where the photos show {them}. "
                "Press F over a fixed corner (a filled square on the photo) to free it, then drag again.")
    where = {"marker": f"turns about marker {getattr(j, 'marker', '?')} only",
             "rests_on": "slides and turns on what it stands on only",
             "hinge": "turns on its hinge only", "slider": "slides along its runner only",
             "fixed": "is fixed to what it hangs on"}.get(j.type, "moves only as its joint lets it")
    if j.type in ("hinge", "slider") and at_limit:
        return (f"This corner {where} and is at the end of its travel. Widen its limits (Model tab, limits) to let "
                "it go further.")
    if j.type in ("marker", "rests_on"):
        return (f"This corner {where}. Press F over another of its corners to fix it where the photo shows it: a "
                "drag then changes its size as well.")
    return f"This corner {where}. Choose the joint \"free\" in the Model tab (joint) to let it go there."
