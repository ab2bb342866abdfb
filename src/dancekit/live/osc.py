"""The pose stream over OSC (Open Sound Control, UDP), an optional extra (``pip install 'dancekit[osc]'``).

:class:`OscSink` sends, for every frame, one message ``/dancekit/pose`` with the arguments
``frame (int), t (float, s of audio), beat (int 0/1), x0, y0, z0, x1, ...`` (the joints' world positions in the
skeleton's units, y up for the embedded models), and once at the start ``/dancekit/skeleton`` with the joint
names (strings) and ``/dancekit/parents`` with the parent indices (ints). TouchDesigner's OSC In CHOP and
Unity / Blender OSC add-ons read them (docs/LIVE.md).
"""

from __future__ import annotations

from dancekit.errors import ParameterError

__all__ = ["OscSink", "parse_address"]


def parse_address(text: str) -> tuple[str, int]:
    """``"HOST:PORT"`` → ``(host, port)``; a bad one is a :class:`ParameterError` that names it."""
    host, sep, port = str(text).rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ParameterError(f"--osc needs HOST:PORT (e.g. 127.0.0.1:9000), got {text!r}")
    return host, int(port)


class OscSink:
    """Send pose frames to ``host:port`` over OSC (UDP: a frame lost on the way is not resent)."""

    def __init__(self, address: str, *, skeleton):
        try:
            from pythonosc.udp_client import SimpleUDPClient
        except ImportError:
            raise ParameterError("--osc needs the optional python-osc package: pip install 'dancekit[osc]'") from None
        host, port = parse_address(address)
        self.client = SimpleUDPClient(host, port)
        self.client.send_message("/dancekit/skeleton", list(skeleton.joint_names))
        self.client.send_message("/dancekit/parents", [int(p) for p in skeleton.parents])

    def __call__(self, frames) -> None:
        for f in frames:
            joints = [round(float(v), 2) for v in f.joints.reshape(-1)]
            self.client.send_message("/dancekit/pose", [int(f.index), float(f.time), int(f.beat), *joints])
