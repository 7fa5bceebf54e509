"""The walk-through viewer (paper §5, Figure 13): walking, picking, moving objects as their joints
allow, hypotheses. :mod:`.collide`, :mod:`.walk` and :mod:`.manipulate` hold the logic as plain
numpy (tested without a window); :mod:`.app` is the glfw window with its Dear ImGui panel.
"""
