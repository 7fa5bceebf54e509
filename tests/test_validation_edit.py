"""An edit's validation (``validate(..., valid_before=...)``) checks only the list items the edit
brought, and says exactly what a whole validation says about them: the same field (its index in
the document, not in the list checked) and the same words."""

from __future__ import annotations

import copy
import json

import pytest

from vebuild.errors import ProjectError
from vebuild.project.schema_match import ITEM_LISTS, fast_validator, new_items, plain_item_lists, reference_validator
from vebuild.project.validation import validate
from vebuild.resources import example_project_dir

FILE = "room.vebuild.json"


@pytest.fixture(scope="module")
def example() -> dict:
    return json.loads((example_project_dir() / FILE).read_text("utf-8"))


def test_every_item_list_is_checked_item_by_item():
    """The lists named are all plain item lists in the schema: else an edit of a house would check
    its ten thousand pins again."""
    assert plain_item_lists() == ITEM_LISTS


def _message(data, **kw) -> str | None:
    try:
        validate(data, FILE, **kw)
    except ProjectError as e:
        return str(e)
    return None


def _broken(example, how):
    data = copy.deepcopy(example)
    how(data)
    return data


def _set(path, value):
    def how(data):
        node = data
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value
    return how


def _drop_first_pin_then(how):
    def both(data):
        del data["model"]["pins"][0]  # every later pin moves down one place
        how(data)
    return both


BREAKS = {
    "a pin's uv a word": _set(("model", "pins", 7, "uv"), "here"),
    "a pin without its handle": lambda d: d["model"]["pins"][40].pop("handle"),
    "a new pin with a misspelt key": lambda d: d["model"]["pins"].append(
        {"photo": "p1", "node": "floor", "handel": "v1", "uv": [10.0, 20.0], "fixed": True}),
    "a node's width negative": _set(("model", "nodes", 1, "primitive", "params", "width"), -0.4),
    "a node's joint type unknown": _set(("model", "nodes", 3, "joint", "type"), "glued"),
    "a photo's width a string": _set(("photos", 2, "width"), "1600"),
    "an edge observation's points short": _set(("model", "edge_observations", 5, "points"), [[1.0, 2.0]]),
    "after a removed pin, a later one broken": _drop_first_pin_then(_set(("model", "pins", 90, "fixed"), "yes")),
    "a marker outside the lists broken": _set(("markers", 0, "name"), 5),
}
#: Breaks that the values' check finds before the schema is asked (no JSON has a NaN or a lone
#: surrogate: the schema's validators are not asked about them).
VALUE_BREAKS = {
    "a pin's uv not finite": _set(("model", "pins", 12, "uv", 1), float("nan")),
    "after a removed pin, a later one's uv infinite": _drop_first_pin_then(_set(("model", "pins", 30, "uv", 0),
                                                                                 float("inf"))),
    "a pin taken out and put back at the end, not finite": lambda d: d["model"]["pins"].append(
        {**d["model"]["pins"].pop(3), "uv": [float("nan"), 1.0]}),
    "a new node's name a lone surrogate": lambda d: d["model"]["nodes"].append(
        {**copy.deepcopy(d["model"]["nodes"][1]), "name": "crate\ud800"}),
}


@pytest.mark.parametrize("name", [*BREAKS, *VALUE_BREAKS])
def test_an_edits_check_says_what_the_whole_check_says(example, name):
    data = _broken(example, {**BREAKS, **VALUE_BREAKS}[name])
    whole = _message(data)
    assert whole is not None, "the break is one the validation finds"
    assert _message(data, valid_before=example) == whole


def test_unchanged_and_moved_items_are_not_checked_again_and_the_document_is_untouched(example):
    data = copy.deepcopy(example)
    del data["model"]["pins"][0]
    data["model"]["nodes"][2]["primitive"]["params"]["height"] = 0.9
    snapshot = copy.deepcopy(data)
    checked, where = new_items(data, example)
    assert where[("model", "pins")] == [] and checked["model"]["pins"] == []
    assert where[("model", "nodes")] == [2] and checked["model"]["nodes"] == [data["model"]["nodes"][2]]
    assert where[("photos",)] == [] and where[("model", "edge_observations")] == []
    assert data == snapshot
    assert _message(data, valid_before=example) is None


def test_a_pin_dragged_again_is_the_one_item_checked(example):
    """The modelling screen keeps a dragged pin by taking it out and putting it back at the end:
    the pins after it move down one place, the list keeps its length, and only that pin is new."""
    data = copy.deepcopy(example)
    pins = data["model"]["pins"]
    pins.append({**pins.pop(2), "uv": [401.5, 220.25]})
    checked, where = new_items(data, example)
    assert where[("model", "pins")] == [len(pins) - 1] and checked["model"]["pins"] == [pins[-1]]
    assert _message(data, valid_before=example) is None


def test_a_semantic_mistake_in_unchanged_items_is_still_found(example):
    """What the schema cannot say (a pin naming a node that is gone) is checked on the whole
    document, so removing a node its unchanged pins name is refused."""
    data = copy.deepcopy(example)
    gone = data["model"]["pins"][0]["node"]
    data["model"]["nodes"] = [n for n in data["model"]["nodes"] if n["name"] != gone]
    whole = _message(data)
    assert whole is not None and gone in whole
    assert _message(data, valid_before=example) == whole


@pytest.mark.parametrize("name", [None, *BREAKS])
def test_the_compiled_schema_agrees_with_jsonschema(example, name):
    """jsonschema-rs says whether a document matches and jsonschema is asked only where it does
    not: both must agree on every document, valid or broken (the loader's fuzz tries many more)."""
    data = example if name is None else _broken(example, BREAKS[name])
    assert fast_validator().is_valid(data) == (not list(reference_validator().iter_errors(data)))
