"""Hypotheses: named arrangements of the objects, kept apart from the measured scene.

A hypothesis (FORMAT.md, ``hypotheses``) records, for each object moved, the joint it has in that
arrangement; the measured model (``model``) is never changed by one. Wherever a hypothesis is
shown or rendered it is labelled as such (:func:`label`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from vebuild.errors import ProjectError, VebuildError
from vebuild.model.scene import Model, ModelError
from vebuild.project import Project
from vebuild.project.decode import located

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


def model_with(model: Model, joints: Mapping[str, Mapping[str, Any]], where: str = "$.hypotheses") -> Model:
    """A copy of ``model`` with the joints of a hypothesis (the measured model is untouched).

    ``where``: the hypothesis' JSON path, for the messages (:func:`applied_hypothesis` adds the file).
    """
    from vebuild.model.arrange import ObjectMover

    mover = ObjectMover(model)
    mover.apply(joints, where)
    return mover.model


def hypothesis_model(project: Project, model: Model, name: str) -> Model:
    """A copy of ``model`` arranged as the project's hypothesis ``name``, checked.

    Raises ProjectError naming the file and ``$.hypotheses[i].joints.NODE`` where a joint cannot be
    applied (another joint type, a value outside the node's joint limits).
    """
    rec = find_hypothesis(project, name)
    return applied_hypothesis(project, model, project.data["hypotheses"].index(rec))


def applied_hypothesis(project: Project, model: Model, i: int) -> Model:
    """``model`` arranged as ``$.hypotheses[i]`` (a copy), every error a ProjectError with its path."""
    where = f"$.hypotheses[{i}]"
    rec = project.data["hypotheses"][i]
    try:
        return model_with(model, rec["joints"], where)
    except ModelError as e:
        raise located(project, e, f"{where}.joints") from None
    except ProjectError:
        raise
    except VebuildError as e:
        raise ProjectError(project.path, f"{where}.joints", str(e)) from None


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
