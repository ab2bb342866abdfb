"""The pose stream over OSC (optional extra): a receiver gets the skeleton, then every frame in order."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

from dancekit.errors import ParameterError

try:
    import pythonosc  # noqa: F401  (the `osc` extra; in `dev`, so CI has it)
except ImportError:  # pragma: no cover
    if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        raise
    pytest.skip("python-osc is not installed (pip install 'dancekit[osc]')", allow_module_level=True)


def test_osc_sink_sends_the_skeleton_and_the_frames():
    from pythonosc.dispatcher import Dispatcher
    from pythonosc.osc_server import ThreadingOSCUDPServer

    from dancekit.live.osc import OscSink
    from dancekit.live.session import Frame
    from dancekit.pipelines import load_pipeline

    sk = load_pipeline("revolution").skeleton
    got: dict[str, list] = {"/dancekit/skeleton": [], "/dancekit/parents": [], "/dancekit/pose": []}
    d = Dispatcher()
    for address in got:
        d.map(address, lambda addr, *args: got[addr].append(args))
    server = ThreadingOSCUDPServer(("127.0.0.1", 0), d)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        sink = OscSink(f"127.0.0.1:{server.server_address[1]}", skeleton=sk)
        J = sk.num_joints
        frames = [Frame(index=i, time=i / 25, joints=np.full((J, 3), float(i), np.float32), arrival=0.0, ready=0.0,
                        beat=i == 3) for i in range(6)]
        sink(frames)
        deadline = time.monotonic() + 10
        while len(got["/dancekit/pose"]) < 6 and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        server.shutdown()
    assert list(got["/dancekit/skeleton"][0]) == list(sk.joint_names)
    assert list(got["/dancekit/parents"][0]) == [int(p) for p in sk.parents]
    poses = got["/dancekit/pose"]
    assert [p[0] for p in poses] == list(range(6))
    assert all(len(p) == 3 + 3 * J for p in poses)
    assert poses[3][2] == 1 and poses[2][2] == 0
    assert poses[5][3:] == tuple([5.0] * (3 * J))


@pytest.mark.parametrize("address", ["9000", "host:", "host:0", "host:abc", ":9000"])
def test_osc_address_is_checked(address):
    from dancekit.live.osc import parse_address

    with pytest.raises(ParameterError, match="HOST:PORT"):
        parse_address(address)
