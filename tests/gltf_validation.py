"""The Khronos glTF validator (npm package gltf-validator, which .ci/run installs), run on a file
through tests/gltf_validate.mjs by the tests that write glTF."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
VALIDATE = REPO / "tests" / "gltf_validate.mjs"
VALIDATOR_INSTALL = "npm install --no-audit --no-fund --prefix .ci/gltf-validator gltf-validator@2.0.0-dev.3.10"


def validate(path: Path) -> dict:
    """The validator's report on the glTF file at ``path``; fails the test on any error."""
    node = shutil.which("node")
    if node is None:
        pytest.fail(f"Node.js (v18 or later) is needed to run the Khronos glTF validator; install it, then: "
                    f"{VALIDATOR_INSTALL}")
    r = subprocess.run([node, str(VALIDATE), str(path)], capture_output=True, text=True, timeout=120, cwd=REPO)
    if r.returncode == 2:
        pytest.fail(r.stderr.strip())
    report = json.loads(r.stdout)
    issues = report["issues"]
    summary = f"{issues['numErrors']} errors, {issues['numWarnings']} warnings, {issues['numInfos']} infos: " + \
        "; ".join(f"{m['code']} {m.get('pointer', '')}" for m in issues["messages"])
    assert issues["numErrors"] == 0 and r.returncode == 0, summary
    return report
