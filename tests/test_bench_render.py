"""``vebuild bench render --quick``: the figures it reports (their names and that they are sane
numbers; speed itself is the benchmark's business, not a test's). pyrender is optional: each
reference figure is either measured or marked unavailable with a reason."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest

from vebuild.bench import BENCHES
from vebuild.bench import render as bench
from vebuild.gl import headless_context

#: The tests that share `figures` run in one pytest-xdist worker (`--dist loadgroup`, pyproject's
#: addopts), so that it is computed once, not once per worker.
SHARES_FIGURES = pytest.mark.xdist_group("bench_render.figures")


@pytest.fixture(scope="module")
def figures() -> dict[str, Any]:
    return bench.run(quick=True, progress=False)


def _positive(fig: dict[str, Any], key: str) -> None:
    v = fig[key]
    assert isinstance(v, int | float) and not isinstance(v, bool), key
    assert math.isfinite(v) and v > 0, f"{key} = {v}"


def test_registered() -> None:
    assert BENCHES["render"] is bench


@SHARES_FIGURES
def test_quick_figures(figures: dict[str, Any]) -> None:
    json.dumps(figures)  # what --json writes
    assert (figures["width"], figures["height"]) == (1280, 720)
    for scene in bench.SCENES:
        for key in ("primitives", "faces", "triangles", "pages", "texels_millions"):
            _positive(figures, f"{scene}_{key}")
        for lighting in bench.LIGHTINGS:
            case = f"{scene}_{lighting}_mono"
            _positive(figures, f"{case}_frame_loop_fps")
            _positive(figures, f"{case}_render_fps")
            if f"{case}_pyrender_fps" in figures:
                _positive(figures, f"{case}_pyrender_fps")
                _positive(figures, f"{case}_speedup_over_pyrender")
                assert f"{case}_pyrender_unavailable" not in figures
            else:
                why = figures[f"{case}_pyrender_unavailable"]
                assert isinstance(why, str) and why
        _positive(figures, f"{scene}_shadows_mono_render_shadows_redrawn_fps")
    assert figures["primitives200_primitives"] == 201  # 200 and the floor
    _positive(figures, "frame_loop_mono_no_shadows_fps_min")
    assert isinstance(figures["goal_frame_loop_met"], bool)
    if "speedup_over_pyrender_min" in figures:
        _positive(figures, "speedup_over_pyrender_min")
        assert isinstance(figures["goal_speedup_met"], bool)


@SHARES_FIGURES
def test_same_image_as_the_reference(figures: dict[str, Any]) -> None:
    """Where pyrender ran, it drew the same picture (same camera, triangles and textures)."""
    for scene in bench.SCENES:
        key = f"{scene}_unlit_mono_mean_abs_diff_levels"
        if key not in figures:
            continue
        assert figures[key] < 3.0
        assert abs(figures[f"{scene}_unlit_mono_foreground_share"]
                   - figures[f"{scene}_unlit_mono_pyrender_foreground_share"]) < 0.01


@SHARES_FIGURES
def test_table(figures: dict[str, Any]) -> None:
    text = bench.table(figures)
    assert "frame loop" in text and "200 primitives" in text and "goal" in text
    # Without the reference the table says so and still shows vebuild's figures.
    bare = {k: v for k, v in figures.items() if "pyrender" not in k}
    for scene in bench.SCENES:
        for lighting in bench.LIGHTINGS:
            bare[f"{scene}_{lighting}_mono_pyrender_unavailable"] = bench.PYRENDER_MISSING
    bare["pyrender_version"] = None
    text = bench.table(bare)
    assert bench.PYRENDER_MISSING in text and "not measured" in text


@SHARES_FIGURES
def test_vebuild_context_works_afterwards(figures: dict[str, Any]) -> None:
    """The bench leaves vebuild's own context current (pyrender's is gone), so GL work after it runs."""
    ctx = headless_context()
    fbo = ctx.simple_framebuffer((8, 8))
    fbo.use()
    fbo.clear(1.0, 0.0, 0.0, 1.0)
    px = np.frombuffer(fbo.read(components=3), np.uint8).reshape(8, 8, 3)
    assert px[0, 0].tolist() == [255, 0, 0]
    fbo.release()


@SHARES_FIGURES
def test_frame_loop_beside_the_floor(figures: dict[str, Any]) -> None:
    """Each frame-loop setting's fps and its share of the floor program's, with the goals judged."""
    for name in bench.FRAME_SETTINGS.values():
        _positive(figures, f"frame_fps_{name}")
        share = figures[f"frame_share_of_floor_{name}"]
        _positive(figures, f"frame_share_of_floor_{name}")
        assert share < 20.0  # the floor draws every triangle: a frame cannot be that much cheaper
    for name in bench.FLOOR_NAMES.values():
        _positive(figures, f"frame_fps_floor_{name}")
    assert set(bench.FRAME_GOALS) <= set(bench.FRAME_SETTINGS.values())
    assert isinstance(figures["goal_frame_fps_met"], bool) and isinstance(figures["goal_share_of_floor_met"], bool)
    text = bench.table(figures)
    assert "frame loop vs the floor" in text and "example_lit_sun" in text


def test_paired_fps_ratio(monkeypatch: pytest.MonkeyPatch) -> None:
    """The share is floor time over frame time, pair by pair, the median: a frame of twice the
    floor's work is ½, whatever one disturbed pair says. A clock that the draws advance stands in
    for the real one (so that the machine's load cannot enter)."""
    from vebuild.bench import render_floor

    now = [0.0]
    frames = iter([0.004, 0.002, 0.004, 0.002, 0.050, 0.002, 0.004, 0.002, 0.004, 0.002, 0.004, 0.002])

    def draw() -> None:
        now[0] += next(frames)
    monkeypatch.setattr(render_floor.time, "perf_counter", lambda: now[0])
    fps, floor, share = render_floor.paired_fps(draw, draw, 5, 0.0, 5)
    assert share == pytest.approx(0.5)  # the disturbed pair (0.050 s) is outvoted
    assert fps == pytest.approx(250.0) and floor == pytest.approx(500.0)
