"""The removal layer of the 3D replay (hybrid_force/viz/scene_removal.py, docs/replay.md).

References independent of the layer's code: matplotlib's viridis (the colormap of removal.png)
evaluated here on the normalised depth, the result's own removal_points, the mean of a linear
depth field over a voxel (the field at the voxel's mean position), and, in a real browser, the
pixel colours three.js renders at the screen projection of chosen cells.
"""

from __future__ import annotations

import io
import math
from typing import Any

import matplotlib
import numpy as np
import pytest
from test_replay import embedded_commands, synthetic_result

from hybrid_force.geometry.builtin_surfaces import Plane
from hybrid_force.result import Result
from hybrid_force.viz import replay, scene_removal

NODE = "/meshcat/replay/removal"
SPACING = 2e-3  # m, the synthetic grid's cell size


def with_removal(base: Result, depth_of: Any = None, n: int = 51) -> Result:
    """``base`` with an n × n removal grid of ``SPACING`` cells on the plane z = c_z through
    the centre c of its desired path, the depth ``depth_of(x, y)`` [m] of the offsets from c
    (default: 1 µm to 2 µm linearly along x)."""
    c = 0.5 * (base.p_d.min(axis=0) + base.p_d.max(axis=0))
    offsets = (np.arange(n) - (n - 1) / 2) * SPACING
    x, y = (g.ravel() for g in np.meshgrid(offsets, offsets, indexing="ij"))
    points = c + np.column_stack([x, y, np.zeros_like(x)])
    half = offsets[-1]
    depth = (1e-6 * (1.0 + (x + half) / (2 * half))) if depth_of is None else depth_of(x, y)
    meta = dict(base.meta)
    meta["removal"] = {"resolution": SPACING, "grid": "chart"}
    fields = {name: getattr(base, name) for name in Result.__dataclass_fields__}
    fields.update(
        meta=meta,
        removal_points=points,
        removal_depth=depth,
        removal_target=np.ones(points.shape[0]),
    )
    return Result(**fields)


def viridis(x: np.ndarray) -> np.ndarray:
    """(K, 3) matplotlib's viridis at x (K,) in [0, 1], RGB in [0, 1]."""
    out: np.ndarray = matplotlib.colormaps["viridis"](np.asarray(x, dtype=float))[:, :3]
    return out


def unpack(attribute: dict[str, Any]) -> np.ndarray:
    """(K, 3) float32 triples of a packed meshcat geometry attribute."""
    return np.frombuffer(attribute["array"].data, dtype=np.float32).reshape(-1, 3)


def removal_object(commands: list[dict[str, Any]]) -> dict[str, Any]:
    (command,) = [c for c in commands if c["type"] == "set_object" and c["path"] == NODE]
    obj: dict[str, Any] = command["object"]
    return obj


@pytest.fixture(scope="module")
def base() -> Result:
    """The synthetic RTR run with a plane 1 mm above the centre of its desired path, the plane
    of the grid of :func:`with_removal`: the translucent plane lies between the cells and a
    camera above them, as the drawn chords of a concave part do."""
    p_d = synthetic_result(duration=0.3).p_d
    centre = 0.5 * (p_d.min(axis=0) + p_d.max(axis=0))
    plane = Plane(centre + np.array([0.0, 0.0, 1e-3]), [0.0, 0.0, 1.0])
    return synthetic_result(duration=0.3, surfaces=[plane])


@pytest.fixture(scope="module")
def run(base: Result) -> Result:
    return with_removal(base)


@pytest.fixture(scope="module")
def page(run: Result) -> str:
    return replay.html(run)


def test_colormap_is_matplotlibs_viridis() -> None:
    x = np.linspace(0.0, 1.0, 2001)
    assert np.max(np.abs(scene_removal.colormap(x) - viridis(x))) < 3 / 255
    # its ends: matplotlib's first and last colours, to the byte
    ends = np.array([0.0, 1.0])
    assert np.array_equal(scene_removal.colormap(ends) * 255, np.round(viridis(ends) * 255))


def test_points_are_the_cells_coloured_by_depth(run: Result, page: str) -> None:
    obj = removal_object(embedded_commands(page))
    (geometry,) = obj["geometries"]
    attributes = geometry["data"]["attributes"]
    assert run.removal_points is not None and run.removal_depth is not None
    points = unpack(attributes["position"])
    assert np.array_equal(points, run.removal_points.astype(np.float32))
    colors = unpack(attributes["color"]).astype(float)
    depth = run.removal_depth
    x = (depth - depth.min()) / (depth.max() - depth.min())
    assert np.max(np.abs(colors - viridis(x))) < 3 / 255
    # the shallowest and the deepest cells are the colormap's two ends
    assert np.allclose(colors[np.argmin(depth)], viridis(np.zeros(1))[0], atol=0.5 / 255)
    assert np.allclose(colors[np.argmax(depth)], viridis(np.ones(1))[0], atol=0.5 / 255)
    (material,) = obj["materials"]
    assert material["type"] == "PointsMaterial" and material["vertexColors"]
    assert material["color"] == 0xFFFFFF  # white: the vertex colours are shown as they are
    assert material["size"] == pytest.approx(2.0 * SPACING)


def test_page_states_the_scale_in_micrometres(run: Result, page: str) -> None:
    assert run.removal_depth is not None
    assert "depth removed at the end of the run [µm]" in page
    low = f'<span id="removal-legend-low">{run.removal_depth.min() * 1e6:.4g}</span>'
    high = f'<span id="removal-legend-high">{run.removal_depth.max() * 1e6:.4g}</span>'
    assert low in page and high in page
    assert ">1</span>" in low and ">2</span>" in high  # 1 µm and 2 µm (with_removal)
    rep = replay.Replay(run)
    assert rep.node_paths()["removal"] == NODE
    # drawn after the translucent surfaces (render order 1 on the points object)
    commands = embedded_commands(page)
    orders = [
        c["value"]
        for c in commands
        if c["type"] == "set_property" and c["path"] == NODE + "/<object>"
    ]
    assert orders == [1]


def test_a_run_without_removal_draws_none(base: Result) -> None:
    page = replay.html(base)
    commands = embedded_commands(page)
    assert not [c for c in commands if c.get("path", "").startswith(NODE)]
    assert "removal-legend" not in page
    assert replay.Replay(base).node_paths()["removal"] is None


def test_a_large_grid_is_averaged_into_voxels(base: Result) -> None:
    """A linear depth field's voxel means are the field at the voxels' mean positions."""
    a, b, d0 = 3e-5, -2e-5, 5e-6  # depth = d0 + a x + b y [m], x and y [m]
    run = with_removal(base, lambda x, y: d0 + a * x + b * y, n=101)
    bound = 900
    rep = replay.Replay(run, replay.ReplaySettings(max_removal_points=bound))
    layer = rep.removal
    assert layer is not None and layer.merged and layer.cells == 101 * 101
    assert 0.5 * bound < layer.points.shape[0] <= bound
    c = 0.5 * (base.p_d.min(axis=0) + base.p_d.max(axis=0))
    offset = layer.points - c
    assert np.allclose(layer.depth, d0 + a * offset[:, 0] + b * offset[:, 1], rtol=0, atol=1e-15)
    assert np.allclose(layer.points[:, 2], c[2], atol=1e-12)  # still on the plane
    assert layer.spacing > SPACING


def test_bad_bound() -> None:
    from hybrid_force.errors import BadInputError

    with pytest.raises(BadInputError, match="max_removal_points"):
        replay.ReplaySettings(max_removal_points=0)


# --------------------------------------------------------------------------- in a browser
# Everything but the removal layer and the translucent plane over it hidden, the camera above
# the grid's centre, the cells' screen positions (pixels from the top left) returned.
JS_PROJECT = """
(indices) => {
  const v = window.viewer;
  for (const p of ["/meshcat/robot", "/Grid", "/Axes", "/meshcat/replay/tip",
                   "/meshcat/replay/force", "/meshcat/replay/paths"]) {
    v.handle_command({type: "set_property", path: p, property: "visible", value: false});
  }
  v.handle_command({type: "set_property", path: "/Cameras/default/rotated/<object>",
                    property: "position", value: [0.0001, 0.12, 0.0001]});
  v.set_dirty();
  v.render();
  let node = v.scene_tree;
  for (const name of "/meshcat/replay/removal/<object>".split("/").filter((s) => s.length)) {
    node = node.children[name];
  }
  const points = node.object;
  points.updateMatrixWorld(true);
  v.camera.updateMatrixWorld(true);
  const position = points.geometry.attributes.position;
  const canvas = v.renderer.domElement.getBoundingClientRect();
  const out = [];
  for (const i of indices) {
    const p = points.position.clone().set(position.getX(i), position.getY(i), position.getZ(i));
    p.applyMatrix4(points.matrixWorld).project(v.camera);
    out.push([canvas.left + (p.x + 1) / 2 * canvas.width,
              canvas.top + (1 - p.y) / 2 * canvas.height]);
  }
  return {out: out, type: points.type};
}
"""


@pytest.mark.browser
def test_colours_rendered_in_browser(browser: Any, run: Result, tmp_path: Any) -> None:
    """The pixels at five cells across the depth ramp have matplotlib's viridis colour of the
    normalised depth of the cell or of a neighbour, untinted by the translucent plane between
    them and the camera (the legend's text too)."""
    from PIL import Image

    path = replay.write_html(run, tmp_path / "removal.html")
    context = browser.new_context(viewport={"width": 800, "height": 600})
    try:
        page = context.new_page()
        page.goto(path.as_uri())
        page.wait_for_function("window.hybridForceReplay && window.hybridForceReplay.ready")
        n = 51
        # cells along the middle row (y = 0), from the shallowest column to the deepest
        columns = [2, 13, 25, 37, 48]
        indices = [i * n + (n - 1) // 2 for i in columns]
        got = page.evaluate(JS_PROJECT, indices)
        assert got["type"] == "Points"
        page.wait_for_timeout(300)
        image = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB")) / 255.0
        assert run.removal_depth is not None
        depth = run.removal_depth
        span = depth.max() - depth.min()
        for (u, v), column in zip(got["out"], columns, strict=True):
            pixel = image[math.floor(v), math.floor(u)]
            # the points overlap their neighbours (2 cells wide): the pixel at a cell's centre
            # is its colour or a neighbouring column's (drawn later)
            near = [(column + d) * n + (n - 1) // 2 for d in (-1, 0, 1)]
            candidates = viridis((depth[near] - depth.min()) / span)
            error = np.min(np.max(np.abs(candidates - pixel), axis=1))
            assert error < 4 / 255, (column, pixel, candidates)
        legend = page.inner_text("#removal-legend")
        assert "depth removed at the end of the run [µm]" in legend
    finally:
        context.close()
