"""The walk-through viewer (paper §5, Figure 13): walking, picking, moving objects as their joints
allow, hypotheses. :mod:`.walk` holds walking as plain numpy (tested without a window); the
arrangements and collisions it uses are modelling logic (:mod:`vebuild.model.arrange`,
:mod:`vebuild.model.collide`); :mod:`.app` is the glfw window with its Dear ImGui panel.
"""
