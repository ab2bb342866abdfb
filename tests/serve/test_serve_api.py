"""``dancekit serve``'s HTTP API through the framework's test client: every route, every error, the queue.

Most tests run a server without workers (``workers=0``: jobs wait in the queue), so that what the API does
with a request is checked without dancing; the tests marked ``worker`` share one server with a worker
process and check real jobs against ``dancekit dance`` / ``dancekit compose``.
"""

from __future__ import annotations

import json
import uuid
from pathlib import Path

import numpy as np
import pytest
from _serve import need, ode_wav, wait_job

need("fastapi")
need("httpx")
from fastapi.testclient import TestClient  # noqa: E402

from dancekit.serve import JobManager, ServeConfig, create_app  # noqa: E402

BASE = "http://127.0.0.1"


def client_for(cache: Path, **kw) -> TestClient:
    return TestClient(create_app(ServeConfig(cache=cache, **kw)), base_url=BASE)


@pytest.fixture(scope="module")
def song(tmp_path_factory) -> bytes:
    return ode_wav(tmp_path_factory.mktemp("song") / "ode.wav", 4.0).read_bytes()


@pytest.fixture
def idle(tmp_path):
    """A server without workers (jobs stay queued), queue of 3, uploads capped at 2 MB."""
    with client_for(tmp_path / "cache", workers=0, max_queue=3, max_upload_bytes=2_000_000) as c:
        yield c


def job_dirs(cache: Path) -> list[str]:
    return sorted(p.name for p in cache.iterdir())


# ---- pages and reads ------------------------------------------------------------------------------------
def test_pages_static_and_openapi(idle):
    for path, marker in (("/", 'id="drop"'), ("/compose", "Compose</button>"), ("/models", 'id="cards"')):
        r = idle.get(path)
        assert r.status_code == 200 and marker in r.text, path
    assert "DK" in idle.get("/static/app.js").text
    paths = idle.get("/openapi.json").json()["paths"]
    for p in ("/api/jobs/dance", "/api/jobs/compose", "/api/jobs/{job_id}", "/api/jobs/{job_id}/files",
              "/api/jobs/{job_id}/files/{name}", "/api/jobs/{job_id}/cancel", "/api/options", "/api/models"):
        assert p in paths, p


def test_options_and_models_list_the_embedded_models(idle):
    o = idle.get("/api/options").json()
    assert set(o["dance_models"]) >= {"revolution", "music2dance", "dual"}
    assert o["default_model"] == "revolution" and o["compose_models"] == ["dual"]
    assert o["workers"] == 0 and o["workers_ready"] == 0 and o["max_queue"] == 3
    assert o["dance_models"]["revolution"]["genres"][:2] == ["auto", "none"]
    assert "waltz" in o["dance_models"]["revolution"]["genres"]
    cards = idle.get("/api/models").json()
    assert cards["revolution"]["default"] is True and "metrics" in cards["revolution"]
    assert all("folder" not in c for c in cards.values())  # no server paths to the client


# ---- creating jobs and their errors ------------------------------------------------------------------------
def test_a_client_file_name_never_becomes_a_path(idle, tmp_path, song):
    r = idle.post("/api/jobs/dance", files={"file": ("../../x.wav", song, "audio/wav")})
    assert r.status_code == 202, r.text
    s = r.json()
    assert uuid.UUID(s["id"]).version == 4 and s["stem"] == "x" and s["input"] == "upload.wav"
    cache = tmp_path / "cache"
    assert job_dirs(cache) == [s["id"]]
    assert sorted(p.name for p in (cache / s["id"] / "input").iterdir()) == ["upload.wav"]
    assert not (tmp_path / "x.wav").exists() and not (tmp_path.parent / "x.wav").exists()
    assert json.loads((cache / s["id"] / "status.json").read_text())["state"] == "queued"
    assert idle.get(f"/api/jobs/{s['id']}").json()["queue_position"] == 1
    assert [j["id"] for j in idle.get("/api/jobs").json()] == [s["id"]]


@pytest.mark.parametrize("name, body, data, code, words", [
    ("empty.wav", b"", {}, 400, "empty"),
    ("notes.wav", b"these are my notes, not a song\n" * 20, {}, 415, "not audio"),
    ("dance.npz", b"PK\x03\x04" + b"\0" * 200, {}, 415, "not audio (a npz file)"),
    ("page.mp3", b"<!doctype html><html></html>", {}, 415, "a html file"),
    ("ok.wav", None, {"model": "/etc"}, 400, "unknown model '/etc'"),
    ("ok.wav", None, {"model": "../revolution"}, 400, "unknown model"),
    ("ok.wav", None, {"genre": "polka"}, 400, "no genre 'polka'"),
    ("ok.wav", None, {"seeds": "3-1"}, 400, "bad seed range"),
    ("ok.wav", None, {"seeds": "0-20"}, 400, "at most 8"),
    ("ok.wav", None, {"start": "5", "end": "2"}, 400, "must be after start"),
    ("ok.wav", None, {"start": "-1"}, 400, "non-negative"),
    ("ok.wav", None, {"figure": "robot"}, 400, "figure"),
    ("ok.wav", None, {"formats": "mp4,exe"}, 400, "unknown output format exe"),
])
def test_bad_dance_requests_get_a_4xx_with_one_line_and_leave_nothing(idle, tmp_path, song, name, body, data,
                                                                       code, words):
    r = idle.post("/api/jobs/dance", files={"file": (name, song if body is None else body, "audio/wav")}, data=data)
    assert r.status_code == code, r.text
    detail = r.json()["detail"]
    assert words in detail and "\n" not in detail
    assert job_dirs(tmp_path / "cache") == []  # no job, no staging folder


def test_no_file_and_oversized_uploads(idle, tmp_path, song):
    r = idle.post("/api/jobs/dance", data={"model": "revolution"})
    assert r.status_code == 400 and "no file" in r.json()["detail"]
    big = song + b"\0" * 2_100_000  # a wav header, over the 2 MB cap
    r = idle.post("/api/jobs/dance", files={"file": ("big.wav", big, "audio/wav")})
    assert r.status_code == 413 and "limit of 2 MB" in r.json()["detail"]
    assert job_dirs(tmp_path / "cache") == []


def test_an_upload_over_the_cap_without_content_length_is_stopped(tmp_path, song):
    """A chunked body (no Content-Length) is counted as it arrives."""
    with client_for(tmp_path / "cache", workers=0, max_upload_bytes=50_000) as c:
        boundary = "dkboundary"
        head = (f"--{boundary}\r\nContent-Disposition: form-data; name=\"file\"; filename=\"a.wav\"\r\n"
                f"Content-Type: audio/wav\r\n\r\n").encode()
        body = head + song + b"\0" * 200_000 + f"\r\n--{boundary}--\r\n".encode()

        def chunks():
            for a in range(0, len(body), 8192):
                yield body[a: a + 8192]

        r = c.post("/api/jobs/dance", content=chunks(),
                   headers={"Content-Type": f"multipart/form-data; boundary={boundary}"})
        assert r.request.headers.get("transfer-encoding") == "chunked" and "content-length" not in r.request.headers
        # cut off as it arrived (the body guard's words), not parsed whole and refused when copied
        assert r.status_code == 413 and r.json()["detail"] == "the upload is larger than the limit of 0.05 MB", r.text
        assert job_dirs(tmp_path / "cache") == []


def test_compose_takes_dances_only(idle, tmp_path, song):
    r = idle.post("/api/jobs/compose", files={"file": ("song.wav", song, "audio/wav")})
    assert r.status_code == 415 and "is not a dance (a wav file)" in r.json()["detail"]
    r = idle.post("/api/jobs/compose", files={"file": ("d.bvh", b"HIERARCHY\nROOT x\n", "text/plain")},
                  data={"tempo": "fast"})
    assert r.status_code == 400 and "tempo" in r.json()["detail"]
    assert job_dirs(tmp_path / "cache") == []
    r = idle.post("/api/jobs/compose", files={"file": ("../d.bvh", b"HIERARCHY\nROOT x\n", "text/plain")})
    assert r.status_code == 202 and r.json()["input"] == "upload.bvh" and r.json()["stem"] == "d"
    # the composer's default, the dance's own tempo, can be asked for by name
    r = idle.post("/api/jobs/compose", files={"file": ("d.bvh", b"HIERARCHY\nROOT x\n", "text/plain")},
                  data={"tempo": "dance"})
    assert r.status_code == 202, r.text
    # a glb (dancekit reads the glb files it writes) is a dance too, stored by its content's kind
    r = idle.post("/api/jobs/compose", files={"file": ("e.bin", b"glTF\x02\x00\x00\x00" + b"\0" * 100, "model/gltf-binary")})
    assert r.status_code == 202 and r.json()["input"] == "upload.glb" and r.json()["stem"] == "e"


def test_unknown_jobs_and_files(idle, song):
    for bad in (uuid.uuid4().hex, "..", "not-a-job", "%2e%2e%2fetc"):
        assert idle.get(f"/api/jobs/{bad}").status_code == 404, bad
        assert idle.post(f"/api/jobs/{bad}/cancel").status_code == 404, bad
    job = idle.post("/api/jobs/dance", files={"file": ("a.wav", song, "audio/wav")}).json()["id"]
    for name in ("a.html", "../status.json", "status.json", "..%2Fstatus.json"):
        r = idle.get(f"/api/jobs/{job}/files/{name}")
        assert r.status_code == 404, name
    assert idle.get(f"/api/jobs/{job}/files").json() == []


def test_the_full_queue_answers_429_and_a_cancelled_job_leaves_only_its_status(idle, tmp_path, song):
    ids = [idle.post("/api/jobs/dance", files={"file": ("a.wav", song, "audio/wav")}).json()["id"] for _ in range(3)]
    r = idle.post("/api/jobs/dance", files={"file": ("a.wav", song, "audio/wav")})
    assert r.status_code == 429 and "queue is full" in r.json()["detail"] and r.headers["retry-after"] == "10"
    assert idle.post("/api/jobs/compose", files={"file": ("a.bvh", b"HIERARCHY\n", "text/plain")}).status_code == 429
    c = idle.post(f"/api/jobs/{ids[1]}/cancel")
    assert c.status_code == 200 and c.json()["state"] == "cancelled"
    assert sorted(p.name for p in (tmp_path / "cache" / ids[1]).iterdir()) == ["status.json"]
    assert idle.post(f"/api/jobs/{ids[1]}/cancel").status_code == 409
    assert idle.get(f"/api/jobs/{ids[1]}/files").status_code == 409
    assert idle.get(f"/api/jobs/{ids[2]}").json()["queue_position"] == 2
    assert idle.post("/api/jobs/dance", files={"file": ("a.wav", song, "audio/wav")}).status_code == 202
    assert idle.delete(f"/api/jobs/{ids[0]}").status_code == 200
    assert not (tmp_path / "cache" / ids[0]).exists() and idle.get(f"/api/jobs/{ids[0]}").status_code == 404


def test_token_guards_every_route(tmp_path):
    with client_for(tmp_path / "cache", workers=0, token="s3cret", host="0.0.0.0") as c:
        for path in ("/", "/models", "/api/options", "/openapi.json", "/static/app.js"):
            r = c.get(path)
            assert r.status_code == 401 and "token" in r.json()["detail"], path
        assert c.get("/api/options", headers={"Authorization": "Bearer wrong"}).status_code == 401
        assert c.get("/api/options", headers={"Authorization": "Bearer s3cret"}).status_code == 200
        assert c.get("/api/options?token=s3cret").status_code == 200


def test_loopback_server_refuses_other_host_names(idle):
    """A page of another site that resolves its name to 127.0.0.1 (DNS rebinding) is refused."""
    assert idle.get("/api/options", headers={"Host": "evil.example:8000"}).status_code == 421
    assert idle.get("/api/options", headers={"Host": "localhost:8000"}).status_code == 200


def test_serve_refuses_a_public_host_without_token(tmp_path):
    from dancekit.cli.main import main

    assert main(["serve", "--host", "0.0.0.0", "--cache", str(tmp_path / "c"), "--workers", "1"]) == 2
    assert not (tmp_path / "c").exists()


# ---- the cache -------------------------------------------------------------------------------------------------
def _finished(root: Path, age_s: float, nbytes: int, now: float) -> str:
    job = uuid.uuid4().hex
    (root / job / "files").mkdir(parents=True)
    (root / job / "files" / "x.npz").write_bytes(b"\0" * nbytes)
    (root / job / "status.json").write_text(json.dumps({"id": job, "state": "done", "created": now - age_s,
                                                        "updated": now - age_s, "files": []}))
    return job


def test_cache_keeps_finished_jobs_over_a_restart_within_its_bounds(tmp_path):
    import time

    root = tmp_path / "cache"
    root.mkdir()
    now = time.time()
    old = _finished(root, 10 * 86400, 1000, now)  # past the 7-day age bound
    a = _finished(root, 3 * 3600, 400_000, now)  # oldest within the age bound: goes for the size bound
    b = _finished(root, 2 * 3600, 400_000, now)
    c = _finished(root, 1 * 3600, 400_000, now)
    running = uuid.uuid4().hex
    (root / running / "work").mkdir(parents=True)
    (root / running / "input").mkdir()
    (root / running / "status.json").write_text(json.dumps({"id": running, "state": "running", "created": now,
                                                            "updated": now}))
    (root / ".new-123").mkdir()  # a staging folder of an upload cut short
    m = JobManager(ServeConfig(cache=root, workers=0, max_bytes=1_000_000))
    m.start()
    try:
        assert sorted(job_dirs(root)) == sorted([b, c, running])  # not old (age), not a (size), no .new-
        assert old not in m.jobs and a not in m.jobs
        assert m.status(b)["state"] == "done" and m.status(c)["state"] == "done"
        s = m.status(running)
        assert s["state"] == "failed" and "stopped" in s["error"]
        assert sorted(p.name for p in (root / running).iterdir()) == ["status.json"]
    finally:
        m.stop()


# ---- real jobs (one worker) ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def working(tmp_path_factory):
    cache = tmp_path_factory.mktemp("serve") / "cache"
    with client_for(cache, workers=1, preload=["revolution"]) as c:
        yield c, cache


def test_a_dance_job_equals_the_cli_dance_and_serves_every_file(working, song, tmp_path):
    from dancekit.cli.main import main
    from dancekit.motion.formats import read_motion

    c, cache = working
    r = c.post("/api/jobs/dance", files={"file": ("ode.wav", song, "audio/wav")},
               data={"seeds": "3", "genre": "none", "start": "0.5", "end": "3.5", "formats": "npz,bvh,glb,openpose"})
    assert r.status_code == 202, r.text
    s = wait_job(c, r.json()["id"])
    assert s["state"] == "done", s
    names = {f["name"] for f in s["files"]}
    assert names == {"ode.html", "ode.npz", "ode.bvh", "ode_humanoid.bvh", "ode.glb", "ode_openpose.zip"}
    assert sorted(p.name for p in (cache / s["id"]).iterdir()) == ["files", "status.json"]  # input removed
    assert s["result"]["dances"][0]["seed"] == 3
    got = tmp_path / "got.npz"
    got.write_bytes(c.get(f"/api/jobs/{s['id']}/files/ode.npz").content)
    song_path = tmp_path / "ode.wav"
    song_path.write_bytes(song)
    assert main(["dance", str(song_path), "-o", str(tmp_path / "cli"), "--seed", "3", "--genre", "none",
                 "--start", "0.5", "--end", "3.5", "--format", "npz", "--quiet"]) == 0
    want, have = read_motion(tmp_path / "cli" / "ode.npz"), read_motion(got)
    assert have.num_frames == want.num_frames and have.fps == want.fps
    np.testing.assert_array_equal(have.positions, want.positions)
    html = c.get(f"/api/jobs/{s['id']}/files/ode.html")
    assert html.status_code == 200 and html.headers["content-type"].startswith("text/html") and "dk-data" in html.text
    z = c.get(f"/api/jobs/{s['id']}/files/ode_openpose.zip")
    assert z.headers["content-type"] == "application/zip" and z.content[:4] == b"PK\x03\x04"
    assert [f["name"] for f in c.get(f"/api/jobs/{s['id']}/files").json()] == sorted(names)


def test_a_song_that_does_not_decode_fails_with_its_reason_and_no_files(working):
    c, cache = working
    r = c.post("/api/jobs/dance", files={"file": ("broken.ogg", b"OggS" + bytes(range(256)) * 40, "audio/ogg")})
    assert r.status_code == 202
    s = wait_job(c, r.json()["id"])
    assert s["state"] == "failed" and s["error"] and "\n" not in s["error"]
    assert sorted(p.name for p in (cache / s["id"]).iterdir()) == ["status.json"]


def test_cancelling_a_running_job_stops_it_and_a_new_worker_takes_the_next(working, tmp_path):
    c, cache = working
    long_song = ode_wav(tmp_path / "long.wav", 64.0).read_bytes()
    r = c.post("/api/jobs/dance", files={"file": ("long.wav", long_song, "audio/wav")},
               data={"seeds": "0-3", "figure": "body"})
    job = r.json()["id"]
    s = wait_job(c, job, states=("running", "done", "failed"))
    assert s["state"] == "running", s
    r = c.post(f"/api/jobs/{job}/cancel")
    assert r.status_code == 200 and r.json()["state"] == "cancelled"
    assert sorted(p.name for p in (cache / job).iterdir()) == ["status.json"]
    assert not any(p.name.startswith(".") for p in cache.iterdir())
    short = ode_wav(tmp_path / "short.wav", 3.0).read_bytes()
    s = wait_job(c, c.post("/api/jobs/dance", files={"file": ("s.wav", short, "audio/wav")},
                           data={"formats": "npz"}).json()["id"])
    assert s["state"] == "done", s


def test_compose_job_writes_midi_wav_mp4_and_html(working, fixtures_dir):
    c, cache = working
    bvh = (fixtures_dir / "bvh" / "bandai_namco_dance_short_001.bvh").read_bytes()
    r = c.post("/api/jobs/compose", files={"file": ("dance.bvh", bvh, "text/plain")}, data={"seed": "1"})
    assert r.status_code == 202, r.text
    s = wait_job(c, r.json()["id"])
    assert s["state"] == "done", s
    assert {f["name"] for f in s["files"]} == {"dance.mid", "dance.wav", "dance.mp4", "dance.html"}
    assert c.get(f"/api/jobs/{s['id']}/files/dance.mid").content[:4] == b"MThd"
    assert "BPM" in s["result"]["summary"]


# ---- the upload helpers ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name, stem", [
    ("../../x.mp3", "x"), ("..\\..\\evil.wav", "evil"), ("C:\\songs\\my song.ogg", "my_song"), ("..", "song"),
    ("", "song"), (None, "song"), (".hidden.wav", "hidden"), ("a/b/../c.tar.gz", "c.tar"), ("ünï côdé.flac", "n_c_d"),
    ("x" * 200 + ".wav", "x" * 60), ("/etc/passwd", "passwd"),
])
def test_safe_stem_keeps_a_plain_name_only(name, stem):
    from dancekit.serve.uploads import safe_stem

    assert safe_stem(name, "song") == stem


@pytest.mark.parametrize("head, kind", [
    (b"RIFF\x24\x00\x00\x00WAVEfmt ", "wav"), (b"fLaC\x00\x00\x00\x22", "flac"), (b"OggS\x00\x02", "ogg"),
    (b"ID3\x04\x00", "mp3"), (b"\xff\xfb\x90\x64", "mp3"), (b"\x00\x00\x00\x20ftypM4A ", "mp4"),
    (b"FORM\x00\x00\x00\x00AIFF", "aiff"), (b"PK\x03\x04\x14\x00", "npz"), (b"glTF\x02\x00", "glb"),
    (b"\x80\x04\x95\x00", "pkl"), (b"\xef\xbb\xbf  HIERARCHY\r\nROOT", "bvh"), (b"MThd\x00\x00", "midi"),
    (b"\xff\xd8\xff\xe0", "jpeg"), (b"hello world", None), (b"\xff\xf9\x00", None), (b"", None),
])
def test_sniff_reads_the_kind_from_the_bytes(head, kind):
    from dancekit.serve.uploads import sniff

    assert sniff(head) == kind
