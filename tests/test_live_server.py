"""Tests of hybrid_force.viz.live_server without a browser: the server binds to the loopback
interface only, a port in use is a BadInputError naming it, and closing it ends the process.
"""

from __future__ import annotations

import socket
import time

import pytest
from conftest import process_alive

from hybrid_force.errors import BadInputError
from hybrid_force.viz.live_server import LiveServer


def _listening(port: int) -> list[str]:
    """Local addresses (hex, as in /proc/net/tcp{,6}) listening on ``port``."""
    out = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table, encoding="ascii") as fh:
            for line in fh.readlines()[1:]:
                fields = line.split()
                addr, port_hex = fields[1].split(":")
                if fields[3] == "0A" and int(port_hex, 16) == port:
                    out.append(addr)
    return out


@pytest.mark.slow
def test_live_server_loopback_port_in_use_and_cleanup() -> None:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        busy_port = probe.getsockname()[1]
        probe.listen()
        with pytest.raises(BadInputError, match=f"port {busy_port} .* already in use"):
            LiveServer(busy_port)
    server = LiveServer()
    pid = server.pid
    assert pid is not None and process_alive(pid)
    try:
        web_port = int(server.url.split(":")[2].split("/")[0])
        zmq_port = int(server.zmq_url.rsplit(":", 1)[1])
        assert server.url.startswith("http://127.0.0.1:")
        for port in (web_port, zmq_port):
            assert _listening(port) == ["0100007F"], (port, _listening(port))
    finally:
        server.close()
    deadline = time.monotonic() + 5
    while process_alive(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not process_alive(pid)
