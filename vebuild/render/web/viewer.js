// vebuild's HTML viewer (docs/html-viewer.md): walks through the glTF export of a project, with its
// evidence markers, analyses, cameras, photos and hypotheses. Classic script (no ES modules: the
// page must work opened from file://); three.js comes from three-bundle.min.js (window.VEBUILD_THREE),
// the scene from scene.js (window.VEBUILD_SCENE, base64 GLB), the rest from data.js (window.VEBUILD_DATA).
//
// The page keeps its state as JSON in <pre id="vebuild-state"> (loaded, errors, the labels' screen
// positions, the current camera) so that a headless browser's --dump-dom can read it.
// URL hash: #camera=photo-ID or #camera=view-NAME (look through a camera), &photo=0..1 (the photo's
// opacity), &clean=1 (no panel, labels or camera glyphs: the model alone), &hypothesis=NAME.
(function () {
  "use strict";

  var state = { ok: false, stage: "script", errors: [], warnings: [], labels: [], camera: null, requests: [],
                frames: 0, viewport: [0, 0], xr: "unknown", hypothesis: null, textured: null, clean: false };
  var stateEl = null;

  function writeState() {
    if (!stateEl) stateEl = document.getElementById("vebuild-state");
    try {
      state.requests = performance.getEntriesByType("resource").map(function (e) { return e.name; });
    } catch (e) { /* no performance API */ }
    state.ok = state.stage === "running" && state.errors.length === 0;
    if (stateEl) stateEl.textContent = JSON.stringify(state);
  }

  function fail(message) {
    state.errors.push(String(message));
    writeState();
  }

  window.onerror = function (message, source, line, column) {
    fail(message + " (" + (source || "?") + ":" + (line || 0) + ":" + (column || 0) + ")");
    return false;
  };
  window.addEventListener("unhandledrejection", function (e) {
    fail("unhandled rejection: " + (e.reason && e.reason.message ? e.reason.message : e.reason));
  });
  document.addEventListener("securitypolicyviolation", function (e) {
    fail("blocked by the page's Content-Security-Policy: " + e.blockedURI + " (" + e.violatedDirective + ")");
  });

  var T, THREE, data, renderer, scene, camera, dolly, orbit, walk, raycaster, root, gltf;
  var modelMeshes = [], unseenMaterials = [], labels = [], cameraGlyphs = [], cameraDefs = {}, nodeObjects = {};
  var photoPlanes = {};  // camera id -> the photo plane of a camera-only scene (docs/export.md)
  var originalMatrices = {}, current = null, keys = {}, lastTime = 0, hashOptions = {}, labelsDirty = true;
  var photoEl, labelsEl, bannerEl, overlays = [];

  function parseHash() {
    var out = {};
    var text = (location.hash || "").replace(/^#/, "");
    text.split("&").forEach(function (part) {
      if (!part) return;
      var i = part.indexOf("=");
      var k = decodeURIComponent(i < 0 ? part : part.slice(0, i));
      out[k] = i < 0 ? "1" : decodeURIComponent(part.slice(i + 1).replace(/\+/g, " "));
    });
    return out;
  }

  function base64Bytes(text) {
    var bin = atob(text);
    var out = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out.buffer;
  }

  function el(tag, attrs, text) {
    var e = document.createElement(tag);
    Object.keys(attrs || {}).forEach(function (k) { e.setAttribute(k, attrs[k]); });
    if (text !== undefined) e.textContent = text;
    return e;
  }

  // vebuild world (right-handed, +Z up) to three's (glTF's +Y up): (x, y, z) -> (x, z, -y).
  function toThree(p) { return new THREE.Vector3(p[0], p[2], -p[1]); }
  function toWorld(v) { return [v.x, -v.z, v.y]; }

  // -- materials: the atlas unlit, with the surfaces no photo saw hatched as vebuild's renders do --

  var VERTEX = [
    "uniform mat4 worldFromThree;",
    "varying vec2 vUv;",
    "varying vec3 vWorld;",
    "void main() {",
    "  vUv = uv;",
    "  vec4 w = modelMatrix * vec4(position, 1.0);",
    "  vWorld = (worldFromThree * w).xyz;",
    "  gl_Position = projectionMatrix * viewMatrix * w;",
    "}"].join("\n");
  var FRAGMENT = [
    "uniform sampler2D atlas;",        // sRGB page: sampled as linear
    "uniform sampler2D coverage;",     // the coverage map, nearest
    "uniform float hasCoverage;",
    "uniform float mode;",             // 0 off, 1 hatch
    "uniform vec3 unseenColour;",      // linear
    "uniform float strength;",
    "uniform float period;",
    "uniform float duty;",
    "uniform vec3 unseenRgb;",         // the coverage map's colour of unseen texels (0..1)
    "varying vec2 vUv;",
    "varying vec3 vWorld;",
    "vec3 toSrgb(vec3 c) {",
    "  c = clamp(c, 0.0, 1.0);",
    "  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));",
    "}",
    "void main() {",
    "  vec3 colour = texture2D(atlas, vUv).rgb;",
    "  vec4 cov = texture2D(coverage, vUv);",
    "  float unseen = (hasCoverage > 0.5 && cov.a > 0.5 && all(lessThan(abs(cov.rgb - unseenRgb), vec3(0.02)))) ? 1.0 : 0.0;",
    "  float s = (vWorld.x + vWorld.y + vWorld.z) / (period * 1.41421356);",
    "  float ds = max(fwidth(s), 1e-6);",
    "  if (mode > 0.5 && unseen > 0.5) {",
    "    float tri = abs(fract(s) - 0.5);",
    "    float cover = clamp((0.5 * duty - tri) / ds + 0.5, 0.0, 1.0);",
    "    float k = mix(cover, duty, smoothstep(0.125, 0.25, ds));",
    "    colour = mix(colour, unseenColour, strength * k);",
    "  }",
    "  gl_FragColor = vec4(toSrgb(colour), 1.0);",
    "}"].join("\n");

  function srgbToLinear(c) { return c <= 0.04045 ? c / 12.92 : Math.pow((c + 0.055) / 1.055, 2.4); }

  function prepareMaterials(parser) {
    var json = parser.json, u = data.unobserved || {};
    var rgb = (u.colour_srgb || [255, 0, 255]).map(function (v) { return v / 255; });
    var worldFromThree = new THREE.Matrix4().copy(root.matrixWorld).invert();
    var jobs = [];
    var replacement = {};  // material index -> ShaderMaterial
    (json.materials || []).forEach(function (def, mi) {
      var pbr = def.pbrMetallicRoughness || {};
      if (!pbr.baseColorTexture) return;
      var cov = def.extras && def.extras.vebuild_coverage;
      var job = Promise.all([parser.getDependency("texture", pbr.baseColorTexture.index),
                             cov ? parser.getDependency("texture", cov.texture.index) : Promise.resolve(null)])
        .then(function (tex) {
          var atlas = tex[0], coverage = tex[1];
          atlas.colorSpace = THREE.SRGBColorSpace;
          if (coverage) {
            coverage = coverage.clone();
            coverage.colorSpace = THREE.NoColorSpace;
            coverage.magFilter = coverage.minFilter = THREE.NearestFilter;
            coverage.generateMipmaps = false;
            coverage.needsUpdate = true;
          }
          var unseen = cov ? cov.unseen_rgba.slice(0, 3).map(function (v) { return v / 255; }) : [1, 0, 1];
          var m = new THREE.ShaderMaterial({
            uniforms: {
              atlas: { value: atlas }, coverage: { value: coverage || atlas }, hasCoverage: { value: coverage ? 1 : 0 },
              mode: { value: 1 }, unseenColour: { value: new THREE.Vector3(srgbToLinear(rgb[0]), srgbToLinear(rgb[1]), srgbToLinear(rgb[2])) },
              strength: { value: u.strength || 0.7 }, period: { value: u.period_m || 0.08 }, duty: { value: u.duty || 0.5 },
              unseenRgb: { value: new THREE.Vector3(unseen[0], unseen[1], unseen[2]) },
              worldFromThree: { value: worldFromThree } },
            vertexShader: VERTEX, fragmentShader: FRAGMENT, side: THREE.DoubleSide });
          replacement[mi] = m;
          unseenMaterials.push(m);
        });
      jobs.push(job);
    });
    return Promise.all(jobs).then(function () { return replacement; });
  }

  // -- cameras ------------------------------------------------------------------------------------

  function fittedRect(w, h) {
    var W = window.innerWidth, H = window.innerHeight;
    var s = Math.min(W / w, H / h);
    return { s: s, x: (W - w * s) / 2, y: (H - h * s) / 2, w: w * s, h: h * s, W: W, H: H };
  }

  // A projection from the camera's K (pixels, image v down) fitted into the window: the camera's
  // image fills the largest centred rectangle of the window with its aspect; the rest shows beyond it.
  function projectionFromK(K, w, h) {
    var r = fittedRect(w, h);
    var fx = K[0][0] * r.s, fy = K[1][1] * r.s, cx = K[0][2] * r.s + r.x, cy = K[1][2] * r.s + r.y;
    var n = 0.05, f = 500, W = r.W, H = r.H;
    var P = new THREE.Matrix4();
    P.set(2 * fx / W, 0, 1 - 2 * cx / W, 0,
          0, 2 * fy / H, 2 * cy / H - 1, 0,
          0, 0, -(f + n) / (f - n), -2 * f * n / (f - n),
          0, 0, -1, 0);
    return { P: P, rect: r };
  }

  function lookThrough(id) {
    var def = cameraDefs[id];
    if (!def) { fail("no camera called " + JSON.stringify(id) + " (the cameras are: " + Object.keys(cameraDefs).join(", ") + ")"); return; }
    if (walk && walk.isLocked) walk.unlock();
    current = id;
    def.object.updateMatrixWorld(true);
    var m = def.object.matrixWorld;
    dolly.position.set(0, 0, 0); dolly.quaternion.identity(); dolly.updateMatrixWorld(true);
    m.decompose(camera.position, camera.quaternion, new THREE.Vector3());
    var fwd = new THREE.Vector3(0, 0, -1).applyQuaternion(camera.quaternion);
    orbit.target.copy(camera.position).addScaledVector(fwd, 2.0);
    orbit.enabled = false;
    applyProjection();
    var photo = data.photos[id];
    var opacity = hashOptions.photo !== undefined ? parseFloat(hashOptions.photo) : parseFloat(document.getElementById("opacity").value);
    if (photoPlanes[id]) {  // the scene holds the photo at the camera's frustum: no overlay needed
      photoPlanes[id].visible = hashOptions.photo === undefined || parseFloat(hashOptions.photo) > 0;
      photoEl.style.display = "none";
    } else if (photo && opacity > 0) {
      photoEl.src = photo.file;
      photoEl.style.opacity = String(opacity);
      photoEl.style.display = "block";
    } else {
      photoEl.style.display = "none";
    }
    cameraGlyphs.forEach(function (g) { g.visible = !state.clean && g.userData.id !== id; });
    document.querySelectorAll("#cameras button").forEach(function (b) { b.classList.toggle("on", b.dataset.id === id); });
    labelsDirty = true;
  }

  function leaveCamera() {
    if (current === null) return;
    current = null;
    photoEl.style.display = "none";
    orbit.enabled = true;
    cameraGlyphs.forEach(function (g) { g.visible = !state.clean; });
    document.querySelectorAll("#cameras button").forEach(function (b) { b.classList.remove("on"); });
    applyProjection();
  }

  function applyProjection() {
    var W = window.innerWidth, H = window.innerHeight;
    renderer.setSize(W, H);
    state.viewport = [W, H];
    if (current !== null) {
      var def = cameraDefs[current];
      var pr = projectionFromK(def.extras.K, def.extras.width, def.extras.height);
      camera.projectionMatrix.copy(pr.P);
      camera.projectionMatrixInverse.copy(pr.P).invert();
      var r = pr.rect;
      photoEl.style.left = r.x + "px"; photoEl.style.top = r.y + "px";
      photoEl.style.width = r.w + "px"; photoEl.style.height = r.h + "px";
    } else {
      camera.aspect = W / H;
      camera.updateProjectionMatrix();
    }
    labelsDirty = true;
  }

  function addCameraGlyph(id, def) {
    var ex = def.extras, K = ex.K, w = ex.width, h = ex.height, d = 0.25;
    var corners = [[0, 0], [w, 0], [w, h], [0, h]].map(function (c) {
      return new THREE.Vector3((c[0] - K[0][2]) / K[0][0] * d, -(c[1] - K[1][2]) / K[1][1] * d, -d);
    });
    var pts = [];
    corners.forEach(function (c, i) { pts.push(new THREE.Vector3(), c, c, corners[(i + 1) % 4]); });
    var geo = new THREE.BufferGeometry().setFromPoints(pts);
    var colour = ex.source === "photo" ? 0xb0b0b0 : 0x70a0ff;
    var g = new THREE.LineSegments(geo, new THREE.LineBasicMaterial({ color: colour }));
    var pick = new THREE.Mesh(new THREE.SphereGeometry(0.15, 8, 6),
                              new THREE.MeshBasicMaterial({ colorWrite: false, depthWrite: false }));
    g.add(pick);
    def.object.updateMatrixWorld(true);
    def.object.matrixWorld.decompose(g.position, g.quaternion, g.scale);
    g.userData.id = id;
    pick.userData.id = id;
    scene.add(g);
    cameraGlyphs.push(g);
    addLabel(ex.source === "photo" ? "photo " + id.slice(6) : "view " + id.slice(5), "camera", g, new THREE.Vector3());
  }

  // -- labels ---------------------------------------------------------------------------------------

  function addLabel(text, kind, parent, local, extra) {
    var div = el("div", { "class": "label " + kind }, text);
    labelsEl.appendChild(div);
    var anchor = new THREE.Object3D();
    anchor.position.copy(local);
    parent.add(anchor);
    var item = { text: text, kind: kind, el: div, anchor: anchor, hidden: false, extra: extra || {} };
    labels.push(item);
    return item;
  }

  var occlusionTick = 0;
  function updateLabels() {
    var W = window.innerWidth, H = window.innerHeight, out = [];
    var checkOcclusion = labelsDirty || (occlusionTick++ % 15 === 0);
    var camPos = new THREE.Vector3();
    camera.getWorldPosition(camPos);
    labels.forEach(function (item) {
      var p = new THREE.Vector3();
      item.anchor.getWorldPosition(p);
      var v = p.clone().project(camera);
      var front = v.z > -1 && v.z < 1;
      var x = (v.x + 1) / 2 * W, y = (1 - v.y) / 2 * H;
      var onScreen = front && x >= 0 && x <= W && y >= 0 && y <= H;
      if (checkOcclusion && onScreen && item.kind !== "camera") {
        var dir = p.clone().sub(camPos);
        var dist = dir.length();
        raycaster.set(camPos, dir.normalize());
        raycaster.near = 0; raycaster.far = dist;
        var hits = raycaster.intersectObjects(modelMeshes, false);
        item.hidden = hits.length > 0 && hits[0].distance < dist - 0.02;
      }
      var visible = onScreen && !state.clean;
      item.el.classList.toggle("off", !visible);
      item.el.classList.toggle("hidden", item.hidden);
      item.visible = visible; item.x = x; item.y = y;
      out.push({ text: item.text, kind: item.kind, x: +x.toFixed(1), y: +y.toFixed(1), on_screen: onScreen,
                 hidden_by_model: item.hidden, world: toWorld(p) });
    });
    placeLabels();
    labelsDirty = false;
    state.labels = out;
  }

  // Each visible label at its point, lifted above any label already placed that it would cover
  // (nearest the viewer first: markers, then measurements, then cameras). The state keeps the points.
  var ORDER = { marker: 0, measure: 1, trajectory: 1, camera: 2 };
  function placeLabels() {
    var placed = [];
    labels.filter(function (it) { return it.visible; })
      .sort(function (a, b) { return (ORDER[a.kind] - ORDER[b.kind]) || (b.y - a.y); })
      .forEach(function (it) {
        var w = it.el.offsetWidth, h = it.el.offsetHeight + 2, y = it.y;
        for (var tries = 0; tries < 20; tries++) {
          var hit = placed.some(function (r) {
            return Math.abs(r.x - it.x) < (r.w + w) / 2 && y > r.y - h && y - h < r.y;
          });
          if (!hit) break;
          y -= h;
        }
        placed.push({ x: it.x, y: y, w: w });
        it.el.style.left = it.x.toFixed(1) + "px";
        it.el.style.top = y.toFixed(1) + "px";
      });
  }

  // -- overlays -------------------------------------------------------------------------------------

  function polyline(points, colour, opacity) {
    var geo = new THREE.BufferGeometry().setFromPoints(points.map(toThree));
    var mat = new THREE.LineBasicMaterial({ color: colour, transparent: opacity < 1, opacity: opacity });
    var line = new THREE.Line(geo, mat);
    scene.add(line);
    overlays.push(line);
    return line;
  }

  function nodeIndexByName(name) {
    var nodes = gltf.parser.json.nodes || [];
    for (var i = 0; i < nodes.length; i++) if (nodes[i].name === name) return i;
    return -1;
  }

  function addMarkers() {
    var list = document.getElementById("markers");
    data.markers.forEach(function (m) {
      var p = toThree(m.position);
      var idx = m.node ? nodeIndexByName(m.node) : -1;
      var parent = idx >= 0 ? nodeObjects[idx] : scene;
      parent.updateMatrixWorld(true);
      var local = parent.worldToLocal(p.clone());
      var dot = new THREE.Mesh(new THREE.SphereGeometry(0.025, 12, 8), new THREE.MeshBasicMaterial({ color: 0xffd000 }));
      dot.position.copy(local);
      parent.add(dot);
      overlays.push(dot);
      addLabel(m.label, "marker", parent, local, { node: m.node });
      var li = el("li", {}, m.label + " — on " + (m.node || "?") + " at (" + m.position.map(function (v) { return v.toFixed(3); }).join(", ") + ")" + (m.description ? ": " + m.description : ""));
      list.appendChild(li);
    });
    if (!data.markers.length) list.appendChild(el("li", {}, "none recorded"));
  }

  function addAnalyses() {
    var box = document.getElementById("analyses");
    data.analyses.forEach(function (a) {
      var colour = a.kind === "trajectory" ? 0xff5050 : 0x40c0ff;
      (a.paths || []).forEach(function (P) { polyline(P, colour, 1.0); });
      (a.cone || []).forEach(function (P) { polyline(P, colour, 0.35); });
      if (a.anchor) addLabel(a.label, a.kind === "trajectory" ? "trajectory" : "measure", scene, toThree(a.anchor));
      var d = el("details");
      d.appendChild(el("summary", {}, a.label));
      if (a.description) d.appendChild(el("div", {}, a.description));
      d.appendChild(el("div", {}, "vebuild analyse " + data.project + " " + a.command.join(" ")));
      d.appendChild(el("pre", {}, a.table));
      if (a.image) {
        var link = el("a", { href: a.image, target: "_blank" }, "its image: " + a.image);
        d.appendChild(link);
      }
      box.appendChild(d);
    });
    if (!data.analyses.length) box.textContent = "none recorded";
  }

  function setHypothesis(name) {
    Object.keys(originalMatrices).forEach(function (i) {
      var o = nodeObjects[i];
      o.matrix.fromArray(originalMatrices[i]);
      o.matrix.decompose(o.position, o.quaternion, o.scale);
    });
    var h = null;
    data.hypotheses.forEach(function (x) { if (x.name === name) h = x; });
    if (name && !h) fail("no hypothesis called " + JSON.stringify(name));
    if (h) {
      Object.keys(h.nodes).forEach(function (i) {
        var o = nodeObjects[i];
        if (!o) return;
        o.matrix.fromArray(h.nodes[i]);
        o.matrix.decompose(o.position, o.quaternion, o.scale);
      });
      bannerEl.textContent = h.label;
      bannerEl.style.display = "block";
    } else {
      bannerEl.style.display = "none";
    }
    scene.updateMatrixWorld(true);
    state.hypothesis = h ? h.name : null;
    document.querySelectorAll("#hypotheses button").forEach(function (b) { b.classList.toggle("on", (b.dataset.name || null) === state.hypothesis); });
    labelsDirty = true;
  }

  function buildPanel() {
    document.getElementById("subtitle").textContent = data.project + " — lengths in " + data.units +
      (data.units_note ? " (" + data.units_note + ")" : "");
    var cams = document.getElementById("cameras");
    data.cameras.forEach(function (id) {
      if (!cameraDefs[id]) return;
      var still = data.photos[id] && data.photos[id].video;  // a still from video: its source, frame and field
      var b = el("button", { "data-id": id, title: still ? still.words : "" },
        id.replace(/^photo-/, "photo ").replace(/^view-/, "view "));
      b.addEventListener("click", function () { location.hash = "camera=" + encodeURIComponent(id); });
      cams.appendChild(b);
      if (still) cams.appendChild(el("div", { "class": "small still" }, id.replace(/^photo-/, "") + ": " + still.words));
    });
    var hyp = document.getElementById("hypotheses");
    var measured = el("button", { "class": "on" }, "measured scene");
    measured.addEventListener("click", function () { setHypothesis(null); });
    hyp.appendChild(measured);
    data.hypotheses.forEach(function (h) {
      var b = el("button", { "data-name": h.name, title: h.description || "" }, "HYPOTHESIS: " + h.name);
      b.addEventListener("click", function () { setHypothesis(h.name); });
      hyp.appendChild(b);
    });
    if (!data.hypotheses.length) hyp.appendChild(el("div", { "class": "small" }, "none recorded"));
    var about = document.getElementById("about");
    about.textContent = data.software + "; three.js (MIT, THREE-LICENSE). " + (data.textured ? "Textured from the photos; " : "Untextured (face colours); ") +
      "the photos are downscaled copies in photos/. " + (data.warnings.length ? "Warnings: " + data.warnings.join("; ") : "");
    document.getElementById("opacity").addEventListener("input", function (e) {
      photoEl.style.opacity = e.target.value;
      if (current !== null && data.photos[current]) { photoEl.src = data.photos[current].file; photoEl.style.display = "block"; }
    });
    var unobs = document.getElementById("unobserved");
    unobs.addEventListener("click", function () {
      var on = !unobs.classList.contains("on");
      unobs.classList.toggle("on", on);
      unseenMaterials.forEach(function (m) { m.uniforms.mode.value = on ? 1 : 0; });
    });
    document.getElementById("home").addEventListener("click", function () { location.hash = ""; home(); });
    document.getElementById("mode").addEventListener("click", toggleWalk);
    document.getElementById("toggle").addEventListener("click", togglePanel);
  }

  function togglePanel() {
    var p = document.getElementById("panel"), t = document.getElementById("toggle");
    var show = p.style.display === "none";
    p.style.display = show ? "" : "none";
    t.style.display = show ? "none" : "block";
  }

  function toggleWalk() {
    if (walk.isLocked) walk.unlock(); else { leaveCamera(); walk.lock(); }
  }

  var box = null;
  function home() {
    leaveCamera();
    var c = box.getCenter(new THREE.Vector3()), size = box.getSize(new THREE.Vector3());
    var first = null;
    data.cameras.forEach(function (id) { if (!first && /^view-/.test(id) && cameraDefs[id]) first = cameraDefs[id]; });
    if (first) {  // the project's first named view: a place inside the scene chosen by its author
      first.object.updateMatrixWorld(true);
      first.object.matrixWorld.decompose(camera.position, camera.quaternion, new THREE.Vector3());
      var fwd = new THREE.Vector3(0, 0, -1).applyQuaternion(camera.quaternion);
      var hit = null;
      raycaster.set(camera.position, fwd); raycaster.near = 0; raycaster.far = Infinity;
      hit = raycaster.intersectObjects(modelMeshes, false)[0];
      orbit.target.copy(camera.position).addScaledVector(fwd, hit ? hit.distance : 2.0);
    } else {
      camera.position.set(c.x + size.x * 0.9, c.y + size.y * 1.2 + 1, c.z + size.z * 0.9);
      orbit.target.copy(c);
    }
    orbit.update();
    labelsDirty = true;
  }

  function applyHash() {
    hashOptions = parseHash();
    state.clean = hashOptions.clean === "1";
    document.body.classList.toggle("clean", state.clean);
    cameraGlyphs.forEach(function (g) { g.visible = !state.clean && g.userData.id !== current; });
    overlays.forEach(function (o) { o.visible = !state.clean; });
    if ((hashOptions.hypothesis || null) !== state.hypothesis) setHypothesis(hashOptions.hypothesis || null);
    if (hashOptions.camera) lookThrough(hashOptions.camera); else if (current !== null) home();
  }

  // -- moving -----------------------------------------------------------------------------------------

  function onKey(e, down) {
    if (e.target && (e.target.tagName === "INPUT" || e.target.tagName === "TEXTAREA")) return;
    var k = e.key.length === 1 ? e.key.toLowerCase() : e.key;
    if (down && k === "h") togglePanel();
    if (down && k === "f") toggleWalk();
    keys[k] = down;
    keys.shift = e.shiftKey;
  }

  function move(dt) {
    var f = (keys.w || keys.ArrowUp ? 1 : 0) - (keys.s || keys.ArrowDown ? 1 : 0);
    var r = (keys.d || keys.ArrowRight ? 1 : 0) - (keys.a || keys.ArrowLeft ? 1 : 0);
    var u = (keys.e ? 1 : 0) - (keys.q ? 1 : 0);
    if (!f && !r && !u) return;
    leaveCamera();
    var speed = (keys.shift ? 4.0 : 1.4) * dt;  // metres per second: a walk
    var fwd = new THREE.Vector3();
    camera.getWorldDirection(fwd);
    fwd.y = 0;
    if (fwd.lengthSq() < 1e-8) fwd.set(0, 0, -1);
    fwd.normalize();
    var right = new THREE.Vector3().crossVectors(fwd, new THREE.Vector3(0, 1, 0));
    var step = fwd.multiplyScalar(f * speed).add(right.multiplyScalar(r * speed)).add(new THREE.Vector3(0, u * speed, 0));
    camera.position.add(step);
    orbit.target.add(step);
    labelsDirty = true;
  }

  function frame(time) {
    var dt = Math.min(0.1, lastTime ? (time - lastTime) / 1000 : 0);
    lastTime = time;
    move(dt);
    if (orbit.enabled && !walk.isLocked && !renderer.xr.isPresenting) orbit.update();
    var eye = new THREE.Vector3();
    camera.getWorldPosition(eye);
    cameraGlyphs.forEach(function (g) {  // not the glyph one stands in
      g.visible = !state.clean && g.userData.id !== current && g.position.distanceTo(eye) > 0.4;
    });
    renderer.render(scene, camera);
    updateLabels();
    var p = new THREE.Vector3(), d = new THREE.Vector3();
    camera.getWorldPosition(p);
    camera.getWorldDirection(d);
    state.camera = { id: current, position: toWorld(p), direction: toWorld(d),
                     walk: !!(walk && walk.isLocked), xr: renderer.xr.isPresenting };
    state.frames++;
    if (state.frames <= 3 || state.frames % 30 === 0) writeState();
  }

  function start() {
    try {
      state.stage = "starting";
      T = window.VEBUILD_THREE;
      if (!T) throw new Error("three-bundle.min.js did not load");
      if (typeof window.VEBUILD_SCENE !== "string") throw new Error("scene.js did not load");
      if (!window.VEBUILD_DATA) throw new Error("data.js did not load");
      THREE = T.THREE;
      data = window.VEBUILD_DATA;
      state.warnings = data.warnings || [];
      state.textured = data.textured;
      THREE.ColorManagement.enabled = false;  // colours as written; the shader encodes sRGB itself
      photoEl = document.getElementById("photo");
      labelsEl = document.getElementById("labels");
      bannerEl = document.getElementById("banner");
      renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
      renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
      renderer.setPixelRatio(window.devicePixelRatio || 1);
      renderer.setClearColor(0x202024, 1);
      document.getElementById("view").appendChild(renderer.domElement);
      scene = new THREE.Scene();
      scene.add(new THREE.HemisphereLight(0xffffff, 0x808080, 2.0));  // only the untextured model is lit
      camera = new THREE.PerspectiveCamera(60, window.innerWidth / window.innerHeight, 0.05, 500);
      var headlight = new THREE.DirectionalLight(0xffffff, 1.5);  // shading that shows the shapes
      headlight.position.set(0.3, 0.5, 1);
      camera.add(headlight);
      camera.add(headlight.target);
      dolly = new THREE.Group();
      dolly.add(camera);
      scene.add(dolly);
      raycaster = new THREE.Raycaster();
      state.stage = "parsing the scene";
      writeState();
      new T.GLTFLoader().parse(base64Bytes(window.VEBUILD_SCENE), "", loaded, function (e) {
        fail("the scene could not be read: " + (e && e.message ? e.message : e));
      });
    } catch (e) {
      fail(e && e.message ? e.message : e);
    }
  }

  function loaded(result) {
    gltf = result;
    var parser = gltf.parser, json = parser.json;
    scene.add(gltf.scene);
    gltf.scene.updateMatrixWorld(true);
    var nodePromises = (json.nodes || []).map(function (_, i) { return parser.getDependency("node", i); });
    Promise.all(nodePromises).then(function (objects) {
      objects.forEach(function (o, i) {
        nodeObjects[i] = o;
        o.updateMatrix();
        originalMatrices[i] = o.matrix.toArray();
        var def = json.nodes[i];
        var role = def.extras && def.extras.vebuild_role;
        if (role === "photo plane") {
          // Drawn first and behind everything (it stands at the far end of the frustum), the photo's
          // pixels as they are (no colour conversion), never hiding a label.
          photoPlanes["photo-" + def.extras.photo] = o;
          o.traverse(function (c) {
            c.userData.vebuildPlane = true;
            c.renderOrder = -1;
            if (c.material) {
              c.material.depthWrite = false;
              if (c.material.map) { c.material.map.colorSpace = THREE.NoColorSpace; c.material.map.needsUpdate = true; }
            }
          });
        }
        if (role === "measurement") o.visible = false;  // drawn with its label from data.js instead
        if (def.camera !== undefined) {
          var cdef = json.cameras[def.camera];
          var id = cdef.extras.source === "photo" ? "photo-" + cdef.name.slice(6) : "view-" + cdef.name;
          cameraDefs[id] = { object: o, extras: cdef.extras, name: cdef.name };
        }
      });
      root = nodeObjects[0];
      root.updateMatrixWorld(true);
      return prepareMaterials(parser);
    }).then(function (replacement) {
      gltf.scene.traverse(function (o) {
        if (!o.isMesh || o.userData.vebuildPlane) return;
        modelMeshes.push(o);
        var a = parser.associations.get(o.material);
        if (a && replacement[a.materials] !== undefined) o.material = replacement[a.materials];
      });
      box = new THREE.Box3().setFromObject(gltf.scene);
      Object.keys(cameraDefs).forEach(function (id) { addCameraGlyph(id, cameraDefs[id]); });
      addMarkers();
      addAnalyses();
      buildPanel();
      orbit = new T.OrbitControls(camera, renderer.domElement);
      orbit.enableDamping = false;
      orbit.addEventListener("start", function () { leaveCamera(); });
      walk = new T.PointerLockControls(camera, document.body);
      window.addEventListener("keydown", function (e) { onKey(e, true); });
      window.addEventListener("keyup", function (e) { onKey(e, false); });
      var downAt = null;
      renderer.domElement.addEventListener("pointerdown", function (e) { downAt = [e.clientX, e.clientY]; });
      renderer.domElement.addEventListener("pointerup", function (e) {
        if (!downAt || Math.hypot(e.clientX - downAt[0], e.clientY - downAt[1]) > 4) return;
        var ndc = new THREE.Vector2(e.clientX / window.innerWidth * 2 - 1, -(e.clientY / window.innerHeight) * 2 + 1);
        raycaster.near = 0; raycaster.far = Infinity;
        raycaster.setFromCamera(ndc, camera);
        var hits = raycaster.intersectObjects(cameraGlyphs, true).filter(function (h) { return h.object.isMesh && h.object.parent.visible; });
        if (hits.length) location.hash = "camera=" + encodeURIComponent(hits[0].object.userData.id);
      });
      window.addEventListener("resize", applyProjection);
      window.addEventListener("hashchange", applyHash);
      home();
      applyProjection();
      applyHash();
      if (data.single_photo && !hashOptions.camera && data.cameras.length) lookThrough(data.cameras[0]);
      setupXR();
      state.stage = "running";
      writeState();
      renderer.setAnimationLoop(frame);
    }).catch(function (e) { fail(e && e.message ? e.message : e); });
  }

  function setupXR() {
    if (!navigator.xr || !navigator.xr.isSessionSupported) { state.xr = "absent"; return; }
    state.xr = "checking";
    navigator.xr.isSessionSupported("immersive-vr").then(function (ok) {
      state.xr = ok ? "offered" : "unsupported";
      if (!ok) return;
      renderer.xr.enabled = true;
      var button = T.VRButton.createButton(renderer);
      button.id = "vr";
      document.body.appendChild(button);
      renderer.xr.addEventListener("sessionstart", function () {
        // Stand where the camera is, eyes at its height: the headset adds its own pose.
        leaveCamera();
        var p = camera.position.clone();
        camera.position.set(0, 0, 0);
        camera.quaternion.identity();
        dolly.position.set(p.x, 0, p.z);
      });
      renderer.xr.addEventListener("sessionend", function () {
        camera.position.copy(dolly.position).add(new THREE.Vector3(0, 1.6, 0));
        dolly.position.set(0, 0, 0);
        home();
      });
    }).catch(function () { state.xr = "unsupported"; });
  }

  window.VebuildViewer = { start: start, state: state };
})();
