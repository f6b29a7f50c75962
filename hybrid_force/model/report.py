"""What a model is, as the simulation will see it: ``hybrid-force robots --check MODEL``.

:func:`model_report` loads a model exactly as a scenario does
(:func:`hybrid_force.model.loading.load_robot`: every refusal is the same
:class:`~hybrid_force.errors.RobotError`) and gathers, in a :class:`ModelReport`:

* the moving joints with their URDF type, position range and effort limit as the
  simulation reads them (:attr:`~hybrid_force.model.robot.Robot.position_limits`
  and :attr:`~hybrid_force.model.robot.Robot.effort_limits`: ∓inf for a
  continuous joint or an empty range, +inf for an effort of 0 or none), the fixed joints and
  the joints the loader locked;
* the tip (given or default), and the other frames a tool could be put on: the body frames
  at the end of each chain (on a joint that has no child joint) and on the tip's own joint;
* the total mass of the model (every link, including those welded to the root) and the mass
  the moving joints carry [kg];
* the :class:`~hybrid_force.errors.ModelWarning` messages the load issued;
* the meshes the URDF's ``<visual>`` elements reference and whether each file exists and can
  be read (by coal's mesh loader, the replay's);
* the reach (:class:`Reach`): a bound on the distance from the first moving joint to the tip.

The URDF's own content (joint types such as ``continuous``, which Pinocchio turns into
revolute joints, the full joint list and the visuals) is read with yourdfpy (imported here, on
first use: about 0.7 s), from the text the model was built from
(:attr:`Robot.urdf_xml <hybrid_force.model.robot.Robot.urdf_xml>`: the file as
:func:`hybrid_force.model.urdf_text.urdf_text` reads it, or xacro's expansion). The dynamics-side
numbers (limits, masses, placements) come from the Pinocchio model the simulation uses. An
MJCF model, or a file yourdfpy cannot read, still gets the Pinocchio part and a note.

Mesh resolution, the replay's (:func:`hybrid_force.viz.robot_visuals.visual_geometry`), so
that a mesh reported found is one the replay draws: ``package://NAME/REST`` is
``DIR/NAME/REST`` in the first of the robot's ``package_dirs`` that holds it; ``file://PATH``
and a plain path are taken as is when absolute, else relative to the model file's folder, then
to each package folder; another URI scheme (``http://``) names no file.
"""

from __future__ import annotations

import io
import logging
import math
import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from hybrid_force.errors import HybridForceError, ModelWarning
from hybrid_force.model.loading import load_robot

__all__ = ["JointInfo", "MeshRef", "ModelReport", "Reach", "format_report", "model_report"]


@dataclass(frozen=True)
class JointInfo:
    """One moving joint of the loaded arm.

    Attributes:
        name: joint name (the URDF's).
        urdf_type: ``revolute``, ``continuous`` or ``prismatic`` (as the URDF declares it).
        lower, upper: position range [rad, or m for a prismatic joint]; ∓inf when unbounded.
        effort: effort limit [N·m, or N for a prismatic joint]; +inf when unspecified.
    """

    name: str
    urdf_type: str
    lower: float
    upper: float
    effort: float

    @property
    def prismatic(self) -> bool:
        """True for a prismatic joint (metres and newtons), False for a revolute one."""
        return self.urdf_type == "prismatic"


@dataclass(frozen=True)
class MeshRef:
    """A mesh file a ``<visual>`` references.

    Attributes:
        uri: the ``filename`` attribute as written.
        link: the first link whose visual references it.
        found: the file it resolves to, if it exists and can be read as a mesh (by the
            replay's loader, coal's), else None.
        candidates: every path that was looked at, in order.
        unreadable: where the file exists but cannot be read: the file and why; else None.
    """

    uri: str
    link: str
    found: Path | None
    candidates: tuple[Path, ...]
    unreadable: str | None = None


@dataclass(frozen=True)
class Reach:
    """A bound on the tip's distance from the first moving joint [m].

    With o_1 the origin of the first moving joint of the chain from the root to the tip frame
    (a point fixed in the world), every tip position p(q) within the joint limits satisfies
    ‖p(q) − o_1‖ ≤ :attr:`total` = :attr:`links` + :attr:`prismatic` (triangle inequality):

    * :attr:`links`: the sum of the distances between consecutive joint origins along that
      chain and from the last joint to the tip frame, at q = 0. A revolute joint turns about its
      own origin, so its segment keeps that length in every configuration;
    * :attr:`prismatic`: the sum over the chain's prismatic joints of max(|lower|, |upper|)
      (a prismatic joint at q moves its segment by q along its axis); +inf when one of them has
      no finite range.

    The bound is reached only when every segment lines up (for an arm of revolute joints,
    fully stretched). The RTR arm: links 0 + 0.9 + 1.0 = 1.9 m (the largest horizontal
    distance of its tip from the q1 axis), prismatic q2 in [-1, 16] m: 16 m; total 17.9 m.

    Attributes:
        first_joint: name of the joint whose origin is o_1.
        links: see above [m].
        prismatic: see above [m].
    """

    first_joint: str
    links: float
    prismatic: float

    @property
    def total(self) -> float:
        """links + prismatic [m]."""
        return self.links + self.prismatic


@dataclass(frozen=True)
class ModelReport:
    """What ``hybrid-force robots --check`` prints (see the module docstring).

    Attributes:
        name: the model as given (registry name or path).
        urdf_path: the model file.
        joints: the moving joints, root to leaves (model order).
        fixed_joints: the URDF's fixed joints.
        locked_joints: the model file's moving joints the loader held at a fixed value (not
            in joints; :attr:`~hybrid_force.model.robot.Robot.locked_joints`).
        tip: the tip frame the load used; default_tip: the one it uses without ``tip``
            (None if that load is refused).
        tip_candidates: other body frames a tool could be put on (module docstring).
        total_mass: mass of every link [kg]; moving_mass: the part the moving joints carry.
        model_warnings: the ModelWarning messages of the load.
        meshes: the visual meshes, in the URDF's order (each URI once).
        reach: see :class:`Reach`.
        notes: what could not be reported, and why.
    """

    name: str
    urdf_path: Path
    joints: tuple[JointInfo, ...]
    fixed_joints: tuple[str, ...]
    locked_joints: tuple[str, ...]
    tip: str
    default_tip: str | None
    tip_candidates: tuple[str, ...]
    total_mass: float
    moving_mass: float
    model_warnings: tuple[str, ...]
    meshes: tuple[MeshRef, ...]
    reach: Reach
    notes: tuple[str, ...] = field(default=())


def model_report(
    model: str | Path,
    tip: str | None = None,
    *,
    package_dirs: Sequence[str | Path] = (),
    xacro_args: Mapping[str, str] | None = None,
    lock_off_chain: bool | None = None,
    xacro_trust: bool = False,
) -> ModelReport:
    """Load ``model`` as a scenario would and report what the simulation will see.

    Args:
        model: a registry name or a model path (see :func:`~hybrid_force.load_robot`).
        tip: the tip frame (default: the model's default tip).
        package_dirs, xacro_args, lock_off_chain, xacro_trust: as for
            :func:`~hybrid_force.model.loading.load_robot` (the scenario's ``[robot]`` keys).

    Raises:
        RobotError, RobotError, RobotError: as :func:`~hybrid_force.model.loading.load_robot`
            (a model that cannot be simulated, an unknown name, a tip that is no frame).
    """

    options: dict[str, Any] = {
        "package_dirs": tuple(package_dirs),
        "xacro_args": xacro_args,
        "lock_off_chain": lock_off_chain,
        "xacro_trust": xacro_trust,
    }
    with _recorded_model_warnings() as said:
        robot = load_robot(model, tip=tip, **options)
    default_tip: str | None = robot.tip
    if tip is not None:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ModelWarning)  # already recorded above
                default_tip = load_robot(model, **options).tip
        except HybridForceError:
            default_tip = None
    notes: list[str] = []
    xml = robot.urdf_xml
    if xml is None:
        notes.append(
            f"{robot.urdf_path} is an MJCF model: joint types are Pinocchio's, and fixed "
            "joints and meshes are not reported"
        )
    urdf = _read_urdf(xml, robot.urdf_path, notes) if xml is not None else None
    pin_model = robot.model
    names = [str(pin_model.names[j]) for j in range(1, pin_model.njoints)]
    urdf_types = {j.name: j.type for j in urdf.robot.joints} if urdf is not None else {}
    lower, upper = robot.position_limits
    effort = robot.effort_limits
    joints = []
    for jid, name in enumerate(names, start=1):
        kind = "prismatic" if pin_model.joints[jid].shortname().startswith("JointModelP") else None
        iq, iv = pin_model.idx_qs[jid], pin_model.idx_vs[jid]
        joints.append(
            JointInfo(
                name=name,
                urdf_type=urdf_types.get(name, kind or "revolute"),
                lower=float(lower[iq]),
                upper=float(upper[iq]),
                effort=float(effort[iv]),
            )
        )
    fixed = tuple(j.name for j in urdf.robot.joints if j.type == "fixed") if urdf else ()
    locked = tuple(robot.locked_joints)  # also an MJCF model's (no URDF to read)
    masses = [float(inertia.mass) for inertia in pin_model.inertias]
    return ModelReport(
        name=str(model),
        urdf_path=Path(robot.urdf_path),
        joints=tuple(joints),
        fixed_joints=fixed,
        locked_joints=locked,
        tip=robot.tip,
        default_tip=default_tip,
        tip_candidates=_tip_candidates(pin_model, robot.tip),
        total_mass=sum(masses),
        moving_mass=sum(masses[1:]),
        model_warnings=tuple(said),
        meshes=_meshes(urdf, Path(robot.urdf_path), robot.package_dirs) if urdf else (),
        reach=reach(pin_model, robot.tip, joints),
        notes=tuple(notes),
    )


def reach(model: pin.Model, tip: str, joints: list[JointInfo] | tuple[JointInfo, ...]) -> Reach:
    """The :class:`Reach` of the chain from the root to the frame ``tip``.

    Args:
        model: a Pinocchio model whose moving joints are one-coordinate revolute or prismatic.
        tip: a frame of ``model``.
        joints: one :class:`JointInfo` per moving joint of ``model``, in model order (their
            ranges give the prismatic travel).
    """
    frame = model.frames[model.getFrameId(tip)]
    chain = [int(j) for j in model.supports[frame.parentJoint]][1:]  # without the universe
    if not chain:  # the tip is welded to the root: nothing moves it
        return Reach(first_joint="", links=0.0, prismatic=0.0)
    segments = [model.jointPlacements[j].translation for j in chain[1:]]
    segments.append(frame.placement.translation)
    links = float(sum(np.linalg.norm(t) for t in segments))
    travel = 0.0
    for j in chain:
        info = joints[j - 1]
        if info.prismatic:
            travel += max(abs(info.lower), abs(info.upper))  # inf when unbounded
    return Reach(first_joint=str(model.names[chain[0]]), links=links, prismatic=travel)


def _tip_candidates(model: pin.Model, tip: str) -> tuple[str, ...]:
    """Body frames on a leaf joint (no child joint) or on the tip's joint, except the tip."""
    parents = {int(model.parents[j]) for j in range(1, model.njoints)}
    leaves = {j for j in range(1, model.njoints) if j not in parents}
    tip_joint = model.frames[model.getFrameId(tip)].parentJoint
    return tuple(
        frame.name
        for frame in model.frames
        if frame.type == pin.FrameType.BODY
        and frame.name != tip
        and (frame.parentJoint in leaves or frame.parentJoint == tip_joint)
        and frame.parentJoint != 0
    )


@contextmanager
def _recorded_model_warnings() -> Iterator[list[str]]:
    """Record the ModelWarning messages issued inside the block (each one, every time);
    other warnings go on as the caller's filters say."""
    said: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ModelWarning)
        yield said
    for w in caught:
        if issubclass(w.category, ModelWarning):
            said.append(" ".join(str(w.message).split()))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno, source=w.source)


def _read_urdf(xml: str, path: Path, notes: list[str]) -> Any | None:
    """The yourdfpy model of the URDF text ``xml`` read from ``path`` (no meshes loaded), or
    None with a note saying why."""
    import yourdfpy  # about 0.7 s (trimesh, scipy): only here

    logger = logging.getLogger("yourdfpy")
    records: list[logging.LogRecord] = []

    class _Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record)

    handler, propagate = _Keep(level=logging.WARNING), logger.propagate
    logger.addHandler(handler)
    logger.propagate = False  # nothing on stderr: what it says goes into the notes
    try:
        data = xml.encode("utf-8")  # urdf_text's declaration, if any, says UTF-8
        urdf = yourdfpy.URDF.load(
            io.BytesIO(data),
            build_scene_graph=False,
            load_meshes=False,
            load_collision_meshes=False,
        )
    except Exception as exc:  # yourdfpy raises bare KeyError/ValueError on odd input
        notes.append(
            f"yourdfpy cannot read {path} ({type(exc).__name__}: {exc}): URDF joint types, "
            "fixed and locked joints and meshes are not reported"
        )
        urdf = None
    finally:
        logger.removeHandler(handler)
        logger.propagate = propagate
    notes.extend(f"yourdfpy: {record.getMessage()}" for record in records)
    return urdf


def _meshes(urdf: Any, urdf_path: Path, package_dirs: tuple[str, ...]) -> tuple[MeshRef, ...]:
    """Each mesh URI of the visuals, once, with the file it resolves to (module docstring)."""
    seen: dict[str, MeshRef] = {}
    folder = urdf_path.resolve().parent
    for link in urdf.robot.links:
        for visual in link.visuals:
            mesh = visual.geometry.mesh if visual.geometry is not None else None
            if mesh is None or mesh.filename in seen:
                continue
            candidates = tuple(dict.fromkeys(_mesh_candidates(mesh.filename, folder, package_dirs)))
            found = next((c.resolve() for c in candidates if c.is_file()), None)
            why = _mesh_unreadable(found) if found is not None else None
            seen[mesh.filename] = MeshRef(
                str(mesh.filename),
                link.name,
                None if why else found,
                candidates,
                f"{found}: {why}" if why else None,
            )
    return tuple(seen.values())


def _mesh_unreadable(path: Path) -> str | None:
    """Why the replay's mesh loader (coal's) cannot read ``path``, or None if it can: a file
    that exists is not yet a mesh (a corrupt or empty STL is drawn as a placeholder)."""
    try:
        import coal
    except ImportError:  # pragma: no cover - coal comes with Pinocchio
        return None
    try:
        coal.MeshLoader().load(str(path), np.ones(3))
    except (RuntimeError, ValueError) as exc:  # coal's message ends with the loader's reason
        return " ".join(str(exc).split("message:", 1)[-1].split()) or type(exc).__name__
    return None


def _mesh_candidates(uri: str, folder: Path, package_dirs: tuple[str, ...]) -> tuple[Path, ...]:
    """The paths a mesh URI may name, in the order they are tried (module docstring)."""
    if uri.startswith("package://"):
        name, _, rest = uri.removeprefix("package://").partition("/")
        if not name or not rest or name in (".", ".."):
            return ()
        return tuple(Path(d) / name / rest for d in package_dirs)
    text = uri.removeprefix("file://")
    if not text or "://" in text:
        return ()  # http:// and the like: never fetched
    path = Path(text)
    if path.is_absolute():
        return (path,)
    return (folder / path, *(Path(d) / path for d in package_dirs))


def format_report(report: ModelReport) -> str:
    """The report as the lines ``robots --check`` prints (ends with a newline)."""
    file = report.urdf_path.resolve()
    lines = [
        f"model: {file}"
        if Path(report.name).resolve() == file
        else f"model: {report.name} ({file})"
    ]
    lines.append(f"joints: {len(report.joints)} moving")
    rows = [("name", "type", "range", "effort")]
    for j in report.joints:
        unit, force = ("m", "N") if j.prismatic else ("rad", "N·m")
        bounded = math.isfinite(j.lower) and math.isfinite(j.upper)
        span = f"[{j.lower:g}, {j.upper:g}] {unit}" if bounded else "unbounded"
        strength = f"{j.effort:g} {force}" if math.isfinite(j.effort) else "unspecified"
        rows.append((j.name, j.urdf_type, span, strength))
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    lines += [
        "  " + "  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows
    ]
    lines.append(f"fixed joints: {', '.join(report.fixed_joints) or 'none'}")
    if report.locked_joints:
        lines.append(f"locked joints (held fixed): {', '.join(report.locked_joints)}")
    if report.tip == report.default_tip:
        lines.append(f"tip: {report.tip} (default)")
    else:
        default = report.default_tip or "refused, see 'robots --check' without --tip"
        lines.append(f"tip: {report.tip} (given; default: {default})")
    lines.append(f"other tip frames: {', '.join(report.tip_candidates) or 'none'}")
    lines.append(
        f"total mass: {report.total_mass:.6g} kg ({report.moving_mass:.6g} kg on moving joints)"
    )
    r = report.reach
    if r.first_joint:
        how = (
            f"joint-to-joint distances {r.links:.6g} m + prismatic travel {r.prismatic:.6g} m"
            if r.prismatic
            else "the sum of the joint-to-joint distances to the tip"
        )
        lines.append(f"reach: {r.total:.6g} m from the origin of joint {r.first_joint} ({how})")
    else:
        lines.append("reach: 0 m (no moving joint between the root and the tip)")
    found = sum(m.found is not None for m in report.meshes)
    unreadable = sum(m.unreadable is not None for m in report.meshes)
    lines.append(
        f"meshes: {len(report.meshes)} referenced, {found} found"
        + (f", {unreadable} unreadable" if unreadable else "")
    )
    for m in report.meshes:
        if m.found is not None:
            lines.append(f"  found    {m.uri}")
        elif m.unreadable is not None:
            lines.append(f"  unreadable {m.uri} (link {m.link}; {m.unreadable})")
        else:
            if m.candidates:
                where = "looked for " + ", ".join(map(str, m.candidates))
            elif m.uri.startswith("package://"):
                where = "no package folder to look in"
            else:
                where = "not a file path"
            lines.append(f"  missing  {m.uri} (link {m.link}; {where})")
    lines.append(f"warnings: {len(report.model_warnings) or 'none'}")
    lines += [f"  warning: {text}" for text in report.model_warnings]
    lines += [f"note: {text}" for text in report.notes]
    return "\n".join(lines) + "\n"
