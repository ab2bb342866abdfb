// Shared by the pages of `dancekit serve`: the token (kept from ?token=), API calls, job polling, downloads.
"use strict";
var DK = (function () {
  var token = new URLSearchParams(location.search).get("token");
  function withToken(url) {
    if (!token) return url;
    return url + (url.indexOf("?") < 0 ? "?" : "&") + "token=" + encodeURIComponent(token);
  }
  function headers() { return token ? { "Authorization": "Bearer " + token } : {}; }
  async function reason(resp) {
    try { var j = await resp.json(); return j.detail || resp.statusText; } catch (e) { return resp.status + " " + resp.statusText; }
  }
  async function get(url) {
    var r = await fetch(url, { headers: headers() });
    if (!r.ok) throw new Error(await reason(r));
    return r.json();
  }
  async function post(url, body) {
    var r = await fetch(url, { method: "POST", headers: headers(), body: body });
    if (!r.ok) throw new Error(await reason(r));
    return r.json();
  }
  function fileUrl(id, name) { return withToken("/api/jobs/" + id + "/files/" + encodeURIComponent(name)); }
  function size(n) { return n > 1e6 ? (n / 1e6).toFixed(1) + " MB" : Math.max(1, Math.round(n / 1e3)) + " KB"; }
  // Poll a job until it is finished; onStatus(status) on every change.
  async function follow(id, onStatus) {
    for (;;) {
      var s = await get("/api/jobs/" + id);
      onStatus(s);
      if (s.state === "done" || s.state === "failed" || s.state === "cancelled") return s;
      await new Promise(function (r) { setTimeout(r, 300); });
    }
  }
  // The nav links keep the token.
  document.addEventListener("DOMContentLoaded", function () {
    document.querySelectorAll("header nav a").forEach(function (a) { a.href = withToken(a.getAttribute("href")); });
  });
  // A drop zone: click to pick, or drop a file; onFile(file).
  function dropZone(zone, input, onFile) {
    zone.addEventListener("click", function () { input.click(); });
    input.addEventListener("change", function () { if (input.files.length) onFile(input.files[0]); });
    zone.addEventListener("dragover", function (e) { e.preventDefault(); zone.classList.add("over"); });
    zone.addEventListener("dragleave", function () { zone.classList.remove("over"); });
    zone.addEventListener("drop", function (e) {
      e.preventDefault(); zone.classList.remove("over");
      if (e.dataTransfer.files.length) onFile(e.dataTransfer.files[0]);
    });
  }
  var LABELS = { mp4: "video (mp4)", html: "3D player (html)", glb: "glTF (glb)", bvh: "BVH", pkl: "SMPL (AIST++ pkl)",
                 npz: "motion (npz)", zip: "keypoints (zip)", mid: "MIDI", wav: "WAV" };
  function label(name) {
    var ext = name.split(".").pop();
    if (ext === "bvh") return name.indexOf("_humanoid.") >= 0 ? "BVH (humanoid rig)" : "BVH (exact rig)";
    if (ext === "zip") return name.indexOf("_openpose") >= 0 ? "OpenPose (zip)" : name.indexOf("_coco") >= 0 ? "COCO (zip)" : "zip";
    return LABELS[ext] || ext;
  }
  function downloads(el, id, files) {
    el.innerHTML = "";
    files.forEach(function (f) {
      var a = document.createElement("a");
      a.href = fileUrl(id, f.name); a.download = f.name; a.dataset.name = f.name;
      a.innerHTML = label(f.name) + " <small>" + size(f.bytes) + "</small>";
      a.title = f.name;
      el.appendChild(a);
    });
  }
  return { get: get, post: post, fileUrl: fileUrl, follow: follow, dropZone: dropZone, downloads: downloads,
           headers: headers, withToken: withToken, reason: reason };
})();
