"""The walk-through's keys and mouse (they follow games and 3-D viewers): one table, from which
the window's dispatch, its panel's key list (F1) and the manual's list (docs/manual.md) are made."""

from __future__ import annotations

import math

import glfw

from vebuild.gl.app import CTRL, SHIFT, Binding, Chord, KeyTable

#: The turn of the selected object per Q / E press or wheel step.
TURN_STEP = math.radians(5.0)

VIEWER_KEYS = KeyTable([
    Binding("W A S D, arrows; Shift", "walk at eye height (1.6 m), parallel to the floor; run"),
    Binding("right mouse button, drag", "look around"),
    Binding("F (Space up, C down)", "fly, through everything / walk again", (Chord(glfw.KEY_F, "toggle_fly"),)),
    Binding("left click", "select the object under the cursor (a one-pixel ID buffer of the frame): it is "
            "highlighted, its name, group and joint shown"),
    Binding("left drag", "move it as its joint allows"),
    Binding("wheel, Q / E", "turn the selected object about the vertical",
            (Chord(glfw.KEY_Q, "turn_selection", (TURN_STEP,)), Chord(glfw.KEY_E, "turn_selection", (-TURN_STEP,)))),
    Binding("Ctrl+Z, Ctrl+Y (Ctrl+Shift+Z)", "undo, redo",
            (Chord(glfw.KEY_Z, "undo", mods=CTRL), Chord(glfw.KEY_Y, "redo", mods=CTRL),
             Chord(glfw.KEY_Z, "redo", mods=CTRL | SHIFT))),
    Binding("R, Shift+R", "put the selected object, or all, back where they were measured",
            (Chord(glfw.KEY_R, "reset", (False,)), Chord(glfw.KEY_R, "reset", (True,), SHIFT))),
    Binding("Esc", "cancel a drag, or clear the selection", (Chord(glfw.KEY_ESCAPE, "escape"),)),
    Binding("V / Shift+V, P / Shift+P", "next / previous named view; photo (its calibrated camera, letterboxed "
            "to its shape, the photo over the view)",
            (Chord(glfw.KEY_V, "step_view", (1,)), Chord(glfw.KEY_V, "step_view", (-1,), SHIFT),
             Chord(glfw.KEY_P, "step_photo", (1,)), Chord(glfw.KEY_P, "step_photo", (-1,), SHIFT))),
    Binding("G", "the floor (z = 0) as a grid 1 m apart and the axes at the origin (x red, y green, z blue), drawn "
            "through the camera's lens; off a photo's camera also each calibrated photo's camera as its frustum. On "
            "at first for a project with no model, which opens at its first calibrated photo",
            (Chord(glfw.KEY_G, "toggle_floor"),)),
    Binding("[ and ]", "photo overlay opacity",
            (Chord(glfw.KEY_LEFT_BRACKET, "change_opacity", (-0.1,)),
             Chord(glfw.KEY_RIGHT_BRACKET, "change_opacity", (0.1,)))),
    Binding("L", "next lighting preset (as photographed, then the project's presets)",
            (Chord(glfw.KEY_L, "next_lighting"),)),
    Binding("U", "surfaces no photo saw: hatched, tinted, as extracted (the texture filled in, unmarked)",
            (Chord(glfw.KEY_U, "next_unobserved"),)),
    Binding("B", "next stereo mode (off, anaglyph, side by side, top and bottom, quad-buffered where offered)",
            (Chord(glfw.KEY_B, "next_stereo"),)),
    Binding("K", "show or hide the registered laser scans (points; shown where the project has any)",
            (Chord(glfw.KEY_K, "toggle_scans"),)),
    Binding("T", "measure by clicking: distance between two surface points, then (T again) height of a point above "
            "the floor, then an object's dimensions, then off; each with 1σ and 95 % interval, drawn and saved as an "
            "analysis of the project. With no solved model, on a photo shown at its camera (P): a height (its foot on "
            "the floor, then its top), T again a distance on the floor, and so on, measured on the photo alone",
            (Chord(glfw.KEY_T, "measure_cycle"),)),
    Binding("M", "evidence markers: a click on a surface places the next (E1, E2, …), a click on one removes it "
            "(saved in the project); M again: off", (Chord(glfw.KEY_M, "marker_tool"),)),
    Binding("J, H", "trajectory: click the entry hole, then the exit hole (its cone from the holes' 1σ in the "
            "solve), or H: from the entry hole along the view; drawn and saved as an analysis",
            (Chord(glfw.KEY_J, "trajectory_tool"), Chord(glfw.KEY_H, "trajectory_along_view"))),
    Binding("N", "clear the clicked measurements from the view (they stay saved)",
            (Chord(glfw.KEY_N, "clear_measures"),)),
    Binding("F1", "show or hide the panel", (Chord(glfw.KEY_F1, "toggle_panel"),)),
    Binding("F11, Tab", "present: full screen (F11) or in the window (Tab), the panel hidden and a legend shown "
            "(hypothesis, unobserved surfaces, scale bar); again: back",
            (Chord(glfw.KEY_F11, "toggle_fullscreen"), Chord(glfw.KEY_TAB, "toggle_presentation"))),
    Binding("F12", "screenshot with provenance (labelled if a hypothesis is shown)",
            (Chord(glfw.KEY_F12, "screenshot"),)),
])
