"""The modelling screen's keys and mouse: one table, from which the screen's dispatch, its
on-screen help (the Keys tab, the tools' tooltips) and the manual's list (docs/manual.md) are made."""

from __future__ import annotations

import glfw

from vebuild.gl.app import CTRL, SHIFT, Binding, Chord, KeyTable

EDITOR_KEYS = KeyTable([
    Binding("wheel; middle drag or Space + drag; Home", "zoom about the cursor (up to 16×, pixels drawn as squares "
            "above 2×); pan; fit the photo", (Chord(glfw.KEY_HOME, "fit"),)),
    Binding("1, 2, 3", "Segment X, Y, Z: press on an edge, drag along it toward the axis' positive sense, release: "
            "a directed vanishing segment",
            (Chord(glfw.KEY_1, "set_tool", ("x",)), Chord(glfw.KEY_2, "set_tool", ("y",)),
             Chord(glfw.KEY_3, "set_tool", ("z",)))),
    Binding("Ctrl+click (Segment X, Y, Z)", "a middle point on the segment of that axis under the click, where the "
            "edge really runs: a long edge marked as a polyline through two or more such points shows how the lens "
            "bent it, from which the calibration estimates the lens distortion (drag a middle point with Select, "
            "remove it with Delete)"),
    Binding("Shift+click (Segment X, Y, Z)", "a polyline along one edge, point by point: a stroke released (or a "
            "click) with Shift held goes on from there, each Shift+click adds a middle point, a click without Shift "
            "ends it at its last point (Esc cancels)"),
    Binding("M", "Marker: a click places the marker named in the toolbar's field (a new name makes a new marker; "
            "the first is the origin until another is chosen). The field offers the first marker placed in other "
            "photos that this photo lacks, in the order of first placement (highlighted in the Calibration tab's "
            "list), and after each click the next one after it, then a new name (M1, M2, …); a marker's name in the "
            "Calibration tab picks it for the next click",
            (Chord(glfw.KEY_M, "set_tool", ("marker",)),)),
    Binding("], [; Shift+M; F2", "the Marker tool's offer: the next, the previous marker this photo lacks (then a "
            "new name, round); a new name at once; the cursor in the toolbar's name field to type a name (what it "
            "held selected; Enter, or the click in the photo that places the marker, ends the typing)",
            (Chord(glfw.KEY_RIGHT_BRACKET, "step_marker_offer", (1,)),
             Chord(glfw.KEY_LEFT_BRACKET, "step_marker_offer", (-1,)),
             Chord(glfw.KEY_M, "offer_new_marker", mods=SHIFT), Chord(glfw.KEY_F2, "type_marker_name"))),
    Binding("Ctrl+D; Tab (in its fields); Ctrl+Enter (in its fields)", "a reference distance from the keyboard: "
            "the cursor in the Calibration tab's first marker field; the next field (the second marker, the "
            "metres); add the distance (the row is emptied and keeps the cursor for the next one)",
            (Chord(glfw.KEY_D, "type_distance", mods=CTRL),)),
    Binding("E", "Edge: press and drag along an edge of the selected primitive: an edge observation (drawn red) on "
            "the nearest projected edge", (Chord(glfw.KEY_E, "set_tool", ("edge",)),)),
    Binding("K", "Known length: press on one end of an edge along an axis whose length is known (a vertical's foot "
            "on the floor first, or an edge on the floor), drag to its other end, release; then type its axis, metres "
            "and σ (optional) in the Scale tab and press Add length", (Chord(glfw.KEY_K, "set_tool", ("length",)),)),
    Binding("R", "Relate: click a face of a node in the photo (it is highlighted), then a face of another node "
            "(Shift+click picks a projected edge instead); then, in the popup or by key, Flush (the first face "
            "against the second, facing it, with the offset typed in metres) or Aligned (coplanar faces facing the "
            "same way, or collinear edges); the Model tab lists the relations with their residuals",
            (Chord(glfw.KEY_R, "set_tool", ("relate",)),)),
    Binding("F, A (two faces picked with Relate)", "make them flush (F) or aligned (A); Esc cancels",
            (Chord(glfw.KEY_A, "relate_choose", ("aligned",)),)),
    Binding("T", "Measure: click two points on the model (distance), T again a point (height above the floor), T "
            "again an object (its dimensions); each with its 1σ and 95 % interval from the solve, drawn over the photo "
            "and added to the project's analyses (the report shows them). With no solved model, on a calibrated photo "
            "alone: a height (its foot on the floor, then its top), T again a distance on the floor (two points), and "
            "so on; the message line names each point to click", (Chord(glfw.KEY_T, "measure_cycle"),)),
    Binding("X", "Evidence marker: a click on a surface places the next marker (E1, E2, …), a click on a marker "
            "removes it", (Chord(glfw.KEY_X, "set_tool", ("evidence",)),)),
    Binding("J", "Trajectory: click the entry hole, then the exit hole: the path and its uncertainty cone (from the "
            "holes' 1σ in the solve), drawn and added to the analyses",
            (Chord(glfw.KEY_J, "set_tool", ("trajectory",)),)),
    Binding("H", "Room: click the floor's corners in turn where they meet the walls (each snaps to where two marked "
            "lines meet, or else to the image corner, within a few px; Alt: exactly where clicked), then the first "
            "corner again or Enter to close the floor; then "
            "click a wall's top straight above a corner, or type the height in the Model tab. The room appears with "
            "its corners fixed where clicked; untick in the Model tab (walls) each wall the photos do not show",
            (Chord(glfw.KEY_H, "set_tool", ("room",)),)),
    Binding("O", "Opening: on a wall of the selected room, click a doorway's or a window's two bottom corners, then "
            "its top: its place, width, height and sill (a bottom on the floor makes a doorway)",
            (Chord(glfw.KEY_O, "set_tool", ("opening",)),)),
    Binding("B", "Box: click three corners of its footprint in turn round it, on the floor, a room's floor or a "
            "box's top (it stands on what it was clicked on), then its top straight above a corner, or type the height",
            (Chord(glfw.KEY_B, "set_tool", ("box",)),)),
    Binding("U", "clear the measurements drawn over the photo (the analyses stay in the project)",
            (Chord(glfw.KEY_U, "clear_measures"),)),
    Binding("Delete", "Delete: click a segment, a middle point, a marker, a known length or a drawn edge to remove it",
            (Chord(glfw.KEY_DELETE, "set_tool", ("delete",)),)),
    Binding("Esc", "Select (also cancels a drag or stroke): press on a vertex and drag, the solver fits the model on "
            "every move; press on a segment's end or middle point or a marker and drag to move it; click an edge to "
            "select its primitive", (Chord(glfw.KEY_ESCAPE, "escape"),)),
    Binding("F", "fix the vertex under the cursor where it is seen, or unfix it",
            (Chord(glfw.KEY_F, "fix_under_cursor"),)),
    Binding("L", "labels over the photo (residuals, vertex names) on or off; markers' names stay",
            (Chord(glfw.KEY_L, "toggle_labels"),)),
    Binding("V", "the Layers popup: each layer over the photo (segments, residuals, markers, model, vanishing "
            "points) shown or hidden, and its labels: none, on hover and on the selection, or all",
            (Chord(glfw.KEY_V, "toggle_layers"),)),
    Binding("I", "name every corner and face of the selected primitive on the photo, by where it is seen from the "
            "photo's camera (front-left-bottom · v0), or stop; a click (Select) on a corner or face, in the photo or "
            "the 3-D preview, names that one", (Chord(glfw.KEY_I, "toggle_names"),)),
    Binding("Ctrl+L", "laser scans in the 3-D preview on or off (shown where the project has any)",
            (Chord(glfw.KEY_L, "toggle_preview_scans", mods=CTRL),)),
    Binding("Shift", "magnifier (6 window pixels per photo pixel, a crosshair, the stroke being drawn and the "
            "sub-pixel position; always on with the Segment, Marker, Edge and Known length tools)"),
    Binding("Alt (held while placing)", "place a click, a segment, a marker or a segment's end exactly where the "
            "cursor is: without it a mark within 3 px of an image corner or edge snaps to it (a drawn segment to the "
            "image line it covers, with its σ from the fit; a dragged vertex, on release, to an image corner), and the "
            "status line says how far it moved"),
    Binding("D", "detect the photo's straight edges and propose them as vanishing segments, dashed in their axis' "
            "colour, world x as the markers shared with other photos show it (else to the right); D again turns x "
            "to the next of right, left, away, toward (the arrows show it)",
            (Chord(glfw.KEY_D, "detect_here"),)),
    Binding("Shift+D", "detect on every photo and propose the segments, each photo's world x chosen so that the "
            "photos agree through the markers they share (three or more shared between photos: place markers first)",
            (Chord(glfw.KEY_D, "detect_everywhere", mods=SHIFT),)),
    Binding("W", "suggest, in every calibrated photo, the markers placed in the other calibrated photos (N on each)",
            (Chord(glfw.KEY_W, "suggest_markers_everywhere"),)),
    Binding("Q", "accept every proposal on every photo (one undoable edit)",
            (Chord(glfw.KEY_Q, "accept_everywhere"),)),
    Binding("N, Shift+N", "suggest markers in this calibrated photo (dashed circles): the markers placed in other "
            "calibrated photos, triangulated or found along their epipolar lines; Shift+N: new markers at feature "
            "points matched with the other calibrated photos and checked against their epipolar geometry",
            (Chord(glfw.KEY_N, "suggest_markers_here"), Chord(glfw.KEY_N, "suggest_markers_here", (True,), SHIFT))),
    Binding("P", "propose pins: the image corner near each model vertex in view (dashed squares)",
            (Chord(glfw.KEY_P, "suggest_pins_here"),)),
    Binding("Enter; click (Select); click (Delete); C", "accept every proposal on the photo (one undoable "
            "edit; with the Room tool, close the floor's outline); accept the one clicked; reject the one "
            "clicked; drop them all",
            (Chord(glfw.KEY_ENTER, "accept_all_here"),
             Chord(glfw.KEY_C, "clear_proposals_here"))),
    Binding("PageUp / PageDown", "previous / next photo (or click its thumbnail)",
            (Chord(glfw.KEY_PAGE_UP, "step_photo", (-1,)), Chord(glfw.KEY_PAGE_DOWN, "step_photo", (1,)))),
    Binding("F1, ? (Shift+/)", "help: this list of every key and mouse input, over the screen (Esc, F1 or ? closes it)",
            (Chord(glfw.KEY_F1, "toggle_help"), Chord(glfw.KEY_SLASH, "toggle_help", mods=SHIFT))),
    Binding("Tab", "first steps: the guided sequence (the axes, x, y and up lines, markers, a distance, calibrate, the "
            "floor, a first object), each step ticked by itself when done; shown or hidden",
            (Chord(glfw.KEY_TAB, "toggle_guide"),)),
    Binding("Ctrl+O; files dropped onto the window", "add photos: a file browser in the window (folders, Up, the "
            "image and RAW files vebuild reads; click files to pick them, then Add); image files (or a folder of "
            "them) dropped onto the window are added too", (Chord(glfw.KEY_O, "open_browser", mods=CTRL),)),
    Binding("Ctrl+Z, Ctrl+Y (Ctrl+Shift+Z), Ctrl+S", "undo, redo, save",
            (Chord(glfw.KEY_Z, "undo", mods=CTRL), Chord(glfw.KEY_Y, "redo", mods=CTRL),
             Chord(glfw.KEY_Z, "redo", mods=CTRL | SHIFT), Chord(glfw.KEY_S, "save", mods=CTRL))),
])


def tool_key(tool: str) -> str:
    """The key that picks a tool, as written (the Select tool is Esc's)."""
    chord = EDITOR_KEYS.chord_for("escape") if tool == "select" else EDITOR_KEYS.chord_for("set_tool", tool)
    chord = EDITOR_KEYS.chord_for("measure_cycle") if tool == "measure" else chord
    return chord.label if chord is not None else ""
