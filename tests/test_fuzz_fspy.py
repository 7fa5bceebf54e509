"""A property-based fuzz of the fSpy import: whatever an ``.fspy`` file holds, reading it (and
turning its control points into vebuild's marks, and importing it whole) either works or raises a
VebuildError naming the file, never any other exception; a refused import leaves nothing behind.

The files are ones fSpy's releases write (tests/fspy_writer.py: two and one vanishing points, the
third vanishing point, quad mode, the dragged horizon saved as an object, the oldest layout)
mutated in a few places of the state JSON — a value replaced by another of the wrong type or size
(whole numbers of hundreds of digits, 1e400, lists and objects where a name or a number belongs,
pairs of the wrong length, objects keyed "0" and "1"), a key removed — and with a random 16-byte
header (magic, version, state and image sizes) over a state and image cut or padded at random.
VEBUILD_FUZZ_EXAMPLES and VEBUILD_FUZZ_RANDOM work as in tests/test_fuzz_loader.py.
"""

from __future__ import annotations

import copy
import hashlib
import os
import struct
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from fspy_writer import KnownCamera, StateBuilder, as_saved_by, fspy_bytes, make_image
from fuzz_json import Raw, at, dumps, paths
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vebuild.actions.fspy import import_fspy, marks_from_fspy
from vebuild.errors import ProjectError, VebuildError
from vebuild.project.fspy import AXES, UNITS_M, parse_fspy
from vebuild.project.outputs import temporaries

EXAMPLES = int(os.environ.get("VEBUILD_FUZZ_EXAMPLES", 2000))
DERANDOMIZE = os.environ.get("VEBUILD_FUZZ_RANDOM", "") != "1"
W, H = 160, 120
IMAGE = make_image(W, H)


def _bases() -> list[dict[str, Any]]:
    cam = KnownCamera.looking_at_corner(W, H)
    out = []
    for release, kw, saved in [("1.0.2", {}, {}), ("1.0.2", {"mode": "OneVanishingPoint"}, {"horizon_moved": True}),
                               ("1.0.0", {"principal_point_mode": "FromThirdVanishingPoint"}, {}),
                               ("1.0.0", {"quad": True, "principal_point_mode": "Manual"}, {}),
                               ("1.0.0-alpha.1", {"mode": "OneVanishingPoint", "preset": "canon_5d",
                                                  "reference_unit": "Yards"}, {})]:
        b = StateBuilder(cam, np.random.default_rng(1), noise_px=0.0, **kw)
        out.append(as_saved_by(b.build(), release, **saved))
    return out


BASES = _bases()




PATHS = [paths(b)[1:] for b in BASES]
NAMES = sorted(AXES) + sorted(UNITS_M) + ["OneVanishingPoint", "TwoVanishingPoints", "Default", "Manual",
                                          "FromThirdVanishingPoint", "canon_5d", "no_such_camera", "0", "1", "x", "y"]
point = st.fixed_dictionaries({"x": st.floats(-0.5, 1.5), "y": st.floats(-0.5, 1.5)})
scalars = st.one_of(
    st.none(), st.booleans(), st.integers(-(2**70), 2**70), st.integers(30, 600).map(lambda n: 10**n),
    st.sampled_from([0, -1, 1, 2, 0.0, -0.0, 5e-324, 1e-300, 1e300, -1e300, 1e5, 1e-5, 0.5, 65535, 2**32]),
    st.floats(allow_nan=False, allow_infinity=False), st.sampled_from([Raw("1e400"), Raw("-1e999"), Raw('"\\ud800"')]),
    st.text(max_size=5), st.sampled_from(NAMES),
)
values = st.recursive(
    scalars | point,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.sampled_from(NAMES) | st.text(max_size=3),
                                                                         inner, max_size=3),
                            st.fixed_dictionaries({"0": inner, "1": inner})),
    max_leaves=6)


@st.composite
def mutated_state(draw: Any, numbers_only: bool = False) -> str:
    k = draw(st.integers(0, len(BASES) - 1))
    doc = copy.deepcopy(BASES[k])
    for _ in range(draw(st.sampled_from([1, 1, 2, 3]))):
        path = draw(st.sampled_from(PATHS[k]))
        found = at(doc, path)
        if found is None:
            continue  # an earlier mutation changed it
        parent, target = found
        if numbers_only:
            if isinstance(target, bool) or not isinstance(target, int | float):
                continue
            bound = min(4 * abs(float(target)) + 1, 1e300)
            parent[path[-1]] = draw(st.floats(-bound, bound) | st.sampled_from([0, 1e-3, 1e-9, 1e5, 1e9, -1e9, 1e300]))
            continue
        how = draw(st.sampled_from(["replace", "replace", "remove", "pair"]))
        if how == "remove":
            del parent[path[-1]]
        elif how == "pair" and isinstance(target, list):
            parent[path[-1]] = {str(i): v for i, v in enumerate(target)}  # as fSpy's { ...list } saves it
        else:
            parent[path[-1]] = draw(values)
    return dumps(doc, compact=True)


FOLDER = Path(tempfile.mkdtemp(prefix="vebuild-fuzz-fspy-"))
FILE = FOLDER / "fuzz.fspy"
FUZZ = settings(max_examples=EXAMPLES // 2, deadline=None, database=None, derandomize=DERANDOMIZE,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much])


def _read(data: bytes) -> str:
    """The property: the file is read and its marks made, or a ProjectError names the file."""
    try:
        fp = parse_fspy(data, FILE)
        marks_from_fspy(fp)
    except ProjectError as e:
        assert str(e).startswith(str(FILE)) and e.where, e
        return "refused"
    return "read"


@FUZZ
@given(mutated_state())
def test_mutated_state_is_read_or_refused(text: str) -> None:
    _read(fspy_bytes(text.encode("utf-8", "surrogatepass"), IMAGE))


@settings(FUZZ, max_examples=max(EXAMPLES // 40, 10))
@given(mutated_state(numbers_only=True))
def test_mutated_numbers_are_imported_or_refused_leaving_nothing(text: str) -> None:
    """The whole import (calibration included) over states whose numbers are changed: a result, or
    a VebuildError with nothing written (the file unchanged, no output folder, no temporaries)."""
    data = fspy_bytes(text.encode("utf-8"), IMAGE)
    folder = Path(tempfile.mkdtemp(dir=FOLDER))
    src = folder / "scene.fspy"
    src.write_bytes(data)
    out = folder / "out"
    try:
        import_fspy(src, out)
    except VebuildError as e:
        assert str(src) in str(e) or str(out) in str(e), e
        assert sorted(p.name for p in folder.iterdir()) == ["scene.fspy"] and temporaries(folder) == []
    assert hashlib.sha256(src.read_bytes()).digest() == hashlib.sha256(data).digest()


STATE = dumps(BASES[0], compact=True).encode()




def _size(n: int) -> Any:
    """A uint32 of the header: the true size mostly, one off, 0, the largest, or any."""
    return st.sampled_from([n] * 3 + [0, 1, n - 1, n + 1, 2**32 - 1]) | st.integers(0, 2**32 - 1)


@FUZZ
@given(st.sampled_from([b"fspy", b"fspy", b"fspx", b"FSPY", b"\x00\x00\x00\x00", b"fsp"]),
       st.sampled_from([1, 1, 1, 0, 2, 2**32 - 1]) | st.integers(0, 2**32 - 1), _size(len(STATE)), _size(len(IMAGE)),
       st.integers(-len(IMAGE) - len(STATE) - 20, 64))
def test_header_is_read_or_refused(magic: bytes, version: int, state_size: int, image_size: int, cut: int) -> None:
    """Any header over the state and image, cut short or with bytes added."""
    data = magic + struct.pack("<III", version, state_size, image_size) + STATE + IMAGE
    data = data[:len(data) + cut] if cut < 0 else data + bytes(range(cut))
    _read(data)


def test_the_unmutated_bases_are_read() -> None:
    for doc in BASES:
        assert _read(fspy_bytes(doc, IMAGE)) == "read"
