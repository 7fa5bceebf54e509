"""The vanishing segments a calibration left out as not meeting at their axis' vanishing point
(clutter: a roof's slope, cobbles, another building; :mod:`vebuild.calibration.robust`), as the
modelling screen shows them: grey, crossed at the middle in their axis' colour, each labelled
with why; a legend in the Calibration panel saying what they are and how many of each axis; and
one undoable edit that deletes them from a photo. Kept, they do no harm: each calibration leaves
them out again.

What was left out is read from the photo's calibration record
(:func:`vebuild.project.left_out.rejected_by_calibration`)."""

from __future__ import annotations

from .history import EditError
from .marks import AXES, Marks

#: What the grey lines are, after "N grey crossed x segments: ".
WHAT_THEY_ARE = "left out by the calibration: they do not meet the other {axis} lines' vanishing point"
#: What to do with them, under the legend's lines.
WHAT_TO_DO = ("Such lines are often a roof's slope, cobbles or another building. Point at a grey line to read "
              "why it was left out. Kept, they do no harm: each calibration leaves them out again. Or delete "
              "them from this photo (Ctrl+Z brings them back):")


def legend_line(axis: str, count: int) -> str:
    """The legend's line for ``count`` grey segments of ``axis``."""
    lines = "segment" if count == 1 else "segments"
    return f"{count} grey crossed {axis} {lines}: " + WHAT_THEY_ARE.format(axis=axis)


class LeftOut(Marks):
    """The segments a calibration left out, and deleting them (mixed into the session)."""

    def left_out_segments(self, photo: str) -> dict[str, dict[int, str]]:
        """Axis → {index of a segment of ``photo`` → why its calibration left it out}; only the
        axes with any (see the module doc)."""
        segments = self.photo(photo).get("vanishing_segments") or {}
        out = {}
        for axis in AXES:
            found = self._left_out_of(photo, axis, len(segments.get(axis, [])))
            if found:
                out[axis] = found
        return out

    def delete_left_out(self, photo: str) -> dict[str, list[int]]:
        """Delete, as one undoable edit, every segment of ``photo`` its calibration left out;
        returns axis → the indices deleted (as they were). Their clicked 1σ goes with them."""
        left = self.left_out_segments(photo)
        if not left:
            raise EditError(f"photo '{photo}' has no segments left out by its calibration: nothing to delete "
                            "(calibrate first, or its segments have changed since)")
        n = sum(len(v) for v in left.values())
        with self._edit(f"delete the {n} segments of {photo} left out by the calibration"):
            p = self.photo(photo)
            segs = p["vanishing_segments"]
            sigmas = p.get("vanishing_segment_sigmas") or {}
            for axis, gone in left.items():
                segs[axis] = [s for i, s in enumerate(segs[axis]) if i not in gone]
                if axis in sigmas:
                    sigmas[axis] = [s for i, s in enumerate(sigmas[axis]) if i not in gone]
                    if not sigmas[axis]:
                        del sigmas[axis]
                if not segs[axis]:
                    del segs[axis]
            if "vanishing_segment_sigmas" in p and not sigmas:
                del p["vanishing_segment_sigmas"]
        deleted = {a: sorted(v) for a, v in left.items()}
        self.say(f"deleted the {n} segments of {photo} left out by the calibration ("
                 + "; ".join(f"{a}: {', '.join(map(str, ix))}" for a, ix in deleted.items())
                 + "); Ctrl+Z brings them back; calibrate again for the cameras without them")
        return deleted
