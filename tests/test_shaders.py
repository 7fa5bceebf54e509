"""Shader loading: a broken shader's compile error names the file and the line its author wrote."""

from __future__ import annotations

import re

import pytest

from vebuild.gl import headless_context, shaders
from vebuild.gl.shaders import ShaderError, load_program

_VERT = "#version 330\nin vec2 pos;\nvoid main() { gl_Position = vec4(pos, 0.0, 1.0); }\n"
# The undeclared name sits on line 5 of the file as written.
_BROKEN_FRAG = ("#version 330\n"
                "out vec4 colour;\n"
                "\n"
                "void main() {\n"
                "    colour = vec4(undeclared_name, 1.0);\n"
                "}\n")


@pytest.mark.parametrize("defines", [None, {"MODE": 2, "SCALE": "1.5"}])
def test_a_compile_error_names_the_file_and_the_authors_line(tmp_path, monkeypatch, defines):
    (tmp_path / "broken.vert").write_text(_VERT, "utf-8")
    (tmp_path / "broken.frag").write_text(_BROKEN_FRAG, "utf-8")
    monkeypatch.setattr(shaders, "shader_dir", lambda: tmp_path)
    with pytest.raises(ShaderError) as err:
        load_program(headless_context(), "broken", defines)
    message = str(err.value)
    path = re.escape(str(tmp_path / "broken.frag"))
    # Injected #define lines must not shift the number: `#line` restores the author's numbering.
    assert re.search(path + r":5\b", message), message
    assert "undeclared_name" in message
    assert "broken.vert:" not in message  # the vertex stage compiled; only the failing file is named
