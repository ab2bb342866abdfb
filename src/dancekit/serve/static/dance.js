// The dance page: a song (or the demo tune) and options -> a job -> progress -> the 3D player -> downloads.
"use strict";
(function () {
  var $ = function (id) { return document.getElementById(id); };
  var song = null, demo = false, job = null, options = null, shown = null, result = null;

  // What the pipeline decided for the dance on show (the genre it read or drew, the stages).
  function describe() {
    if (!result) return;
    result.dances.forEach(function (d) {
      if (shown === d.stem + ".html")
        $("summary").textContent = (result.dances.length > 1 ? "seed " + d.seed + ": " : "") + d.seconds.toFixed(1) +
          " s at " + d.fps + " fps" + (d.summary ? ", " + d.summary : "");
    });
  }

  function error(msg) { $("error").textContent = msg || ""; }
  function ready() { $("go").disabled = !(song || demo) || !!job; }

  DK.dropZone($("drop"), $("file"), function (f) {
    song = f; demo = false; error("");
    $("song-name").textContent = f.name + " (" + (f.size / 1e6).toFixed(1) + " MB)";
    ready();
  });
  $("demo").addEventListener("click", function (e) {
    e.stopPropagation(); song = null; demo = true; error("");
    $("song-name").textContent = "the demo tune: Ode to Joy (synthesised, 32 s)";
    ready();
  });

  function fillGenres() {
    var m = options.dance_models[$("model").value];
    $("genre").innerHTML = "";
    m.genres.forEach(function (g) {
      var o = document.createElement("option"); o.value = g;
      o.textContent = g === "auto" ? (m.reads_genre_from_music ? "auto (read from the music)" : "auto") :
                      g === "none" ? "none (the model alone)" : g;
      $("genre").appendChild(o);
    });
  }
  DK.get("/api/options").then(function (o) {
    options = o;
    var names = Object.keys(o.dance_models).sort(function (a, b) { return (b === o.default_model) - (a === o.default_model); });
    names.forEach(function (name) {
      var opt = document.createElement("option"); opt.value = name; opt.textContent = name;
      opt.title = o.dance_models[name].description; $("model").appendChild(opt);
    });
    $("model").value = o.default_model; fillGenres();
  }).catch(function (e) { error(e.message); });
  $("model").addEventListener("change", fillGenres);

  function show(name) {
    shown = name;
    $("frame").src = DK.fileUrl(job, name);
    document.querySelectorAll("#seed-buttons button").forEach(function (b) {
      b.className = b.dataset.name === name ? "" : "plain";
    });
    describe();
  }

  function update(s) {
    $("bar").style.width = Math.round(100 * s.progress) + "%";
    $("msg").textContent = s.state === "queued" ? "waiting for a worker" + (s.queue_position ? " (" + s.queue_position + " in the queue)" : "")
                                                : s.message;
    if (s.playable && s.playable.length && !shown) {
      $("player").style.display = "block";
      var box = $("seed-buttons"); box.innerHTML = "";
      if (s.playable.length > 1) s.playable.forEach(function (name, i) {
        var b = document.createElement("button"); b.type = "button"; b.dataset.name = name;
        b.textContent = "seed " + s.options.seeds[i]; b.addEventListener("click", function () { show(name); });
        box.appendChild(b);
      });
      show(s.playable[0]);
    }
  }

  function finish(s) {
    $("cancel").hidden = true;
    if (s.state === "done") {
      $("bar").style.width = "100%"; $("msg").textContent = "done";
      if (!shown) update(Object.assign({}, s, { playable: s.files.filter(function (f) { return /\.html$/.test(f.name); }).map(function (f) { return f.name; }) }));
      result = s.result;
      describe();
      var box = $("downloads"); box.innerHTML = "";
      s.result.dances.forEach(function (d) {
        var mine = s.files.filter(function (f) { return f.name.indexOf(d.stem + ".") === 0 || f.name.indexOf(d.stem + "_") === 0; });
        var row = document.createElement("div");
        if (s.result.dances.length > 1) { var h = document.createElement("b"); h.textContent = "seed " + d.seed + ": "; row.appendChild(h); }
        var links = document.createElement("span"); row.appendChild(links);
        DK.downloads(links, s.id, mine);
        box.appendChild(row);
      });
    } else {
      $("progress").style.display = "none";
      error(s.state === "cancelled" ? "cancelled" : s.error);
    }
    job = null; ready();
  }

  $("go").addEventListener("click", async function () {
    error(""); shown = null; result = null; $("player").style.display = "none"; $("summary").textContent = "";
    $("downloads").innerHTML = '<span class="muted">the files appear here when they are written</span>';
    var fd = new FormData();
    if (demo) fd.append("demo", "true"); else fd.append("file", song, song.name);
    ["model", "genre", "seeds", "start", "end", "figure"].forEach(function (k) { fd.append(k, $(k).value); });
    $("go").disabled = true; $("progress").style.display = "flex";
    $("bar").style.width = "0"; $("msg").textContent = "uploading";
    try {
      var s = await DK.post("/api/jobs/dance", fd);
      job = s.id; $("cancel").hidden = false;
      finish(await DK.follow(job, update));
    } catch (e) {
      $("progress").style.display = "none"; $("cancel").hidden = true; error(e.message); job = null; ready();
    }
  });
  $("cancel").addEventListener("click", function () {
    if (job) DK.post("/api/jobs/" + job + "/cancel", null).catch(function (e) { error(e.message); });
  });
})();
