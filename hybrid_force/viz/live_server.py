"""The live replay server: meshcat's websocket bridge in a subprocess bound to 127.0.0.1, shut
down in every case (Ctrl-C, SIGTERM, SIGHUP, or the death of the process that started it).
"""

from __future__ import annotations

import contextlib
import functools
import os
import select
import signal
import subprocess
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import hybrid_force
from hybrid_force._extras import require as require_extra
from hybrid_force.errors import BadInputError

if TYPE_CHECKING:
    from hybrid_force.viz.replay_view import ReplayView

__all__ = ["LiveServer"]

#: Repetitions used for an endlessly looping live replay.
_LOOP_REPETITIONS = 1_000_000
_SERVER_START_TIMEOUT = 30.0  # [s]
_ZMQ_TIMEOUT_MS = 30_000


class _ZmqWindow:
    """A meshcat window talking to a server over zmq REQ with timeouts (never hangs forever)."""

    def __init__(self, zmq_url: str) -> None:
        import zmq

        self._zmq = zmq
        self.context: Any = zmq.Context.instance()
        self.socket = self.context.socket(zmq.REQ)
        self.socket.setsockopt(zmq.LINGER, 0)
        self.socket.setsockopt(zmq.SNDTIMEO, _ZMQ_TIMEOUT_MS)
        self.socket.connect(zmq_url)

    def _request(self, frames: list[bytes], timeout_ms: int = _ZMQ_TIMEOUT_MS) -> bytes:
        self.socket.send_multipart(frames)
        if not self.socket.poll(timeout_ms):
            raise BadInputError(f"the meshcat server did not answer within {timeout_ms / 1000:g} s")
        return self.socket.recv()

    def send(self, command: Any) -> None:
        import umsgpack

        data = command.lower()
        reply = self._request(
            [data["type"].encode("utf-8"), data["path"].encode("utf-8"), umsgpack.packb(data)]
        )
        if reply != b"ok":
            raise BadInputError(f"the meshcat server refused a command: {reply!r}")

    def wait_for_browser(self, timeout: float | None = None) -> bool:
        """Block until a browser is connected (True) or ``timeout`` [s] passed (False).

        Polls in short slices so Ctrl-C stays responsive. After a timeout the socket is
        unusable for further commands (REQ state); the caller then closes it.
        """
        self.socket.send(b"wait")
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            if self.socket.poll(200):
                self.socket.recv()
                return True
            if deadline is not None and time.monotonic() > deadline:
                return False

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.socket.close(linger=0)


class LiveServer:
    """A meshcat server subprocess bound to 127.0.0.1 only (context manager).

    Args:
        port: web port; None picks the first free port from 7000 up.

    Raises:
        BadInputError: the port is in use or invalid, or the server did not start.
        MissingExtraError: meshcat cannot be imported (the ``replay`` extra).

    ``url`` is the page to open; ``visualizer()`` returns a ``meshcat.Visualizer`` connected to
    it. ``close()`` (or leaving the ``with`` block) terminates the process and waits for it; the
    server also exits by itself if this process dies.
    """

    def __init__(self, port: int | None = None) -> None:
        if port is not None and (
            isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535
        ):
            raise BadInputError(f"port must be an int in 1..65535 or None (pick one), got {port!r}")
        require_extra("replay", "the live 3D viewer")
        self.port_requested = port
        self.process: subprocess.Popen[bytes] | None = None
        self._window: _ZmqWindow | None = None
        self.zmq_url = ""
        self.url = ""
        self._start()

    def _start(self) -> None:

        package_parent = str(Path(hybrid_force.__file__).resolve().parent.parent)
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(
            [package_parent, *filter(None, [env.get("PYTHONPATH", "")])]
        )
        args = [
            sys.executable,
            "-u",
            "-c",
            "from hybrid_force.viz.live_server import _server_main; _server_main()",
            str(os.getpid()),
            "" if self.port_requested is None else str(self.port_requested),
        ]
        self.process = subprocess.Popen(
            args,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
        )
        try:
            self._read_urls()
            self._window = _ZmqWindow(self.zmq_url)
        except BaseException:
            self.close()
            raise

    def _read_urls(self) -> None:
        proc = self.process
        assert proc is not None and proc.stdout is not None
        deadline = time.monotonic() + _SERVER_START_TIMEOUT
        buffer = b""
        while not (b"zmq_url=" in buffer and b"web_url=" in buffer and buffer.endswith(b"\n")):
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise BadInputError(
                    f"the meshcat server did not start within {_SERVER_START_TIMEOUT:g} s"
                )
            ready, _, _ = select.select([proc.stdout], [], [], min(remaining, 0.2))
            if ready:
                chunk = os.read(proc.stdout.fileno(), 4096)
                if chunk:
                    buffer += chunk
                    continue
            if proc.poll() is not None:
                err = proc.stderr.read().decode("utf-8", "replace") if proc.stderr else ""
                if "port in use" in err:
                    raise BadInputError(
                        f"port {self.port_requested} on 127.0.0.1 is already in use; choose "
                        "another port or omit it to pick a free one"
                    )
                raise BadInputError(
                    f"the meshcat server exited with status {proc.returncode}: "
                    f"{err.strip()[-800:] or '(no output)'}"
                )
        for line in buffer.decode("utf-8", "replace").splitlines():
            if line.startswith("zmq_url="):
                self.zmq_url = line.split("=", 1)[1].strip()
            elif line.startswith("web_url="):
                self.url = line.split("=", 1)[1].strip()

    @property
    def pid(self) -> int | None:
        """Process id of the server subprocess (None once closed)."""
        return None if self.process is None else self.process.pid

    def visualizer(self) -> Any:
        """A ``meshcat.Visualizer`` sending to this server."""
        import meshcat

        if self._window is None:
            raise BadInputError("the meshcat server is closed")
        return meshcat.Visualizer(window=self._window)

    def wait_for_browser(self, timeout: float | None = None) -> bool:
        """Block until a browser has connected (True), or ``timeout`` [s] passed (False)."""
        if self._window is None:
            raise BadInputError("the meshcat server is closed")
        return self._window.wait_for_browser(timeout)

    def close(self) -> None:
        """Terminate the server process and wait for it (idempotent)."""
        if self._window is not None:
            self._window.close()
            self._window = None
        proc = self.process
        if proc is None:
            return
        self.process = None
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                with contextlib.suppress(OSError):
                    stream.close()

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        with contextlib.suppress(Exception):
            self.close()


def _server_main() -> None:
    """Entry point of the server subprocess: meshcat's bridge with its web port on 127.0.0.1.

    argv: [parent pid, port or ""]. Exits when the parent process goes away, on SIGTERM, and
    ignores SIGINT (the parent shuts it down after Ctrl-C). Prints ``zmq_url=`` and ``web_url=``.
    """

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = int(sys.argv[1])
    port = int(sys.argv[2]) if len(sys.argv) > 2 and sys.argv[2] else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        import tornado.ioloop
        from meshcat.servers import zmqserver

    class LoopbackBridge(zmqserver.ZMQWebSocketBridge):
        def make_app(self) -> Any:
            app = super().make_app()
            app.listen = functools.partial(app.listen, address="127.0.0.1")
            return app

    try:
        bridge = LoopbackBridge(host="127.0.0.1", port=port)
    except OSError as exc:
        print(f"error: port in use: {port}: {exc}", file=sys.stderr, flush=True)
        sys.exit(3)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    loop = tornado.ioloop.IOLoop.current()

    def _watch_parent() -> None:
        if os.getppid() != parent:
            loop.stop()

    tornado.ioloop.PeriodicCallback(_watch_parent, 500).start()
    signal.signal(signal.SIGTERM, lambda *_: loop.add_callback_from_signal(loop.stop))
    bridge.run()


@contextlib.contextmanager
def _signals_raise_interrupt() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise KeyboardInterrupt (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def _handler(signum: int, frame: object) -> None:
        raise KeyboardInterrupt(f"signal {signum}")

    old: dict[signal.Signals, Any] = {}
    for sig in (signal.SIGTERM, signal.SIGHUP):
        old[sig] = signal.signal(sig, _handler)
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def _serve_replay(
    replay: ReplayView,
    *,
    port: int | None,
    loop: bool,
    browser_timeout: float | None = None,
    announce: Callable[[str], None] | None = None,
) -> None:
    say = announce if announce is not None else (lambda msg: print(msg, flush=True))
    with _signals_raise_interrupt(), LiveServer(port) as server:
        vis = server.visualizer()
        replay.draw(vis, play=True, repetitions=_LOOP_REPETITIONS if loop else 1)
        say(f"replay of '{replay.result.meta.get('name') or 'run'}' at {server.url}")
        say("open it in a browser; Ctrl-C stops the server")
        if not server.wait_for_browser(browser_timeout):
            say("no browser connected; stopping the server")
            return
        if loop:
            while True:
                time.sleep(0.5)
        time.sleep(replay.duration + 0.5)
