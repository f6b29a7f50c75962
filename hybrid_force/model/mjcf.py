"""MJCF files made fit for Pinocchio's parser: every element honoured or refused, never dropped.

:func:`prepare_mjcf` rewrites an MJCF tree (a copy; the file is never changed) into a form that
Pinocchio 4.1's MJCF parser reads the way MuJoCo does, and reads the joint data the toolkit
takes from MuJoCo's definitions; :func:`complete_model` writes that data into the built model.
What each element maps to is listed in ``docs/robots.md``; in short:

* orientations (``quat``, ``axisangle``, ``euler`` with the compiler's ``eulerseq``,
  ``xyaxes``, ``zaxis``; degrees or radians by ``<compiler angle>``) of bodies, inertials,
  geoms, sites and cameras, also in ``<default>`` classes, are written as unit quaternions and
  the compiler set to radians (Pinocchio 4.1 ignores ``eulerseq`` and scales a slide joint's
  range as if it were an angle);
* ``<replicate count offset euler sep>`` becomes ``count`` copies of its children, the k-th
  placed by the k-th power of (offset, euler) and every name in it suffixed with ``sep`` and
  k padded to the digits of ``count`` (MuJoCo's names: ``leg-00`` … ``leg-11``);
* ``<frame pos orientation childclass>`` is removed, its pose composed into each child
  (bodies, geoms, sites, cameras, inertials, joints' ``pos`` and ``axis``, lights'
  ``pos`` and ``dir``; also when the child's class gives them), its ``childclass`` given to
  the children that name no class;
* the bodies and sites of ``<worldbody>`` are moved into one jointless body ``world`` at the
  origin (MuJoCo's name for its world body, which no MJCF body may take). Pinocchio 4.1's
  parser drops the pose of the first body when it has no joint (Pinocchio issue #2782,
  https://github.com/stack-of-tasks/pinocchio/issues/2782, fixed upstream by PR #2934 after
  the 4.1.0 wheel) and reads only the first body of ``<worldbody>``; nested jointless bodies
  keep their poses. The named sites of ``<worldbody>`` become frames of the universe (the
  parser makes none of a site in that first body). Geoms of ``<worldbody>`` itself (floors,
  scenery) are static world geometry and not part of the arm;
* a body with several joints becomes a chain of one-joint bodies (the first ones massless,
  named ``<body>__<joint>``): the same motion, where the parser builds one composite joint;
* a joint's ``ref`` (its position in the file's pose) is moved into its body's pose, so q is
  MuJoCo's qpos;
* per joint, from the joint and its default classes (``class``, or the nearest ``childclass``)
  by MuJoCo's rules: ``range`` and ``limited`` (with ``<compiler autolimits>``: limited when
  a range is given, unless ``limited="false"``) give the position limits (±inf when not
  limited); ``actuatorfrcrange`` and the actuators acting on the joint the effort limit
  (:func:`_actuated`; +inf when nothing bounds it); ``damping``, ``frictionloss`` and
  ``armature`` Pinocchio's ``model.damping``, ``model.friction`` and ``model.armature``.

Refused (:class:`~hybrid_force.errors.RobotError` naming the file and the element):
``<include>``, ``<attach>``, ``<composite>``, ``<flexcomp>``, free and ball joints, an element
with two orientations, an undefined class,
a gravity other than MuJoCo's default (0, 0, -9.81) m/s² (the toolkit's),
``<compiler>`` options by which MuJoCo changes masses or inertias (``settotalmass``,
``boundmass``, ``boundinertia``, ``balanceinertia``, ``inertiagrouprange``), numbers that do
not parse, ranges MuJoCo refuses; by the loader, once joints are locked, a
moving joint whose torque range is not symmetric about 0 (:attr:`MjcfJoint.effort`).
Warned (:class:`~hybrid_force.errors.ModelWarning`): joint ``stiffness`` and body
``gravcomp``, which are not modelled.
"""

from __future__ import annotations

import copy
import math
import os
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pinocchio as pin

from hybrid_force.errors import ModelWarning, RobotError
from hybrid_force.model.urdf_text import MAX_ELEMENTS

__all__ = ["MjcfJoint", "PreparedMjcf", "complete_model", "prepare_mjcf"]

WORLD_BODY = "world"
"""Name of the jointless body at the origin that holds the bodies of ``<worldbody>``."""

_ORIENTATIONS = ("quat", "axisangle", "euler", "xyaxes", "zaxis")
_POSED = frozenset({"body", "geom", "site", "camera", "inertial", "frame"})
_REFUSED = {
    "include": "Pinocchio's MJCF parser ignores includes (the included bodies would be "
    "missing); write the included file's content in place of the <include>",
    "attach": "the attached model would be missing; write its bodies in place of the <attach>",
    "composite": "composite objects are not rigid-arm links",
    "flexcomp": "deformable bodies are not rigid-arm links",
}


@dataclass(frozen=True)
class MjcfJoint:
    """A joint's data as MuJoCo reads it (defaults applied), in the toolkit's units.

    Attributes:
        name: the joint's name.
        kind: ``"hinge"`` or ``"slide"``.
        lower, upper: position limits [rad or m]; ∓inf when the joint is not limited.
        torque: (lowest, highest) torque [N·m or N] MuJoCo lets act on the joint (its
            ``actuatorfrcrange`` and its actuators: :func:`_actuated`); ∓inf where unbounded.
        damping: viscous damping [N·m·s/rad or N·s/m].
        frictionloss: dry friction [N·m or N].
        armature: rotor inertia added to M's diagonal [kg·m² or kg].
    """

    name: str
    kind: str
    lower: float
    upper: float
    torque: tuple[float, float]
    damping: float
    frictionloss: float
    armature: float

    @property
    def effort(self) -> float | None:
        """The effort limit e (|u| <= e; +inf when unbounded), None when the torque range
        is not symmetric about 0 (the toolkit's limit cannot say it)."""
        lo, hi = self.torque
        return hi if -lo == hi and hi > 0.0 else None


@dataclass(frozen=True)
class _Compiler:
    degrees: bool
    eulerseq: str
    autolimits: bool


@dataclass(frozen=True)
class PreparedMjcf:
    """What :func:`prepare_mjcf` gives: the text Pinocchio parses and what it would miss.

    Attributes:
        text: the rewritten MJCF text (module docstring).
        joints: ``{joint name: MjcfJoint}`` of every hinge and slide joint, in file order.
        world_sites: ``{name: pose}`` of the named sites of ``<worldbody>`` itself, which
            Pinocchio 4.1 does not make frames of in the first body (:func:`complete_model`
            adds them as frames of the universe).
    """

    text: str
    joints: dict[str, MjcfJoint]
    world_sites: dict[str, pin.SE3]


def prepare_mjcf(path: Path, root: ET.Element) -> PreparedMjcf:
    """The MJCF text to give Pinocchio's parser, and every hinge or slide joint's data.

    Args:
        path: the MJCF file (named in messages; its folder resolves meshes).
        root: its parsed ``<mujoco>`` element (not changed).

    Returns:
        the rewritten text, the joints' data and the world's sites (:class:`PreparedMjcf`).

    Raises:
        RobotError: an element refused (module docstring), naming the file and the element.
    """
    root = copy.deepcopy(root)
    for tag, why in _REFUSED.items():
        found = root.find(f".//{tag}")
        if found is not None:
            detail = " ".join(f"{k}={v!r}" for k, v in found.attrib.items())
            raise RobotError(
                f"unsupported MJCF {path}: <{tag}{' ' + detail if detail else ''}>: {why}"
            )
    compiler = _compiler(path, root)
    _check_gravity(path, root)
    for element in root.iter():
        if element.tag in _POSED:
            _to_quaternion(path, element, compiler)
    worldbody = root.find("worldbody")
    if worldbody is None:
        raise RobotError(f"unsupported MJCF {path}: no <worldbody>: the model has no body")
    defaults = _defaults(root)
    _expand_replicates(path, worldbody, compiler)
    _expand_frames(path, worldbody, defaults)
    _split_joints(worldbody)
    for default in root.findall("default"):
        default.set("class", default.get("class", "main"))  # Pinocchio knows no "main"
    joints = _actuated(path, root, _joints(path, worldbody, defaults, compiler), defaults, compiler)
    sites = {
        site.get("name", ""): _pose(path, site)
        for site in worldbody.findall("site")
        if site.get("name")
    }
    _wrap_world(worldbody)
    _set_compiler(path, root)
    return PreparedMjcf(ET.tostring(root, encoding="unicode"), joints, sites)


def complete_model(model: pin.Model, prepared: PreparedMjcf) -> None:
    """Write each joint's limits, damping, friction and armature into ``model``, and add the
    world's sites as frames (in place)."""
    world = model.getFrameId(WORLD_BODY) if model.existFrame(WORLD_BODY) else 0
    for name, pose in prepared.world_sites.items():
        if not model.existFrame(name):
            model.addFrame(pin.Frame(name, 0, world, pose, pin.FrameType.OP_FRAME))
    for name, joint in prepared.joints.items():
        if not model.existJointName(name):
            continue
        jid = model.getJointId(name)
        if model.nqs[jid] != 1 or model.nvs[jid] != 1:
            continue  # check_arm_model refuses it, naming the joint
        iq, iv = model.idx_qs[jid], model.idx_vs[jid]
        model.lowerPositionLimit[iq] = joint.lower
        model.upperPositionLimit[iq] = joint.upper
        effort = joint.effort
        model.effortLimit[iv] = max(map(abs, joint.torque)) if effort is None else effort
        model.damping[iv] = joint.damping
        model.friction[iv] = joint.frictionloss
        model.armature[iv] = joint.armature


# --- compiler and orientations --------------------------------------------------------------
def _compiler(path: Path, root: ET.Element) -> _Compiler:
    attrs: dict[str, str] = {}
    for element in root.findall("compiler"):
        attrs.update(element.attrib)
    angle = attrs.get("angle", "degree")
    if angle not in ("degree", "radian"):
        raise RobotError(f"malformed MJCF {path}: <compiler angle={angle!r}>: degree or radian")
    seq = attrs.get("eulerseq", "xyz")
    if len(seq) != 3 or any(c not in "xyzXYZ" for c in seq):
        raise RobotError(
            f"malformed MJCF {path}: <compiler eulerseq={seq!r}>: three of x, y, z, X, Y, Z"
        )
    for key, neutral in _MASS_OPTIONS.items():
        raw = attrs.get(key)
        if raw is None:
            continue
        try:
            same = [float(x) for x in raw.split()] == [float(x) for x in neutral.split()]
        except ValueError:
            same = raw == neutral
        if not same:
            raise RobotError(
                f"unsupported MJCF {path}: <compiler {key}={raw!r}>: MuJoCo changes the bodies' "
                "masses or inertias by it and Pinocchio's parser does not: write the masses "
                "and inertias the model should have"
            )
    return _Compiler(angle == "degree", seq, _bool(path, "<compiler>", attrs, "autolimits", True))


def _check_gravity(path: Path, root: ET.Element) -> None:
    """The toolkit's gravity is (0, 0, -9.81) m/s², MuJoCo's default: refuse another one."""
    for option in root.findall("option"):
        raw = option.get("gravity")
        if raw is not None:
            values = _numbers(path, "<option>", option, "gravity", 3)
            if not np.array_equal(values, [0.0, 0.0, -9.81]):
                raise RobotError(
                    f"unsupported MJCF {path}: <option gravity={raw!r}>: the toolkit simulates "
                    "gravity (0, 0, -9.81) m/s² (MuJoCo's default)"
                )
        for flag in option.findall("flag"):
            if flag.get("gravity", "enable") != "enable":
                raise RobotError(
                    f"unsupported MJCF {path}: <flag gravity={flag.get('gravity')!r}>: the "
                    "toolkit simulates gravity (0, 0, -9.81) m/s² (MuJoCo's default)"
                )


# <compiler> options by which MuJoCo changes masses or inertias, with their neutral values
_MASS_OPTIONS = {
    "settotalmass": "-1",
    "boundmass": "0",
    "boundinertia": "0",
    "balanceinertia": "false",
    "inertiagrouprange": "0 5",
}


def _set_compiler(path: Path, root: ET.Element) -> None:
    """One ``<compiler>``: radians, no eulerseq, meshes found from the file's own folder."""
    elements = root.findall("compiler")
    attrs: dict[str, str] = {}
    for element in elements:
        attrs.update(element.attrib)
        root.remove(element)
    attrs["angle"] = "radian"
    attrs.pop("eulerseq", None)
    base = Path(path).resolve().parent
    mesh = attrs.get("meshdir", attrs.get("assetdir", ""))
    attrs["meshdir"] = str(base / mesh) + os.sep
    root.insert(0, ET.Element("compiler", attrs))


def _numbers(path: Path, where: str, element: ET.Element, key: str, count: int) -> np.ndarray:
    raw = element.get(key, "")
    try:
        values = np.array([float(x) for x in raw.split()], dtype=float)
    except ValueError:
        values = np.zeros(0)
    if values.size != count or not np.all(np.isfinite(values)):
        raise RobotError(
            f"malformed MJCF {path}: {where} attribute {key}={raw!r} must be {count} finite numbers"
        )
    return values


def _bool(path: Path, where: str, attrs: Mapping[str, str], key: str, default: bool) -> bool:
    raw = attrs.get(key)
    if raw is None:
        return default
    if raw not in ("true", "false"):
        raise RobotError(f"malformed MJCF {path}: {where} {key}={raw!r} must be true or false")
    return raw == "true"


def _where(element: ET.Element) -> str:
    name = element.get("name")
    return f"<{element.tag} name={name!r}>" if name else f"<{element.tag}>"


def _axis_angle(axis: np.ndarray, angle: float) -> pin.Quaternion:
    return pin.Quaternion(pin.AngleAxis(angle, axis / np.linalg.norm(axis)))


def _orientation(path: Path, element: ET.Element, compiler: _Compiler) -> pin.Quaternion | None:
    """The element's orientation (any of MJCF's five forms), None when it gives none."""
    given = [k for k in _ORIENTATIONS if element.get(k) is not None]
    if not given:
        return None
    where = _where(element)
    if len(given) > 1:
        raise RobotError(
            f"malformed MJCF {path}: {where} gives several orientations ({', '.join(given)})"
        )
    key = given[0]
    unit = math.pi / 180.0 if compiler.degrees else 1.0
    if key == "quat":
        w, x, y, z = _numbers(path, where, element, key, 4)
        quat = pin.Quaternion(w, x, y, z)
    elif key == "axisangle":
        values = _numbers(path, where, element, key, 4)
        quat = _axis_angle(_nonzero(path, where, key, values[:3]), values[3] * unit)
    elif key == "euler":
        quat = _euler(_numbers(path, where, element, key, 3) * unit, compiler.eulerseq)
    elif key == "xyaxes":
        values = _numbers(path, where, element, key, 6)
        x = _nonzero(path, where, key, values[:3])
        x = x / np.linalg.norm(x)
        y = values[3:] - np.dot(values[3:], x) * x
        y = _nonzero(path, where, key, y)
        y = y / np.linalg.norm(y)
        quat = pin.Quaternion(np.column_stack((x, y, np.cross(x, y))))
    else:  # zaxis: the smallest rotation taking z to the given axis
        z = _nonzero(path, where, key, _numbers(path, where, element, key, 3))
        quat = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), z / np.linalg.norm(z))
    if quat.norm() == 0.0:
        raise RobotError(f"malformed MJCF {path}: {where} quat={element.get('quat')!r} is zero")
    quat.normalize()
    return quat


def _nonzero(path: Path, where: str, key: str, vector: np.ndarray) -> np.ndarray:
    if not np.linalg.norm(vector) > 1e-12:
        raise RobotError(f"malformed MJCF {path}: {where} {key} has a zero-length axis")
    return vector


def _euler(angles: np.ndarray, seq: str) -> pin.Quaternion:
    """MuJoCo's Euler angles: lowercase axes rotate with the body, uppercase stay fixed."""
    quat = pin.Quaternion.Identity()
    for angle, axis in zip(angles, seq, strict=True):
        step = _axis_angle(np.eye(3)["xyz".index(axis.lower())], float(angle))
        quat = quat * step if axis.islower() else step * quat
    return quat


def _to_quaternion(path: Path, element: ET.Element, compiler: _Compiler) -> None:
    quat = _orientation(path, element, compiler)
    if quat is None:
        return
    for key in _ORIENTATIONS:
        element.attrib.pop(key, None)
    element.set("quat", _text(np.array([quat.w, quat.x, quat.y, quat.z])))


def _text(values: np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in values)


def _pose(path: Path, element: ET.Element) -> pin.SE3:
    """Pose of an element whose orientation is a quaternion (or none)."""
    where = _where(element)
    pos = _numbers(path, where, element, "pos", 3) if element.get("pos") else np.zeros(3)
    if element.get("quat") is None:
        return pin.SE3(np.eye(3), pos)
    w, x, y, z = _numbers(path, where, element, "quat", 4)
    quat = pin.Quaternion(w, x, y, z)
    quat.normalize()
    return pin.SE3(quat.matrix(), pos)


def _set_pose(element: ET.Element, pose: pin.SE3) -> None:
    quat = pin.Quaternion(pose.rotation)
    element.set("pos", _text(pose.translation))
    element.set("quat", _text(np.array([quat.w, quat.x, quat.y, quat.z])))


# --- replicate and frame --------------------------------------------------------------------
def _expand_replicates(path: Path, element: ET.Element, compiler: _Compiler) -> None:
    """Each ``<replicate>`` (innermost first) becomes ``count`` frames of renamed copies."""
    for child in list(element):
        _expand_replicates(path, child, compiler)
    out: list[ET.Element] = []
    for child in element:
        if child.tag != "replicate":
            out.append(child)
            continue
        where = f"<replicate count={child.get('count')!r}>"
        try:
            count = int(child.get("count", ""))
        except ValueError:
            count = 0
        if count < 1:
            raise RobotError(f"malformed MJCF {path}: {where}: count must be a positive integer")
        # bounded before copying: nested replicates multiply (1000 x 1000 bodies in two lines)
        inside = sum(1 for e in child.iter() if e.tag in ("body", "joint"))
        if count * inside > 2 * MAX_ELEMENTS:
            raise RobotError(
                f"unsupported MJCF {path}: {where} would make {count * inside} bodies and "
                f"joints, more than a model may have (MAX_ELEMENTS = {MAX_ELEMENTS} of each, "
                "docs/robots.md)"
            )
        offset = _numbers(path, where, child, "offset", 3) if child.get("offset") else np.zeros(3)
        unit = math.pi / 180.0 if compiler.degrees else 1.0
        turn = (
            _euler(_numbers(path, where, child, "euler", 3) * unit, compiler.eulerseq)
            if child.get("euler")
            else pin.Quaternion.Identity()
        )
        step, pose = pin.SE3(turn.matrix(), offset), pin.SE3.Identity()
        sep, width = child.get("sep", ""), len(str(count))
        for k in range(count):
            frame = ET.Element("frame")
            _set_pose(frame, pose)
            for part in child:
                duplicate = copy.deepcopy(part)
                for named in duplicate.iter():
                    if named.get("name") is not None:
                        named.set("name", f"{named.get('name')}{sep}{k:0{width}d}")
                frame.append(duplicate)
            out.append(frame)
            pose = pose * step
    element[:] = out


def _expand_frames(
    path: Path,
    element: ET.Element,
    defaults: Mapping[str, Mapping[str, Mapping[str, str]]],
    childclass: str = "main",
) -> None:
    """Each ``<frame>`` (innermost first) is replaced by its children, its pose composed in.

    ``childclass``: the class the children of ``element`` default to. A child's placement
    that comes from its class (a site's ``pos``, a joint's ``axis``) is written on it first,
    so that the frame turns it too."""
    for child in list(element):
        inner = child.get("childclass", childclass) if child.tag in ("body", "frame") else ""
        _expand_frames(path, child, defaults, inner or childclass)
    out: list[ET.Element] = []
    for child in element:
        if child.tag != "frame":
            out.append(child)
            continue
        pose, own = _pose(path, child), child.get("childclass")
        for part in child:
            cls = part.get("class", own or childclass)
            for key in _PLACEMENT.get(part.tag, ()):
                value = defaults.get(cls, {}).get(part.tag, {}).get(key)
                if part.get(key) is None and value is not None:
                    part.set(key, value)
            _compose(path, part, pose)
            key = "childclass" if part.tag in ("body", "frame") else "class"
            if own is not None and part.get(key) is None:
                part.set(key, own)
            out.append(part)
    element[:] = out


# what places an element that a default class can give (written on it before a frame turns it)
_PLACEMENT = {
    "geom": ("pos", "quat", "fromto"),
    "site": ("pos", "quat"),
    "camera": ("pos", "quat"),
    "joint": ("pos", "axis"),
    "light": ("pos", "dir"),
}


def _compose(path: Path, element: ET.Element, pose: pin.SE3) -> None:
    """Express ``element`` (a child of a frame at ``pose``) in the frame's parent."""
    where = _where(element)
    if element.tag == "geom" and element.get("fromto") is not None:
        ends = _numbers(path, where, element, "fromto", 6).reshape(2, 3)
        element.set("fromto", _text(np.concatenate([pose.act(p) for p in ends])))
    elif element.tag in _POSED:
        _set_pose(element, pose * _pose(path, element))
    elif element.tag == "joint":
        pos = _numbers(path, where, element, "pos", 3) if element.get("pos") else np.zeros(3)
        axis = _numbers(path, where, element, "axis", 3) if element.get("axis") else np.eye(3)[2]
        element.set("pos", _text(pose.act(pos)))
        element.set("axis", _text(pose.rotation @ axis))
    elif element.tag == "light":
        pos = _numbers(path, where, element, "pos", 3) if element.get("pos") else np.zeros(3)
        element.set("pos", _text(pose.act(pos)))
        if element.get("dir") is not None:
            element.set("dir", _text(pose.rotation @ _numbers(path, where, element, "dir", 3)))
    else:
        raise RobotError(
            f"unsupported MJCF {path}: {where} inside a <frame>: only bodies, geoms, sites, "
            "cameras, lights, inertials, joints, frames and replicates are placed by a frame"
        )


def _split_joints(element: ET.Element) -> None:
    """A body with k > 1 joints becomes a chain of k bodies, one joint each: k - 1 massless
    bodies ``<body>__<joint>`` holding the first joints (the first one at the body's pose),
    then the body itself at their end with its last joint. MuJoCo moves a body by its joints
    in order, each about its axis through its position in the body's frame as the previous
    ones left it: the chain is the same motion, with one-coordinate joints (Pinocchio would
    build one composite joint)."""
    for index, child in enumerate(list(element)):
        if child.tag != "body":
            continue
        _split_joints(child)
        joints = [c for c in child if c.tag == "joint"]
        if len(joints) < 2:
            continue
        name = child.get("name", "body")
        chain = []
        for joint in joints[:-1]:
            link = ET.Element("body", {"name": f"{name}__{joint.get('name', 'joint')}"})
            if child.get("childclass") is not None:
                link.set("childclass", child.get("childclass", ""))
            child.remove(joint)
            link.append(joint)
            chain.append(link)
        for key in ("pos", "quat"):
            if child.get(key) is not None:
                chain[0].set(key, child.attrib.pop(key))
        for outer, inner in zip(chain, [*chain[1:], child], strict=True):
            outer.append(inner)
        element.remove(child)
        element.insert(index, chain[0])


# --- defaults and joints --------------------------------------------------------------------
def _defaults(root: ET.Element) -> dict[str, dict[str, dict[str, str]]]:
    """``{class: {element tag: attributes}}``, each class with what it inherits."""
    out: dict[str, dict[str, dict[str, str]]] = {"main": {}}

    def walk(default: ET.Element, inherited: dict[str, dict[str, str]], name: str) -> None:
        own = {tag: dict(attrs) for tag, attrs in inherited.items()}
        for child in default:
            if child.tag != "default":
                own.setdefault(child.tag, {}).update(child.attrib)
        out[name] = own
        for child in default:
            if child.tag == "default":
                walk(child, own, child.get("class", ""))

    for default in root.findall("default"):
        walk(default, out["main"], default.get("class", "main"))
    return out


def _bodies_with_class(element: ET.Element, childclass: str) -> Iterator[tuple[ET.Element, str]]:
    """Every body under ``element`` with the class its children default to."""
    for child in element:
        if child.tag == "body":
            own = child.get("childclass", childclass)
            yield child, own
            yield from _bodies_with_class(child, own)


def _joints(
    path: Path,
    worldbody: ET.Element,
    defaults: Mapping[str, Mapping[str, Mapping[str, str]]],
    compiler: _Compiler,
) -> dict[str, MjcfJoint]:
    joints: dict[str, MjcfJoint] = {}
    stiff: list[str] = []
    gravcomp: list[str] = []
    for body, childclass in _bodies_with_class(worldbody, "main"):
        if body.get("gravcomp") not in (None, "0"):
            gravcomp.append(body.get("name", "?"))
        elements = [c for c in body if c.tag in ("joint", "freejoint")]
        for element in elements:
            cls = element.get("class", childclass)
            if cls not in defaults:
                raise RobotError(
                    f"malformed MJCF {path}: {_where(element)} uses class {cls!r}, which no "
                    "<default> defines"
                )
            attrs = {**defaults[cls].get("joint", {}), **element.attrib}
            kind = "free" if element.tag == "freejoint" else attrs.get("type", "hinge")
            name = element.get("name", "(unnamed)")
            if kind in ("free", "ball"):
                raise RobotError(
                    f"unsupported MJCF {path}: body {body.get('name', '?')!r} has a {kind} "
                    f"joint {name!r}; hybrid_force simulates fixed-base arms with "
                    "one-coordinate joints (hinge, slide) only: remove the joint (the body is "
                    "then welded to its parent) or replace it"
                )
            if kind not in ("hinge", "slide"):
                continue  # Pinocchio's parser names it in its refusal
            joint = _joint(path, name, kind, attrs, compiler)
            joints[name] = joint
            if _float(path, f"joint {name!r}", attrs, "stiffness") != 0.0:
                stiff.append(name)
            ref = _float(path, f"joint {name!r}", attrs, "ref")
            if ref != 0.0:  # the body's only joint (_split_joints)
                _move_ref(path, body, element, attrs, kind, ref, compiler)
    notes = []
    if stiff:
        notes.append(f"joint stiffness (springs) of {', '.join(map(repr, stiff))}")
    if gravcomp:
        notes.append(f"gravity compensation (gravcomp) of body(ies) {', '.join(gravcomp)}")
    for note in notes:
        warnings.warn(
            f"{path}: {note} is not modelled: the toolkit's plant has no such force",
            ModelWarning,
            stacklevel=4,
        )
    return joints


def _float(path: Path, who: str, attrs: Mapping[str, str], key: str) -> float:
    raw = attrs.get(key, "0")
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise RobotError(f"malformed MJCF {path}: {who}: {key}={raw!r} is not a finite number")
    return value


def _pair(path: Path, who: str, attrs: Mapping[str, str], key: str) -> tuple[float, float]:
    raw = attrs.get(key, "0 0")
    try:
        values = [float(x) for x in raw.split()]
    except ValueError:
        values = []
    if len(values) != 2 or not all(math.isfinite(v) for v in values):
        raise RobotError(f"malformed MJCF {path}: {who}: {key}={raw!r} must be 2 finite numbers")
    return values[0], values[1]


def _limited(
    path: Path, who: str, attrs: Mapping[str, str], flag: str, key: str, autolimits: bool
) -> tuple[float, float] | None:
    """The range ``key`` when MuJoCo enforces it (``flag``: true, false or auto), else None."""
    value = attrs.get(flag, "auto")
    if value not in ("true", "false", "auto"):
        raise RobotError(
            f"malformed MJCF {path}: {who}: {flag}={value!r} must be true, false or auto"
        )
    if value == "auto":
        if key in attrs and not autolimits:
            raise RobotError(
                f"malformed MJCF {path}: {who} has {key} but no {flag}, and "
                '<compiler autolimits="false">: MuJoCo refuses it (give limited="true" or '
                '"false")'
            )
        value = "true" if key in attrs else "false"
    if value == "false":
        return None
    lo, hi = _pair(path, who, attrs, key)
    if not lo < hi:
        raise RobotError(
            f"malformed MJCF {path}: {who}: {flag}=true needs {key} lower < upper, "
            f"got {attrs.get(key, '(none)')!r}"
        )
    return lo, hi


def _joint(
    path: Path, name: str, kind: str, attrs: Mapping[str, str], compiler: _Compiler
) -> MjcfJoint:
    auto = compiler.autolimits
    limits = _limited(path, f"joint {name!r}", attrs, "limited", "range", auto)
    lower, upper = (-math.inf, math.inf) if limits is None else limits
    if limits is not None and kind == "hinge" and compiler.degrees:
        lower, upper = math.radians(lower), math.radians(upper)
    force = _limited(path, f"joint {name!r}", attrs, "actuatorfrclimited", "actuatorfrcrange", auto)
    values = {}
    for key in ("damping", "frictionloss", "armature"):
        values[key] = _float(path, f"joint {name!r}", attrs, key)
        if values[key] < 0.0:
            raise RobotError(
                f"malformed MJCF {path}: joint {name!r}: {key}={attrs[key]!r} is negative"
            )
    return MjcfJoint(
        name=name,
        kind=kind,
        lower=lower,
        upper=upper,
        torque=(-math.inf, math.inf) if force is None else force,
        **values,
    )


_ACTUATORS = (
    "general", "motor", "position", "velocity", "intvelocity", "damper", "cylinder", "muscle",
    "adhesion", "dcmotor",
)  # fmt: skip


def _actuated(
    path: Path,
    root: ET.Element,
    joints: dict[str, MjcfJoint],
    defaults: Mapping[str, Mapping[str, Mapping[str, str]]],
    compiler: _Compiler,
) -> dict[str, MjcfJoint]:
    """The joints with the torque range their actuators allow.

    An actuator acting on a joint (``joint`` or ``jointinparent``) applies gear₀ times its
    force there; that force lies in ``forcerange`` when MuJoCo limits it (``forcelimited``,
    by the same rule as a joint's ``limited``) and, for a ``<motor>`` (force = control) or a
    ``<general>`` whose force is a fixed gain times the control, in that gain times
    ``ctrlrange`` when the control is limited. A joint's torque range is its
    ``actuatorfrcrange`` (when limited) met with the sum of its actuators' ranges (unbounded
    when one of them is, or when no actuator acts on it).
    """
    sums: dict[str, tuple[float, float]] = {}
    auto = compiler.autolimits
    for block in root.findall("actuator"):
        for element in block:
            if element.tag not in _ACTUATORS:
                continue
            cls = element.get("class", "main")
            if cls not in defaults:
                raise RobotError(
                    f"malformed MJCF {path}: {_where(element)} uses class {cls!r}, which no "
                    "<default> defines"
                )
            attrs: dict[str, str] = {}
            for tag in _ACTUATORS:  # one actuator default per class, whichever tag sets it
                attrs.update(defaults[cls].get(tag, {}))
            attrs.update(element.attrib)
            joint = attrs.get("joint", attrs.get("jointinparent"))
            if joint not in joints:
                continue  # a tendon, site or body transmission: no joint's effort
            who = f"actuator {element.get('name', element.tag)!r} (on joint {joint!r})"
            force = _limited(path, who, attrs, "forcelimited", "forcerange", auto) or _ANY
            gain = _control_gain(path, who, element.tag, attrs)
            ctrl = _limited(path, who, attrs, "ctrllimited", "ctrlrange", auto)
            if gain is not None and ctrl is not None:  # force = gain · control
                force = _meet(force, _scaled(gain, ctrl))
            gear = attrs.get("gear", "1").split()
            try:
                ratio = float(gear[0])
            except (ValueError, IndexError):
                raise RobotError(
                    f"malformed MJCF {path}: {who}: gear={attrs.get('gear')!r} is not a number"
                ) from None
            torque = _scaled(ratio, force)
            total = sums.get(joint, (0.0, 0.0))
            sums[joint] = (total[0] + torque[0], total[1] + torque[1])
    return {
        name: replace(joint, torque=_meet(joint.torque, sums[name])) if name in sums else joint
        for name, joint in joints.items()
    }


_ANY = (-math.inf, math.inf)


def _scaled(factor: float, span: tuple[float, float]) -> tuple[float, float]:
    """{factor · x : x in span} (a point at 0 for factor 0)."""
    if factor == 0.0:
        return 0.0, 0.0
    ends = sorted((factor * span[0], factor * span[1]))
    return ends[0], ends[1]


def _meet(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
    return max(a[0], b[0]), min(a[1], b[1])


def _control_gain(path: Path, who: str, tag: str, attrs: Mapping[str, str]) -> float | None:
    """force / control of a ``<motor>`` (1), or of a ``<general>`` without activation
    dynamics or bias whose gain is fixed (gainprm₀); None for the others."""
    if tag == "motor":
        return 1.0
    plain = (
        attrs.get("gaintype", "fixed") == "fixed"
        and attrs.get("biastype", "none") == "none"
        and attrs.get("dyntype", "none") == "none"
    )
    if tag != "general" or not plain:
        return None
    raw = attrs.get("gainprm", "1").split()
    try:
        return float(raw[0])
    except (ValueError, IndexError):
        raise RobotError(
            f"malformed MJCF {path}: {who}: gainprm={attrs.get('gainprm')!r} is not a number"
        ) from None


def _move_ref(
    path: Path,
    body: ET.Element,
    joint: ET.Element,
    attrs: Mapping[str, str],
    kind: str,
    ref: float,
    compiler: _Compiler,
) -> None:
    """Turn (hinge) or shift (slide) the body by -ref about its joint, so q = 0 there is
    MuJoCo's qpos = 0, and drop the ref."""
    where = _where(joint)
    resolved = ET.Element("joint", dict(attrs))  # the joint with its defaults
    axis = _numbers(path, where, resolved, "axis", 3) if "axis" in attrs else np.eye(3)[2]
    axis = _nonzero(path, where, "axis", axis) / np.linalg.norm(axis)
    pos = _numbers(path, where, resolved, "pos", 3) if "pos" in attrs else np.zeros(3)
    if kind == "hinge":
        angle = math.radians(ref) if compiler.degrees else ref
        turn = _axis_angle(axis, -angle).matrix()
        shift = pin.SE3(turn, pos - turn @ pos)
    else:
        shift = pin.SE3(np.eye(3), -ref * axis)
    _set_pose(body, _pose(path, body) * shift)
    joint.set("ref", "0")


def _wrap_world(worldbody: ET.Element) -> None:
    """Move the bodies and sites of ``<worldbody>`` into one jointless body at the origin
    (Pinocchio issue #2782: the first body's pose is otherwise dropped when it has no joint;
    and only the first body is read)."""
    world = ET.Element("body", {"name": WORLD_BODY})
    keep: list[ET.Element] = []
    for child in worldbody:
        (world if child.tag in ("body", "site") else keep).append(child)
    worldbody[:] = [*keep, world]
