"""The robot of a replayed run: the load options its result records, and its visual geometry
with a placeholder cube for every mesh that cannot be found or read.
"""

from __future__ import annotations

import os
import tempfile
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from hybrid_force.errors import BadInputError, ModelWarning, RobotError
from hybrid_force.model.xacro_files import xacro_argument_text

__all__ = ["PLACEHOLDER_SIZE", "visual_geometry"]


def _load_options(meta: dict[str, Any]) -> dict[str, Any]:
    """The :func:`~hybrid_force.model.loading.load_robot` options a result's meta records.

    From ``meta["robot"]`` (``package_dirs``, ``xacro_args``, ``lock_off_chain``,
    ``locked_positions``: what :attr:`~hybrid_force.model.robot.Robot.reference` gives). A key
    ``meta["robot"]`` lacks is taken from the scenario's ``[robot]`` table
    (``meta["scenario"]["robot"]``): ``xacro_args`` and ``lock_off_chain`` as written;
    ``package_dirs`` (relative to the scenario file) only when the scenario's ``robot.model``
    is a relative path without ``..`` whose parts end ``meta["robot"]["model"]`` (the
    scenario's folder is then known). Values of the wrong type
    are ignored (the arm is then loaded without them).
    """
    robot_meta = meta.get("robot")
    info: dict[str, Any] = robot_meta if isinstance(robot_meta, dict) else {}
    scenario = meta.get("scenario")
    table = scenario.get("robot") if isinstance(scenario, dict) else None
    table = table if isinstance(table, dict) else {}
    out: dict[str, Any] = {}
    args = info.get("xacro_args", table.get("xacro_args"))
    if isinstance(args, dict) and args:
        texts = {str(k): _toml_text(v) for k, v in args.items()}
        if all(isinstance(v, str) for v in texts.values()):
            out["xacro_args"] = texts
    lock = info.get("lock_off_chain", table.get("lock_off_chain"))
    if isinstance(lock, bool):
        out["lock_off_chain"] = lock
    held = info.get("locked_positions")
    if isinstance(held, dict) and all(
        isinstance(k, str) and isinstance(v, int | float) and not isinstance(v, bool)
        for k, v in held.items()
    ):
        out["locked_positions"] = {k: float(v) for k, v in held.items()}
    dirs = info.get("package_dirs")
    if dirs is None:
        dirs = _scenario_package_dirs(info.get("model"), table)
    if isinstance(dirs, list) and dirs and all(isinstance(d, str) and d for d in dirs):
        out["package_dirs"] = list(dirs)
    return out


def _toml_text(value: object) -> str | None:
    """A scenario's xacro argument as the loader passes it (a TOML number or boolean as its
    text), or None for a value the loader refuses."""

    try:
        return xacro_argument_text(value)
    except TypeError:
        return None


def _scenario_package_dirs(model: object, table: dict[str, Any]) -> list[str] | None:
    """The scenario's ``robot.package_dirs`` made absolute, when its folder can be told."""
    dirs, written = table.get("package_dirs"), table.get("model")
    if not (isinstance(dirs, list) and isinstance(model, str) and isinstance(written, str)):
        return None
    rel = Path(written)
    if rel.is_absolute() or ".." in rel.parts or not rel.parts:
        return None
    full = Path(model)
    if len(full.parts) <= len(rel.parts) or full.parts[-len(rel.parts) :] != rel.parts:
        return None
    folder = full.parents[len(rel.parts) - 1]
    return [os.path.normpath(folder / d) for d in dirs if isinstance(d, str) and d]


#: Edge of the cube drawn in place of a mesh that cannot be found or read [m].
PLACEHOLDER_SIZE = 0.05


def visual_geometry(robot: Any) -> Any:
    """The visual ``pinocchio.GeometryModel`` of a robot, with a placeholder for every mesh
    that cannot be found or read: a mesh never makes it an error.

    A URDF's (or xacro's expansion's) ``<visual><geometry><mesh filename=...>`` URIs are
    resolved here: ``package://NAME/rest`` as ``NAME/rest`` in the first of
    ``robot.package_dirs`` that holds it, ``file://path`` and plain paths (relative ones to
    the model file's folder, then to each package folder). An MJCF file's ``<asset><mesh
    file=...>`` resolve against its folder (and ``<compiler meshdir>`` or ``assetdir``).
    Each file found is loaded first by coal's cached mesh loader (which Pinocchio then reuses
    for a URDF); Pinocchio builds the geometry (``pin.buildGeomFromUrdfString`` /
    ``pin.buildGeomFromMJCF``) from a copy of the XML whose readable meshes are absolute
    paths and whose missing or unreadable ones are a cube of :data:`PLACEHOLDER_SIZE` at the
    visual's origin. Each such
    mesh gives one :class:`~hybrid_force.errors.ModelWarning` naming its URI, the link(s)
    (MJCF: bodies) that use it and why. Should Pinocchio still fail on the meshes, every mesh
    of the robot becomes a placeholder, with one warning saying why.

    Raises:
        BadInputError: the model file cannot be read or parsed any more.
    """

    label = f"robot '{robot.name}'"
    if str(robot.urdf_path) != robot.name:
        label += f" ({robot.urdf_path})"
    try:
        return _build_visuals(robot, pin, placeholders_only=False, label=label)
    except BadInputError:
        raise
    except (RuntimeError, ValueError, IndexError) as exc:  # a mesh Pinocchio cannot use
        why = " ".join(str(exc).split("message:", 1)[-1].split())
    try:
        visual = _build_visuals(robot, pin, placeholders_only=True, label=label)
    except BadInputError:
        raise
    except (RuntimeError, ValueError, IndexError, OSError) as exc:
        raise BadInputError(f"cannot load the visual geometry of {label}: {exc}") from exc
    warnings.warn(
        f"{label}: Pinocchio cannot read its meshes ({why}); every mesh is drawn as a "
        f"{PLACEHOLDER_SIZE:g} m cube",
        ModelWarning,
        stacklevel=3,
    )
    return visual


class _Meshes:
    """Mesh files of one robot: resolved, loaded once, or why they are placeholders."""

    def __init__(self, all_missing: bool) -> None:
        import coal

        self.loader = coal.CachedMeshLoader()
        self.all_missing = all_missing
        self.missing: dict[str, tuple[list[str], str]] = {}  # URI: (owners, why)

    def usable(self, uri: str, path: Path | None, scale: str | None, owner: str, why: str) -> bool:
        """Whether the file ``path`` (None: not found, ``why``) can be drawn; else record
        ``uri`` and ``owner`` for the warning."""
        if path is not None and not self.all_missing:
            try:
                self.loader.load(str(path), _scale(scale))
                return True
            except (RuntimeError, ValueError) as exc:
                message = " ".join(str(exc).split("message:", 1)[-1].split())
                why = f"cannot be read ({message})"
        owners, _ = self.missing.setdefault(uri, ([], why))
        if owner not in owners:
            owners.append(owner)
        return False


def _scale(text: str | None) -> np.ndarray:
    """A mesh's scale attribute as 3 numbers (1 1 1 when absent or unreadable)."""
    try:
        values = [float(x) for x in (text or "").split()]
    except ValueError:
        values = []
    return np.array(values if len(values) == 3 else [1.0, 1.0, 1.0])


def _build_visuals(robot: Any, pin: Any, *, placeholders_only: bool, label: str) -> Any:
    """Build the visual geometry from a copy of the model's XML (see :func:`visual_geometry`);
    warn about each mesh drawn as a placeholder (not when ``placeholders_only``)."""

    try:
        if robot.kind == "mjcf":  # its text (a replayed arm's, from its result file)
            root = _prepared_mjcf(Path(robot.urdf_path), robot.model_xml)
        else:
            root = ET.fromstring(robot.urdf_xml)
    except (OSError, ET.ParseError, RobotError) as exc:
        raise BadInputError(f"cannot load the visual geometry of {label}: {exc}") from exc
    base = Path(robot.urdf_path).resolve().parent
    dirs = [str(d) for d in robot.package_dirs]
    meshes = _Meshes(all_missing=placeholders_only)
    if robot.kind == "mjcf":
        _mjcf_meshes(root, base, meshes)
        with tempfile.TemporaryDirectory(prefix="hybrid_force_visuals_") as tmp:
            copy = Path(tmp) / Path(robot.urdf_path).name
            ET.ElementTree(root).write(copy, encoding="unicode")
            # (its binding takes no CachedMeshLoader: the meshes checked are loaded again)
            visual = pin.buildGeomFromMJCF(robot.model, str(copy), pin.GeometryType.VISUAL)
    else:
        _urdf_meshes(root, base, dirs, meshes)
        visual = pin.buildGeomFromUrdfString(
            robot.model, ET.tostring(root, encoding="unicode"), pin.GeometryType.VISUAL,
            package_dirs=dirs, mesh_loader=meshes.loader,
        )  # fmt: skip
    if not placeholders_only:
        what = "body" if robot.kind == "mjcf" else "link"
        for uri, (owners, why) in meshes.missing.items():
            names = ", ".join(f"'{o}'" for o in owners)
            warnings.warn(
                f"{label}: mesh '{uri}' of {what}{'s' if len(owners) > 1 else ''} {names} "
                f"{why}; drawn as a {PLACEHOLDER_SIZE:g} m cube",
                ModelWarning,
                stacklevel=4,
            )
    return visual


def _prepared_mjcf(path: Path, text: str) -> ET.Element:
    """The MJCF tree of ``text`` (the model's, named ``path``) as the loader gives it to
    Pinocchio (frames and replicates expanded, the bodies in one body ``world``:
    :func:`~hybrid_force.model.mjcf.prepare_mjcf`), so that the geoms sit on the bodies the
    model has; its warnings were given when the arm was loaded."""
    from hybrid_force.model.mjcf import prepare_mjcf

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ModelWarning)
        return ET.fromstring(prepare_mjcf(path, ET.fromstring(text)).text)


def _resolve_mesh(uri: str, base: Path, dirs: list[str]) -> Path | None:
    """The file a URDF mesh URI names, or None (see :func:`visual_geometry`): for
    ``package://NAME/rest``, the first ``DIR/NAME/rest`` that exists (as Pinocchio does)."""
    if uri.startswith("package://"):
        name, _, rest = uri[len("package://") :].partition("/")
        ok = name not in ("", ".", "..") and rest
        candidates = [Path(d) / name / rest for d in dirs] if ok else []
    else:
        path = Path(uri.removeprefix("file://"))
        if "://" in uri.removeprefix("file://"):
            candidates = []  # http:// and the like: never fetched
        elif path.is_absolute():
            candidates = [path]
        else:
            candidates = [base / path, *(Path(d) / path for d in dirs)]
    for candidate in candidates:
        if uri and candidate.is_file():
            return candidate.resolve()
    return None


def _placeholder_box(half: bool) -> str:
    """The size attribute of the placeholder cube: full edges (URDF) or half (MJCF) [m]."""
    edge = PLACEHOLDER_SIZE / 2 if half else PLACEHOLDER_SIZE
    return f"{edge:g} {edge:g} {edge:g}"


def _urdf_meshes(root: ET.Element, base: Path, dirs: list[str], meshes: _Meshes) -> None:
    """Make a URDF tree's visual meshes absolute paths, or placeholder boxes when they are
    missing or unreadable (recorded in ``meshes``)."""
    where = f"not found (package folders: {', '.join(dirs) or 'none'})"
    for link in root.findall("link"):
        for visual in link.findall("visual"):
            geometry = visual.find("geometry")
            mesh = geometry.find("mesh") if geometry is not None else None
            if geometry is None or mesh is None:
                continue
            uri = mesh.get("filename", "")
            found = _resolve_mesh(uri, base, dirs)
            if meshes.usable(uri, found, mesh.get("scale"), link.get("name", "?"), where):
                mesh.set("filename", str(found))
                continue
            geometry.remove(mesh)
            ET.SubElement(geometry, "box", size=_placeholder_box(half=False))


def _mjcf_meshes(root: ET.Element, base: Path, meshes: _Meshes) -> None:
    """Make an MJCF tree's mesh assets absolute paths; replace the geoms of a missing or
    unreadable one by placeholder boxes (recorded in ``meshes`` under the file as written)."""
    folder = base
    for compiler in root.iter("compiler"):
        sub = compiler.get("meshdir") or compiler.get("assetdir")
        if sub:
            folder = base / sub
        for key in ("meshdir", "assetdir"):
            compiler.attrib.pop(key, None)
    assets: dict[str, tuple[str, Path | None, str | None]] = {}  # name: (file, path, scale)
    for asset in root.iter("asset"):
        for mesh in list(asset.findall("mesh")):
            file = mesh.get("file")
            if not file:
                continue
            path = Path(file) if Path(file).is_absolute() else folder / file
            found = path.resolve() if path.is_file() else None
            assets[mesh.get("name") or Path(file).stem] = (file, found, mesh.get("scale"))
            if found is not None:
                mesh.set("file", str(found))
    gone: set[str] = set()
    for body in [*root.iter("worldbody"), *root.iter("body")]:
        for geom in body.findall("geom"):
            name = geom.get("mesh")
            if name is None or name not in assets:
                continue
            file, found, scale = assets[name]
            owner = body.get("name", "world") if body.tag == "body" else "world"
            why = f"not found (in {folder})"
            if name not in gone and meshes.usable(file, found, scale, owner, why):
                continue
            gone.add(name)
            meshes.usable(file, None, None, owner, why)  # the owner joins the warning
            del geom.attrib["mesh"]
            geom.set("type", "box")
            geom.set("size", _placeholder_box(half=True))
    for asset in root.iter("asset"):
        for mesh in list(asset.findall("mesh")):
            if (mesh.get("name") or Path(mesh.get("file", "")).stem) in gone:
                asset.remove(mesh)
