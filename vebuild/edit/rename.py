"""Renaming a marker in the modelling screen (the Calibration tab's rename field): the marker
gets its new name wherever the project names it, in one undoable edit.

What names a marker (scenes/FORMAT.md): ``markers[].name``, ``origin_marker``, each photo's
``marker_observations``, the ends of ``reference_distances``, a model node's marker joint
(``model.nodes[].joint.marker``), a scan target's ``point``, and the results that list markers by
name (``calibration.markers``, each calibrated camera's ``marker_residuals_px``,
``model_solution.markers`` and its cameras'). Recorded analyses keep their command lines as they
were run (the report runs them again: a renamed marker there is named in its error)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .history import EditError


def _renamed_keys(d: Any, old: str, new: str) -> Any:
    """A mapping with key ``old`` renamed ``new`` (its order kept), or d itself if it has none."""
    if not isinstance(d, dict) or old not in d:
        return d
    return {(new if k == old else k): v for k, v in d.items()}


class MarkerRename:
    """Mixed into the session (:class:`vebuild.edit.session.EditSession`)."""

    if TYPE_CHECKING:
        project: Any

        @property
        def data(self) -> dict[str, Any]: ...

        def say(self, text: str) -> None: ...

        def _edit(self, label: str) -> Any: ...

    def rename_marker(self, old: str, new: str) -> None:
        """Call marker ``old`` ``new`` wherever the project names it (one undoable edit). A name
        in use, an empty one or one with ':' (which names model vertices) is refused."""
        new = new.strip()
        names = list(self.project.marker_names())
        if old not in names:
            raise EditError(f"no marker is called '{old}' (the markers: {', '.join(names) or 'none'})")
        if not new or ":" in new:
            raise EditError(f"a marker's new name must be given, without ':' (which names model vertices): {new!r}")
        if new == old:
            raise EditError(f"marker '{old}' is called that already")
        if new in names:
            raise EditError(f"a marker is called '{new}' already: choose another name, or remove that marker first")
        with self._edit(f"rename marker {old} to {new}"):
            d = self.data
            for m in d.get("markers") or []:
                if m.get("name") == old:
                    m["name"] = new
            if d.get("origin_marker") == old:
                d["origin_marker"] = new
            for p in d.get("photos") or []:
                if "marker_observations" in p:
                    p["marker_observations"] = _renamed_keys(p["marker_observations"], old, new)
            for r in d.get("reference_distances") or []:
                for end in ("a", "b"):
                    if r.get(end) == old:
                        r[end] = new
            for n in (d.get("model") or {}).get("nodes") or []:
                joint = n.get("joint")
                if isinstance(joint, dict) and joint.get("type") == "marker" and joint.get("marker") == old:
                    joint["marker"] = new
            for scan in d.get("scans") or []:
                for t in (scan.get("targets") or []) if isinstance(scan, dict) else []:
                    if isinstance(t, dict) and t.get("point") == old:
                        t["point"] = new
            for key in ("calibration", "model_solution"):
                res = d.get(key)
                if not isinstance(res, dict):
                    continue
                if "markers" in res:
                    res["markers"] = _renamed_keys(res["markers"], old, new)
                for cam in (res.get("cameras") or {}).values():
                    if isinstance(cam, dict) and "marker_residuals_px" in cam:
                        cam["marker_residuals_px"] = _renamed_keys(cam["marker_residuals_px"], old, new)
                if res.get("origin_marker") == old:
                    res["origin_marker"] = new
        self.say(f"marker {old} is now called {new} in every photo, distance and joint that named it")
