"""`vebuild export PROJECT --html DIR`: the self-contained web viewer (vebuild/render/html.py,
docs/html-viewer.md), checked in a real headless Chromium (SwiftShader WebGL) driven over the
DevTools protocol on a pipe (tests/chromium_cdp.py): it loads with no error and asks for nothing
outside its folder, renders the textured model, puts the labels on screen, and a photo's camera
view in the page matches vebuild's own render of that camera.

The browser tests are skipped, saying why, where no Chromium is installed
(`apt-get install chromium`; CI's .ci/run installs it); the rest need no browser.
"""

from __future__ import annotations

import base64
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from chromium_cdp import Browser, find_chromium

from vebuild.cli import main
from vebuild.errors import VebuildError

#: The browser window (CSS pixels, device scale 1) and the size vebuild renders at for comparison.
SIZE = (800, 600)
#: Seconds the page may take to load the scene and draw its first frames under SwiftShader.
LOAD_S = 40
CHROMIUM = find_chromium()
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="the HTML viewer's tests need a headless Chromium: "
                                    "`apt-get install chromium` (CI's .ci/run installs it)")

STATE = "JSON.parse(document.getElementById('vebuild-state').textContent)"
READY = f"(function(){{var s={STATE};return s.errors.length>0||(s.stage==='running'&&s.frames>3);}})()"

#: On the floor: A in plain sight of the first view (the doorway), C behind the box from there.
MARKERS = [{"label": "A", "position": [3.5, 2.5, 0.0], "node": "floor", "description": "a cartridge case"},
           {"label": "C", "position": [2.5, 1.5, 0.0], "node": "floor"}]
ANALYSES = [{"name": "cabinet to table", "command": ["distance", "cabinet:v4", "table.top@top"]},
            {"name": "shot", "command": ["trajectory", "--from", "1,3,1.2", "--to", "2,2.8,1", "--sigma", "0.005",
                                         "--view", "overview", "--out", "shot.png"]}]


@pytest.fixture(scope="session")
def html_project(textured_room, tmp_path_factory):
    """A copy of the textured example room with an evidence marker (on the floor and one on the box),
    two analyses and a hypothesis that moves the box, exported to HTML once."""
    folder = tmp_path_factory.mktemp("html") / "room"
    shutil.copytree(textured_room.parent, folder)
    proj = folder / textured_room.name
    data = json.loads(proj.read_text())
    box = next(n for n in data["model"]["nodes"] if n["name"] == "box")
    moved = dict(box["joint"], position=[box["joint"]["position"][0] + 0.5, box["joint"]["position"][1]])
    box_top = _node_top_centre(proj, "box")
    data["evidence_markers"] = [*MARKERS, {"label": "B", "position": box_top, "node": "box"}]
    data["analyses"] = ANALYSES
    data["hypotheses"] = [{"name": "box by the window", "description": "moved 0.5 m", "joints": {"box": moved}}]
    proj.write_text(json.dumps(data, indent=1))
    out = folder.parent / "viewer"
    assert main(["export", str(proj), "--html", str(out)]) == 0
    return proj, out


def _node_top_centre(proj: Path, node: str) -> list[float]:
    from vebuild.project import load_project
    from vebuild.render.scene import load_scene

    scene = load_scene(load_project(proj))
    world = scene.model.world_transforms()[node]
    mesh = next(n for n in scene.model.nodes if n.name == node).primitive.mesh(None, 8)  # type: ignore[union-attr]
    P = mesh.vertices @ world[:3, :3].T + world[:3, 3]
    top = P[:, 2].max()
    return [float(P[:, 0].mean()), float(P[:, 1].mean()), float(top)]


@pytest.fixture(scope="session")
def plain_html(textured_room, tmp_path_factory):
    """The textured room exported as it is (no markers or analyses: what `vebuild render` draws too)."""
    out = tmp_path_factory.mktemp("html-plain") / "viewer"
    assert main(["export", str(textured_room), "--html", str(out)]) == 0
    return out


@pytest.fixture(scope="module")  # closed with the module: its last page's WebGL loop would take a core
def browser():
    if CHROMIUM is None:
        pytest.skip("the HTML viewer's tests need a headless Chromium: `apt-get install chromium`")
    b = Browser(CHROMIUM, *SIZE)
    yield b
    b.close()


def _open(browser: Browser, folder: Path, hash_: str = "") -> dict[str, Any]:
    browser.open("about:blank")  # a fresh load each time (a changed hash alone would not reload the page)
    browser.wait_for("document.readyState === 'complete' && location.href === 'about:blank'", 10)
    browser.requests.clear()
    browser.open((folder / "index.html").as_uri() + hash_)
    browser.wait_for(READY, LOAD_S)
    state: dict[str, Any] = browser.evaluate(STATE)
    return state


def _rehash(browser: Browser, hash_: str, until: str) -> dict[str, Any]:
    """Change the page's hash in place (no reload) and wait until ``until`` (JS, on ``s``, the state)
    holds and two more frames were drawn."""
    frames = browser.evaluate(STATE)["frames"]
    browser.evaluate(f"location.hash = {json.dumps(hash_)}")
    browser.wait_for(f"(function(){{var s={STATE};return ({until})&&s.frames>{frames + 2};}})()", LOAD_S)
    state: dict[str, Any] = browser.evaluate(STATE)
    return state


def _pixels(path: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"))


# -- the folder -------------------------------------------------------------------------------------


def test_folder_holds_everything(html_project):
    from vebuild.render.export import read_glb
    from vebuild.render.html import MANIFEST, STATIC

    proj, out = html_project
    for name in ("index.html", "scene.glb", "scene.js", "data.js", MANIFEST, *STATIC):
        assert (out / name).is_file(), name
    glb = (out / "scene.glb").read_bytes()
    doc, _ = read_glb(glb)  # the glTF export, as `vebuild export --out X.glb` writes it
    assert doc["asset"]["generator"].startswith("vebuild")
    js = (out / "scene.js").read_text()
    assert js.startswith('window.VEBUILD_SCENE = "') and base64.b64decode(js.split('"')[1]) == glb
    data = json.loads((out / "data.js").read_text().removeprefix("window.VEBUILD_DATA = ").rstrip().rstrip(";"))
    assert [m["label"] for m in data["markers"]] == ["A", "C", "B"]
    assert [a["name"] for a in data["analyses"]] == ["cabinet to table", "shot"]
    assert data["hypotheses"][0]["label"].startswith("HYPOTHESIS: box by the window")
    assert set(data["hypotheses"][0]["nodes"]) == {str(1 + [n["name"] for n in doc["nodes"][1:]].index("box"))}
    # Each calibrated photo copied downscaled; the originals untouched (their recorded hashes hold).
    from PIL import Image

    from vebuild.project import load_project, sha256_file

    project = load_project(proj)
    for photo in project.data["photos"]:
        copy = out / "photos" / f"{photo['id']}.jpg"
        with Image.open(copy) as im:
            assert max(im.size) <= 1280 and im.size[0] / im.size[1] == pytest.approx(photo["width"] / photo["height"],
                                                                                     rel=0.01)
        assert sha256_file(project.photo_path(photo)) == photo["sha256"]
    # Nothing in the page points outside the folder.
    page = (out / "index.html").read_text()
    assert "http://" not in page and "https://" not in page
    assert "Content-Security-Policy" in page


def test_measurement_label_carries_its_figures(html_project):
    """The label of a distance says the value, 1σ and 95 % interval the analysis gives."""
    from vebuild.analysis.recorded import parse_recorded
    from vebuild.project import load_project

    proj, out = html_project
    data = json.loads((out / "data.js").read_text().removeprefix("window.VEBUILD_DATA = ").rstrip().rstrip(";"))
    m = parse_recorded(ANALYSES[0]["command"]).run(load_project(proj)).figures["measurements"][0]
    label = data["analyses"][0]["label"]
    assert f"{m['value_m']:.3f} m ± {1000 * m['sigma_m']:.1f} mm" in label
    assert f"95 % [{m['ci95_m'][0]:.3f}, {m['ci95_m'][1]:.3f}]" in label
    tr = data["analyses"][1]
    assert tr["kind"] == "trajectory" and "cone" in tr["label"] and len(tr["cone"]) > 0
    # Its image goes into the folder (with vebuild's mark), not where the recorded command says.
    from vebuild.project.outputs import written_by_vebuild

    assert tr["image"] == "analyses/analysis-2.png" and written_by_vebuild(out / tr["image"])
    assert not (proj.parent / "shot.png").exists() and not Path("shot.png").exists()
    assert data["analyses"][0]["image"] is None


def test_export_again_into_its_own_folder(html_project):
    proj, out = html_project
    before = (out / "scene.glb").read_bytes()
    assert main(["export", str(proj), "--html", str(out)]) == 0
    assert (out / "scene.glb").read_bytes() == before


def test_refuses_a_folder_it_did_not_write(textured_room, tmp_path):
    from vebuild.actions.export_html import export_html
    from vebuild.project import load_project

    project = load_project(textured_room)
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "notes.txt").write_text("mine")
    with pytest.raises(VebuildError, match=r"busy: is not empty and holds no vebuild-html\.json"):
        export_html(project, busy)
    assert sorted(p.name for p in busy.iterdir()) == ["notes.txt"]
    afile = tmp_path / "file"
    afile.write_text("x")
    with pytest.raises(VebuildError, match=r"file: is not a folder"):
        export_html(project, afile)
    with pytest.raises(VebuildError, match=r"does not exist; create it first"):
        export_html(project, tmp_path / "missing" / "viewer")
    with pytest.raises(VebuildError, match=r"is the project's own folder"):
        export_html(project, textured_room.parent)


def test_bad_analysis_is_named_and_nothing_is_written(textured_room, tmp_path):
    folder = tmp_path / "room"
    shutil.copytree(textured_room.parent, folder)
    proj = folder / textured_room.name
    data = json.loads(proj.read_text())
    data["analyses"] = [{"name": "bad", "command": ["distance", "cabinet:v4", "nosuchnode@top"]}]
    proj.write_text(json.dumps(data))
    out = tmp_path / "viewer"
    from vebuild.actions.export_html import export_html
    from vebuild.project import load_project

    with pytest.raises(VebuildError, match=r"\$\.analyses\[0\]\.command"):
        export_html(load_project(proj), out)
    assert not out.exists()


def test_command_line_needs_out_or_html(textured_room, capsys):
    assert main(["export", str(textured_room)]) == 2
    assert "--html DIR" in capsys.readouterr().err


# -- in the browser -----------------------------------------------------------------------------------


@needs_chromium
def test_page_loads_with_no_error_and_no_network(browser, html_project):
    proj, out = html_project
    state = _open(browser, out)
    assert state["errors"] == [] and state["ok"] is True, state["errors"]
    assert state["viewport"] == list(SIZE)
    base = out.as_uri() + "/"
    outside = [u for u in browser.requests if not (u.startswith(base) or u.startswith(("blob:", "data:")))]
    assert outside == [], f"the page asked for something outside its folder: {outside}"
    assert {base + n for n in ("viewer.js", "three-bundle.min.js", "scene.js", "data.js")} <= set(browser.requests)
    # The marker on the floor, seen from the first view (the doorway), is labelled on screen, unhidden.
    label = next(x for x in state["labels"] if x["kind"] == "marker" and x["text"] == "A")
    assert label["on_screen"] and 0 <= label["x"] <= SIZE[0] and 0 <= label["y"] <= SIZE[1]
    assert not label["hidden_by_model"]
    assert np.allclose(label["world"], MARKERS[0]["position"], atol=1e-6)
    hidden = next(x for x in state["labels"] if x["text"] == "C")
    assert hidden["on_screen"] and hidden["hidden_by_model"]  # the box stands between: its label is dashed
    texts = [x["text"] for x in state["labels"]]
    assert any(t.startswith("cabinet to table: ") and "±" in t for t in texts)
    assert any(t.startswith("shot: azimuth") for t in texts)
    assert state["xr"] in ("absent", "unsupported")  # headless offers no headset: no Enter VR button
    assert browser.evaluate("document.getElementById('vr') === null")


@needs_chromium
def test_hypothesis_is_labelled_and_moves_its_object(browser, html_project):
    from vebuild.project import load_project
    from vebuild.project.hypotheses import applied_hypothesis
    from vebuild.render.scene import load_scene

    proj, out = html_project
    measured = _open(browser, out)
    state = _rehash(browser, "#hypothesis=box%20by%20the%20window", "s.hypothesis==='box by the window'")
    assert state["errors"] == [] and state["hypothesis"] == "box by the window"
    banner = browser.evaluate("document.getElementById('banner').textContent")
    assert banner.startswith("HYPOTHESIS: box by the window")
    # Marker B lies on the box: it moves with it, as the hypothesis moves the box.
    project = load_project(proj)
    model = load_scene(project).model
    T0 = model.world_transforms()["box"]
    T1 = applied_hypothesis(project, model, 0).world_transforms()["box"]
    b0 = next(x for x in measured["labels"] if x["text"] == "B")["world"]
    b1 = next(x for x in state["labels"] if x["text"] == "B")["world"]
    want = (T1 @ np.linalg.inv(T0) @ np.array([*b0, 1.0]))[:3]
    assert np.linalg.norm(np.array(b1) - b0) > 0.1
    assert np.allclose(b1, want, atol=1e-4)


@needs_chromium
def test_model_renders_textured(browser, plain_html, tmp_path):
    state = _open(browser, plain_html, "#camera=photo-p1&photo=0&clean=1")
    assert state["errors"] == [] and state["camera"]["id"] == "photo-p1"
    img = _pixels(browser.screenshot(tmp_path / "page.png"))
    assert img.shape == (SIZE[1], SIZE[0], 3)
    background = np.all(img == [0x20, 0x20, 0x24], axis=2)
    assert background.mean() < 0.05  # looking into the room from a photo's camera: model everywhere
    grey = img.astype(float).mean(axis=2)[~background]
    colours = len(np.unique(img.reshape(-1, 3), axis=0))
    # Textured: many colours and wide variation (an untextured or blank page has a handful).
    assert colours > 5000 and grey.std() > 20, (colours, grey.std())


@needs_chromium
def test_camera_view_matches_vebuild_render(browser, plain_html, textured_room, tmp_path):
    """The page looking through photo p1 shows what `vebuild render --photo p1` shows, as closely as
    the render matches itself moved by one pixel; the view through another photo does not."""
    from vebuild.render.observed import draw_legend

    render = tmp_path / "render.png"
    assert main(["render", str(textured_room), "--photo", "p1", "--size", f"{SIZE[0]}x{SIZE[1]}",
                 "--out", str(render)]) == 0
    r = _pixels(render).astype(float)
    # The renders' legend, drawn the same way into the page's screenshot: it is not part of the scene.
    shots = {}
    for cam in ("photo-p1", "photo-p2"):
        hash_ = f"#camera={cam}&photo=0&clean=1"
        if cam == "photo-p1":
            state = _open(browser, plain_html, hash_)
        else:  # the same page, its hash changed
            state = _rehash(browser, hash_, f"s.camera.id==='{cam}'")
        assert state["errors"] == [] and state["camera"]["id"] == cam
        shots[cam] = draw_legend(_pixels(browser.screenshot(tmp_path / f"{cam}.png")), "hatch").astype(float)
    diff = float(np.abs(shots["photo-p1"] - r).mean())
    other = float(np.abs(shots["photo-p2"] - r).mean())
    one_pixel = min(float(np.abs(r[:, 1:] - r[:, :-1]).mean()), float(np.abs(r[1:] - r[:-1]).mean()))
    # Measured (Chromium 150, SwiftShader): diff 0.76 sRGB levels, one_pixel 2.21, other 37.6.
    assert diff < one_pixel, (diff, one_pixel)
    assert other > 5 * one_pixel, (other, one_pixel)


@needs_chromium
def test_photo_is_laid_over_its_camera_view(browser, plain_html):
    state = _open(browser, plain_html, "#camera=photo-p2")
    assert state["errors"] == []
    photo = browser.wait_for("(function(){var p=document.getElementById('photo');return p.complete&&p.naturalWidth>0"
                             "&&{src:p.getAttribute('src'),o:getComputedStyle(p).opacity,w:p.clientWidth,h:p.clientHeight,"
                             "l:p.offsetLeft,t:p.offsetTop};})()", 10)
    assert photo["src"] == "photos/p2.jpg" and float(photo["o"]) == pytest.approx(0.5)
    # 1600×1200 photo in an 800×600 window: it fills it.
    assert (photo["w"], photo["h"], photo["l"], photo["t"]) == (800, 600, 0, 0)


@needs_chromium
def test_page_works_from_a_plain_web_server(browser, plain_html):
    """Served over HTTP (here Python's http.server on the loopback), it loads from its own origin only."""
    import functools
    import http.server
    import threading

    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(plain_html))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        origin = f"http://127.0.0.1:{server.server_address[1]}/"
        browser.open("about:blank")
        browser.wait_for("location.href === 'about:blank'", 10)
        browser.requests.clear()
        browser.open(origin + "index.html")
        browser.wait_for(READY, LOAD_S)
        state = browser.evaluate(STATE)
    finally:
        server.shutdown()
        server.server_close()
    assert state["errors"] == [] and state["ok"] is True
    outside = [u for u in browser.requests if not (u.startswith(origin) or u.startswith(("blob:", "data:")))]
    assert outside == [] and origin + "scene.js" in browser.requests


def _key(browser: Browser, kind: str, key: str, code: str, vk: int) -> None:
    browser.page("Input.dispatchKeyEvent", {"type": kind, "key": key, "code": code, "windowsVirtualKeyCode": vk})


@needs_chromium
def test_click_a_camera_and_walk_with_the_keys(browser, plain_html):
    _open(browser, plain_html)
    _key(browser, "keyDown", "h", "KeyH", 72)  # H hides the panel
    _key(browser, "keyUp", "h", "KeyH", 72)
    assert browser.evaluate("document.getElementById('panel').style.display") == "none"
    # Clicking a photo camera's glyph looks through it.
    state = browser.evaluate(STATE)
    glyph = next(x for x in state["labels"]
                 if x["text"].startswith("photo ") and x["on_screen"] and 10 < x["x"] < SIZE[0] - 10
                 and 10 < x["y"] < SIZE[1] - 10)
    want = "photo-" + glyph["text"].split()[1]
    for kind in ("mousePressed", "mouseReleased"):
        browser.page("Input.dispatchMouseEvent", {"type": kind, "x": glyph["x"], "y": glyph["y"], "button": "left",
                                                  "clickCount": 1})
    browser.wait_for(f"{STATE}.camera.id === '{want}'", 10)
    assert browser.evaluate("location.hash") == f"#camera={want}"
    # W walks straight ahead, level (and leaves the camera's view).
    state = browser.evaluate(STATE)
    start = np.array(state["camera"]["position"])
    direction = np.array(state["camera"]["direction"])
    frames = state["frames"]
    _key(browser, "keyDown", "w", "KeyW", 87)
    browser.wait_for(f"{STATE}.frames > {frames + 20}", 20)
    _key(browser, "keyUp", "w", "KeyW", 87)
    state = browser.evaluate(STATE)
    moved = np.array(state["camera"]["position"]) - start
    ahead = direction[:2] / np.linalg.norm(direction[:2])
    assert state["camera"]["id"] is None
    assert moved[2] == pytest.approx(0.0, abs=1e-9)
    assert moved[:2] @ ahead > 0.05 and abs(moved[0] * ahead[1] - moved[1] * ahead[0]) < 1e-6


@needs_chromium
def test_untextured_model_is_drawn_lit(browser, textured_room, tmp_path):
    """A project with no textures yet: the faces in their colours, shaded, and the page says so."""
    from vebuild.project import load_project, save_project

    folder = tmp_path / "room"
    shutil.copytree(textured_room.parent, folder)
    project = load_project(folder / textured_room.name)
    del project.data["textures"]
    save_project(project)
    out = tmp_path / "viewer"
    assert main(["export", str(project.path), "--html", str(out)]) == 0
    state = _open(browser, out, "#camera=photo-p1&photo=0&clean=1")
    assert state["errors"] == [] and state["ok"] is True and state["textured"] is False
    assert any("untextured" in w for w in state["warnings"])
    img = _pixels(browser.screenshot(tmp_path / "page.png")).astype(float)
    grey = img.mean(axis=2)
    assert grey.mean() > 60 and grey.std() > 10  # lit and shaded, not black and not flat


@needs_chromium
def test_page_policy_blocks_anything_from_elsewhere(browser, plain_html):
    """The page's Content-Security-Policy holds under file://: a request for an outside image is
    blocked before it is made, and the page reports it in its state."""
    _open(browser, plain_html)
    browser.events.clear()
    browser.evaluate("(function(){var i=new Image();i.src='https://example.com/x.png';"
                     "document.body.appendChild(i);return 1;})()")
    errors = browser.wait_for(f"(function(){{var e={STATE}.errors;return e.length?e:null;}})()", 10)
    assert any("Content-Security-Policy" in e and "example.com" in e for e in errors), errors
    # Chromium reports the attempt (requestWillBeSent), then its failure, blocked by the policy.
    failed = browser.wait_event("Network.loadingFailed")
    assert any(f.get("blockedReason") == "csp" for f in failed), failed
    assert browser.evaluate(STATE)["ok"] is False


def test_vendored_bundle_is_the_pinned_three():
    """The committed bundle names the versions web/package.json pins, and three.js's licence travels with it."""
    from vebuild.render.html import WEB

    pins = json.loads((WEB / "package.json").read_text())
    head = (WEB / "three-bundle.min.js").read_text()[:300]
    assert head.startswith(f"/* three.js {pins['dependencies']['three']} (MIT")
    assert f"esbuild {pins['devDependencies']['esbuild']} " in head
    assert "var VEBUILD_THREE=" in head  # a classic script setting one global: no ES module
    assert (WEB / "THREE-LICENSE").read_text().startswith("The MIT License")


@needs_chromium
def test_enter_vr_button_where_webxr_offers_a_headset(browser, plain_html):
    """Headless Chromium has no headset; a stand-in navigator.xr that offers immersive-vr (set before
    the page's scripts run) makes the page show three.js's "ENTER VR" button."""
    fake = ("Object.defineProperty(navigator, 'xr', {configurable: true, value: {"
            "isSessionSupported: function (mode) { return Promise.resolve(mode === 'immersive-vr'); },"
            "requestSession: function () { return Promise.reject(new Error('no headset')); },"
            "addEventListener: function () {}, removeEventListener: function () {}}});")
    script = browser.page("Page.addScriptToEvaluateOnNewDocument", {"source": fake})["identifier"]
    try:
        state = _open(browser, plain_html)
        browser.wait_for(f"{STATE}.xr === 'offered'", 10)
        text = browser.wait_for("(function(){var b=document.getElementById('vr');return b&&b.textContent;})()", 10)
    finally:
        browser.page("Page.removeScriptToEvaluateOnNewDocument", {"identifier": script})
    assert state["errors"] == []
    assert text == "ENTER VR"
