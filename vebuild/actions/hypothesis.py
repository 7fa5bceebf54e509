"""Hypotheses: named arrangements of the objects, kept apart from the measured scene.

A hypothesis (FORMAT.md, ``hypotheses``) records, for each object moved, the joint it has in that
arrangement; the measured model (``model``) is never changed by one. Wherever a hypothesis is
shown or rendered it is labelled as such (:func:`label`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from vebuild.errors import ProjectError
from vebuild.model.scene import Model
from vebuild.project import Project

#: The words put on every image of a hypothesis.
LABEL = "HYPOTHESIS"


def label(name: str) -> str:
    """The text shown with an arrangement that is not the measured scene."""
    return f"{LABEL}: {name} (not the measured scene)"


def find_hypothesis(project: Project, name: str) -> dict[str, Any]:
    hyps = project.data.get("hypotheses", [])
    for h in hyps:
        if h["name"] == name:
            return h
    known = ", ".join(repr(h["name"]) for h in hyps) or "none (save one in `vebuild view`)"
    raise ProjectError(project.path, "$.hypotheses", f"no hypothesis is called {name!r}; the hypotheses are: {known}")


def model_with(model: Model, joints: Mapping[str, Mapping[str, Any]]) -> Model:
    """A copy of ``model`` with the joints of a hypothesis (the measured model is untouched)."""
    from vebuild.viewer.manipulate import ObjectMover

    mover = ObjectMover(model)
    mover.apply(joints)
    return mover.model


def save_hypothesis(project: Project, name: str, joints: Mapping[str, Mapping[str, Any]],
                    description: str = "") -> dict[str, Any]:
    """Add (or replace) the hypothesis ``name`` in the project's data (the caller saves the file)."""
    if not name.strip():
        raise ProjectError(project.path, "$.hypotheses", "a hypothesis needs a name")
    rec: dict[str, Any] = {"name": name.strip(), "joints": {k: dict(v) for k, v in joints.items()}}
    if description:
        rec["description"] = description
    hyps = [h for h in project.data.get("hypotheses", []) if h["name"] != rec["name"]]
    project.data["hypotheses"] = hyps + [rec]
    return rec
