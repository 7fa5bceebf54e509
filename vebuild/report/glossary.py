"""The report's glossary: each technical term the annex must keep, said in plain words for a reader
who is not a photogrammetrist. The annex uses these terms; the first page and the body avoid them."""

from __future__ import annotations

from .page import esc

#: (term, what it means), in the order a reader meets them.
GLOSSARY: tuple[tuple[str, str], ...] = (
    ("1σ (one sigma)", "the standard uncertainty of a figure: the true value lies within one σ of the figure "
     "about two times in three, and within 1.96 σ about 95 times in 100."),
    ("95 % interval", "the range, figure ± 1.96 σ, that would hold the true value in about 95 of 100 repetitions "
     "of the work with new photos and new clicks of the same quality."),
    ("vanishing point", "the point in a photo where lines that are parallel in the scene (the edges of a floor, "
     "the verticals of a door) meet; from where they meet, the camera's direction and lens are worked out."),
    ("vanishing segment", "a straight edge marked on a photo and labelled with the direction it runs in the "
     "scene (x, y or z); the segments of one direction give one vanishing point."),
    ("1vp, 2vp, 3vp", "a photo calibrated from one, two or three vanishing points; three fix the lens's focal "
     "length and centre, fewer need the camera's recorded focal length or assume the centre."),
    ("focal length", "how far the lens magnifies, here in pixels of the photo (the photo's width divided by "
     "twice the tangent of half its horizontal angle of view)."),
    ("principal point", "the point of the photo straight in front of the lens, usually near its centre."),
    ("lens distortion (k1, k2)", "how much the lens bends straight lines near the photo's edges (barrel: "
     "outward). vebuild straightens them with the division model: a point's distance from the principal "
     "point is divided by 1 + k1 r² + k2 r⁴."),
    ("camera position, rotation", "where the camera stood (metres, in the scene's axes) and which way it "
     "pointed (degrees)."),
    ("marker", "a point the examiner clicked in two photos or more (a corner, a stain); the photos' cameras are "
     "placed so that the markers' rays meet."),
    ("reference distance, scale distance", "a distance measured at the scene with a tape and entered: it gives "
     "the reconstruction its scale."),
    ("check distance", "a distance measured at the scene and entered, but not used to build the model: the "
     "independent test of its accuracy."),
    ("pin, edge observation", "a corner or an edge of a modelled object clicked on a photo: what the model is "
     "fitted to."),
    ("entered value", "a figure the examiner typed in (a measured door width, say) with its own σ; the report "
     "marks every figure that rests on one."),
    ("held by a relation or a joint", "a figure not measured but fixed by how objects sit on each other (a box "
     "resting on the floor, a door flush with its wall)."),
    ("residual", "how far a click lies from where the final cameras and model put it, in pixels."),
    ("re-calibration", "the cameras refined together with the model, after the model was fitted."),
    ("SHA-256", "a fingerprint of a file's bytes: any change to a photo, however small, changes it."),
)


def glossary_html() -> str:
    """The glossary as a definition list."""
    return "<dl class='glossary'>" + "".join(f"<dt>{esc(t)}</dt><dd>{esc(d)}</dd>" for t, d in GLOSSARY) + "</dl>"
