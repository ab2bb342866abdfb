// dancekit html player: a small Canvas-2D perspective renderer for one dance.
// Reads the JSON in <script id="dk-data">, draws a checkerboard floor, a soft shadow
// and the skeleton (left blue, right orange) or, with data.figure "body", a mannequin
// (shaded capsules, a rounded torso, a head with a face that turns with the body), and keeps the dance in sync with the
// <audio id="dk-audio"> element when there is one: frame = floor(currentTime * fps).
// Without audio it plays on a clock. Orbit camera: drag to rotate, wheel to zoom,
// double-click to reset; space plays/pauses, arrows step; "#t=SECONDS" opens it paused there.
// Scene: metres, +y up, floor at y = 0 (see dancekit/render/_scene.py).
(function () {
  "use strict";

  var data = JSON.parse(document.getElementById("dk-data").textContent);
  var FPS = data.fps, T = data.frames, J = data.joints;
  var DURATION = data.duration;
  var NFRAMES = Math.max(1, Math.round(DURATION * FPS));

  function b64bytes(s) {
    var bin = atob(s), out = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out;
  }

  // positions: uint16 little-endian, p = offset + v * scale per axis
  var pos = new Float32Array(T * J * 3);
  (function () {
    var bytes = b64bytes(data.positions), dv = new DataView(bytes.buffer);
    var off = data.offset, sc = data.scale;
    for (var i = 0, n = T * J * 3; i < n; i++) {
      var a = i % 3;
      pos[i] = off[a] + dv.getUint16(2 * i, true) * sc[a];
    }
  })();
  var target = new Float32Array(T * 3);
  (function () {
    var bytes = b64bytes(data.target), dv = new DataView(bytes.buffer);
    for (var i = 0; i < T * 3; i++) target[i] = dv.getFloat32(4 * i, true);
  })();

  var bones = data.bones, sides = data.sides, head = data.head;
  var boneSide = bones.map(function (b) {
    var sc = sides[b[0]], sp = sides[b[1]];
    return sc === sp || sp === 0 ? sc : 0;
  });
  var COLORS = { "1": [52, 120, 220], "-1": [236, 112, 40], "0": [70, 78, 96] };
  var TILE = 0.5, FOG = 14.0, RADIUS = 9.0;
  var BONE_R = 0.032 * data.height / 1.75, JOINT_R = 0.04 * data.height / 1.75, HEAD_R = 0.11 * data.height / 1.75;
  var FOV = 40 * Math.PI / 180, NEAR = 0.05;
  var BODY = data.figure === "body";
  // body figure: a mannequin with a slight blue / orange tint for the left / right limbs (as the mp4)
  var SKIN = { "1": [196, 200, 222], "-1": [226, 196, 178], "0": [214, 200, 194] };
  var TORSO_R = 0.075 * data.height / 1.75, FACE_R = 1.15 * HEAD_R;
  var torso = data.torso || [], limbR = data.limbRadius || [], isLimb = data.limb || [];

  // ------------------------------------------------------------------ DOM
  var canvas = document.getElementById("dk-canvas");
  var ctx = canvas.getContext("2d");
  var audio = document.getElementById("dk-audio");
  var playBtn = document.getElementById("dk-play");
  var scrub = document.getElementById("dk-scrub");
  var timeLabel = document.getElementById("dk-time");
  scrub.max = String(NFRAMES - 1);

  // ------------------------------------------------------------------ camera
  var cam = { az: data.azimuth, el: data.elevation, dist: data.distance };
  function resetCamera() { cam.az = data.azimuth; cam.el = data.elevation; cam.dist = data.distance; }

  function basis() {
    var a = cam.az * Math.PI / 180, e = cam.el * Math.PI / 180;
    var ce = Math.cos(e), se = Math.sin(e);
    var f = [-ce * Math.sin(a), -se, -ce * Math.cos(a)];
    var r = [-f[2], 0, f[0]];  // f x (0, 1, 0)
    var rn = Math.hypot(r[0], r[2]) || 1;
    r = [r[0] / rn, 0, r[2] / rn];
    var u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]];
    return { r: r, u: u, f: f };
  }

  // ------------------------------------------------------------------ playback state
  var frame = 0, playing = false, clockStart = 0, clockOffset = 0;

  function currentTime() {
    if (audio) return audio.currentTime;
    if (playing) return clockOffset + (performance.now() - clockStart) / 1000;
    return clockOffset;
  }
  function setTime(t) {
    t = Math.max(0, Math.min(t, DURATION));
    if (audio) { audio.currentTime = t; }
    clockOffset = t; clockStart = performance.now();
  }
  function fmt(t) {
    var m = Math.floor(t / 60), s = t - 60 * m;
    return m + ":" + (s < 10 ? "0" : "") + s.toFixed(1);
  }
  function play() {
    if (currentTime() >= DURATION - 0.5 / FPS) setTime(0);
    playing = true;
    clockStart = performance.now();
    if (audio) {
      var p = audio.play();
      if (p && p.catch) p.catch(function (err) { playing = false; updateButton(); showNote("audio: " + err.message); });
    }
    updateButton();
  }
  function pause() {
    if (!audio) clockOffset = currentTime();
    playing = false;
    if (audio) audio.pause();
    updateButton();
  }
  function updateButton() {
    playBtn.textContent = playing ? "\u275A\u275A" : "\u25B6";
    playBtn.setAttribute("aria-label", playing ? "pause" : "play");
  }
  function showNote(msg) { document.getElementById("dk-help").textContent = msg; }

  var scrubbing = false;
  playBtn.addEventListener("click", function () { if (playing) pause(); else play(); });
  scrub.addEventListener("input", function () { setTime(Number(scrub.value) / FPS); draw(); });
  scrub.addEventListener("pointerdown", function () { scrubbing = true; });
  window.addEventListener("pointerup", function () { scrubbing = false; });
  if (audio) {
    audio.addEventListener("ended", function () { playing = false; updateButton(); });
    audio.addEventListener("pause", function () { if (playing && audio.ended) { playing = false; updateButton(); } });
  }
  window.addEventListener("keydown", function (e) {
    if (e.target && e.target.tagName === "INPUT" && e.key !== " ") return;
    if (e.key === " ") { e.preventDefault(); if (playing) pause(); else play(); }
    else if (e.key === "ArrowRight") { setTime((frame + 1 + 0.5) / FPS); draw(); }
    else if (e.key === "ArrowLeft") { setTime((frame - 1 + 0.5) / FPS); draw(); }
  });

  // orbit: drag rotates, wheel zooms, double-click resets
  var drag = null;
  canvas.addEventListener("pointerdown", function (e) {
    drag = { x: e.clientX, y: e.clientY, az: cam.az, el: cam.el };
    try { canvas.setPointerCapture(e.pointerId); } catch (err) { /* synthetic events have no capture */ }
    canvas.classList.add("dk-dragging");
  });
  canvas.addEventListener("pointermove", function (e) {
    if (!drag) return;
    cam.az = drag.az - (e.clientX - drag.x) * 0.4;
    cam.el = Math.max(1, Math.min(85, drag.el + (e.clientY - drag.y) * 0.3));
    draw();
  });
  function endDrag() { drag = null; canvas.classList.remove("dk-dragging"); }
  canvas.addEventListener("pointerup", endDrag);
  canvas.addEventListener("pointercancel", endDrag);
  canvas.addEventListener("wheel", function (e) {
    e.preventDefault();
    cam.dist = Math.max(0.5, Math.min(60, cam.dist * Math.exp(e.deltaY * 0.0012)));
    draw();
  }, { passive: false });
  canvas.addEventListener("dblclick", function () { resetCamera(); draw(); });

  // ------------------------------------------------------------------ drawing
  var W = 0, H = 0, DPR = 1;
  function resize() {
    DPR = window.devicePixelRatio || 1;
    var rect = canvas.getBoundingClientRect();
    W = Math.max(1, Math.round(rect.width * DPR));
    H = Math.max(1, Math.round(rect.height * DPR));
    if (canvas.width !== W || canvas.height !== H) { canvas.width = W; canvas.height = H; }
  }
  window.addEventListener("resize", function () { resize(); draw(); });

  function shade(rgb, k) {
    return "rgb(" + Math.min(255, Math.round(rgb[0] * k)) + "," + Math.min(255, Math.round(rgb[1] * k)) + "," +
      Math.min(255, Math.round(rgb[2] * k)) + ")";
  }

  function draw() {
    frame = Math.min(NFRAMES - 1, Math.max(0, Math.floor(currentTime() * FPS + 1e-6)));
    var t = Math.min(frame, T - 1);
    if (!scrubbing) scrub.value = String(frame);
    timeLabel.textContent = fmt(Math.min(currentTime(), DURATION)) + " / " + fmt(DURATION);

    var B = basis(), r = B.r, u = B.u, f = B.f;
    var tx = target[3 * t], ty = target[3 * t + 1], tz = target[3 * t + 2];
    var cx = tx - cam.dist * f[0], cy = ty - cam.dist * f[1], cz = tz - cam.dist * f[2];
    var foc = 0.5 * H / Math.tan(FOV / 2);
    // camera coordinates of a world point: [x, y, z]
    function toCam(x, y, z) {
      var dx = x - cx, dy = y - cy, dz = z - cz;
      return [dx * r[0] + dy * r[1] + dz * r[2], dx * u[0] + dy * u[1] + dz * u[2], dx * f[0] + dy * f[1] + dz * f[2]];
    }
    function toPix(c) { return [0.5 * W + foc * c[0] / c[2], 0.5 * H - foc * c[1] / c[2]]; }

    // sky
    var sky = ctx.createLinearGradient(0, 0, 0, H);
    sky.addColorStop(0, "#ecf0f6");
    sky.addColorStop(1, "#cdd5e0");
    ctx.fillStyle = sky;
    ctx.fillRect(0, 0, W, H);

    // floor: tiles around the target, clipped at the near plane, fading with distance
    if (cy > 0) {
      var n = Math.ceil(RADIUS / TILE);
      var gx0 = Math.floor(tx / TILE) - n, gz0 = Math.floor(tz / TILE) - n, G = 2 * n + 1;
      var verts = new Array((G + 1) * (G + 1));
      for (var i = 0; i <= G; i++) for (var k = 0; k <= G; k++) verts[i * (G + 1) + k] = toCam((gx0 + i) * TILE, 0, (gz0 + k) * TILE);
      for (i = 0; i < G; i++) {
        for (k = 0; k < G; k++) {
          var mx = (gx0 + i + 0.5) * TILE - tx, mz = (gz0 + k + 0.5) * TILE - tz;
          if (mx * mx + mz * mz > RADIUS * RADIUS) continue;
          var poly = clipNear([verts[i * (G + 1) + k], verts[(i + 1) * (G + 1) + k], verts[(i + 1) * (G + 1) + k + 1], verts[i * (G + 1) + k + 1]]);
          if (poly.length < 3) continue;
          var dcam = Math.hypot((gx0 + i + 0.5) * TILE - cx, cy, (gz0 + k + 0.5) * TILE - cz);
          var fog = Math.min(1, Math.max(dcam / FOG, Math.sqrt(mx * mx + mz * mz) / RADIUS));
          var dark = ((gx0 + i + gz0 + k) % 2 + 2) % 2 === 1;
          ctx.globalAlpha = Math.max(0, 1 - Math.pow(fog, 1.5));
          ctx.fillStyle = dark ? "#a8b0be" : "#e2e5ea";
          ctx.beginPath();
          for (var q = 0; q < poly.length; q++) {
            var p = toPix(poly[q]);
            if (q === 0) ctx.moveTo(p[0], p[1]); else ctx.lineTo(p[0], p[1]);
          }
          ctx.closePath();
          ctx.fill();
        }
      }
      ctx.globalAlpha = 1;
    }

    // joints of this frame in camera space
    var cj = new Array(J);
    for (var j = 0; j < J; j++) cj[j] = toCam(pos[3 * (t * J + j)], pos[3 * (t * J + j) + 1], pos[3 * (t * J + j) + 2]);
    ctx.lineCap = "round";

    // shadow: bones projected straight down, one path (overlaps do not darken)
    if (cy > 0) {
      var gz = toCam(target[3 * t], 0, target[3 * t + 2])[2];
      if (gz > NEAR) {
        var shadowPasses = [[4.2, "rgba(40, 46, 62, 0.15)"]];
        for (var pass = 0; pass < shadowPasses.length; pass++) {
          ctx.strokeStyle = shadowPasses[pass][1];
          ctx.lineWidth = shadowPasses[pass][0] * BONE_R * foc / gz;
          ctx.beginPath();
          for (var b = 0; b < bones.length; b++) {
            var a0 = bones[b][0], a1 = bones[b][1];
            var g0 = toCam(pos[3 * (t * J + a0)], 0, pos[3 * (t * J + a0) + 2]);
            var g1 = toCam(pos[3 * (t * J + a1)], 0, pos[3 * (t * J + a1) + 2]);
            if (g0[2] < NEAR || g1[2] < NEAR) continue;
            var s0 = toPix(g0), s1 = toPix(g1);
            ctx.moveTo(s0[0], s0[1]); ctx.lineTo(s1[0], s1[1]);
          }
          ctx.stroke();
        }
      }
    }

    if (BODY) {
      drawBody(t, cj, toCam, toPix, foc, [cx, cy, cz]);
      return;
    }
    // figure: bones far to near, head disc in front of the bones that end at it
    var zs = cj.map(function (c) { return c[2]; }).slice().sort(function (a, b) { return a - b; });
    var zmid = zs[Math.floor(zs.length / 2)];
    var items = [];
    for (b = 0; b < bones.length; b++) items.push({ d: 0.5 * (cj[bones[b][0]][2] + cj[bones[b][1]][2]), b: b });
    if (head !== null) {
      var hd = cj[head][2];
      for (b = 0; b < bones.length; b++) if (bones[b][0] === head || bones[b][1] === head) hd = Math.min(hd, cj[bones[b][0]][2], cj[bones[b][1]][2]);
      items.push({ d: hd - 1e-3, b: -1 });
    }
    items.sort(function (x, y) { return y.d - x.d; });
    var drawn = 0;
    for (var it = 0; it < items.length; it++) {
      var kb = 1 + 0.22 * Math.max(-1, Math.min(1, (zmid - items[it].d) / 0.6));
      if (items[it].b < 0) {
        var ch = cj[head];
        if (ch[2] < NEAR) continue;
        var ph = toPix(ch), rh = HEAD_R * foc / ch[2];
        ctx.fillStyle = shade([232, 196, 160], kb);
        ctx.strokeStyle = shade([150, 112, 84], kb);
        ctx.lineWidth = Math.max(1, 0.12 * rh);
        ctx.beginPath(); ctx.arc(ph[0], ph[1], rh, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
        drawn++;
        continue;
      }
      var c0 = cj[bones[items[it].b][0]], c1 = cj[bones[items[it].b][1]];
      if (c0[2] < NEAR || c1[2] < NEAR) continue;
      var p0 = toPix(c0), p1 = toPix(c1);
      ctx.strokeStyle = shade(COLORS[String(boneSide[items[it].b])], kb);
      ctx.lineWidth = BONE_R * foc * (1 / c0[2] + 1 / c1[2]);
      ctx.beginPath(); ctx.moveTo(p0[0], p0[1]); ctx.lineTo(p1[0], p1[1]); ctx.stroke();
      var ends = [[bones[items[it].b][0], c0, p0], [bones[items[it].b][1], c1, p1]];
      for (var e = 0; e < 2; e++) {
        ctx.fillStyle = shade(COLORS[String(sides[ends[e][0]])], 0.82 * kb);
        ctx.beginPath(); ctx.arc(ends[e][2][0], ends[e][2][1], JOINT_R * foc / ends[e][1][2], 0, 2 * Math.PI); ctx.fill();
      }
      drawn++;
    }
    report(drawn);
  }

  function report(drawn) {
    var ds = document.documentElement.dataset;
    ds.dkStatus = "drawn";
    ds.dkFigure = BODY ? "body" : "stick";
    ds.dkDrawn = String(drawn);
    ds.dkFrame = String(frame);
    ds.dkCamera = cam.az.toFixed(1) + "," + cam.el.toFixed(1) + "," + cam.dist.toFixed(2);
  }

  // the body figure: limbs as shaded capsules, the torso as the rounded outline of its joints, the
  // head as a ball with a face towards the body's front; far to near (painter's order)
  function drawBody(t, cj, toCam, toPix, foc, camPos) {
    var zs = cj.map(function (c) { return c[2]; }).slice().sort(function (a, b) { return a - b; });
    var zmid = zs[Math.floor(zs.length / 2)];
    function level(d) { return 1 + 0.22 * Math.max(-1, Math.min(1, (zmid - d) / 0.6)); }
    function P(j, a) { return pos[3 * (t * J + j) + a]; }
    // the body's front this frame: left (mean of left joints - mean of right joints) x up
    var lx = 0, lz = 0, nl = 0, nr = 0, rx = 0, rz = 0;
    for (var j = 0; j < J; j++) {
      if (sides[j] > 0) { lx += P(j, 0); lz += P(j, 2); nl++; }
      else if (sides[j] < 0) { rx += P(j, 0); rz += P(j, 2); nr++; }
    }
    var side = null, front = null;
    if (nl && nr) {
      var ax = lx / nl - rx / nr, az = lz / nl - rz / nr, an = Math.hypot(ax, az);
      if (an > 1e-6) { side = [ax / an, 0, az / an]; front = [-side[2], 0, side[0]]; }
    }
    var items = [];
    for (var b = 0; b < bones.length; b++) {
      if (isLimb[b]) items.push({ d: 0.5 * (cj[bones[b][0]][2] + cj[bones[b][1]][2]), k: 0, i: b });
    }
    if (torso.length >= 3) {
      var tz = 0;
      for (var q = 0; q < torso.length; q++) tz += cj[torso[q]][2];
      items.push({ d: tz / torso.length, k: 1, i: 0 });
    }
    if (head !== null) {
      var hd = cj[head][2];
      for (b = 0; b < bones.length; b++) if (bones[b][0] === head || bones[b][1] === head) hd = Math.min(hd, cj[bones[b][0]][2], cj[bones[b][1]][2]);
      items.push({ d: hd - 1e-3, k: 2, i: head });
    }
    items.sort(function (x, y) { return y.d - x.d; });
    ctx.lineCap = "round";
    ctx.lineJoin = "round";
    var drawn = 0;
    for (var it = 0; it < items.length; it++) {
      var item = items[it], kb = level(item.d);
      if (item.k === 0) {
        var c = bones[item.i][0], p = bones[item.i][1];
        if (cj[c][2] < NEAR || cj[p][2] < NEAR) continue;
        var a = toPix(cj[c]), e = toPix(cj[p]);
        var r = limbR[item.i] * 0.5 * foc * (1 / cj[c][2] + 1 / cj[p][2]);
        var skin = SKIN[String(boneSide[item.i])];
        capsule(a, e, r, shade(skin, 0.62 * kb));
        // the inside: a gradient across the limb, lit from the upper left
        var dx = e[0] - a[0], dy = e[1] - a[1], dn = Math.hypot(dx, dy) || 1;
        var nx = -dy / dn, ny = dx / dn;
        if (nx + ny > 0) { nx = -nx; ny = -ny; }
        var mx = 0.5 * (a[0] + e[0]), my = 0.5 * (a[1] + e[1]);
        var g = ctx.createLinearGradient(mx + nx * r, my + ny * r, mx - nx * r, my - ny * r);
        g.addColorStop(0, shade(skin, 1.1 * kb));
        g.addColorStop(0.45, shade(skin, 0.92 * kb));
        g.addColorStop(1, shade(skin, 0.7 * kb));
        capsule(a, e, 0.82 * r, g);
        drawn++;
      } else if (item.k === 1) {
        var pts = [], zsum = 0, ok = true;
        for (q = 0; q < torso.length; q++) {
          if (cj[torso[q]][2] < NEAR) { ok = false; break; }
          pts.push(toPix(cj[torso[q]])); zsum += cj[torso[q]][2];
        }
        if (!ok) continue;
        var hull = convexHull(pts), R = TORSO_R * foc * torso.length / zsum;
        // the chest is lit when it faces the camera, the back is a little darker
        var kf = kb;
        if (front) {
          var tc = [0, 0, 0];
          for (q = 0; q < torso.length; q++) for (var ax3 = 0; ax3 < 3; ax3++) tc[ax3] += P(torso[q], ax3) / torso.length;
          var vx = camPos[0] - tc[0], vz = camPos[2] - tc[2], vn = Math.hypot(vx, vz) || 1;
          kf = kb * (0.94 + 0.08 * (front[0] * vx + front[2] * vz) / vn);
        }
        var sk0 = SKIN["0"];
        polygon(hull, 2 * R, shade(sk0, 0.62 * kf));
        var lo = hull[0][1], hi = hull[0][1], left = hull[0][0], right = hull[0][0];
        for (q = 1; q < hull.length; q++) {
          lo = Math.min(lo, hull[q][1]); hi = Math.max(hi, hull[q][1]);
          left = Math.min(left, hull[q][0]); right = Math.max(right, hull[q][0]);
        }
        var tg = ctx.createLinearGradient(left - R, lo - R, right + R, hi + R);
        tg.addColorStop(0, shade(sk0, 1.08 * kf));
        tg.addColorStop(0.5, shade(sk0, 0.92 * kf));
        tg.addColorStop(1, shade(sk0, 0.76 * kf));
        polygon(hull, 1.64 * R, tg);
        if (front) {  // the sternum: a crease down the front of the chest, when it faces the camera
          var neckTop = null, lowest = null;
          for (q = 0; q < torso.length; q++) {
            var jt = torso[q];
            if (neckTop === null || P(jt, 1) > P(neckTop, 1)) neckTop = jt;
            if (lowest === null || P(jt, 1) < P(lowest, 1)) lowest = jt;
          }
          var fr = 0.6 * TORSO_R;
          var s0 = toCam(P(neckTop, 0) + front[0] * fr, 0.85 * P(neckTop, 1) + 0.15 * P(lowest, 1), P(neckTop, 2) + front[2] * fr);
          var s1 = toCam(P(lowest, 0) + front[0] * fr, 0.35 * P(neckTop, 1) + 0.65 * P(lowest, 1), P(lowest, 2) + front[2] * fr);
          var midz = 0.5 * (cj[neckTop][2] + cj[lowest][2]);
          if (s0[2] > NEAR && s1[2] > NEAR && 0.5 * (s0[2] + s1[2]) < midz) {
            var q0 = toPix(s0), q1 = toPix(s1);
            ctx.strokeStyle = shade(sk0, 0.72 * kf);
            ctx.lineWidth = Math.max(1, 0.12 * R);
            ctx.beginPath(); ctx.moveTo(q0[0], q0[1]); ctx.lineTo(q1[0], q1[1]); ctx.stroke();
          }
        }
        drawn++;
      } else {
        var ch = cj[head];
        if (ch[2] < NEAR) continue;
        var ph = toPix(ch), rh = FACE_R * foc / ch[2];
        var hs = SKIN["0"];
        ctx.fillStyle = shade(hs, 0.62 * kb);
        ctx.beginPath(); ctx.arc(ph[0], ph[1], rh, 0, 2 * Math.PI); ctx.fill();
        var hg = ctx.createRadialGradient(ph[0] - 0.35 * rh, ph[1] - 0.35 * rh, 0.1 * rh, ph[0], ph[1], 0.86 * rh);
        hg.addColorStop(0, shade(hs, 1.12 * kb));
        hg.addColorStop(1, shade(hs, 0.8 * kb));
        ctx.fillStyle = hg;
        ctx.beginPath(); ctx.arc(ph[0], ph[1], 0.86 * rh, 0, 2 * Math.PI); ctx.fill();
        if (front) {  // eyes towards the body's front, hidden when the face looks away
          var R3 = FACE_R, hx = P(head, 0), hy = P(head, 1), hz = P(head, 2);
          for (var eye = -1; eye <= 1; eye += 2) {
            var ec = toCam(hx + front[0] * 0.82 * R3 + eye * side[0] * 0.36 * R3, hy + 0.12 * R3,
              hz + front[2] * 0.82 * R3 + eye * side[2] * 0.36 * R3);
            if (ec[2] < NEAR || ec[2] > ch[2]) continue;
            var pe = toPix(ec);
            ctx.fillStyle = shade([70, 60, 66], kb);
            ctx.beginPath(); ctx.arc(pe[0], pe[1], Math.max(1, 0.11 * rh), 0, 2 * Math.PI); ctx.fill();
          }
        }
        drawn++;
      }
    }
    report(drawn);
  }

  function capsule(a, b, r, style) {
    ctx.strokeStyle = style;
    ctx.lineWidth = Math.max(1, 2 * r);
    ctx.beginPath(); ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0] + 1e-3, b[1]); ctx.stroke();
  }

  // a convex polygon grown by half the line width, with round corners
  function polygon(pts, width, style) {
    ctx.strokeStyle = style;
    ctx.fillStyle = style;
    ctx.lineWidth = Math.max(1, width);
    ctx.beginPath();
    for (var i = 0; i < pts.length; i++) { if (i === 0) ctx.moveTo(pts[i][0], pts[i][1]); else ctx.lineTo(pts[i][0], pts[i][1]); }
    ctx.closePath();
    ctx.fill();
    ctx.stroke();
  }

  // Andrew's monotone chain: the convex hull of 2D points
  function convexHull(points) {
    var pts = points.slice().sort(function (a, b) { return a[0] - b[0] || a[1] - b[1]; });
    if (pts.length <= 2) return pts;
    function cross(o, a, b) { return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]); }
    var lower = [], upper = [];
    for (var i = 0; i < pts.length; i++) {
      while (lower.length >= 2 && cross(lower[lower.length - 2], lower[lower.length - 1], pts[i]) <= 0) lower.pop();
      lower.push(pts[i]);
    }
    for (i = pts.length - 1; i >= 0; i--) {
      while (upper.length >= 2 && cross(upper[upper.length - 2], upper[upper.length - 1], pts[i]) <= 0) upper.pop();
      upper.push(pts[i]);
    }
    return lower.slice(0, -1).concat(upper.slice(0, -1));
  }

  // Sutherland-Hodgman against the plane z = NEAR (camera space)
  function clipNear(poly) {
    var out = [];
    for (var i = 0; i < poly.length; i++) {
      var a = poly[i], b = poly[(i + 1) % poly.length];
      var ina = a[2] >= NEAR, inb = b[2] >= NEAR;
      if (ina) out.push(a);
      if (ina !== inb) {
        var s = (NEAR - a[2]) / (b[2] - a[2]);
        out.push([a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), NEAR]);
      }
    }
    return out;
  }

  function loop() {
    if (playing) {
      if (!audio && currentTime() >= DURATION) { clockOffset = DURATION; playing = false; updateButton(); }
      draw();
    }
    requestAnimationFrame(loop);
  }

  // "#t=SECONDS" in the address opens the page paused at that time
  var hashTime = /(?:^#|&)t=([0-9.]+)/.exec(window.location.hash);
  if (hashTime) {
    setTime(parseFloat(hashTime[1]));
    if (audio) audio.addEventListener("loadedmetadata", function () { setTime(parseFloat(hashTime[1])); draw(); });
  }
  resize();
  updateButton();
  draw();
  requestAnimationFrame(loop);
})();
