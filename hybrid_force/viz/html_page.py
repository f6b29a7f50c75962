"""The self-contained HTML page of a replay: meshcat's viewer JavaScript inlined and the scene's
commands recorded as base64 msgpack, decoded synchronously; the page makes no network request.
"""

from __future__ import annotations

import base64
import html as html_lib
import json
from pathlib import Path
from typing import Any

from hybrid_force._atomic import atomic_file, prepare_target
from hybrid_force.errors import BadInputError


def _pack_command(command: Any) -> bytes:
    """msgpack bytes of a meshcat command (what the websocket would carry)."""
    import umsgpack

    return umsgpack.packb(command.lower())


class _RecordingWindow:
    """A meshcat window that records commands instead of sending them (for static HTML)."""

    def __init__(self) -> None:
        self.commands: list[bytes] = []

    def send(self, command: Any) -> None:
        self.commands.append(_pack_command(command))


_MAIN_JS: list[str] = []


def _meshcat_js() -> str:
    """meshcat's bundled viewer JavaScript (main.min.js), read once."""
    if not _MAIN_JS:
        import meshcat

        js = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
        try:
            _MAIN_JS.append(js.read_text(encoding="utf-8"))
        except OSError as exc:
            raise BadInputError(
                f"meshcat's viewer JavaScript '{js}' cannot be read: {exc}"
            ) from exc
    return _MAIN_JS[0]


def _legend_html(scale: dict[str, Any] | None) -> str:
    """The removal layer's colour bar (an overlay, ``id="removal-legend"``), or "" without one.

    ``scale``: ``title``, ``low_um`` and ``high_um`` (the colour scale's ends [µm]), ``colors``
    (CSS colours from the low end) and ``note`` (:func:`~hybrid_force.viz.scene_removal.legend`).
    """
    if not scale:
        return ""
    gradient = ", ".join(html_lib.escape(str(c)) for c in scale["colors"])
    low, high = float(scale["low_um"]), float(scale["high_um"])
    return f"""<div id="removal-legend" style="position: absolute; left: 12px; bottom: 12px;
 padding: 6px 10px; background: rgba(255, 255, 255, 0.85); font: 12px sans-serif;
 border-radius: 4px; pointer-events: none; z-index: 10">
<div id="removal-legend-title">{html_lib.escape(str(scale["title"]))}</div>
<div style="width: 240px; height: 12px; margin: 4px 0;
 background: linear-gradient(to right, {gradient})"></div>
<div style="display: flex; justify-content: space-between; width: 240px">
<span id="removal-legend-low">{low:.4g}</span><span id="removal-legend-high">{high:.4g}</span>
</div>
<div style="color: #555">{html_lib.escape(str(scale["note"]))}</div>
</div>
"""


def _static_page(commands: list[bytes], info: dict[str, Any]) -> str:
    """A complete HTML page that builds the scene from ``commands`` without any request (with
    the removal layer's colour bar when ``info["removal"]`` holds its scale)."""
    js = _meshcat_js().replace("</script", "<\\/script")
    legend = _legend_html(info.get("removal"))
    blobs = ",\n".join(f'"{base64.b64encode(c).decode("ascii")}"' for c in commands)
    info_json = json.dumps(info).replace("</", "<\\/")
    title = html_lib.escape(f"hybrid_force replay: {info.get('name') or 'run'}")
    return f"""<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
body {{ margin: 0; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
{legend}<script>
{js}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
window.viewer = viewer;
(function () {{
  var commands = [
{blobs}
  ];
  for (var i = 0; i < commands.length; i++) {{
    var text = atob(commands[i]);
    var bytes = new Uint8Array(text.length);
    for (var j = 0; j < text.length; j++) {{ bytes[j] = text.charCodeAt(j); }}
    viewer.handle_command_bytearray(bytes);
  }}
  var info = {info_json};
  info.ready = true;
  window.hybridForceReplay = info;
}})();
</script>
</body>
</html>
"""


def _atomic_write_text(target: Path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``target`` through a temp file in its folder and os.replace."""
    prepare_target(target, BadInputError, "write HTML")
    try:
        with atomic_file(target, "w", encoding="utf-8") as fh:
            fh.write(text)
    except OSError as exc:
        raise BadInputError(f"cannot write HTML to '{target}': {exc}") from exc
    return target
