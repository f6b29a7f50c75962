"""Tests of hybrid_force.viz.replay without a browser.

The HTML recording is checked by decoding the meshcat commands embedded in it (base64 msgpack)
and comparing the animation tracks with references computed here: Pinocchio's geometry
placements at configurations interpolated with numpy, the closed-form RTR forward kinematics of
robots/rtr.urdf, the result's contact force and phase. Also: no remote resource, size bounds,
atomic write and bad inputs.
"""

from __future__ import annotations

import base64
import math
import os
import re
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import umsgpack

from hybrid_force.errors import BadInputError
from hybrid_force.geometry.builtin_surfaces import Cylinder, Plane, Sphere
from hybrid_force.model.loading import load_robot
from hybrid_force.result import Result
from hybrid_force.viz import replay, scene_objects

L2, L3 = 0.9, 1.0  # RTR link lengths [m] (robots/rtr.urdf)


def rtr_tip(q: np.ndarray) -> np.ndarray:
    """Closed-form tip position of the RTR arm (the URDF's comment, paper section 6) [m]."""
    q1, q2, q3 = q
    reach = L3 * math.cos(q3) + L2
    return np.array([math.cos(q1) * reach, math.sin(q1) * reach, L3 * math.sin(q3) + q2])


def synthetic_result(
    duration: float = 1.0, dt: float = 0.01, surfaces: list[Any] | None = None, seed: int = 7
) -> Result:
    """An RTR run: smooth q(t), p = FK(q), force 10 N in the contact phase (t ≥ 0.6 s)."""
    rng = np.random.default_rng(seed)
    t = np.arange(round(duration / dt) + 1) * dt
    a = rng.uniform(0.5, 1.5, size=3)
    q = np.column_stack(
        [0.3 + a[0] * np.sin(t), 10.0 + 0.2 * a[1] * t, -2.0 + 0.3 * np.cos(a[2] * t)]
    )
    v = np.gradient(q, t, axis=0)
    p = np.array([rtr_tip(qi) for qi in q])
    phase = np.where(t < 0.4, 0, np.where(t < 0.6, 1, 2)).astype(np.int64)
    f = np.where(phase == 2, 10.0 + t, 0.0)
    surfaces = surfaces if surfaces is not None else [Cylinder(0.4, inside=True)]
    meta = {
        "name": "synthetic",
        "robot": {"model": "rtr", "tip": "tip", "nq": 3},
        "surfaces": [s.to_dict() for s in surfaces],
        "events": [],
        "status": "ok",
    }
    return Result(
        t=t,
        q=q,
        v=v,
        q_d=q,
        u=np.zeros_like(q),
        p=p,
        p_d=p + np.array([0.0, 0.0, 0.01]),
        f=f,
        f_d=np.full_like(t, 10.0),
        phi=np.zeros_like(t),
        V=np.zeros_like(t),
        phase=phase,
        meta=meta,
    )


def embedded_commands(page: str) -> list[dict[str, Any]]:
    """Decode the meshcat commands inlined in a replay page."""
    block = page[page.index("var commands = [") : page.index("];", page.index("var commands = ["))]
    blobs = re.findall(r'"([A-Za-z0-9+/=]+)"', block)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def animation_tracks(commands: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """{node path: {track name: (fps, [(frame, value), ...])}} of the set_animation command."""
    (anim,) = [c for c in commands if c["type"] == "set_animation"]
    out: dict[str, dict[str, Any]] = {}
    for entry in anim["animations"]:
        clip = entry["clip"]
        out[entry["path"]] = {
            tr["name"]: (clip["fps"], [(k["time"], k["value"]) for k in tr["keys"]])
            for tr in clip["tracks"]
        }
    return out


@pytest.fixture(scope="module")
def result() -> Result:
    return synthetic_result()


@pytest.fixture(scope="module")
def page(result: Result) -> str:
    return replay.html(result, fps=30)


# --------------------------------------------------------------------------- the page
def test_html_is_self_contained(page: str) -> None:
    # no remote script, stylesheet, image or font: every src=/href= is absent or local
    refs = re.findall(r"""(?:src|href)\s*=\s*["']?([^"'\s>]+)""", page, flags=re.IGNORECASE)
    assert not [r for r in refs if re.match(r"(https?:)?//", r, flags=re.IGNORECASE)]
    assert not re.search(r"@import|url\(\s*['\"]?https?:", page, flags=re.IGNORECASE)
    assert "<link" not in page.lower()
    assert "MeshCat.Viewer" in page and "fetch(" not in page.split("var viewer", 1)[1]
    # the only http(s) strings are XML namespace names inside the bundled JavaScript
    for url in re.findall(r"https?://[^\s\"'<>)]+", page):
        assert url.startswith("http://www.w3.org/"), url


def test_scene_objects_present(result: Result, page: str) -> None:
    commands = embedded_commands(page)
    objects = {c["path"] for c in commands if c["type"] == "set_object"}
    visual = pin.buildGeomFromUrdf(
        load_robot("rtr").model,
        str(load_robot("rtr").urdf_path),
        pin.GeometryType.VISUAL,
    )
    for g in visual.geometryObjects:  # every URDF visual is drawn, no collision group
        assert f"/meshcat/robot/visuals/{g.name}" in objects
    assert not any("collisions/" in p for p in objects)
    for path in (
        "/meshcat/replay/surfaces/surface_0",
        "/meshcat/replay/paths/desired",
        "/meshcat/replay/paths/actual",
        "/meshcat/replay/tip/free",
        "/meshcat/replay/tip/near",
        "/meshcat/replay/tip/contact",
        "/meshcat/replay/force/arrow_0/shaft",
        "/meshcat/replay/force/arrow_0/head",
    ):
        assert path in objects, path


def test_animation_matches_forward_kinematics(result: Result, page: str) -> None:
    """Tracks at frame i equal references at t0 + i/fps (numpy interpolation of q)."""
    fps = 30.0
    tracks = animation_tracks(embedded_commands(page))
    robot = load_robot("rtr")
    visual = pin.buildGeomFromUrdf(robot.model, str(robot.urdf_path), pin.GeometryType.VISUAL)
    vdata = visual.createData()
    gid = visual.getGeometryId("link3_0")
    n_frames = math.floor((result.t[-1] - result.t[0]) * fps + 1e-9) + 1
    link_track = tracks["/meshcat/robot/visuals/link3_0"][".position"]
    tip_visual = tracks["/meshcat/robot/visuals/tip_0"][".position"]
    assert link_track[0] == fps and len(link_track[1]) == n_frames
    worst_link = worst_tip = 0.0
    for frame, pos in link_track[1]:
        tau = result.t[0] + frame / fps
        q = np.array([np.interp(tau, result.t, result.q[:, j]) for j in range(3)])
        pin.updateGeometryPlacements(robot.model, robot.data, visual, vdata, q)
        worst_link = max(
            worst_link, float(np.max(np.abs(np.array(pos) - vdata.oMg[gid].translation)))
        )
        tip = np.array(tip_visual[1][frame][1])
        worst_tip = max(worst_tip, float(np.max(np.abs(tip - rtr_tip(q)))))
    assert worst_link < 1e-12
    assert worst_tip < 1e-12
    # the fixed column is not animated (placed once)
    assert "/meshcat/robot/visuals/world_0" not in tracks


def test_phase_marker_and_force_arrow_tracks(result: Result, page: str) -> None:
    fps = 30.0
    tracks = animation_tracks(embedded_commands(page))
    visible = {
        name: dict(tracks[f"/meshcat/replay/tip/{name}"][".visible"][1])
        for name in ("free", "near", "contact")
    }
    arrow = tracks["/meshcat/replay/force/arrow_0"]
    arrow_visible = dict(arrow[".visible"][1])
    arrow_scale = dict(arrow[".scale"][1])
    arrow_quat = dict(arrow[".quaternion"][1])
    arrow_pos = dict(arrow[".position"][1])
    tip_pos = dict(tracks["/meshcat/replay/tip"][".position"][1])
    wall = Cylinder(0.4, inside=True)
    for frame in arrow_visible:
        tau = result.t[0] + frame / fps
        k = int(np.searchsorted(result.t, tau + 1e-9, side="right") - 1)
        phase = int(result.phase[k])
        expected = {"free": phase == 0, "near": phase == 1, "contact": phase == 2}
        assert {n: visible[n][frame] for n in expected} == expected, frame
        f = float(np.interp(tau, result.t, result.f))
        p = np.array([np.interp(tau, result.t, result.p[:, j]) for j in range(3)])
        assert np.allclose(tip_pos[frame], p, atol=1e-12)
        assert arrow_visible[frame] == (f > 0)
        if f > 0:
            # length 0.02 m/N, arrow ends at the tip, +y of the arrow = free-side normal
            assert arrow_scale[frame][1] == pytest.approx(min(0.02 * f, 0.5), rel=1e-12)
            assert np.allclose(arrow_pos[frame], p, atol=1e-12)
            x, y, z, w = arrow_quat[frame]
            R = pin.Quaternion(w, x, y, z).toRotationMatrix()
            n = -np.array([p[0], p[1], 0.0]) / math.hypot(p[0], p[1])  # inside: towards axis
            assert np.allclose(R[:, 1], n, atol=1e-9)
            assert np.allclose(wall.normal(p), n, atol=1e-12)


def test_frames_resampled_at_real_speed() -> None:
    r = synthetic_result(duration=2.0, dt=0.001)
    rep = replay.Replay(r, replay.ReplaySettings(fps=25))
    assert rep.n_frames == 51
    assert rep.duration == pytest.approx(2.0)
    assert np.allclose(np.diff(rep.frame_times), 1 / 25)


@pytest.mark.parametrize(
    "surfaces",
    [
        [Sphere(0.5, center=[0.0, 0.5, 10.0])],
        [Plane([0.0, 0.0, 10.0], [0.0, 0.0, 1.0]), Cylinder(0.4, inside=True)],
    ],
    ids=["sphere", "plane+cylinder"],
)
def test_other_and_stacked_surfaces(surfaces: list[Any]) -> None:
    r = synthetic_result(duration=0.3, surfaces=surfaces)
    if len(surfaces) > 1:  # stacked constraint: f and phi are (N, k)
        k = len(surfaces)
        r = Result(
            **{n: getattr(r, n) for n in ("t", "q", "v", "q_d", "u", "p", "p_d", "V", "phase")},
            f=np.column_stack([r.f] * k),
            f_d=np.column_stack([r.f_d] * k),
            phi=np.column_stack([r.phi] * k),
            meta=r.meta,
        )
    commands = embedded_commands(replay.html(r))
    objects = {c["path"] for c in commands if c["type"] == "set_object"}
    for i in range(len(surfaces)):
        assert f"/meshcat/replay/surfaces/surface_{i}" in objects
        assert f"/meshcat/replay/force/arrow_{i}/head" in objects


def test_paper_length_run_size_bound(tmp_path: Path) -> None:
    """A 20 s run sampled at 1 kHz gives a page under 3 MB (resampled frames, thinned lines)."""
    r = synthetic_result(duration=20.0, dt=0.001)
    out = replay.write_html(r, tmp_path / "long.html")
    size = out.stat().st_size
    assert size < 3_000_000, size
    commands = embedded_commands(out.read_text(encoding="utf-8"))
    lines = [c for c in commands if c["path"] == "/meshcat/replay/paths/actual"]
    packed = lines[0]["object"]["geometries"][0]["data"]["attributes"]["position"]["array"]
    n_points = len(packed.data) // (3 * 4)  # msgpack extension holding float32 xyz triples
    assert 100 < n_points <= replay.ReplaySettings().max_path_points + 2


def test_thin_polyline_keeps_ends_and_bound() -> None:
    t = np.linspace(0.0, 20.0, 20001)
    pts = np.column_stack([np.cos(t), np.sin(t), 0.1 * t])
    pts[:300, 2] = np.linspace(-8.0, 0.0, 300)  # a fast segment at the start
    idx = scene_objects._thin_polyline(t, pts, 500)
    assert idx[0] == 0 and idx[-1] == t.size - 1
    assert idx.size <= 502 and np.all(np.diff(idx) > 0)
    # the fast segment keeps points: no gap between kept points longer than 0.2 m
    assert np.max(np.linalg.norm(np.diff(pts[idx], axis=0), axis=1)) < 0.2


# --------------------------------------------------------------------------- files
def test_write_html_atomic(result: Result, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    target = tmp_path / "out" / "replay.html"
    assert replay.write_html(result, target) == target
    assert target.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    assert sorted(p.name for p in target.parent.iterdir()) == ["replay.html"]
    target.write_text("old", encoding="utf-8")

    def failing_replace(src: str, dst: str) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(BadInputError, match="disk full"):
        replay.write_html(result, target)
    assert target.read_text(encoding="utf-8") == "old"
    assert sorted(p.name for p in target.parent.iterdir()) == ["replay.html"]


def test_write_html_from_saved_file_and_command(result: Result, tmp_path: Path) -> None:
    saved = result.save(tmp_path / "result.npz")
    out = tmp_path / "r.html"
    args = SimpleNamespace(result=str(saved), html=str(out), port=None)
    assert replay.replay_command(args) == 0
    assert embedded_commands(out.read_text(encoding="utf-8"))


def test_bad_result_files(result: Result, tmp_path: Path) -> None:
    with pytest.raises(BadInputError, match="does not exist"):
        replay.write_html(tmp_path / "missing.npz", tmp_path / "x.html")
    saved = result.save(tmp_path / "result.npz")
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(saved.read_bytes()[: saved.stat().st_size // 2])
    with pytest.raises(BadInputError, match="truncated"):
        replay.write_html(truncated, tmp_path / "x.html")
    text = tmp_path / "notes.npz"
    text.write_text("not a result", encoding="utf-8")
    with pytest.raises(BadInputError, match=r"notes\.npz"):
        replay.replay_command(SimpleNamespace(result=str(text), html=str(tmp_path / "x.html")))
    assert not (tmp_path / "x.html").exists()
    with pytest.raises(BadInputError, match="is a directory"):
        replay.write_html(result, tmp_path)


def test_missing_robot(result: Result) -> None:
    meta = dict(result.meta)
    meta["robot"] = {"model": "no_such_robot", "tip": "tip", "nq": 3}
    with pytest.raises(BadInputError, match="result's robot 'no_such_robot' cannot be found"):
        replay.Replay(result.with_meta(**meta))
    meta["robot"] = {"model": "ur5", "tip": None, "nq": 6}
    with pytest.raises(BadInputError, match="nq = 6"):
        replay.Replay(result.with_meta(**meta))


def test_load_options_of_the_wrong_type_in_meta_are_ignored(result: Result) -> None:
    """A result file is input: package folders, xacro arguments or locking of the wrong type
    in meta['robot'] are not passed to load_robot (the arm loads without them)."""
    meta = dict(result.meta)
    meta["robot"] = {
        "model": "rtr", "tip": "tip", "nq": 3, "package_dirs": "/not/a/list",
        "xacro_args": {"a": [1]}, "lock_off_chain": "maybe",
    }  # fmt: skip
    rep = replay.Replay(result.with_meta(**meta))
    assert rep.robot.nv == 3 and rep.robot.reference["package_dirs"] == []
    meta["robot"] = {"model": "rtr", "tip": "tip", "nq": 3, "xacro_args": {"l2": "1"}}
    with pytest.raises(BadInputError, match=r"xacro arguments \(l2\) are given for rtr"):
        replay.Replay(result.with_meta(**meta))


@pytest.mark.parametrize(
    ("name", "value"),
    [("fps", 0), ("fps", float("nan")), ("force_scale", -1.0), ("surface_opacity", 1.5)],
)
def test_bad_settings(name: str, value: float) -> None:
    with pytest.raises(BadInputError, match=name):
        replay.ReplaySettings(**{name: value})
