"""The 3D replay in a real browser: headless Debian Chromium driven by Playwright.

Two tests, one on the self-contained HTML recording (opened from a file) and one on the live
meshcat server (``replay.serve`` in a subprocess, stopped with SIGINT). Each opens the page with
every non-local request blocked, waits until the three.js scene is built, checks that the robot's
link objects, the surface, both paths and the force arrow exist, seeks the animation to a frame
in contact and compares a link's position in the browser with Pinocchio's forward kinematics (and
the tip with the RTR closed form) at the configuration interpolated at that exact frame time,
and checks that two different times render different images.

Skipped, with the reason, when /usr/bin/chromium or Playwright is missing, unless
HYBRID_FORCE_CI=1 (then those tests fail instead).
"""

from __future__ import annotations

import io
import math
import os
import select
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

import numpy as np
import pinocchio as pin
import pytest
from conftest import process_alive

from hybrid_force.result import Result

pytestmark = pytest.mark.browser

FPS = 30.0
L2, L3 = 0.9, 1.0  # RTR link lengths [m] (robots/rtr.urdf)

# JavaScript: find a scene node by meshcat path without creating it (SceneNode.find creates).
JS_FIND = """
(path) => {
  let node = window.viewer.scene_tree;
  for (const name of path.split('/').filter((s) => s.length > 0)) {
    node = node.children[name];
    if (node === undefined) return null;
  }
  return node;
}
"""
JS_DESCRIBE = (
    """
(paths) => {
  const find = """
    + JS_FIND
    + """;
  window.viewer.scene.updateMatrixWorld(true);
  const out = {};
  for (const path of paths) {
    const node = find(path);
    if (node === null) { out[path] = null; continue; }
    const obj = node.children['<object>'];
    out[path] = {
      matrixWorld: Array.from(node.object.matrixWorld.elements),
      visible: node.object.visible,
      type: obj === undefined ? null : obj.object.type,
    };
  }
  return out;
}
"""
)


@pytest.fixture(scope="module")
def run_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The paper's 6.4 setup simulated for 1.2 s (contact from t ≈ 0.9 s), saved."""
    from hybrid_force.control.clik import inverse_kinematics
    from hybrid_force.control.supervisor import ControlSettings
    from hybrid_force.geometry.builtin_surfaces import Cylinder
    from hybrid_force.geometry.paths import paper_helix
    from hybrid_force.model.loading import load_robot
    from hybrid_force.sim.loop import simulate
    from hybrid_force.sim.settings import Scenario, SimSettings

    robot = load_robot("rtr")
    q0 = inverse_kinematics(robot, [0.1, 0.1, 2], seed=[0.5, 1, 2.0])
    scenario = Scenario(
        robot,
        [Cylinder(0.4, inside=True)],
        paper_helix(),
        q0,
        control=ControlSettings(),
        sim=SimSettings(duration=1.2),
        name="approach_short",
    )
    result = simulate(scenario)
    assert np.any(result.phase == 2) and np.max(result.f) > 0
    return result.save(tmp_path_factory.mktemp("browser") / "result.npz")


def _rtr_tip(q: np.ndarray) -> np.ndarray:
    """Closed-form tip position of the RTR arm (robots/rtr.urdf comment) [m]."""
    q1, q2, q3 = q
    reach = L3 * math.cos(q3) + L2
    return np.array([math.cos(q1) * reach, math.sin(q1) * reach, L3 * math.sin(q3) + q2])


def _new_page(browser: Any, allowed_hosts: tuple[str, ...]) -> tuple[Any, Any, _Requests]:
    """A page whose non-file, non-allowed-host requests are aborted and recorded."""
    context = browser.new_context(viewport={"width": 800, "height": 600})
    refused: list[str] = []

    def _route(route: Any) -> None:
        url = urlparse(route.request.url)
        if url.scheme in ("file", "data", "blob") or url.hostname in allowed_hosts:
            route.continue_()
        else:
            refused.append(route.request.url)
            route.abort()

    context.route("**/*", _route)
    page = context.new_page()
    seen: list[str] = []
    page.on("request", lambda req: seen.append(req.url))
    page.on("websocket", lambda ws: seen.append(ws.url))
    page.on("pageerror", lambda err: seen.append(f"pageerror: {err}"))
    return context, page, _Requests(refused, seen)


@dataclass(frozen=True)
class _Requests:
    """URLs refused by the route (``refused``) and every request/websocket/page error seen."""

    refused: list[str]
    seen: list[str]


def _check_scene(page: Any, result: Result) -> None:
    """Scene content, FK at a contact frame, phase/force state, two times → two images."""
    from PIL import Image

    from hybrid_force.model.loading import load_robot
    from hybrid_force.viz.scene import Replay

    rep = Replay(result)
    nodes = rep.node_paths()
    paths = [
        "/meshcat",
        *nodes["robot"],
        *nodes["surfaces"],
        nodes["desired_path"],
        nodes["actual_path"],
        nodes["tip"],
        *nodes["phase_markers"],
        *nodes["force_arrows"],
        nodes["force_arrows"][0] + "/head",
    ]
    desc = page.evaluate(JS_DESCRIBE, paths)
    missing = [p for p in paths if desc[p] is None]
    assert not missing, missing
    for p in nodes["robot"] + nodes["surfaces"]:
        assert desc[p]["type"] == "Mesh", (p, desc[p])
    assert desc[nodes["desired_path"]]["type"] == "Line"
    assert desc[nodes["actual_path"]]["type"] == "Line"
    assert desc[nodes["force_arrows"][0] + "/head"]["type"] == "Mesh"

    # a frame in contact with the largest force, and frame 0 (free space)
    frame_t = result.t[0] + np.arange(rep.n_frames) / FPS
    f_frames = np.interp(frame_t, result.t, result.f)
    in_contact = np.flatnonzero(f_frames > 0)
    contact = int(in_contact[in_contact.size // 2])
    robot = load_robot("rtr")
    visual = pin.buildGeomFromUrdf(robot.model, str(robot.urdf_path), pin.GeometryType.VISUAL)
    vdata = visual.createData()
    link = "/meshcat/robot/visuals/link3_0"
    tip = "/meshcat/robot/visuals/tip_0"
    page.evaluate("() => window.viewer.animator.pause()")
    images = []
    worst: dict[str, float] = {}
    for frame in (contact, 0):
        # positions exactly at the frame's key time (three.js stores key times as float32: the
        # interpolation weight of the next key is then ~1e-7)
        got = _seek(page, frame / FPS, ["/meshcat", link, tip])
        root = np.array(got["/meshcat"]["matrixWorld"]).reshape(4, 4).T
        q = np.array([np.interp(frame_t[frame], result.t, result.q[:, j]) for j in range(3)])
        pin.updateGeometryPlacements(robot.model, robot.data, visual, vdata, q)
        for path, expected in (
            (link, vdata.oMg[visual.getGeometryId("link3_0")].translation),
            (tip, _rtr_tip(q)),
        ):
            world = np.array(got[path]["matrixWorld"]).reshape(4, 4).T
            in_run_frame = np.linalg.solve(root, world)[:3, 3]
            error = float(np.max(np.abs(in_run_frame - expected)))
            worst[path] = max(worst.get(path, 0.0), error)
            assert error < 1e-3, (path, frame, error)
        # discrete tracks (visibility) half-way to the next key: the frame's own value
        got = _seek(page, (frame + 0.5) / FPS, [*nodes["phase_markers"], *nodes["force_arrows"]])
        markers = {p.rsplit("/", 1)[1]: got[p]["visible"] for p in nodes["phase_markers"]}
        arrow_visible = got[nodes["force_arrows"][0]]["visible"]
        if frame == contact:
            assert markers == {"free": False, "near": False, "contact": True}
            assert arrow_visible
        else:
            assert markers == {"free": True, "near": False, "contact": False}
            assert not arrow_visible
        page.wait_for_timeout(300)  # let the render loop draw the seeked frame
        images.append(np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")))
    changed = np.mean(np.any(images[0] != images[1], axis=2))
    assert changed > 0.001, changed
    print(f"browser vs FK, worst |error| [m]: {worst}; pixels changed: {changed:.3f}")


def _seek(page: Any, tau: float, paths: list[str]) -> dict[str, Any]:
    """Seek the paused animation to τ [s] and describe the given scene nodes."""
    page.evaluate("(tau) => { window.viewer.animator.seek(tau); window.viewer.set_dirty(); }", tau)
    return page.evaluate(JS_DESCRIBE, paths)


def test_static_html_in_browser(browser: Any, run_file: Path, tmp_path: Path) -> None:
    from hybrid_force.viz.replay import write_html

    html = write_html(run_file, tmp_path / "replay.html")
    context, page, record = _new_page(browser, allowed_hosts=())
    try:
        page.goto(html.as_uri())
        page.wait_for_function(
            "() => window.hybridForceReplay !== undefined && window.hybridForceReplay.ready",
            timeout=30_000,
        )
        _check_scene(page, Result.load(run_file))
    finally:
        context.close()
    assert record.refused == []
    assert [u for u in record.seen if not u.startswith("file://")] == []


def _children(pid: int) -> list[int]:
    with open(f"/proc/{pid}/task/{pid}/children", encoding="ascii") as fh:
        return [int(x) for x in fh.read().split()]


def test_live_server_in_browser(browser: Any, run_file: Path) -> None:
    code = (
        "import sys; from hybrid_force.viz.replay import serve; "
        "serve(sys.argv[1], loop=True, browser_timeout=60)"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code, str(run_file)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    server_pids: list[int] = []
    try:
        url = _read_url(proc, timeout=40)
        assert urlparse(url).hostname == "127.0.0.1"
        server_pids = _children(proc.pid)
        assert server_pids, "serve() started no server subprocess"
        context, page, record = _new_page(browser, allowed_hosts=("127.0.0.1", "localhost"))
        try:
            page.goto(url)
            page.wait_for_function(
                "() => window.viewer !== undefined && window.viewer.animator.actions.length > 0"
                " && window.viewer.scene_tree.children['meshcat'] !== undefined",
                timeout=30_000,
            )
            _check_scene(page, Result.load(run_file))
        finally:
            context.close()
        assert record.refused == []
        hosts = {urlparse(u).hostname for u in record.seen if not u.startswith("pageerror")}
        assert hosts == {"127.0.0.1"}, record.seen
        assert not [u for u in record.seen if u.startswith("pageerror")]
        assert all(process_alive(pid) for pid in server_pids)
        proc.send_signal(signal.SIGINT)  # Ctrl-C
        proc.wait(timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()
    deadline = time.monotonic() + 5
    while any(process_alive(pid) for pid in server_pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [pid for pid in server_pids if process_alive(pid)], "meshcat server left running"


def _read_url(proc: subprocess.Popen[bytes], timeout: float) -> str:
    """The http URL printed by serve() on its stdout."""
    assert proc.stdout is not None
    deadline = time.monotonic() + timeout
    buffer = b""
    while time.monotonic() < deadline:
        ready, _, _ = select.select([proc.stdout], [], [], 0.2)
        if ready:
            chunk = os.read(proc.stdout.fileno(), 4096)
            buffer += chunk
            for word in buffer.decode("utf-8", "replace").split():
                if word.startswith("http://") and buffer.endswith(b"\n"):
                    return word
            if not chunk and proc.poll() is not None:
                break
        elif proc.poll() is not None:
            break
    err = proc.stderr.read().decode("utf-8", "replace") if proc.stderr else ""
    raise AssertionError(f"serve() printed no URL: {buffer!r} {err[-2000:]}")
