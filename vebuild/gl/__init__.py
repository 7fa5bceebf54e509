"""The GL layer (DESIGN.md layer 4): the one place that makes OpenGL contexts and loads shaders;
beside them the two windows' shared parts (:mod:`.window`, the Dear ImGui back end :mod:`.imgui`,
and the application base with key tables :mod:`.app`)."""

from vebuild.gl.context import GLUnavailableError, headless_context, max_texture_size
from vebuild.gl.shaders import load_program

__all__ = ["GLUnavailableError", "headless_context", "load_program", "max_texture_size"]
