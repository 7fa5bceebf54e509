"""Shader programs, loaded by name from the top-level ``shaders/`` folder (shaders/README.md)."""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from pathlib import Path

import moderngl
import numpy as np

from vebuild.errors import VebuildError
from vebuild.resources import data_dir

_STAGES = {"vert": "vertex_shader", "geom": "geometry_shader", "frag": "fragment_shader"}
#: Mesa's and most drivers' location prefix: source string 0, line, and (column) on Mesa.
_LOCATION = re.compile(r"^0:(\d+)(?:\((\d+)\))?", re.MULTILINE)
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
    sources: dict[str, str] = {}
    paths: dict[str, Path] = {}
    for ext, arg in _STAGES.items():
        path = folder / f"{vertex if (vertex and ext == 'vert') else name}.{ext}"
        if path.is_file():
            sources[arg] = _with_defines(path.read_text("utf-8"), key_defs)
            paths[arg] = path
    if "vertex_shader" not in sources:
        raise ShaderError(f"shader program '{name}' not found: expected {folder / ((vertex or name) + '.vert')}")
    try:
        prog = ctx.program(vertex_shader=sources["vertex_shader"],
                           geometry_shader=sources.get("geometry_shader"),
                           fragment_shader=sources.get("fragment_shader"))
    except Exception as e:
        raise ShaderError(f"shader program '{name}' does not compile:\n{_located(str(e), paths)}") from None
    _cache[key] = prog
    return prog


def forget_context(ctx: moderngl.Context) -> None:
    """Drop the programs compiled for ``ctx`` (a window's context, about to be destroyed)."""
    for key in [k for k in _cache if k[0] == id(ctx)]:
        del _cache[key]


def _with_defines(source: str, defines: tuple[tuple[str, str], ...]) -> str:
    """``source`` with the defines after its ``#version`` line, and a ``#line 2`` after them so
    that the compiler's line numbers stay the ones the author wrote (GLSL 3.30: the line after
    ``#line N`` is line N)."""
    if not defines:
        return source
    first, _, rest = source.partition("\n")
    if not first.startswith("#version"):
        raise ShaderError(f"a shader must start with its #version line, found {first!r}")
    return first + "\n" + "".join(f"#define {k} {v}\n" for k, v in defines) + "#line 2\n" + rest


def _located(log: str, paths: Mapping[str, Path]) -> str:
    """The compiler's log with each stage's ``0:LINE(COL)`` locations written as ``FILE:LINE:COL``.

    moderngl heads each failing stage's log with the stage's keyword (``fragment_shader``) and a
    rule of ``=``; a log it does not shape so is returned as it came, after the files' names.
    """
    out: list[str] = []
    stage: Path | None = None
    for line in log.splitlines():
        word = line.strip()
        if word in paths:
            stage = paths[word]
            continue
        if stage is None or set(word) == {"="}:
            if word and word != "GLSL Compiler failed" and set(word) != {"="}:
                out.append(line)
            continue
        out.append(_LOCATION.sub(_file_location(stage), line))
    if not any(str(p) in text for text in out for p in paths.values()):
        out.insert(0, "in " + ", ".join(str(p) for p in paths.values()) + ":")
    return "\n".join(text for text in out if text.strip())


def _file_location(path: Path) -> Callable[[re.Match[str]], str]:
    def sub(m: re.Match[str]) -> str:
        return f"{path}:{m[1]}" + (f":{m[2]}" if m[2] else "")
    return sub


def uniform(prog: moderngl.Program, name: str) -> moderngl.Uniform:
    """The program's uniform ``name`` (a ShaderError names it if the program has none such)."""
    member = prog.get(name, None)
    if not isinstance(member, moderngl.Uniform):
        raise ShaderError(f"shader program has no uniform '{name}'")
    return member


def set_uniform(prog: moderngl.Program, name: str, value: object) -> None:
    """Set the uniform ``name`` to ``value`` if the program uses it (the compiler drops unused ones)."""
    member = prog.get(name, None)
    if isinstance(member, moderngl.Uniform):
        member.value = value


def write_uniform(prog: moderngl.Program, name: str, data: bytes) -> None:
    """Write ``data`` (e.g. a float32 matrix's bytes) to the uniform ``name`` if the program uses it."""
    member = prog.get(name, None)
    if isinstance(member, moderngl.Uniform):
        member.write(data)


def set_uniforms(prog: moderngl.Program, **values: object) -> None:
    """Set the uniforms ``prog`` uses: an array is written as float32 bytes, anything else is
    assigned; names the program lacks are skipped (the compiler drops those a MODE does not need)."""
    for name, value in values.items():
        if isinstance(value, np.ndarray):
            write_uniform(prog, name, np.ascontiguousarray(value, dtype="f4").tobytes())
        else:
            set_uniform(prog, name, value)
