"""What the overlay shows and labels, layer by layer (the Layers popup, V), which of the model's
edges the photo's camera sees (:mod:`vebuild.edit.visibility`, from the 3-D preview's renderer's ID
buffer of the photo's camera), what is under the cursor, and the corner or face picked by a click
in the photo (the Select tool) or in the 3-D preview, named as :mod:`vebuild.edit.names` says (I:
every corner and face of the selected primitive named at once)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from imgui_bundle import imgui
from numpy.typing import NDArray

from .layout import PICK_RADIUS_PX, EditorPart
from .overlay import Line, Overlay, Point
from .visibility import edge_runs, id_camera

#: The overlay's layers and the kinds of :class:`~vebuild.edit.overlay.Line` and
#: :class:`~vebuild.edit.overlay.Point` each holds.
LAYERS: dict[str, tuple[str, ...]] = {
    "segments": ("segment", "segment-path", "segment-point", "known-length", "known-length-end"),
    "residuals": ("residual", "marker-projected"),
    "markers": ("marker",),
    "model": ("edge", "user-edge", "handle", "pin"),
    "vanishing points": ("vp", "vp-ray", "horizon", "axis", "origin"),
}
LAYER_OF = {kind: layer for layer, kinds in LAYERS.items() for kind in kinds}
#: Label modes: none, the hovered item's and the selection's, every item's.
LABEL_MODES = ("none", "hover and selection", "all")
#: Each layer's labels at first: markers' names and the three vanishing points' and axes' labels
#: always (few, apart); the rest on hover and on the selection only (they overlap).
DEFAULT_LABELS = {"segments": 1, "residuals": 1, "markers": 2, "model": 1, "vanishing points": 2}


class OverlayLayers(EditorPart):
    """Layers, visibility, hover and picks (a part of the Editor)."""

    _picked: dict[str, Any] | None

    # -- state (made on first use: the Editor's constructor is shared) ----------------------------

    @property
    def layer_shown(self) -> dict[str, bool]:
        if "_layer_shown" not in self.__dict__:
            self._layer_shown = {k: True for k in LAYERS}
        return self._layer_shown

    @property
    def layer_labels(self) -> dict[str, int]:
        """Each layer's label mode, an index into :data:`LABEL_MODES`."""
        if "_layer_labels" not in self.__dict__:
            self._layer_labels = dict(DEFAULT_LABELS)
        return self._layer_labels

    @property
    def picked(self) -> dict[str, Any] | None:
        """The corner or face last picked: node, what ("corner" or "face"), stored, shown, where."""
        return self.__dict__.get("_picked")

    @property
    def show_names(self) -> bool:
        return bool(self.__dict__.get("_show_names", False))

    def toggle_names(self) -> None:
        """Name every corner and face of the selected primitive on the photo (I), or stop."""
        self._show_names = not self.show_names
        if self.show_names and self.selected is None:
            self.say("names: select a primitive (click one of its edges) to see its corners and faces named")

    def toggle_layers(self) -> None:
        """Open the Layers popup (V), or close it."""
        self._layers_open = not self.__dict__.get("_layers_open", False)

    # -- visibility ---------------------------------------------------------------------------------

    def edge_visibility(self) -> dict[Any, Any] | None:
        """The shown photo's model edges as seen and hidden runs (:func:`vebuild.edit.visibility.edge_runs`),
        by (node, edge); None until worked out (no camera, no model, no renderer)."""
        vis = self.__dict__.get("_vis")
        return vis[1] if vis is not None and vis[0][1] == self.photo else None

    def _update_visibility(self) -> None:
        """Work the visibility out again when the model or the photo changed (not during a drag:
        the drag's still edges keep theirs, the moving ones are drawn solid)."""
        s = self.session
        if self.photo is None or s.dragging:
            return
        key = (s.revision, self.photo)
        vis = self.__dict__.get("_vis")
        if vis is not None and vis[0] == key:
            return
        r, cam = self._renderer, s.cameras.get(self.photo)
        if r is None or cam is None or self._preview_key is None or self._preview_key[0] != s.revision:
            self._vis = None if vis is None or vis[0][1] != self.photo else vis
            return
        t0 = time.perf_counter()
        try:
            idc = id_camera(cam)
            ids, depth = r.id_buffer(idc)
            self._vis = (key, edge_runs(s.edge_world_ends(), cam, idc, ids, depth))
        except Exception as e:  # noqa: BLE001 - a failed pass draws every edge solid, and says why
            self._vis = (key, {})
            self.say(f"hidden edges not worked out: {e}")
        self.timings["visibility_ms"] = 1e3 * (time.perf_counter() - t0)

    # -- what is drawn and labelled -------------------------------------------------------------------

    def shows(self, kind: str) -> bool:
        layer = LAYER_OF.get(kind)
        return layer is None or self.layer_shown[layer]

    def labelled(self, item: Line | Point, hovered: bool) -> bool:
        """Whether an item's label is drawn: L off draws markers' names only; else its layer's mode."""
        if item.kind == "known-length":
            return True
        if not self.show_labels:
            return item.kind == "marker"
        layer = LAYER_OF.get(item.kind)
        mode = 2 if layer is None else self.layer_labels[layer]
        if mode == 2:
            return True
        if mode == 0:
            return False
        node = item.key[0] if isinstance(item.key, tuple) and item.key else None
        return hovered or (item.kind in ("handle", "pin") and node == self.selected)

    def hovered(self, ov: Overlay) -> Line | Point | None:
        """The item under the cursor: the nearest point within the picking radius, else the nearest
        line (of the layers shown)."""
        x, y = self._cursor
        key = (id(ov), x, y, self.zoom, self.pan, tuple(self.layer_shown.values()))
        memo = self.__dict__.get("_hover_memo")
        if memo is not None and memo[0] == key:
            return memo[1]
        u, v = self.window_to_image(x, y)
        r = PICK_RADIUS_PX / self.zoom
        best: tuple[float, Any] = (r, None)
        for p in ov.points:
            d = float(np.hypot(p.uv[0] - u, p.uv[1] - v))
            if d <= best[0] and p.label and self.shows(p.kind):  # a point without a name: its line's
                best = (d, p)
        if best[1] is None:
            lines, ends = self._hover_lines(ov)
            if len(lines):
                dist = _distances_to_segments(u, v, ends)
                i = len(dist) - 1 - int(np.argmin(dist[::-1]))  # the last of the nearest, as a loop keeping d <= best
                if dist[i] <= best[0]:
                    best = (float(dist[i]), lines[i])
        self._hover_memo = (key, best[1])
        return best[1]

    def _hover_lines(self, ov: Overlay) -> tuple[list[Line], NDArray[np.float64]]:
        """The lines the cursor may hover (of the layers shown; not vanishing rays) and their ends
        (n, 4), kept for the overlay and the layers shown: a house's photo has some 900."""
        shown = tuple(self.layer_shown.values())
        memo = self.__dict__.get("_hover_lines_memo")
        if memo is None or memo[0] is not ov or memo[1] != shown:
            lines = [ln for ln in ov.lines if ln.kind not in ("vp-ray",) and self.shows(ln.kind)]
            ends = np.array([ln.p for ln in lines], float).reshape(-1, 4)
            memo = self._hover_lines_memo = (ov, shown, lines, ends)
        return memo[2], memo[3]

    # -- picks ------------------------------------------------------------------------------------------

    def _press_left(self, x: float, y: float) -> None:
        super()._press_left(x, y)  # type: ignore[misc]  # the Select tool's (tools.py), then the pick
        p = self._press
        if self.tool != "select" or p is None or self.photo is None:
            return
        s = self.session
        if p["kind"] == "handle":
            names = s.corner_names(self.photo, p["node"])
            self.pick("corner", p["node"], p["handle"], names.get(p["handle"], p["handle"]), "photo")
        elif p["kind"] == "click" and self.photo in s.cameras:
            hit = s.face_at(self.photo, self.window_to_image(x, y))
            if hit is not None:
                names = s.face_names(self.photo, hit.node)
                self.pick("face", hit.node, hit.name, names.get(hit.name, hit.name), "photo")
            else:
                self._picked = None

    def pick(self, what: str, node: str, stored: str, shown: str, where: str) -> None:
        self._picked = {"what": what, "node": node, "stored": stored, "shown": shown, "where": where}
        self.say(f"{node}: {what} {shown}")  # a place name ends with the name the project file keeps

    def pick_in_preview(self, u: float, v: float) -> None:
        """A click at pixel (u, v) of the 3-D preview: the corner within the picking radius, else the
        face seen there."""
        r, cam = self._renderer, self.preview_camera()
        if r is None or cam is None:
            return
        from vebuild import camera as cam_math

        s = self.session
        best: tuple[float, Any] = (PICK_RADIUS_PX, None)
        model = s.model
        for node in [n.name for n in model.nodes if n.primitive is not None] if model is not None else []:
            for h, X in s.corners_world(node).items():
                if cam_math.world_to_camera(cam.R, cam.C, X)[2] <= 0:
                    continue
                q = cam_math.project(cam.K, cam.R, cam.C, X)
                d = float(np.hypot(q[0] - u, q[1] - v))
                if d < best[0]:
                    best = (d, (node, h))
        if best[1] is not None:
            node, h = best[1]
            names = s.corner_names(self.photo, node)
            if h in names:
                self.pick("corner", node, h, names[h], "preview")
                return
        ids, _ = r.id_buffer(cam)
        i, j = int(np.clip(u, 0, cam.width - 1)), int(np.clip(v, 0, cam.height - 1))
        face = int(ids[j, i])
        if face == 0:
            self._picked = None
            return
        f = r.scene.mesh.faces[face - 1]
        names = s.face_names(self.photo, f.node)
        self.pick("face", f.node, f.name, names.get(f.name, f.name), "preview")

    # -- the popup --------------------------------------------------------------------------------------

    def _photo_takes(self, x: float, y: float) -> bool:
        """Not where the Layers popup is (over the photo view)."""
        r = self.widget_rects.get("Layers") if self.__dict__.get("_layers_open", False) else None
        if r is not None and r[0] <= x < r[2] and r[1] <= y < r[3]:
            return False
        return bool(super()._photo_takes(x, y))  # type: ignore[misc]  # the tools' (tools.py)

    def _draw_layers_popup(self) -> None:
        """The Layers popup: each layer shown or not, and its labels' mode."""
        if not self.__dict__.get("_layers_open", False):
            return
        x0, y0, x1, _ = self.view_rect()
        imgui.set_next_window_pos((x1 - 8, y0 + 8), imgui.Cond_.always, (1.0, 0.0))
        opened, still = imgui.begin("Layers", True, imgui.WindowFlags_.always_auto_resize
                                    | imgui.WindowFlags_.no_saved_settings | imgui.WindowFlags_.no_collapse)
        self._rects["Layers"] = (*tuple(imgui.get_window_pos()), *(imgui.get_window_pos() + imgui.get_window_size()))
        if opened:
            imgui.text("shown       labels")
            for layer in LAYERS:
                _, on = imgui.checkbox(f"{layer}##layer", self.layer_shown[layer])
                self.rect(f"layer {layer}")
                if imgui.is_item_hovered():
                    imgui.set_tooltip(f"draw the {layer} over the photo")
                self.layer_shown[layer] = on
                imgui.same_line(170)
                imgui.set_next_item_width(170)
                self.layer_labels[layer] = self.combo(f"labels {layer}", self.layer_labels[layer], list(LABEL_MODES))
            imgui.text("hidden model edges: dashed and dim")
        imgui.end()
        if not still:
            self._layers_open = False


def _distances_to_segments(u: float, v: float, ends: NDArray[np.float64]) -> NDArray[np.float64]:
    """The distance from (u, v) to each segment (x1, y1, x2, y2) of ``ends`` (n, 4)."""
    a, d = ends[:, :2], ends[:, 2:] - ends[:, :2]
    q = np.array([u, v])
    t = np.clip(np.einsum("ij,ij->i", q - a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-12), 0.0, 1.0)
    w = a + t[:, None] * d - q
    return np.hypot(w[:, 0], w[:, 1])
