"""Loading an arm (:func:`load_robot`): a registry name or a URDF, xacro or MJCF file, checked,
built by Pinocchio, its joints off the tip's chain locked.

Every refusal is a :class:`~hybrid_force.errors.RobotError` (or RobotError, RobotError) naming the
file and the cause; the checks themselves are in :mod:`hybrid_force.model.urdf_check`.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import tempfile
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from hybrid_force.errors import ModelWarning, RobotError
from hybrid_force.model.registry import resolve_robot
from hybrid_force.model.robot import Robot, default_tip_frame
from hybrid_force.model.urdf_check import check_arm_model, check_urdf
from hybrid_force.model.urdf_text import check_file_size, check_model_size, urdf_text
from hybrid_force.model.xacro_files import (
    _absolute_dirs,
    _check_urdf_text,
    _ros_package_path,
    expand_xacro,
)

__all__ = ["MODEL_SUFFIXES", "load_robot", "model_kind", "robot_from_text"]

MODEL_SUFFIXES: tuple[str, ...] = (".urdf", ".xacro", ".xml")
"""Endings that make a text a model path, not a registry name (also: a path separator)."""

_KIND_LABELS = {"urdf": "URDF file", "xacro": "xacro file", "mjcf": "MJCF file"}


def load_robot(
    model: str | os.PathLike[str],
    tip: str | None = None,
    package_dirs: Sequence[str | os.PathLike[str]] = (),
    *,
    xacro_args: Mapping[str, str] | None = None,
    lock_off_chain: bool | None = None,
    xacro_trust: bool = False,
    locked_positions: Mapping[str, float] | None = None,
) -> Robot:
    """Load an arm by name or model file, refusing models the toolkit cannot simulate.

    Name or path: a :class:`~pathlib.Path` is always a path; a text is a path when it ends with
    ``.urdf``, ``.xacro`` or ``.xml`` or contains a path separator (``/``, ``\\``), and a
    registry name otherwise, even when a file of that name exists in the working directory
    (give ``./ur5`` to use such a file).

    Model files: a ``*.xacro`` file is expanded with the ``xacro`` package (arguments
    ``xacro_args``; ``$(find NAME)`` is the folder NAME inside the first package folder that
    holds one), then read as a URDF. Its ``${...}`` and ``$(eval ...)`` expressions are
    evaluated as data (numbers, texts, properties, math: see
    :mod:`hybrid_force.model.xacro_eval`), never as Python code, unless ``xacro_trust``. A
    ``*.xml`` file whose root element is ``<mujoco>`` is
    read by Pinocchio's MJCF parser (one whose root is ``<robot>`` is a URDF). Anything else
    is a URDF.

    Loading (see :mod:`hybrid_force.model.urdf_check` for every refusal):

    1. a URDF is read by :func:`~hybrid_force.model.urdf_text.urdf_text` (undeclared namespace
       prefixes declared); it, or xacro's expansion, goes through
       :func:`~hybrid_force.model.urdf_check.check_urdf` (structure, inertial data, no floating or
       planar joint, at least one moving joint) before Pinocchio sees it. An MJCF file: no
       ``<include>`` (Pinocchio's parser ignores it), no free or ball joint;
    2. a URDF's ``continuous`` joint is rewritten as a ``revolute`` one (same axis; its
       ``<limit>`` effort and velocity are kept) and the model built with
       ``pin.buildModelFromXML`` (``mimic=False``); its position limits are then set to
       ∓inf, and its effort and velocity limits to +inf when its ``<limit>`` does not give
       them. It has one real coordinate, the angle in rad, never wrapped (not Pinocchio's
       (cos, sin) pair). An MJCF file is built with ``pin.buildModelFromMJCF``;
    3. joints locked (removed from the model, their links merged into their parents by
       ``pin.buildReducedModel``): the registry's ``locked_joints``; every mimic joint that
       is not on the chain from the root to the tip frame (e.g. a mimicking gripper finger),
       held where its master's locked value puts it (offset + multiplier · q_master); and,
       with ``lock_off_chain``, every other joint off that chain (grippers, fingers, a
       humanoid's other limbs). A locked joint is held at 0 (Pinocchio's neutral position:
       0 rad or 0 m), or at the middle of its range when 0 is outside it (at its one finite
       bound when the other is infinite), unless ``locked_positions`` gives its position (a
       mimic joint is then held where it says too);
    4. :func:`~hybrid_force.model.urdf_check.check_arm_model` (nv > 0, one coordinate per joint, no
       mimic joint on the tip's chain) and :class:`Robot` (M(q0) positive definite).

    Every moving joint of a loaded arm then has nq = nv = 1, so q and v are (n,).

    Args:
        model: a bundled name (``"rtr"``), an example-robot-data arm (``"ur5"``, ``"panda"``,
            … see ``hybrid-force robots``), or the path of a URDF, xacro or MJCF file.
        tip: frame touching the surface; default: the arm's documented default tip, or for a
            model file the last body frame of the model (an MJCF file's last body).
        package_dirs: folders in which ``package://NAME/...`` (and xacro's ``$(find NAME)``)
            resolve to ``NAME/...``: each folder holds package folders, as in ROS. Searched
            first, then every folder of the ``ROS_PACKAGE_PATH`` environment variable
            (``os.pathsep``-separated), then the model file's own folder (a registry arm's
            own folders come before ``ROS_PACKAGE_PATH``). Relative folders are relative to
            the working directory. Meshes are read by the replay only: simulating needs none.
        xacro_args: ``{name: value}`` texts passed to a xacro file as its ``<xacro:arg>``
            values (``$(arg name)``); only for a ``.xacro`` model.
        xacro_trust: let xacro evaluate a ``.xacro`` model's expressions as Python (code in
            the file runs: only for files you trust); no effect on other models. Not part of
            :attr:`Robot.reference`: a result file never grants it.
        lock_off_chain: lock every joint off the chain from the root to the tip (step 3).
            Default (None): True for a model file, False for a registry arm (whose entry
            names what it locks: the Panda's fingers; ``z1`` keeps its gripper joint and
            ``g1`` its 29 joints). Mimic joints off the chain are locked whatever this says.
        locked_positions: ``{joint: position}`` [rad or m] of joints this load locks (step
            3): where each is held instead of its default. A scenario's ``initial.q`` (or
            ``initial.seed``) listing every joint of the file gives them. Every name must be
            a locked joint, every value a finite number within the joint's range.

    Raises:
        RobotError: a name that is not known (lists the known names).
        RobotError: the file is missing, malformed, physically impossible, outside the
            toolkit's scope, or xacro cannot expand it (the message names the file and the
            cause; for xacro, its own message), or, without ``xacro_trust``, one of its
            expressions is outside the safe evaluator's allowlist (the message names the
            file, the expression and how to opt in).
        RobotError: ``tip`` is not a frame of the model (lists the frames), or no moving
            joint lies between the root and it while the joints off its chain are locked.
        RobotError: ``locked_positions`` names a joint that is not locked, or holds a value
            that is not a finite number within the joint's range.
    """

    given = _absolute_dirs(package_dirs)
    args = _xacro_arguments(xacro_args)
    if lock_off_chain is not None and not isinstance(lock_off_chain, bool):
        raise RobotError(f"lock_off_chain must be True, False or None, got {lock_off_chain!r}")
    if not isinstance(xacro_trust, bool):
        raise RobotError(f"xacro_trust must be True or False, got {xacro_trust!r}")
    positions = _locked_positions(locked_positions)
    locked: tuple[str, ...] = ()
    if _is_path(model):
        path = Path(model)
        kind = model_kind(path)
        if not path.is_file():
            raise RobotError(f"{_KIND_LABELS[kind]} not found: {path}")
        name, default_tip, source = str(model), None, str(path.resolve())
        search = (*given, *_ros_package_path(), str(path.resolve().parent))
        lock_all = True if lock_off_chain is None else lock_off_chain
    else:
        entry = resolve_robot(str(model))
        path, default_tip, name, kind = entry.urdf_path, entry.default_tip, entry.name, "urdf"
        locked, source = entry.locked_joints, entry.name
        search = (*given, *entry.package_dirs, *_ros_package_path())
        lock_all = False if lock_off_chain is None else lock_off_chain
    if args and kind != "xacro":
        raise RobotError(
            f"xacro arguments ({', '.join(sorted(args))}) are given for {name}, which is not a "
            ".xacro file"
        )
    xml: str | None = None
    mimic: dict[str, tuple[str, float, float]] = {}
    uneven: dict[str, tuple[float, float]] = {}  # MJCF joints whose torque range is uneven
    if kind == "mjcf":
        pin_model, uneven = _build_mjcf(path)
    else:
        if kind == "xacro":
            xml = expand_xacro(path, args, given, check=True, trust=xacro_trust)
        else:
            xml = urdf_text(path)
            _check_urdf_text(path, xml, expanded=False)
        pin_model, mimic = _build_model(path, xml)
    reference: dict[str, object] = {
        "package_dirs": given,
        "xacro_args": args,
        "lock_off_chain": lock_off_chain,
    }
    if positions:
        reference["locked_positions"] = positions
    return _arm(
        pin_model, mimic, path, name, tip if tip is not None else default_tip, locked, lock_all,
        search=search, source=source, kind=kind, xml=xml, reference=reference,
        positions=positions, uneven=uneven,
    )  # fmt: skip


def robot_from_text(
    text: str,
    fmt: str,
    path: str | os.PathLike[str],
    tip: str | None = None,
    package_dirs: Sequence[str | os.PathLike[str]] = (),
    *,
    lock_off_chain: bool | None = None,
    locked_positions: Mapping[str, float] | None = None,
) -> Robot:
    """An arm built from a model's XML text, as :func:`load_robot` builds a model file's.

    What the replay rebuilds a run's arm from: the text its result file stores (a xacro
    model's expansion), so no xacro file is expanded and no model file read again.

    Args:
        text: the URDF (``fmt="urdf"``) or MJCF (``fmt="mjcf"``) text.
        fmt: ``"urdf"`` or ``"mjcf"``.
        path: the model file the text came from: it names the arm in messages, and relative
            mesh paths of its visuals resolve against its folder; it is not read.
        tip, package_dirs, lock_off_chain, locked_positions: as for :func:`load_robot` (a
            model file's).

    Raises:
        RobotError, RobotError: as :func:`load_robot` for the text.
    """

    if fmt not in ("urdf", "mjcf") or not isinstance(text, str):
        raise RobotError(f"a model text must be 'urdf' or 'mjcf' text, got {fmt!r}")
    if lock_off_chain is not None and not isinstance(lock_off_chain, bool):
        raise RobotError(f"lock_off_chain must be True, False or None, got {lock_off_chain!r}")
    given = _absolute_dirs(package_dirs)
    positions = _locked_positions(locked_positions)
    model_path = Path(path)
    xml: str | None = None
    mimic: dict[str, tuple[str, float, float]] = {}
    uneven: dict[str, tuple[float, float]] = {}
    if fmt == "mjcf":
        pin_model, uneven = _build_mjcf(model_path, text)
    else:
        xml = text
        check_urdf(model_path, text=xml)
        pin_model, mimic = _build_model(model_path, xml)
    search = (*given, *_ros_package_path(), str(model_path.parent))
    reference: dict[str, object] = {
        "package_dirs": given,
        "xacro_args": {},
        "lock_off_chain": lock_off_chain,
    }
    if positions:
        reference["locked_positions"] = positions
    return _arm(
        pin_model, mimic, model_path, str(path), tip, (), lock_off_chain is not False,
        search=search, source=str(path), kind=fmt, xml=xml, mjcf_xml=text if xml is None else None,
        reference=reference, positions=positions, uneven=uneven,
    )  # fmt: skip


def _arm(
    pin_model: pin.Model,
    mimic: Mapping[str, tuple[str, float, float]],
    path: Path,
    name: str,
    tip: str | None,
    locked: Sequence[str],
    lock_all: bool,
    *,
    search: Sequence[str],
    source: str,
    kind: str,
    xml: str | None,
    reference: Mapping[str, object],
    positions: Mapping[str, float],
    uneven: Mapping[str, tuple[float, float]],
    mjcf_xml: str | None = None,
) -> Robot:
    """Steps 3 and 4 of :func:`load_robot`: the tip frame, the locked joints, the checks and
    the :class:`Robot`."""
    tip_name = tip if tip is not None else default_tip_frame(pin_model)
    _require_frame(pin_model, tip_name, path)
    file_joints = tuple(pin_model.names[j] for j in range(1, pin_model.njoints))
    pin_model, held = _lock_joints(pin_model, path, tip_name, locked, mimic, lock_all, positions)
    for joint, (lo, hi) in uneven.items():
        if pin_model.existJointName(joint):
            raise RobotError(
                f"unsupported MJCF {path}: joint {joint!r}: the torque MuJoCo lets act on it "
                f"(its actuatorfrcrange and actuators) is [{lo:g}, {hi:g}], not symmetric "
                "about 0; the toolkit's effort limit bounds |u|: make the ranges symmetric "
                "(-e e), or lock the joint (robot.lock_off_chain, for a joint off the tip's "
                "chain)"
            )
    check_arm_model(pin_model, path, tip=tip_name, mimic={j: m[0] for j, m in mimic.items()})
    return Robot(
        pin_model,
        name=name,
        urdf_path=path,
        package_dirs=tuple(dict.fromkeys(search)),
        tip=tip_name,
        source=source,
        kind=kind,
        urdf_xml=xml,
        mjcf_xml=mjcf_xml,
        reference=reference,
        locked_joints=held,
        file_joints=file_joints,
    )


def model_kind(path: str | os.PathLike[str]) -> str:
    """How :func:`load_robot` reads a model file: ``"xacro"`` (a name ending ``.xacro``),
    ``"mjcf"`` (ending ``.xml``, unless its root element is ``<robot>``: a URDF) or
    ``"urdf"``. Reads at most the start of an ``.xml`` file; a missing one is ``"mjcf"``."""
    text = str(path).lower()
    if text.endswith(".xacro"):
        return "xacro"
    if not text.endswith(".xml"):
        return "urdf"
    try:
        with open(path, "rb") as fh:
            for _event, element in ET.iterparse(fh, events=("start",)):
                return "urdf" if element.tag == "robot" else "mjcf"
    except (OSError, ET.ParseError):
        pass  # missing or malformed: the MJCF loader says why
    return "mjcf"


def _xacro_arguments(args: Mapping[str, str] | None) -> dict[str, str]:
    """The xacro arguments as a new {name: text} dict; RobotError for anything else."""
    if args is None:
        return {}
    if not isinstance(args, Mapping):
        raise RobotError(f"xacro_args must be a mapping of names to texts, got {args!r}")
    out = {}
    for key, value in args.items():
        if not isinstance(key, str) or not key or not isinstance(value, str):
            raise RobotError(f"xacro_args must map argument names to texts; got {key!r}: {value!r}")
        out[key] = value
    return out


def _locked_positions(positions: Mapping[str, float] | None) -> dict[str, float]:
    """``locked_positions`` as a new {joint: float} dict; RobotError for anything else."""
    if positions is None:
        return {}
    if not isinstance(positions, Mapping):
        raise RobotError(
            f"locked_positions must be a mapping of joint names to numbers, got {positions!r}"
        )
    out = {}
    for key, value in positions.items():
        if (
            not isinstance(key, str)
            or isinstance(value, bool)
            or not isinstance(value, int | float | np.floating | np.integer)
            or not np.isfinite(value)
        ):
            raise RobotError(
                f"locked_positions must map joint names to finite numbers; got {key!r}: {value!r}"
            )
        out[key] = float(value)
    return out


def _lock_joints(
    model: pin.Model,
    path: Path,
    tip: str,
    locked: Sequence[str],
    mimic: Mapping[str, tuple[str, float, float]],
    lock_all: bool,
    positions: Mapping[str, float],
) -> tuple[pin.Model, dict[str, float]]:
    """The model with ``locked``, the mimic joints off the tip's chain and, with
    ``lock_all``, every joint off that chain, removed (see :func:`load_robot`, step 3), and
    ``{locked joint: the position it is held at}`` in the model's joint order."""
    chain_ids = set(model.supports[model.frames[model.getFrameId(tip)].parentJoint])
    off_chain = [model.names[j] for j in range(1, model.njoints) if j not in chain_ids]
    if lock_all and off_chain and chain_ids <= {0}:
        raise RobotError(
            f"tip frame '{tip}' of {path} is on the base: no joint lies between the root and "
            "it, so locking the joints off its chain would leave none; choose a tip on the arm",
            key="tip",
            value=tip,
        )
    extra = [j for j in off_chain if (lock_all or j in mimic) and j not in locked]
    to_lock = [*locked, *extra]
    unknown = [j for j in positions if j not in to_lock]
    if unknown:
        held_names = ", ".join(to_lock) or "none"
        raise RobotError(
            f"locked_positions names {', '.join(map(repr, unknown))}, which this load of {path} "
            f"does not lock (locked joints: {held_names})"
        )
    if not to_lock:
        return model, {}
    q_ref = pin.neutral(model)
    for joint in to_lock:
        if joint not in mimic:
            q_ref[_q_index(model, joint)] = _lock_position(model, joint)
    for joint, value in positions.items():
        if joint not in mimic:
            q_ref[_q_index(model, joint)] = _checked_position(model, path, joint, value)
    for joint, (master, multiplier, offset) in mimic.items():
        q_ref[_q_index(model, joint)] = offset + multiplier * q_ref[_q_index(model, master)]
    for joint, value in positions.items():
        if joint in mimic:  # given: held there, whatever its master says
            q_ref[_q_index(model, joint)] = _checked_position(model, path, joint, value)
    ids = sorted(model.getJointId(j) for j in to_lock)
    held = {model.names[j]: float(q_ref[model.idx_qs[j]]) for j in ids}
    return pin.buildReducedModel(model, ids, q_ref), held


def _checked_position(model: pin.Model, path: Path, joint: str, value: float) -> float:
    """``value`` when it is within the joint's range (any value for an empty range)."""
    iq = _q_index(model, joint)
    lo, hi = float(model.lowerPositionLimit[iq]), float(model.upperPositionLimit[iq])
    if lo < hi and not lo <= value <= hi:
        raise RobotError(
            f"locked joint {joint!r} of {path}: position {value:g} is outside its range "
            f"[{lo:g}, {hi:g}]"
        )
    return value


def _lock_position(model: pin.Model, joint: str) -> float:
    """Where a locked one-coordinate joint is held [rad or m]: 0 (Pinocchio's neutral), or
    the middle of its range when 0 is outside it (its finite bound if the other is not)."""
    iq = _q_index(model, joint)
    lo, hi = float(model.lowerPositionLimit[iq]), float(model.upperPositionLimit[iq])
    if not lo < hi or lo <= 0.0 <= hi:  # no range (also lower = upper: URDF's "none")
        return 0.0
    if np.isfinite(lo) and np.isfinite(hi):
        return 0.5 * (lo + hi)
    return lo if np.isfinite(lo) else hi


@contextlib.contextmanager
def _native_stderr(source: object, parser: str = "URDF") -> Iterator[Callable[[], list[str]]]:
    """Capture what C++ code (urdfdom) writes to file descriptor 2 inside the block.

    Yields a function returning the captured messages, one per line, without urdfdom's
    "Error:" prefixes and source locations. When the block raised, the caller reports it (one
    error line); when it did not, the messages are issued as one :class:`ModelWarning`
    naming ``source`` (the file parsed).
    """
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)

        def said() -> list[str]:
            sink.seek(0)
            lines = (
                " ".join(x.split()) for x in sink.read().decode("utf-8", "replace").split("\n")
            )
            return [x.removeprefix("Error: ") for x in lines if x and not x.startswith("at line ")]

        try:
            yield said
        finally:
            messages = said()
            os.dup2(saved, 2)  # stderr is back before anything is reported
            os.close(saved)
    if messages:  # reached only when the block did not raise
        text = "; ".join(messages)
        warnings.warn(
            f"{source}: Pinocchio's {parser} parser reported: {text}", ModelWarning, stacklevel=3
        )


def _is_path(model: str | os.PathLike[str]) -> bool:
    """True for a Path (any os.PathLike), or a text ending with one of
    :data:`MODEL_SUFFIXES` (``.urdf``, ``.xacro``, ``.xml``) or holding a path separator
    (``/``, ``\\``, and the platform's own)."""
    if isinstance(model, os.PathLike):
        return True
    text = str(model)
    separators = {"/", "\\", os.sep} | ({os.altsep} if os.altsep else set())
    return text.endswith(MODEL_SUFFIXES) or any(sep in text for sep in separators)


def _build_model(
    path: Path, xml: str | None = None
) -> tuple[pin.Model, dict[str, tuple[str, float, float]]]:
    """Pinocchio model of a checked URDF, continuous joints as unbounded revolute ones.

    Args:
        path: the model file (named in messages; read when ``xml`` is None).
        xml: the URDF text (:func:`~hybrid_force.model.urdf_text.urdf_text` of ``path``, or
            xacro's expansion of it), or None.

    Returns:
        the model, and ``{mimic joint: (master, multiplier, offset)}`` from its ``<mimic>``
        elements (Pinocchio builds them as independent joints: ``mimic=False``).
    """
    root = ET.parse(path).getroot() if xml is None else ET.fromstring(xml)
    continuous: dict[str, tuple[bool, bool]] = {}  # joint: (gives effort, gives velocity)
    mimic: dict[str, tuple[str, float, float]] = {}
    for joint in root.findall("joint"):
        name = joint.get("name", "")
        element = joint.find("mimic")
        if element is not None and joint.get("type") in ("revolute", "continuous", "prismatic"):
            mimic[name] = (
                element.get("joint", ""),
                float(element.get("multiplier", "1")),
                float(element.get("offset", "0")),
            )
        if joint.get("type") != "continuous":
            continue
        joint.set("type", "revolute")
        limit = joint.find("limit")
        if limit is None:
            limit = ET.SubElement(joint, "limit")
        given = (limit.get("effort") is not None, limit.get("velocity") is not None)
        continuous[name] = given
        for key, present in zip(("effort", "velocity"), given, strict=True):
            if not present:
                limit.set(key, "0")  # placeholder, +inf below
        limit.attrib.pop("lower", None)
        limit.attrib.pop("upper", None)
    with _native_stderr(path) as said:
        try:
            model = pin.buildModelFromXML(ET.tostring(root, encoding="unicode"))
        except (RuntimeError, ValueError) as exc:
            # urdfdom says why on stderr, in several lines: its first one joins the error
            why = said()
            detail = f" ({why[0]})" if why else ""
            raise RobotError(f"Pinocchio cannot parse {path}: {exc}{detail}") from exc
    for name, (has_effort, has_velocity) in continuous.items():
        jid = model.getJointId(name)
        iq, iv = model.idx_qs[jid], model.idx_vs[jid]
        model.lowerPositionLimit[iq] = -np.inf
        model.upperPositionLimit[iq] = np.inf
        if not has_effort:
            model.effortLimit[iv] = np.inf
        if not has_velocity:
            model.velocityLimit[iv] = np.inf
    return model, mimic


def _build_mjcf(
    path: Path, text: str | None = None
) -> tuple[pin.Model, dict[str, tuple[float, float]]]:
    """Pinocchio model of an MJCF file (``pin.buildModelFromMJCF``), fixed-base arms only,
    and ``{joint: (lowest, highest) torque}`` of the joints whose torque range is not
    symmetric about 0 (refused unless they are locked). With ``text``, that is the file's
    text (``path`` is then not read; it names the model in messages).

    Refused before the parser runs (RobotError naming the file): malformed XML, a root
    element other than ``<mujoco>``, and what :func:`~hybrid_force.model.mjcf.prepare_mjcf`
    refuses (``<include>``, ``<attach>``, a free or ball joint, …). The parser reads the
    file as :func:`~hybrid_force.model.mjcf.prepare_mjcf` rewrites it (frames and replicates
    expanded, orientations as quaternions, the bodies in one jointless body ``world``:
    Pinocchio issue #2782), written to a temporary folder under the file's own name (the
    parser names unnamed bodies after the file); the joints' limits, damping, friction and
    armature are then MuJoCo's (:func:`~hybrid_force.model.mjcf.complete_model`). Warned
    (:class:`ModelWarning`): a body without ``<inertial>`` whose inertia would come from a
    mesh geom (Pinocchio does not compute a mesh's inertia as MuJoCo does), ``<equality>``
    constraints (ignored: the joints they couple move independently), and what
    :func:`~hybrid_force.model.mjcf.prepare_mjcf` warns about. Meshes and other assets are not
    read to build the model.
    """
    from hybrid_force.model.mjcf import complete_model, prepare_mjcf

    try:
        # its size first, in one streaming pass: Pinocchio's parser recurses per body
        data = _read_model_bytes(path, "MJCF") if text is None else text.encode("utf-8")
        check_model_size(f"MJCF {path}", data, "mjcf")
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise RobotError(f"malformed MJCF {path}: XML parse error: {exc}") from None
    except OSError as exc:
        raise RobotError(f"cannot read MJCF {path}: {exc}") from None
    if root.tag != "mujoco":
        raise RobotError(
            f"not an MJCF file: {path}: root element is <{root.tag}>, expected <mujoco> "
            "(or <robot> for a URDF)"
        )
    _check_mjcf_numbers(root, path)
    prepared = prepare_mjcf(path, root)
    mesh_bodies = []
    for body in root.iter("body"):
        meshes = [
            g
            for g in body.findall("geom")
            if g.get("type", "mesh" if g.get("mesh") else "") == "mesh"
        ]
        if meshes and body.find("inertial") is None:
            mesh_bodies.append(body.get("name", "?"))
    notes = []
    if mesh_bodies:
        notes.append(
            f"body(ies) {', '.join(map(repr, mesh_bodies))} have no <inertial> and a mesh "
            "geom: Pinocchio does not compute a mesh's mass and inertia as MuJoCo does, so "
            "their dynamics may be wrong (give each an <inertial>)"
        )
    if root.find("equality") is not None:
        notes.append(
            "its <equality> constraints are ignored (the joints they couple move "
            "independently; joints off the tip's chain are locked by default)"
        )
    with tempfile.TemporaryDirectory(prefix="hybrid_force_mjcf_") as folder:
        copy = Path(folder) / path.name
        copy.write_text(prepared.text, encoding="utf-8")
        with _native_stderr(path, "MJCF") as said:
            try:
                model = pin.buildModelFromMJCF(str(copy))
            except (RuntimeError, ValueError, IndexError) as exc:
                why = said()
                detail = f" ({why[0]})" if why else ""
                message = _pinocchio_message(exc).replace(str(copy), str(path))
                raise RobotError(f"Pinocchio cannot parse MJCF {path}: {message}{detail}") from None
    complete_model(model, prepared)
    for note in notes:
        warnings.warn(f"{path}: {note}", ModelWarning, stacklevel=3)
    uneven = {n: j.torque for n, j in prepared.joints.items() if j.effort is None}
    return model, uneven


_MJCF_NUMBERS = (
    "pos", "quat", "axis", "euler", "axisangle", "xyaxes", "zaxis", "range", "mass",
    "diaginertia", "fullinertia", "size", "fromto", "armature", "damping", "frictionloss",
    "stiffness", "ref", "springref",
)  # fmt: skip
"""MJCF attributes that hold numbers: Pinocchio's parser turns text it cannot read into
whatever memory held (a body at z = 2e243 for pos="a b c"), so they are read here first."""


def _check_mjcf_numbers(root: ET.Element, path: Path) -> None:
    """RobotError naming the element and attribute for a numeric MJCF attribute that is not
    finite numbers, a negative mass or inertia, or a joint range with lower > upper."""
    for element in root.iter():
        for key in _MJCF_NUMBERS:
            text = element.get(key)
            if text is None:
                continue
            where = f"<{element.tag} name={element.get('name', '?')!r}> {key}={text[:60]!r}"
            try:
                values = [float(x) for x in text.split()]
            except ValueError:
                values = []
            if not values or not all(math.isfinite(x) for x in values):
                raise RobotError(f"malformed MJCF {path}: {where}: must be finite numbers")
            if key in ("mass", "diaginertia") and min(values) < 0.0:
                raise RobotError(f"malformed MJCF {path}: {where}: must not be negative")
            lower_above = len(values) == 2 and values[0] > values[1]
            if key == "range" and element.tag == "joint" and lower_above:
                raise RobotError(f"malformed MJCF {path}: {where}: lower above upper")


_MJCF_SCOPE = (
    "hybrid_force simulates fixed-base arms with one-coordinate joints (hinge, slide) only: "
    "remove the joint (the body is then welded to its parent) or replace it"
)


def _read_model_bytes(path: Path, label: str) -> bytes:
    """The file's bytes, refused (RobotError) beyond MAX_MODEL_BYTES before it is read."""
    check_file_size(path, label)
    return path.read_bytes()


def _pinocchio_message(exc: BaseException) -> str:
    """One line from a Pinocchio exception: the text after its ``message:`` line if any."""
    text = str(exc)
    if "message:" in text:
        text = text.split("message:", 1)[1]
    return " ".join(text.split()) or type(exc).__name__


def _q_index(model: pin.Model, joint: str) -> int:
    """Index in q of a one-coordinate joint."""
    return int(model.idx_qs[model.getJointId(joint)])


def _require_frame(model: pin.Model, tip: str, path: Path) -> None:
    """RobotError listing the model's frames if ``tip`` is not one of them (or not a text)."""
    if not isinstance(tip, str):  # Pinocchio would raise a raw Boost.Python ArgumentError
        frames = [f.name for f in model.frames]
        raise RobotError(
            f"tip must be a frame name (a str), got {tip!r} ({type(tip).__name__}); frames of "
            f"{path} are: {', '.join(frames)}",
            key="tip",
            value=tip,
        )
    if not model.existFrame(tip):
        frames = [f.name for f in model.frames]
        raise RobotError(
            f"tip frame '{tip}' not found in {path}; frames are: {', '.join(frames)}",
            key="tip",
            value=tip,
        )
