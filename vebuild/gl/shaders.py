"""Shader programs, loaded by name from the top-level ``shaders/`` folder (shaders/README.md)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import moderngl

from vebuild.errors import VebuildError
from vebuild.resources import data_dir

_STAGES = {"vert": "vertex_shader", "geom": "geometry_shader", "frag": "fragment_shader"}
_cache: dict[tuple[int, str, tuple[tuple[str, str], ...]], moderngl.Program] = {}


class ShaderError(VebuildError):
    """A shader file is missing or does not compile (a broken installation, not bad input)."""


def shader_dir() -> Path:
    return data_dir("shaders")


def load_program(ctx: moderngl.Context, name: str, defines: Mapping[str, object] | None = None,
                 vertex: str | None = None) -> moderngl.Program:
    """The program ``NAME.vert`` (+ ``NAME.geom``) + ``NAME.frag``, compiled once per context.

    ``vertex`` names a shared vertex stage instead (``fullscreen``: one triangle over the
    viewport). ``defines`` become ``#define KEY VALUE`` lines after each stage's ``#version`` line.
    """
    key_defs = tuple(sorted((k, str(v)) for k, v in (defines or {}).items()))
    key = (id(ctx), f"{vertex or name}+{name}", key_defs)
    if key in _cache:
        return _cache[key]
    folder = shader_dir()
    sources = {}
    for ext, arg in _STAGES.items():
        path = folder / f"{vertex if (vertex and ext == 'vert') else name}.{ext}"
        if path.is_file():
            sources[arg] = _with_defines(path.read_text("utf-8"), key_defs)
    if "vertex_shader" not in sources:
        raise ShaderError(f"shader program '{name}' not found: expected {folder / ((vertex or name) + '.vert')}")
    try:
        prog = ctx.program(**sources)
    except Exception as e:
        raise ShaderError(f"shader program '{name}' in {folder} does not compile: {e}") from None
    _cache[key] = prog
    return prog


def forget_context(ctx: moderngl.Context) -> None:
    """Drop the programs compiled for ``ctx`` (a window's context, about to be destroyed)."""
    for key in [k for k in _cache if k[0] == id(ctx)]:
        del _cache[key]


def _with_defines(source: str, defines: tuple[tuple[str, str], ...]) -> str:
    if not defines:
        return source
    first, _, rest = source.partition("\n")
    if not first.startswith("#version"):
        raise ShaderError(f"a shader must start with its #version line, found {first!r}")
    return first + "\n" + "".join(f"#define {k} {v}\n" for k, v in defines) + rest
