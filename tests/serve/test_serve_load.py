"""``dancekit serve`` under load on the loopback: 20 concurrent submissions of a 30-s song to one worker.

Every submission either finishes with all its files or gets 429; none is lost or mixed up (each job's dance
equals ``dancekit dance``'s for its seed); the memory of the server and its worker stays bounded."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from _serve import Server, need, ode_wav, rss_bytes, wait_job

need("fastapi")
httpx = need("httpx")

N_SUBMISSIONS = 20
SEEDS = (0, 1)
MEMORY_BOUND = 3e9  # bytes, server + worker; a leak per job would pass it long before the 20th


@pytest.mark.slow
def test_twenty_concurrent_submissions_to_one_worker(tmp_path):
    from dancekit.cli.main import main
    from dancekit.motion.formats import read_motion

    song = ode_wav(tmp_path / "ode.wav", 30.0)
    want = {}
    for seed in SEEDS:  # the CLI's dances, made before the server starts (2 cores)
        out = tmp_path / f"cli{seed}"
        assert main(["dance", str(song), "-o", str(out), "--seed", str(seed), "--format", "npz", "--quiet"]) == 0
        want[seed] = read_motion(out / "ode.npz").positions
    srv = Server(tmp_path / "cache", "--workers", "1", "--queue", "4")
    peak = {"total": 0}
    stop = threading.Event()

    def sample():
        while not stop.is_set():
            peak["total"] = max(peak["total"], sum(rss_bytes(p) for p in srv.pids()))
            time.sleep(0.1)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    try:
        body = song.read_bytes()
        barrier = threading.Barrier(N_SUBMISSIONS)
        answers: list = [None] * N_SUBMISSIONS

        def submit(i: int) -> None:
            barrier.wait(timeout=60)
            r = httpx.post(srv.url + "/api/jobs/dance", files={"file": ("ode.wav", body, "audio/wav")},
                           data={"seeds": str(SEEDS[i % len(SEEDS)]), "formats": "npz"}, timeout=60)
            answers[i] = (r.status_code, r.json())

        threads = [threading.Thread(target=submit, args=(i,)) for i in range(N_SUBMISSIONS)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=120)  # each post has its own 60-s timeout
        codes = [a[0] for a in answers]
        assert set(codes) <= {202, 429}, codes
        accepted = {a[1]["id"]: SEEDS[i % len(SEEDS)] for i, a in enumerate(answers) if a[0] == 202}
        assert 1 <= len(accepted) <= 4 + 1 and codes.count(429) >= N_SUBMISSIONS - 5, codes
        assert all("queue is full" in a[1]["detail"] for a in answers if a[0] == 429)
        with httpx.Client(base_url=srv.url, timeout=30) as c:
            for job_id, seed in accepted.items():
                s = wait_job(c, job_id, timeout=600)
                assert s["state"] == "done", s
                assert {f["name"] for f in s["files"]} == {"ode.html", "ode.npz"}
                assert s["options"]["seeds"] == [seed]
                got = tmp_path / f"{job_id}.npz"
                got.write_bytes(c.get(f"/api/jobs/{job_id}/files/ode.npz").content)
                np.testing.assert_array_equal(read_motion(got).positions, want[seed])
            listed = {j["id"] for j in c.get("/api/jobs").json()}
        assert listed == set(accepted)  # none lost, none made up
    finally:
        stop.set()
        sampler.join(timeout=10)
        srv.stop()
    print(f"\n{len(accepted)} accepted, {codes.count(429)} answered 429; peak memory of server + worker "
          f"{peak['total'] / 1e6:.0f} MB")
    assert 0 < peak["total"] < MEMORY_BOUND
