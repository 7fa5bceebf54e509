"""No test module imports another: a helper that several tests share lives in a support module
(a tests/*.py whose name does not start with ``test_``), so that it is not tied to one test file
and no test module is imported twice, once by pytest and once under its plain name."""

from __future__ import annotations

import ast
from pathlib import Path

TESTS = Path(__file__).resolve().parent


def imports_of_test_modules(source: str) -> list[tuple[int, str]]:
    """(line, module) of every import of a ``test_*`` module in ``source``, at any depth (inside
    functions and classes too): ``import test_x``, ``from test_x import ...``,
    ``from tests.test_x import ...`` and ``from tests import test_x``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names if _is_test_module(a.name)]
        elif isinstance(node, ast.ImportFrom):
            if node.module and _is_test_module(node.module):
                found.append((node.lineno, node.module))
            else:
                found += [(node.lineno, f"{node.module or '.'}.{a.name}") for a in node.names
                          if a.name.startswith("test_")]
    return sorted(found)


def _is_test_module(dotted: str) -> bool:
    return any(part.startswith("test_") for part in dotted.split("."))


def test_the_check_finds_imports_of_test_modules_at_any_depth() -> None:
    source = (
        "import json\n"
        "from edit_scene import make_plan\n"
        "import test_model\n"
        "from test_export import _validate\n"
        "def test_x():\n"
        "    from test_distortion_solver import barrel_k1\n"
        "    class Inner:\n"
        "        import tests.test_render as r\n"
        "from tests import test_window\n"
    )
    assert imports_of_test_modules(source) == [
        (3, "test_model"), (4, "test_export"), (6, "test_distortion_solver"), (8, "tests.test_render"),
        (9, "tests.test_window")]
    assert imports_of_test_modules("from one_photo_scene import one_photo\nimport pytest\n") == []


def test_no_module_in_tests_imports_a_test_module() -> None:
    files = sorted(TESTS.glob("*.py"))
    assert TESTS / "conftest.py" in files  # the folder the tests live in, not some other
    offending = [f"{path.name}, line {line}: imports {module}"
                 for path in files for line, module in imports_of_test_modules(path.read_text(encoding="utf-8"))]
    assert offending == [], ("these test files import another test module; move the shared helper into "
                             "a support module (a tests/*.py not named test_*) and import it from there:\n"
                             + "\n".join(offending))
