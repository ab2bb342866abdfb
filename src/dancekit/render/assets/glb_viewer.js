// dancekit glTF viewer: a small WebGL 1 renderer for one skinned, animated .glb.
// Reads the base64 .glb in <script id="dk-glb">, parses its JSON and binary chunks, plays
// the first animation (LINEAR / STEP, slerp for rotations; CUBICSPLINE keys without
// tangents) and skins every mesh on the GPU (glTF joint matrices: the joint's global
// transform times its inverse bind matrix). A checkerboard floor at y = 0, lit surfaces,
// an orbit camera that follows the body: drag to rotate, wheel to zoom, double-click to
// reset; space plays/pauses. "#t=SECONDS" in the address opens the page paused there.
// No network: everything is in the page.
(function () {
  "use strict";

  var ds = document.documentElement.dataset;
  var conf = JSON.parse(document.getElementById("dk-conf").textContent);

  // ------------------------------------------------------------------ glb
  function b64bytes(s) {
    var bin = atob(s.replace(/\s+/g, "")), out = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out;
  }
  var glb = b64bytes(document.getElementById("dk-glb").textContent);
  var dv = new DataView(glb.buffer, glb.byteOffset, glb.byteLength);
  if (dv.getUint32(0, true) !== 0x46546C67) throw new Error("not a glb file (bad magic)");
  if (dv.getUint32(4, true) !== 2) throw new Error("glTF version " + dv.getUint32(4, true) + " is not 2");
  var gltf = null, bin = null, off = 12;
  while (off + 8 <= glb.byteLength) {
    var clen = dv.getUint32(off, true), ctype = dv.getUint32(off + 4, true);
    var chunk = glb.subarray(off + 8, off + 8 + clen);
    if (ctype === 0x4E4F534A) gltf = JSON.parse(new TextDecoder("utf-8").decode(chunk));
    else if (ctype === 0x004E4942) bin = chunk;
    off += 8 + clen;
  }
  if (!gltf) throw new Error("glb without a JSON chunk");

  var COMPONENTS = { SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4, MAT2: 4, MAT3: 9, MAT4: 16 };
  var TYPED = { 5120: Int8Array, 5121: Uint8Array, 5122: Int16Array, 5123: Uint16Array, 5125: Uint32Array, 5126: Float32Array };
  var NORM = { 5120: 127, 5121: 255, 5122: 32767, 5123: 65535 };
  // an accessor as a tightly packed typed array (a copy when strided or unaligned)
  function accessor(i) {
    var a = gltf.accessors[i], n = COMPONENTS[a.type], Typed = TYPED[a.componentType];
    var out = new Typed(a.count * n);
    if (a.bufferView === undefined) return out;  // all zeros (sparse accessors are not supported)
    var bv = gltf.bufferViews[a.bufferView];
    if ((bv.buffer || 0) !== 0 || !bin) throw new Error("only the glb's own binary buffer is supported");
    var start = bin.byteOffset + (bv.byteOffset || 0) + (a.byteOffset || 0);
    var size = Typed.BYTES_PER_ELEMENT, stride = bv.byteStride || n * size;
    var src = new DataView(bin.buffer);
    var get = { 5120: "getInt8", 5121: "getUint8", 5122: "getInt16", 5123: "getUint16", 5125: "getUint32", 5126: "getFloat32" }[a.componentType];
    for (var k = 0; k < a.count; k++) for (var c = 0; c < n; c++) out[k * n + c] = src[get](start + k * stride + c * size, true);
    return out;
  }
  function floats(i) {  // normalised integers to floats
    var a = gltf.accessors[i], v = accessor(i);
    if (v instanceof Float32Array) return v;
    var f = new Float32Array(v.length), s = a.normalized ? NORM[a.componentType] : 1;
    for (var k = 0; k < v.length; k++) f[k] = v[k] / s;
    return f;
  }

  // ------------------------------------------------------------------ math (column-major 4x4)
  function mat4() { var m = new Float32Array(16); m[0] = m[5] = m[10] = m[15] = 1; return m; }
  function mul(a, b, out) {
    out = out || new Float32Array(16);
    for (var c = 0; c < 4; c++) for (var r = 0; r < 4; r++) {
      out[c * 4 + r] = a[r] * b[c * 4] + a[4 + r] * b[c * 4 + 1] + a[8 + r] * b[c * 4 + 2] + a[12 + r] * b[c * 4 + 3];
    }
    return out;
  }
  function trs(t, q, s, out) {
    var x = q[0], y = q[1], z = q[2], w = q[3];
    out[0] = (1 - 2 * (y * y + z * z)) * s[0]; out[1] = 2 * (x * y + z * w) * s[0]; out[2] = 2 * (x * z - y * w) * s[0]; out[3] = 0;
    out[4] = 2 * (x * y - z * w) * s[1]; out[5] = (1 - 2 * (x * x + z * z)) * s[1]; out[6] = 2 * (y * z + x * w) * s[1]; out[7] = 0;
    out[8] = 2 * (x * z + y * w) * s[2]; out[9] = 2 * (y * z - x * w) * s[2]; out[10] = (1 - 2 * (x * x + y * y)) * s[2]; out[11] = 0;
    out[12] = t[0]; out[13] = t[1]; out[14] = t[2]; out[15] = 1;
    return out;
  }

  // ------------------------------------------------------------------ nodes and animation
  var nodes = (gltf.nodes || []).map(function (n) {
    return {
      t: (n.translation || [0, 0, 0]).slice(), r: (n.rotation || [0, 0, 0, 1]).slice(), s: (n.scale || [1, 1, 1]).slice(),
      matrix: n.matrix ? new Float32Array(n.matrix) : null, children: n.children || [], mesh: n.mesh, skin: n.skin,
      local: mat4(), world: mat4(),
    };
  });
  var sceneIndex = gltf.scene || 0;
  var roots = gltf.scenes && gltf.scenes[sceneIndex] ? gltf.scenes[sceneIndex].nodes : nodes.map(function (_, i) { return i; });

  var channels = [], DURATION = 0;
  var anim = (gltf.animations || [])[0];
  if (anim) {
    anim.channels.forEach(function (ch) {
      var sm = anim.samplers[ch.sampler], path = ch.target.path;
      if (ch.target.node === undefined || ["translation", "rotation", "scale"].indexOf(path) < 0) return;
      var times = floats(sm.input), values = floats(sm.output), n = path === "rotation" ? 4 : 3;
      var interp = sm.interpolation || "LINEAR";
      if (interp === "CUBICSPLINE") {  // keep the values, drop the tangents
        var v = new Float32Array(times.length * n);
        for (var k = 0; k < times.length; k++) for (var c = 0; c < n; c++) v[k * n + c] = values[(3 * k + 1) * n + c];
        values = v; interp = "LINEAR";
      }
      channels.push({ node: ch.target.node, path: path, times: times, values: values, n: n, step: interp === "STEP" });
      DURATION = Math.max(DURATION, times[times.length - 1]);
    });
  }

  function sample(ch, t, out) {
    var ts = ch.times, n = ch.n, last = ts.length - 1, k;
    if (t <= ts[0]) k = 0; else if (t >= ts[last]) k = last;
    else {
      var lo = 0, hi = last;
      while (hi - lo > 1) { var mid = (lo + hi) >> 1; if (ts[mid] <= t) lo = mid; else hi = mid; }
      k = lo;
      if (!ch.step) {
        var u = (t - ts[k]) / (ts[k + 1] - ts[k]), a = k * n, b = (k + 1) * n, v = ch.values;
        if (n === 4) {  // slerp (nlerp for nearly equal keys)
          var d = v[a] * v[b] + v[a + 1] * v[b + 1] + v[a + 2] * v[b + 2] + v[a + 3] * v[b + 3], sgn = 1;
          if (d < 0) { d = -d; sgn = -1; }
          var wa = 1 - u, wb = u;
          if (d < 0.9995) { var th = Math.acos(d), st = Math.sin(th); wa = Math.sin((1 - u) * th) / st; wb = Math.sin(u * th) / st; }
          var len = 0;
          for (var c = 0; c < 4; c++) { out[c] = wa * v[a + c] + sgn * wb * v[b + c]; len += out[c] * out[c]; }
          len = Math.sqrt(len) || 1;
          for (c = 0; c < 4; c++) out[c] /= len;
        } else {
          for (c = 0; c < n; c++) out[c] = (1 - u) * v[a + c] + u * v[b + c];
        }
        return;
      }
    }
    for (c = 0; c < n; c++) out[c] = ch.values[k * n + c];
  }

  function pose(t) {
    for (var i = 0; i < channels.length; i++) {
      var ch = channels[i], nd = nodes[ch.node];
      sample(ch, t, ch.path === "translation" ? nd.t : ch.path === "rotation" ? nd.r : nd.s);
    }
    var stack = roots.map(function (r) { return [r, null]; });
    while (stack.length) {
      var top = stack.pop(), nd = nodes[top[0]];
      var local = nd.matrix && !channels.some(function (c) { return c.node === top[0]; }) ? nd.matrix : trs(nd.t, nd.r, nd.s, nd.local);
      if (top[1]) mul(top[1], local, nd.world); else nd.world.set(local);
      for (var k = 0; k < nd.children.length; k++) stack.push([nd.children[k], nd.world]);
    }
  }

  // ------------------------------------------------------------------ WebGL
  var canvas = document.getElementById("dk-canvas");
  var gl = canvas.getContext("webgl", { antialias: true, preserveDrawingBuffer: true }) ||
    canvas.getContext("experimental-webgl", { antialias: true, preserveDrawingBuffer: true });
  if (!gl) { document.getElementById("dk-help").textContent = "this browser has no WebGL"; throw new Error("no WebGL"); }
  var uintIndex = gl.getExtension("OES_element_index_uint");

  var maxJoints = 1;
  (gltf.skins || []).forEach(function (s) { maxJoints = Math.max(maxJoints, s.joints.length); });
  var VS = [
    "attribute vec3 a_pos; attribute vec3 a_nrm; attribute vec4 a_jnt; attribute vec4 a_wgt;",
    "uniform mat4 u_joints[" + maxJoints + "]; uniform mat4 u_viewproj;",
    "varying vec3 v_nrm; varying vec3 v_world;",
    "void main() {",
    "  mat4 m = a_wgt.x * u_joints[int(a_jnt.x)] + a_wgt.y * u_joints[int(a_jnt.y)]",
    "         + a_wgt.z * u_joints[int(a_jnt.z)] + a_wgt.w * u_joints[int(a_jnt.w)];",
    "  vec4 w = m * vec4(a_pos, 1.0);",
    "  v_world = w.xyz; v_nrm = mat3(m) * a_nrm;",
    "  gl_Position = u_viewproj * w;",
    "}",
  ].join("\n");
  var FS = [
    "precision mediump float;",
    "varying vec3 v_nrm; varying vec3 v_world; uniform vec4 u_color; uniform vec3 u_eye;",
    "void main() {",
    "  vec3 n = normalize(v_nrm); vec3 v = normalize(u_eye - v_world);",
    "  if (dot(n, v) < 0.0) n = -n;",
    "  vec3 l = normalize(vec3(-0.4, 1.0, 0.5));",
    "  float diff = max(dot(n, l), 0.0), fill = max(dot(n, normalize(vec3(0.6, 0.2, -0.7))), 0.0);",
    "  float rim = pow(1.0 - max(dot(n, v), 0.0), 3.0);",
    "  float spec = pow(max(dot(n, normalize(l + v)), 0.0), 24.0);",
    "  vec3 c = u_color.rgb * (0.32 + 0.72 * diff + 0.18 * fill) + 0.12 * spec + 0.10 * rim;",
    "  gl_FragColor = vec4(c, u_color.a);",
    "}",
  ].join("\n");
  var FLOOR_VS = "attribute vec3 a_pos; attribute vec3 a_col; uniform mat4 u_viewproj; varying vec3 v_col; varying vec3 v_w;\n" +
    "void main() { v_col = a_col; v_w = a_pos; gl_Position = u_viewproj * vec4(a_pos, 1.0); }";
  var FLOOR_FS = "precision mediump float; varying vec3 v_col; varying vec3 v_w; uniform vec3 u_center; uniform vec3 u_fog;\n" +
    "void main() { float d = length(v_w.xz - u_center.xz); float f = clamp(d / 9.0, 0.0, 1.0);\n" +
    "  gl_FragColor = vec4(mix(v_col, u_fog, f * f), 1.0); }";

  function program(vs, fs) {
    function shader(type, src) {
      var s = gl.createShader(type);
      gl.shaderSource(s, src); gl.compileShader(s);
      if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error("shader: " + gl.getShaderInfoLog(s));
      return s;
    }
    var p = gl.createProgram();
    gl.attachShader(p, shader(gl.VERTEX_SHADER, vs)); gl.attachShader(p, shader(gl.FRAGMENT_SHADER, fs));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error("program: " + gl.getProgramInfoLog(p));
    return p;
  }
  var prog = program(VS, FS), floorProg = program(FLOOR_VS, FLOOR_FS);
  function buffer(data, target) {
    var b = gl.createBuffer();
    gl.bindBuffer(target || gl.ARRAY_BUFFER, b);
    gl.bufferData(target || gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    return b;
  }

  // draw lists: one entry per primitive of every mesh node
  var draws = [], triangles = 0;
  var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  nodes.forEach(function (nd, ni) {
    if (nd.mesh === undefined) return;
    gltf.meshes[nd.mesh].primitives.forEach(function (pr) {
      if ((pr.mode === undefined ? 4 : pr.mode) !== 4 || pr.attributes.POSITION === undefined) return;
      var P = floats(pr.attributes.POSITION), V = P.length / 3;
      for (var k = 0; k < P.length; k++) { lo[k % 3] = Math.min(lo[k % 3], P[k]); hi[k % 3] = Math.max(hi[k % 3], P[k]); }
      var N = pr.attributes.NORMAL !== undefined ? floats(pr.attributes.NORMAL) : new Float32Array(V * 3).fill(0).map(function (_, i) { return i % 3 === 1 ? 1 : 0; });
      var skinned = nd.skin !== undefined && pr.attributes.JOINTS_0 !== undefined && pr.attributes.WEIGHTS_0 !== undefined;
      var Jn = new Float32Array(V * 4), Wt = new Float32Array(V * 4);
      if (skinned) { Jn = Float32Array.from(accessor(pr.attributes.JOINTS_0)); Wt = floats(pr.attributes.WEIGHTS_0); }
      else for (k = 0; k < V; k++) Wt[4 * k] = 1;
      var idx, count, itype;
      if (pr.indices !== undefined) {
        idx = accessor(pr.indices); count = idx.length;
        if (idx instanceof Uint32Array) {
          var big = false;
          for (k = 0; k < idx.length; k++) if (idx[k] > 65535) { big = true; break; }
          if (!big) idx = Uint16Array.from(idx);
          else if (!uintIndex) throw new Error("32-bit indices need OES_element_index_uint");
        } else if (idx instanceof Uint8Array) idx = Uint16Array.from(idx);
        itype = idx instanceof Uint32Array ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT;
      } else { count = V; }
      var mat = pr.material !== undefined && gltf.materials ? gltf.materials[pr.material] : null;
      var color = mat && mat.pbrMetallicRoughness && mat.pbrMetallicRoughness.baseColorFactor || [0.8, 0.8, 0.8, 1];
      triangles += Math.floor(count / 3);
      draws.push({
        node: ni, skin: skinned ? gltf.skins[nd.skin] : null, count: count, itype: itype,
        pos: buffer(P), nrm: buffer(N), jnt: buffer(Jn), wgt: buffer(Wt),
        idx: idx ? buffer(idx, gl.ELEMENT_ARRAY_BUFFER) : null, color: color,
        ibm: skinned && gltf.skins[nd.skin].inverseBindMatrices !== undefined ? floats(gltf.skins[nd.skin].inverseBindMatrices) : null,
        joints: new Float32Array(16 * maxJoints),
      });
    });
  });
  if (!draws.length) throw new Error("the glb has no triangle mesh to show");

  // floor tiles: 0.5 m checkerboard, 24 m wide, two triangles per tile with vertex colours
  var TILE = 0.5, NT = 48, floorPos = [], floorCol = [];
  for (var i = 0; i < NT; i++) for (var k2 = 0; k2 < NT; k2++) {
    var x0 = (i - NT / 2) * TILE, z0 = (k2 - NT / 2) * TILE, dark = (i + k2) % 2 === 1;
    var col = dark ? [0.66, 0.69, 0.745] : [0.886, 0.898, 0.918];
    [[0, 0], [1, 0], [1, 1], [0, 0], [1, 1], [0, 1]].forEach(function (q) {
      floorPos.push(x0 + q[0] * TILE, 0, z0 + q[1] * TILE); floorCol.push(col[0], col[1], col[2]);
    });
  }
  var floorBuf = buffer(new Float32Array(floorPos)), floorColBuf = buffer(new Float32Array(floorCol)), floorCount = floorPos.length / 3;

  // ------------------------------------------------------------------ skinning and camera target
  function skinMatrices(d) {
    var m = new Float32Array(16);
    if (!d.skin) { d.joints.set(nodes[d.node].world, 0); return; }
    var js = d.skin.joints;
    for (var j = 0; j < js.length; j++) {
      if (d.ibm) mul(nodes[js[j]].world, d.ibm.subarray(16 * j, 16 * j + 16), m); else m.set(nodes[js[j]].world);
      d.joints.set(m, 16 * j);
    }
  }
  // the followed point: the centre of the skinned joints (or of the mesh nodes), floor height fixed
  var followNodes = [];
  draws.forEach(function (d) { if (d.skin) followNodes = followNodes.concat(d.skin.joints); else followNodes.push(d.node); });
  function centre() {
    var c = [0, 0, 0];
    followNodes.forEach(function (n) { for (var a = 0; a < 3; a++) c[a] += nodes[n].world[12 + a] / followNodes.length; });
    return c;
  }
  pose(0);
  var size = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 0.5);
  var restCentre = centre();
  var HEIGHT = Math.max(0.5, Math.min(3.0, 2 * restCentre[1] || size));

  // ------------------------------------------------------------------ camera and controls
  var FOV = 40 * Math.PI / 180;
  var cam0 = { az: conf.azimuth, el: conf.elevation, dist: 0.95 * HEIGHT / Math.tan(FOV / 2) };
  var cam = { az: cam0.az, el: cam0.el, dist: cam0.dist };
  var playBtn = document.getElementById("dk-play"), scrub = document.getElementById("dk-scrub");
  var timeLabel = document.getElementById("dk-time");
  var STEPS = 1000;
  scrub.max = String(STEPS);
  var playing = false, clockStart = 0, clockOffset = 0, scrubbing = false, follow = null;
  function currentTime() { return playing ? clockOffset + (performance.now() - clockStart) / 1000 : clockOffset; }
  function setTime(t) { clockOffset = Math.max(0, Math.min(t, DURATION)); clockStart = performance.now(); }
  function fmt(t) { var m = Math.floor(t / 60), s = t - 60 * m; return m + ":" + (s < 10 ? "0" : "") + s.toFixed(1); }
  function updateButton() {
    playBtn.textContent = playing ? "\u275A\u275A" : "\u25B6";
    playBtn.setAttribute("aria-label", playing ? "pause" : "play");
  }
  function play() { if (currentTime() >= DURATION) setTime(0); playing = true; clockStart = performance.now(); updateButton(); }
  function pause() { clockOffset = currentTime(); playing = false; updateButton(); }
  playBtn.addEventListener("click", function () { if (playing) pause(); else play(); });
  scrub.addEventListener("input", function () { setTime(Number(scrub.value) / STEPS * DURATION); draw(); });
  scrub.addEventListener("pointerdown", function () { scrubbing = true; });
  window.addEventListener("pointerup", function () { scrubbing = false; });
  window.addEventListener("keydown", function (e) {
    if (e.key === " ") { e.preventDefault(); if (playing) pause(); else play(); }
  });
  var drag = null;
  canvas.addEventListener("pointerdown", function (e) { drag = { x: e.clientX, y: e.clientY, az: cam.az, el: cam.el }; canvas.classList.add("dk-dragging"); });
  canvas.addEventListener("pointermove", function (e) {
    if (!drag) return;
    cam.az = drag.az - (e.clientX - drag.x) * 0.4;
    cam.el = Math.max(-10, Math.min(85, drag.el + (e.clientY - drag.y) * 0.3));
    draw();
  });
  function endDrag() { drag = null; canvas.classList.remove("dk-dragging"); }
  canvas.addEventListener("pointerup", endDrag);
  canvas.addEventListener("pointercancel", endDrag);
  canvas.addEventListener("wheel", function (e) {
    e.preventDefault();
    cam.dist = Math.max(0.3, Math.min(80, cam.dist * Math.exp(e.deltaY * 0.0012)));
    draw();
  }, { passive: false });
  canvas.addEventListener("dblclick", function () { cam.az = cam0.az; cam.el = cam0.el; cam.dist = cam0.dist; draw(); });

  function viewProj(target, aspect) {
    var a = cam.az * Math.PI / 180, e = cam.el * Math.PI / 180;
    var f = [-Math.cos(e) * Math.sin(a), -Math.sin(e), -Math.cos(e) * Math.cos(a)];
    var eye = [target[0] - cam.dist * f[0], target[1] - cam.dist * f[1], target[2] - cam.dist * f[2]];
    var r = [-f[2], 0, f[0]], rn = Math.hypot(r[0], r[2]) || 1;
    r = [r[0] / rn, 0, r[2] / rn];
    var u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]];
    var view = new Float32Array([r[0], u[0], -f[0], 0, r[1], u[1], -f[1], 0, r[2], u[2], -f[2], 0,
      -(r[0] * eye[0] + r[1] * eye[1] + r[2] * eye[2]), -(u[0] * eye[0] + u[1] * eye[1] + u[2] * eye[2]),
      f[0] * eye[0] + f[1] * eye[1] + f[2] * eye[2], 1]);
    var near = 0.05, far = 200, ft = 1 / Math.tan(FOV / 2);
    var proj = new Float32Array([ft / aspect, 0, 0, 0, 0, ft, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, 2 * far * near / (near - far), 0]);
    return { m: mul(proj, view), eye: eye };
  }

  function resize() {
    var dpr = window.devicePixelRatio || 1, rect = canvas.getBoundingClientRect();
    var w = Math.max(1, Math.round(rect.width * dpr)), h = Math.max(1, Math.round(rect.height * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  }
  window.addEventListener("resize", function () { resize(); draw(); });

  function attrib(p, name, buf, n) {
    var loc = gl.getAttribLocation(p, name);
    if (loc < 0) return;
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.enableVertexAttribArray(loc);
    gl.vertexAttribPointer(loc, n, gl.FLOAT, false, 0, 0);
  }

  function draw() {
    var t = Math.min(currentTime(), DURATION);
    if (!scrubbing) scrub.value = String(DURATION > 0 ? Math.round(t / DURATION * STEPS) : 0);
    timeLabel.textContent = fmt(t) + " / " + fmt(DURATION);
    pose(t);
    var c = centre();
    // follow the body smoothly on the floor, at a fixed height
    if (!follow || !playing) follow = [c[0], 0.5 * HEIGHT, c[2]];
    else { follow[0] += 0.15 * (c[0] - follow[0]); follow[2] += 0.15 * (c[2] - follow[2]); }
    var W = canvas.width, H = canvas.height;
    gl.viewport(0, 0, W, H);
    gl.clearColor(0.91, 0.925, 0.95, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    var vp = viewProj(follow, W / H);

    gl.useProgram(floorProg);
    gl.uniformMatrix4fv(gl.getUniformLocation(floorProg, "u_viewproj"), false, vp.m);
    gl.uniform3fv(gl.getUniformLocation(floorProg, "u_center"), follow);
    gl.uniform3fv(gl.getUniformLocation(floorProg, "u_fog"), [0.91, 0.925, 0.95]);
    attrib(floorProg, "a_pos", floorBuf, 3);
    attrib(floorProg, "a_col", floorColBuf, 3);
    gl.drawArrays(gl.TRIANGLES, 0, floorCount);

    gl.useProgram(prog);
    gl.uniformMatrix4fv(gl.getUniformLocation(prog, "u_viewproj"), false, vp.m);
    gl.uniform3fv(gl.getUniformLocation(prog, "u_eye"), vp.eye);
    var drawn = 0;
    draws.forEach(function (d) {
      skinMatrices(d);
      gl.uniformMatrix4fv(gl.getUniformLocation(prog, "u_joints"), false, d.joints);
      gl.uniform4fv(gl.getUniformLocation(prog, "u_color"), d.color);
      attrib(prog, "a_pos", d.pos, 3); attrib(prog, "a_nrm", d.nrm, 3);
      attrib(prog, "a_jnt", d.jnt, 4); attrib(prog, "a_wgt", d.wgt, 4);
      if (d.idx) { gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, d.idx); gl.drawElements(gl.TRIANGLES, d.count, d.itype, 0); }
      else gl.drawArrays(gl.TRIANGLES, 0, d.count);
      drawn++;
    });
    var err = gl.getError();
    if (err !== gl.NO_ERROR) throw new Error("WebGL error " + err);
    ds.dkStatus = "drawn";
    ds.dkDrawn = String(drawn);
    ds.dkTriangles = String(triangles);
    ds.dkJoints = String(maxJoints);
    ds.dkTime = t.toFixed(3);
    ds.dkDuration = DURATION.toFixed(3);
    ds.dkCamera = cam.az.toFixed(1) + "," + cam.el.toFixed(1) + "," + cam.dist.toFixed(2);
  }

  function loop() {
    if (playing) {
      if (currentTime() >= DURATION) { clockOffset = DURATION; playing = false; updateButton(); }
      draw();
    }
    requestAnimationFrame(loop);
  }

  var m = /(?:^#|&)t=([0-9.]+)/.exec(window.location.hash);
  if (m) setTime(parseFloat(m[1]));
  resize();
  updateButton();
  draw();
  requestAnimationFrame(loop);
})();
