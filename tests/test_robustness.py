"""Bad sizes, layouts and numbers get a VebuildError naming where they came from, never a crash in
native code, a traceback or a half-written file."""

from __future__ import annotations

import json
import re
import shutil
import warnings
from pathlib import Path

import pytest

from vebuild.cli import main
from vebuild.errors import VebuildError
from vebuild.render.sizes import MAX_PIXELS, MAX_SIDE, check_gl_render_size, check_render_size

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"


@pytest.fixture
def room(tmp_path):
    """A copy of the example room (not calibrated: the size checks come before any of that)."""
    folder = tmp_path / "room"
    shutil.copytree(ROOM, folder)
    return folder / "room.vebuild.json"


def _set_view(proj: Path, index: int, width: int, height: int) -> None:
    data = json.loads(proj.read_text())
    data["views"][index].update(width=width, height=height)
    proj.write_text(json.dumps(data))


# -- render sizes ----------------------------------------------------------------------------------

def test_check_render_size_names_the_source_and_the_limits():
    assert check_render_size(1280, 720, "--size") == (1280, 720)
    assert check_render_size(MAX_SIDE, MAX_PIXELS // MAX_SIDE, "x") == (MAX_SIDE, 4096)
    for (w, h), what in [((0, 10), "each side 1 to 16384"), ((20000, 1), "each side 1 to 16384"),
                         ((960, 96_000_000), "each side 1 to 16384"), ((10000, 10000), "at most 67,108,864 pixels"),
                         ((1.5, 10), "a whole number of pixels"), ((True, 10), "a whole number of pixels")]:
        with pytest.raises(VebuildError, match=r"^\$\.views\[2\] \(width × height\): .*" + what):
            check_render_size(w, h, "$.views[2] (width × height)")

    class _Ctx:
        info = {"GL_MAX_TEXTURE_SIZE": 8192, "GL_MAX_RENDERBUFFER_SIZE": 16384, "GL_MAX_VIEWPORT_DIMS": (16384, 16384)}
    with pytest.raises(VebuildError, match=r"--size: .*each side 1 to 8192 pixels \(the most this machine's OpenGL"):
        check_gl_render_size(_Ctx(), 9000, 100, "--size")


@pytest.mark.parametrize(("size", "message"), [
    ((1, 60000), r"\$\.views\[0\] \(width × height\): a 1×60000 image cannot be rendered"),
    ((20000, 1), r"\$\.views\[0\] \(width × height\): a 20000×1 image cannot be rendered: expected each side 1 to "
                 r"16384 pixels"),
    ((40000, 40000), r"\$\.views\[0\] \(width × height\): a 40000×40000 image"),
])
def test_a_view_too_large_to_render_is_refused_naming_the_view(room, tmp_path, capsys, size, message):
    _set_view(room, 0, *size)
    out = tmp_path / "x.png"
    assert main(["render", str(room), "--view", "doorway", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "--size" not in err, err
    assert re.search(message, err), err
    assert not out.exists()


def test_the_report_refuses_a_view_whose_image_would_be_too_tall(room, tmp_path, monkeypatch):
    from vebuild.project import load_project
    from vebuild.report.write import write_report

    project = load_project(room)
    project.data["calibration"] = {"cameras": {"p1": {}}}  # the size check comes before any use of it
    project.data["views"][2].update(width=1, height=100000)
    for section in ("photos", "calibration", "model"):  # only the views' section matters here
        monkeypatch.setattr(f"vebuild.report.sections.{section}", lambda project, rep: None)
    with pytest.raises(VebuildError) as e:
        write_report(project, tmp_path / "r", pdf=False)
    assert "the report's image of view 'overview' (960 pixels wide, its height from the aspect of $.views[2], " \
           "1×100000): a 960×96000000 image cannot be rendered" in str(e.value)
    assert "--size" not in str(e.value)
    assert not (tmp_path / "r").exists() and not (tmp_path / ".r.tmp").exists()


def test_a_video_frame_too_large_names_the_view_or_the_option(room, tmp_path, capsys):
    _set_view(room, 0, 20000, 2)
    out = tmp_path / "v.mp4"
    assert main(["video", str(room), "--views", "doorway,overview", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    # refused on loading, as `vebuild check` refuses it (one decoder, one answer)
    assert "$.views[0] (width × height): a 20000×2 image cannot be rendered" in err, err
    assert "Traceback" not in err and not out.exists()
    _set_view(room, 0, 1280, 720)
    assert main(["video", str(room), "--views", "overview,doorway", "--size", "8000x6000", "--stereo", "sbs",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--size, in stereo side by side (twice the width): a 16000×6000 image cannot be rendered" in err, err
    assert not out.exists()


# -- recorded analyses -----------------------------------------------------------------------------

class _Rep:
    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.images: list[Path] = []
        self.recorded: dict = {}  # the analyses run once already (none here): the report's Report has it


@pytest.mark.parametrize(("command", "message"), [
    (["distance", "--help"], r"\$\.analyses\[0\]\.command: the command asks for help \('--help'\), which is not an "
                             r"analysis; expected the words of a `vebuild analyse` command"),
    (["-h"], r"asks for help \('-h'\)"),
    (["sightline", "--standing", "1,1", "--object", "box", "-h"], r"asks for help"),
    (["distance"], r"\$\.analyses\[0\]\.command: the following arguments are required: a, b"),
    (["sightline", "--standing", "1,1", "--object", "box", "--samples", "many"], r"invalid .*'many'"),
    (["sightline", "--standing", "1,1", "--object", "box", "--size", "40000x40000"],
     r"\$\.analyses\[0\]\.command: --size: a 40000×40000 image cannot be rendered"),
])
def test_recorded_analyses_never_print_help_or_exit(room, tmp_path, capsys, command, message):
    from vebuild.project import load_project
    from vebuild.report.analyses import analyses_html as analyses

    project = load_project(room)
    (tmp_path / "images").mkdir()
    with pytest.raises(VebuildError, match=message):
        analyses(project, _Rep(tmp_path), [{"name": "n", "command": command}])
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""
    assert not (tmp_path / "figures" / "analysis-1.json").exists()


def test_a_report_with_a_recorded_help_fails_with_status_2(room, tmp_path, capsys, monkeypatch):
    from vebuild.report import write as report

    data = json.loads(room.read_text())
    data["analyses"] = [{"name": "help", "command": ["distance", "--help"]}]
    room.write_text(json.dumps(data))
    monkeypatch.setattr(report, "write_report", _report_without_renders(report.write_report, monkeypatch))
    assert main(["report", str(room), "--out", str(tmp_path / "r"), "--no-pdf", "--quiet"]) == 2
    err = capsys.readouterr()
    assert "$.analyses[0].command: the command asks for help ('--help')" in err.err and "usage" not in err.out
    assert "Traceback" not in err.err and not (tmp_path / "r").exists()


def _report_without_renders(write_report, monkeypatch):
    """The report with only its analyses section (the others need a solved, textured project)."""
    from vebuild.report import sections

    def run(project, out, pdf=True, progress=None):
        project.data.setdefault("calibration", {"cameras": {"p1": {}}})
        for section in ("photos", "calibration", "model", "views", "validation", "hypotheses"):
            monkeypatch.setattr(sections, section, lambda project, rep: None)
        return write_report(project, out, pdf, progress)
    return run


# -- texture layout --------------------------------------------------------------------------------

def _boxes(n: int, side_m: float, first_width_m: float | None = None):
    from vebuild.model.scene import model_from_dict

    return model_from_dict([
        {"name": f"box{i}", "primitive": {"type": "box", "params": {
            "width": first_width_m if (i == 0 and first_width_m is not None) else side_m,
            "depth": side_m, "height": side_m}},
         "joint": {"type": "fixed", "translation": [0, 0, 0], "rotation_deg": [0, 0, 0]}} for i in range(n)])


def test_a_face_of_no_finite_size_is_named():
    from vebuild.texture import layout as lay

    with pytest.warns(RuntimeWarning), pytest.raises(VebuildError, match=r"node 'box0' face '\w+': its chart is "
                                                                          r"nan m × nan m, not a finite size"):
        lay.layout(_boxes(1, 1.0, first_width_m=1e308), 200.0, 2048, 4096)


def test_an_atlas_too_large_is_refused_before_anything_is_allocated():
    from vebuild.texture import layout as lay

    model = _boxes(300, 20.0)
    with pytest.raises(VebuildError) as e:
        lay.layout(model, 100.0, 2048, 4096)
    msg = str(e.value)
    assert re.search(r"the texture atlas would need [\d,]+ texels on \d+ page\(s\) of at most 4096² \([\d.]+ GiB", msg)
    assert f"more than the limit of {lay.MAX_ATLAS_TEXELS:,} texels" in msg
    assert "node 'box0' face 'front' 2000×2000 texels (20 m × 20 m)" in msg
    fit = float(re.search(r"Lower --density \(texels per metre\) to ([\d.]+) or less", msg)[1])
    faces = lay.layout(model, fit, 2048, 4096)  # the density it suggests fits
    assert sum(w * h for w, h in lay.page_sizes(faces)) <= lay.MAX_ATLAS_TEXELS
    with pytest.raises(VebuildError, match="Lower --density"):
        lay.layout(model, fit * 1.05, 2048, 4096)
    with pytest.raises(VebuildError, match="too many to texture even at one texel each"):
        lay.layout(model, 1.0, 2048, 4096, max_texels=1000)


def test_vebuild_texture_refuses_a_huge_atlas_with_status_2(room, capsys, monkeypatch):
    from vebuild.actions import texture
    from vebuild.texture import layout as lay

    def refuse(project, options, progress=None, timings=None):  # the layout alone, on the project's model
        lay.layout(_boxes(300, 20.0), options.texels_per_metre, options.max_face_texels, 4096)
    monkeypatch.setattr(texture, "texture_project", refuse)
    assert main(["texture", str(room), "--density", "100"]) == 2
    err = capsys.readouterr().err
    assert "the texture atlas would need" in err and "Lower --density" in err and "Traceback" not in err
    assert not (room.parent / "textures").exists()


# -- calibration numerics --------------------------------------------------------------------------

def _calibration_inputs(rng):
    from vebuild.calibration.photo import calibrate_photo
    from vebuild.calibration.positions import PhotoInput
    from vebuild.synthetic import CLICK_NOISE_PX, random_scene

    photos, markers = random_scene(rng, ("3vp", "3vp", "2vp"))
    inputs = []
    for p in photos:
        cal = calibrate_photo(p.segments, p.width, p.height, photo=p.id, click_sigma_px=CLICK_NOISE_PX)
        inputs.append(PhotoInput(p.id, cal.K, cal.R, cal.covariance, dict(p.markers)))
    return inputs, markers


def test_contradicting_scale_distances_are_named_before_the_solve(rng, monkeypatch):
    import numpy as np

    from vebuild.calibration import positions
    from vebuild.calibration.positions import ReferenceDistance, place_cameras

    inputs, markers = _calibration_inputs(rng)
    true = lambda a, b: float(np.linalg.norm(markers[a] - markers[b]))  # noqa: E731
    seen = set.intersection(*(set(p.markers) for p in inputs[:2])) - {"O"}
    m1, m2, *more = sorted(seen)
    a, b = (more[0], m2) if more else (m1, m2)
    good = [ReferenceDistance("O", m1, true("O", m1)), ReferenceDistance(a, b, true(a, b))]
    place_cameras(inputs, origin="O", distances=good)  # consistent: no complaint
    bad = [good[0], ReferenceDistance(a, b, 100.0 * true(a, b))]
    monkeypatch.setattr(positions, "_refine", _no_full_solve)  # refused before it (which took 21–80 s to fail)
    with pytest.raises(VebuildError, match=rf"the scale distances {a}–{b} \([\d.]+ m\) and O–{m1} \([\d.]+ m\) "
                                           r"contradict each other by a factor of (9\d|10\d|11\d)(\.\d+)?: .*Check "):
        place_cameras(inputs, origin="O", distances=bad)


def _no_full_solve(*args, **kwargs):
    raise AssertionError("the full solve was started: contradicting scale distances must be refused before it")


def test_a_non_finite_start_names_the_photo(rng):
    import numpy as np

    from vebuild.calibration.positions import PhotoInput, ReferenceDistance, place_cameras

    inputs, _ = _calibration_inputs(rng)
    p = inputs[1]
    K = p.K.copy()
    K[0, 0] = np.inf
    inputs[1] = PhotoInput(p.id, K, p.R, p.covariance, p.markers)
    m1 = sorted(set(inputs[0].markers) - {"O"})[0]
    with pytest.raises(VebuildError, match=r"photo 'p2': "):
        place_cameras(inputs, origin="O", distances=[ReferenceDistance("O", m1, 1.0)])


def test_a_solve_that_meets_a_non_finite_residual_names_the_observation():
    import numpy as np

    from vebuild.camera import ImageCamera
    from vebuild.model.residuals import Pin
    from vebuild.model.scene import model_from_dict
    from vebuild.model.solver import Problem
    from vebuild.synthetic import model_scene

    rng = np.random.default_rng(13)
    _, start, pins, photos = model_scene(rng, n_boxes=1, n_photos=2)
    cams = {p.id: ImageCamera(p.id, p.K, p.R, p.C, p.width, p.height) for p in photos.values()}
    model = model_from_dict(start["nodes"], {"O": np.zeros(3)})
    pin = pins[0]
    problem = Problem(model, cams, [Pin(p["photo"], p["node"], p["handle"], np.array(p["uv"])) for p in pins])
    problem.check_finite(problem.x0(), "at the start of the solve")  # a sound start passes
    cam = cams[pin["photo"]]  # the camera moved onto the pinned handle: no finite projection
    cams[pin["photo"]] = ImageCamera(cam.id, cam.K, cam.R, model.handle_world(pin["node"], pin["handle"]),
                                     cam.width, cam.height)
    problem = Problem(model, cams, [Pin(p["photo"], p["node"], p["handle"], np.array(p["uv"])) for p in pins])
    with pytest.raises(VebuildError, match=rf"pin {pin['node']}:{pin['handle']} in photo '{pin['photo']}': its "
                                           r"residual is not a finite number at the start of the solve"):
        problem.check_finite(problem.x0(), "at the start of the solve")


def test_vebuild_calibrate_names_two_scale_distances_that_disagree(room, capsys, monkeypatch):
    from vebuild.calibration import positions

    data = json.loads(room.read_text())
    data["reference_distances"][1]["distance"] = 400.0  # O–Y4 is 4 m
    room.write_text(json.dumps(data))
    monkeypatch.setattr(positions, "_refine", _no_full_solve)  # refused before the full solve
    assert main(["calibrate", str(room), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "the scale distances O–Y4 (400 m) and O–X5 (5 m) contradict each other by a factor of" in err, err
    assert "Traceback" not in err and "marker" not in err.split("contradict")[0]
    assert "calibration" not in json.loads(room.read_text())


def test_a_focal_prior_of_no_spread_is_named_not_a_scipy_error(rng):
    from vebuild.calibration.photo import FocalPrior, calibrate_photo
    from vebuild.synthetic import random_scene

    photos, _ = random_scene(rng, ("3vp", "3vp", "2vp"))
    p = photos[0]
    with pytest.raises(VebuildError, match=r"photo 'p1': focal_px: expected a focal length > 0 px with a σ > 0 px"):
        calibrate_photo(p.segments, p.width, p.height, photo=p.id, focal=FocalPrior(1200.0, 0.0, "user"))


# -- non-finite values inside the solvers, through the command line --------------------------------

def _failing_calibrate(room, capsys):
    """`vebuild calibrate` on ``room``: its stderr, after checking status 2, no traceback and the
    project file untouched."""
    before = room.read_bytes()
    assert main(["calibrate", str(room), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    assert room.read_bytes() == before
    return err


def test_vebuild_calibrate_names_the_observation_whose_refined_residual_is_not_finite(room, capsys, monkeypatch):
    """The joint refinement of cameras and markers ending where photo p2's camera sits on marker O
    (the origin): that sighting's residual is 0/0. No valid input was found that leads the robust
    refinement there (the start is checked, and it does not step onto a marker), so
    its solver (``levenberg_marquardt``) is wrapped to end there."""
    import numpy as np

    from vebuild.calibration import positions

    real = positions.levenberg_marquardt

    def onto_the_origin(fun, jac, x0, *args, **kwargs):
        sol = real(fun, jac, x0, *args, **kwargs)
        sol.x = sol.x.copy()
        sol.x[9 * 1 + 6 : 9 * 1 + 9] = 0.0  # photo p2's camera centre (the second camera) on O
        with np.errstate(all="ignore"):
            assert not np.all(np.isfinite(fun(sol.x)))
        return sol
    monkeypatch.setattr(positions, "levenberg_marquardt", onto_the_origin)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        err = _failing_calibrate(room, capsys)
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)]  # no NumPy warning on stderr
    assert "photo 'p2', marker 'O': the refinement of cameras and markers went to a non-finite value there; " \
           "check that marker's clicks in that photo" in err, err


@pytest.mark.parametrize("failure", [__import__("numpy").linalg.LinAlgError("SVD did not converge"),
                                     ValueError("Residuals are not finite in the initial point.")])
def test_vebuild_calibrate_names_a_numerical_failure_of_the_refinement(room, capsys, monkeypatch, failure):
    """The solver giving up inside the refinement (a singular system, a non-finite step): reached by
    making ``levenberg_marquardt`` raise what NumPy and SciPy raise then, since the start is checked
    for finite residuals before it is called."""
    from vebuild.calibration import positions

    def fail(*args, **kwargs):
        raise failure
    monkeypatch.setattr(positions, "levenberg_marquardt", fail)
    err = _failing_calibrate(room, capsys)
    assert f"the refinement of camera and marker positions failed numerically ({failure}); a photo's vanishing " \
           "lines or marker clicks make it degenerate: check the photos with the fewest markers first" in err, err


def test_vebuild_calibrate_passes_other_errors_of_the_refinement_on(room, monkeypatch):
    """A ValueError that is not about the numbers (a bug) is not dressed up as the user's fault."""
    from vebuild.calibration import positions

    def fail(*args, **kwargs):
        raise ValueError("x0 has the wrong shape")
    monkeypatch.setattr(positions, "levenberg_marquardt", fail)
    with pytest.raises(ValueError, match="x0 has the wrong shape"):
        main(["calibrate", str(room), "--quiet"])


@pytest.fixture
def calibrated_room(room, capsys):
    assert main(["calibrate", str(room), "--quiet"]) == 0
    capsys.readouterr()
    return room


def _failing_solve(room, capsys):
    before = room.read_bytes()
    assert main(["solve", str(room)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    assert room.read_bytes() == before
    return err


def test_vebuild_solve_names_a_pin_whose_camera_sits_on_its_handle(calibrated_room, capsys):
    """A valid project: photo p2's calibrated camera moved onto marker O, where the floor's handle v0
    rests and which p2 pins; that pin's projection is 0/0 at the start of the solve."""
    data = json.loads(calibrated_room.read_text())
    data["calibration"]["cameras"]["p2"]["position"]["value"] = [0.0, 0.0, 0.0]
    calibrated_room.write_text(json.dumps(data))
    err = _failing_solve(calibrated_room, capsys)
    assert f"{calibrated_room}: pin floor:v0 in photo 'p2': its residual is not a finite number at the " \
           "start of the solve" in err, err


def test_vebuild_solve_names_a_parameter_that_ends_non_finite(calibrated_room, capsys, monkeypatch):
    """The solve ending on a non-finite parameter: no valid input was found that leads there (the
    start is checked), so ``Problem.solve`` is wrapped to end there."""
    import numpy as np

    from vebuild.model.solver import Problem

    real = Problem.solve
    names = []

    def to_nan(self, x0, *args, **kwargs):
        sol = real(self, x0, *args, **kwargs)
        sol.x = sol.x.copy()
        sol.x[0] = np.nan
        names.append(self.names[0])
        return sol
    monkeypatch.setattr(Problem, "solve", to_nan)
    err = _failing_solve(calibrated_room, capsys)
    assert f"{calibrated_room}: the model parameter {names[-1]} is not a finite number at the end of the " \
           "solve" in err, err


@pytest.mark.parametrize("failure", [__import__("numpy").linalg.LinAlgError("Singular matrix"),
                                     ValueError("array must not contain infs or NaNs")])
def test_vebuild_solve_names_a_numerical_failure(calibrated_room, capsys, monkeypatch, failure):
    """SciPy or NumPy giving up inside the solve: reached by making ``Problem.solve`` raise what they
    raise then, since a singular system is otherwise reported as undetermined parameters. (A
    LinAlgError is a ValueError, and "Singular matrix" names no non-finite number: it used to
    escape as a traceback.)"""
    from vebuild.model.solver import Problem

    def fail(self, *args, **kwargs):
        raise failure
    monkeypatch.setattr(Problem, "solve", fail)
    err = _failing_solve(calibrated_room, capsys)
    assert f"{calibrated_room}: the solve failed numerically ({failure}): an observation or a node's " \
           "dimensions make it degenerate" in err and "details: $.model" in err, err


def test_vebuild_solve_passes_other_errors_on(calibrated_room, monkeypatch):
    """A ValueError that is not about the numbers (a bug) is not dressed up as the user's fault."""
    from vebuild.model.solver import Problem

    def fail(self, *args, **kwargs):
        raise ValueError("x0 has the wrong shape")
    monkeypatch.setattr(Problem, "solve", fail)
    with pytest.raises(ValueError, match="x0 has the wrong shape"):
        main(["solve", str(calibrated_room)])


def test_a_numeric_failure_is_told_apart_by_whole_words():
    import numpy as np

    from vebuild.calibration.lsq import is_numeric_failure

    for text in ("array must not contain infs or NaNs", "Residuals are not finite in the initial point",
                 "x0 must only have finite values", "Singular matrix"):
        exc = np.linalg.LinAlgError(text) if text == "Singular matrix" else ValueError(text)
        assert is_numeric_failure(exc), text
    for text in ("x0 is infeasible", "information is missing", "the nanometre grid"):
        assert not is_numeric_failure(ValueError(text)), text
