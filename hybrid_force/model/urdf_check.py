"""Checks of a URDF arm: plausibility before Pinocchio parses it, scope after it has built it.

The rule: **refuse only what breaks the simulation, warn about the rest.** Published URDFs
that every mainstream simulator loads (a massless fixed root link, a massless end link that
carries a small inertia, an inertia a few percent off the triangle inequality) load here too,
with one :class:`~hybrid_force.errors.ModelWarning` per implausible link.

Every refusal raises a :class:`~hybrid_force.errors.RobotError` whose message names the file,
the link or joint, and the offending values or the cause; the command line turns it into exit
status 2 and one ``error: ...`` line (never a traceback, never a crash inside Pinocchio).
Every warning names the file, the link and the values.

**Reading**: :func:`~hybrid_force.model.urdf_text.urdf_text` makes the file
acceptable to every XML parser of the toolkit; :func:`check_urdf` checks that text.

**Before parsing**, :func:`check_urdf` (Pinocchio's parser, urdfdom, reports structural errors
only on stderr before raising a bare ``ValueError``, and drops an inertial it cannot read with
a message on stderr) refuses:

* a missing file (or a directory);
* malformed XML (with the XML parser's reason, line and column), or XML that is not a URDF
  (root element not ``<robot>``, links or joints without names, duplicate names, joints of
  unknown type, a revolute/prismatic joint without ``<limit effort=.. velocity=..>``,
  parent/child naming a link that does not exist, a link with two parents, no single root);
* joint origins, axes, limits and mimic attributes that are not finite numbers (an axis of
  zero length, lower above upper, a negative effort or velocity limit);
* on a *simulated* link (see below) that declares ``<inertial>``: a missing ``<mass>`` or
  ``<inertia>``, a number that does not parse or is not finite (mass, inertia, origin), a
  negative mass, and an inertia matrix that is not positive semi-definite beyond round-off:
  its smallest principal moment below ``-(_PSD_REL_TOL · I_max + _ABS_TOL)``;
* models outside the toolkit's scope (fixed-base arms): a ``floating`` or ``planar`` joint
  anywhere (named, with its type), and a model with no moving joint (every joint ``fixed``,
  or no joint at all: nv = 0, on which Pinocchio's algorithms must never run).

It **warns** (one ``ModelWarning`` per link, naming the file, the link and the values, and
listing every finding of that link) about a simulated link whose inertial data no rigid body
has, but on which the dynamics stay well defined:

* mass 0 with a non-zero inertia matrix (Pinocchio keeps it as a rotational inertia without
  mass);
* principal moments that break the triangle inequality ``I1 + I2 >= I3`` by more than
  ``_TRI_REL_TOL · I3 + _ABS_TOL``.

Not a finding: a link without ``<inertial>`` (a massless frame), mass 0 with an all-zero
inertia (the same massless frame, as some exporters write it), and a positive mass with an
all-zero inertia (a point mass: physically fine; on a joint's axis it leaves that joint
without inertia, which the mass-matrix check below refuses, naming the joint).

**Links that are not simulated are not checked at all**: the root link and every link welded
to it by a chain of fixed joints. Pinocchio merges them into the universe, which never moves,
so their inertial data never enters M, C or g (a massless or empty world link is the rule in
published URDFs). If urdfdom cannot read such an inertial, it says so on stderr and drops it;
:func:`hybrid_force.model.loading.load_robot` turns that into a ``ModelWarning``.

**Tolerances, and why the line between refusal and warning is there.** The simulation needs
each link's spatial inertia positive semi-definite: a negative principal moment is a body
with negative kinetic energy about that axis, and M(q) can become indefinite away from the
start (the articulated-body algorithm then divides by non-positive inertias). That is refused.
The triangle inequality only says whether a mass distribution with those moments exists; a
positive semi-definite matrix that breaks it still gives positive-definite M(q) and
well-posed dynamics, so it is reported, not refused. Rounding: a symmetric matrix whose
entries are printed with d significant digits has each entry off by at most 5·10^-d of the
largest moment, so its eigenvalues move by at most 3 · 5·10^-d · I_max (1.5e-5 · I_max at
6 digits). ``_PSD_REL_TOL = _TRI_REL_TOL = 1e-4`` covers any file printed with 6 or more
significant digits (the triangle sum moves by at most 3 × that); a violation larger than
1e-4 of the largest moment is no rounding of a real body. ``_ABS_TOL = 1e-12`` kg m² covers
entries written as ``1e-13``-sized noise around zero.

**Why not yourdfpy here.** yourdfpy (0.0.60) reads links, joints, limits and inertials, and
:mod:`hybrid_force.model.report` (``hybrid-force robots --check``) reads the model through it.
The checks above keep their own reading because, measured on the inputs of
``tests/test_urdf_check.py``, yourdfpy does not refuse what the simulation cannot take and
its messages name no file: it *recovers* malformed XML (mismatched tags: it logs an error and
returns a partial model), accepts duplicate link and joint names, a joint naming an undefined
link, two root links, NaN and negative masses, a NaN or 2-element axis and a revolute joint
without ``<limit>`` (its ``validate()`` only logs the last and returns False), and raises a
bare ``ValueError``/``KeyError`` without the file or link for a non-numeric mass or a root
that is not ``<robot>``. Importing it also costs 0.6–0.9 s (trimesh, scipy, networkx:
``python -X importtime -c "import yourdfpy"``), which every run and every sweep worker would
pay; this module stays on the standard library's parser (a few ms for a 29-joint humanoid).

**After Pinocchio has built the model** (and the loader has made continuous joints unbounded
revolute ones and locked the joints it locks), :func:`check_arm_model` refuses, before any
algorithm that assumes nv > 0 runs:

* nv = 0 (e.g. every moving joint locked);
* a joint that is not a one-coordinate revolute or prismatic joint (nq ≠ nv or nv ≠ 1;
  a free-flyer or planar joint if one got past the XML check): after loading, every moving
  joint of an arm has nq = nv = 1;
* a mimic joint (``<mimic joint=...>``) on the kinematic chain from the root to the tip frame,
  named with its master: Pinocchio 4 models mimic joints (``mimic=True``) as
  ``JointModelMimic``, which its forward and impulse dynamics refuse, and loading them as
  independent joints would simulate an arm that does not exist. Mimic joints *off* that chain
  (gripper fingers) are not refused: :func:`hybrid_force.model.loading.load_robot` locks them (see
  there);
* a mass matrix that is singular at the neutral configuration q0 (:func:`check_mass_matrix`,
  run by :class:`~hybrid_force.model.robot.Robot` for every model): M(q0) must have its smallest
  eigenvalue above ``_MASS_REL_TOL * λ_max + _MASS_ABS_TOL`` (scale-aware: the registry's arms
  have λ_min / λ_max ≥ 4e-5). The message names the joints that carry no inertia (their
  subtree has zero mass and zero rotational inertia), or else the joints that the
  near-null direction of M moves.
"""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pinocchio as pin

from hybrid_force.errors import ModelWarning, RobotError
from hybrid_force.model.urdf_text import urdf_text

__all__ = ["check_arm_model", "check_mass_matrix", "check_urdf"]

# Inertia tolerances [relative to the largest principal moment; kg m²]: module docstring.
_PSD_REL_TOL = 1e-4
_TRI_REL_TOL = 1e-4
_ABS_TOL = 1e-12
# M(q0) is refused as singular when λ_min <= _MASS_REL_TOL·λ_max + _MASS_ABS_TOL
# [kg, kg·m, kg·m²: the units of M's entries].
_MASS_REL_TOL = 1e-10
_MASS_ABS_TOL = 1e-14
_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
_MOVING_TYPES = ("revolute", "continuous", "prismatic")
_FIXED_BASE_ONLY = (
    "hybrid_force simulates fixed-base arms only (make the joint fixed, or remove it and "
    "its parent link)"
)
_INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def check_urdf(path: Path | str, text: str | None = None) -> None:
    """Refuse a URDF that is missing, malformed or cannot be simulated; warn about the rest.

    Args:
        path: path of a ``.urdf`` file (named in every message).
        text: the file's text as :func:`urdf_text` returns it (read from ``path`` if None).

    Raises:
        RobotError: the message names the file and, where relevant, the link or joint and
            the offending values.

    Warns:
        ModelWarning: once per simulated link with implausible inertial data (module
            docstring), naming the file, the link and the values.
    """
    path = Path(path)
    if text is None:
        text = urdf_text(path)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RobotError(f"malformed URDF {path}: XML parse error: {exc}") from exc
    if root.tag != "robot":
        raise RobotError(f"not a URDF: {path}: root element is <{root.tag}>, expected <robot>")
    links = _check_links(path, root)
    welded = _check_joints(path, root, links)
    for link in root.findall("link"):
        name = link.get("name", "?")
        inertial = link.find("inertial")
        if inertial is None or name in welded:
            continue  # a massless frame, or merged into the universe: never simulated
        findings = _check_inertial(path, name, inertial)
        if findings:
            warnings.warn(
                f"{path}: link {name!r}: {findings[0]}: {'; '.join(findings[1:])}; loaded as "
                "written (no rigid body has this inertia, but the dynamics are well defined)",
                ModelWarning,
                stacklevel=2,
            )


def _check_links(path: Path, root: ET.Element) -> set[str]:
    """Return the set of link names; every link has a unique, non-empty name."""
    names: set[str] = set()
    elements = root.findall("link")
    if not elements:
        raise RobotError(f"not a URDF: {path}: <robot> has no <link> element")
    for i, link in enumerate(elements):
        _new_name(path, link, i, names)
    return names


def _new_name(path: Path, element: ET.Element, i: int, seen: set[str]) -> str:
    """The name of ``element``, the (i+1)-th of its tag (link or joint), added to ``seen``;
    it must be non-empty and not in ``seen`` yet."""
    name = element.get("name")
    if not name:
        raise RobotError(f"malformed URDF {path}: <{element.tag}> number {i + 1} has no name")
    if name in seen:
        raise RobotError(f"malformed URDF {path}: duplicate {element.tag} name {name!r}")
    seen.add(name)
    return name


def _check_joints(path: Path, root: ET.Element, links: set[str]) -> set[str]:
    """Joints have names, known types, limits where required, and make one tree of links.

    Also refuses, once the tree is known to be well formed, a floating or planar joint and a
    model without any moving joint (see the module docstring).

    Returns:
        the links that are not simulated: the root link and every link welded to it by a
        chain of fixed joints (Pinocchio merges them into the universe).
    """
    joint_names: set[str] = set()
    parent_of: dict[str, str] = {}
    unsupported: list[tuple[str, str, dict[str, str]]] = []
    masters: dict[str, str] = {}
    types: dict[str, str] = {}
    welded_to: dict[str, list[str]] = {}  # link: the links fixed joints attach to it
    moving = 0
    for i, joint in enumerate(root.findall("joint")):
        name = _new_name(path, joint, i, joint_names)
        jtype = joint.get("type")
        if jtype not in _JOINT_TYPES:
            raise RobotError(
                f"malformed URDF {path}: joint {name!r} has type {jtype!r}; "
                f"valid types: {', '.join(_JOINT_TYPES)}"
            )
        if jtype in ("revolute", "prismatic"):
            limit = joint.find("limit")
            missing = (
                ["<limit>"]
                if limit is None
                else [a for a in ("effort", "velocity") if limit.get(a) is None]
            )
            if missing:
                raise RobotError(
                    f"malformed URDF {path}: {jtype} joint {name!r} lacks "
                    f"{', '.join(missing)} (required by URDF)"
                )
        _check_joint_numbers(path, name, jtype, joint)
        ends = {}
        for tag in ("parent", "child"):
            element = joint.find(tag)
            link = element.get("link") if element is not None else None
            if not link:
                raise RobotError(f"malformed URDF {path}: joint {name!r} has no <{tag} link=...>")
            if link not in links:
                raise RobotError(
                    f"malformed URDF {path}: joint {name!r} names {tag} link {link!r}, "
                    "which is not defined"
                )
            ends[tag] = link
        if jtype in ("floating", "planar"):
            unsupported.append((name, jtype, ends))
        moving += jtype in _MOVING_TYPES
        types[name] = jtype
        mimic = joint.find("mimic")
        if mimic is not None and jtype in _MOVING_TYPES:  # URDF ignores it elsewhere
            masters[name] = mimic.get("joint") or ""
            for key in ("multiplier", "offset"):
                if mimic.get(key) is not None:
                    _float_attr(path, f"joint {name!r}: <mimic>", mimic, key)
        child = ends["child"]
        if child in parent_of:
            raise RobotError(
                f"malformed URDF {path}: link {child!r} is the child of two joints "
                f"({parent_of[child]!r} and {name!r})"
            )
        parent_of[child] = name
        if jtype == "fixed":
            welded_to.setdefault(ends["parent"], []).append(child)
    roots = sorted(links - parent_of.keys())
    if len(roots) != 1:
        detail = "none (the joints form a cycle)" if not roots else ", ".join(map(repr, roots))
        raise RobotError(
            f"malformed URDF {path}: the links must form one tree with one root link; "
            f"root links found: {detail}"
        )
    for name, master in masters.items():
        if types.get(master) not in _MOVING_TYPES or master == name:
            raise RobotError(
                f"malformed URDF {path}: joint {name!r} has <mimic joint={master!r}>, which "
                "names no other revolute, continuous or prismatic joint of the model"
            )
    if unsupported:
        name, jtype, ends = unsupported[0]
        raise RobotError(
            f"unsupported URDF {path}: joint {name!r} (parent link {ends['parent']!r}, child "
            f"link {ends['child']!r}) is a {jtype} joint; {_FIXED_BASE_ONLY}"
        )
    if moving == 0:
        count = len(joint_names)
        what = {0: "it has no joint", 1: "its only joint is fixed"}.get(
            count, f"all {count} joints are fixed"
        )
        raise RobotError(
            f"unsupported URDF {path}: the model has no moving joint ({what}, so nv = 0); "
            "an arm needs at least one revolute, continuous or prismatic joint"
        )
    welded, stack = {roots[0]}, [roots[0]]
    while stack:
        for child in welded_to.get(stack.pop(), ()):
            welded.add(child)
            stack.append(child)
    return welded


def _vector_attr(path: Path, where: str, element: ET.Element, key: str) -> list[float] | None:
    """The attribute as 3 finite numbers, None when absent; RobotError otherwise."""
    raw = element.get(key)
    if raw is None:
        return None
    try:
        values = [float(x) for x in raw.split()]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise RobotError(
            f"malformed URDF {path}: {where} attribute {key}={raw!r} must be 3 finite numbers"
        )
    return values


def _check_origin(path: Path, where: str, parent: ET.Element) -> None:
    """The ``<origin>`` of ``parent``, if any, has 3 finite numbers in xyz and in rpy."""
    origin = parent.find("origin")
    if origin is not None:
        for key in ("xyz", "rpy"):
            _vector_attr(path, where, origin, key)


def _check_joint_numbers(path: Path, name: str, jtype: str, joint: ET.Element) -> None:
    """Origin, axis and limits hold finite numbers (urdfdom would otherwise print several
    lines on stderr, or accept NaN); a moving joint's axis is not zero; lower <= upper."""
    where = f"joint {name!r}"
    _check_origin(path, f"{where}: <origin>", joint)
    axis = joint.find("axis")
    if axis is not None:
        xyz = _vector_attr(path, f"{where}: <axis>", axis, "xyz")
        if xyz is not None and jtype in _MOVING_TYPES and not any(xyz):
            raise RobotError(f"malformed URDF {path}: {where}: <axis xyz='0 0 0'> has no direction")
    limit = joint.find("limit")
    if limit is None:
        return
    values = {}
    for key in ("lower", "upper", "effort", "velocity"):
        if limit.get(key) is not None:
            value = _float_attr(path, f"{where}: <limit>", limit, key)
            if not math.isfinite(value) or (key in ("effort", "velocity") and value < 0):
                valid = "finite" if key in ("lower", "upper") else "finite and >= 0"
                raise RobotError(
                    f"malformed URDF {path}: {where}: <limit {key}={limit.get(key)!r}> must be "
                    f"{valid}"
                )
            values[key] = value
    if values.get("lower", -math.inf) > values.get("upper", math.inf):
        raise RobotError(
            f"malformed URDF {path}: {where}: <limit lower={values['lower']:g} "
            f"upper={values['upper']:g}>: lower is above upper"
        )


def _float_attr(path: Path, where: str, element: ET.Element, key: str) -> float:
    raw = element.get(key)
    if raw is None:
        raise RobotError(f"malformed URDF {path}: {where} lacks attribute {key!r}")
    try:
        return float(raw)
    except ValueError:
        raise RobotError(
            f"malformed URDF {path}: {where} attribute {key}={raw!r} is not a number"
        ) from None


def _check_inertial(path: Path, link: str, inertial: ET.Element) -> list[str]:
    """Refuse what breaks the simulation; return the findings to warn about (module doc).

    Refused: a missing ``<mass>`` or ``<inertia>``, numbers that do not parse or are not
    finite, a negative mass, an inertia that is not positive semi-definite beyond round-off.

    Returns:
        [] for a plausible inertial; else the inertial's values, then one text per finding
        (mass 0 with a non-zero inertia, a broken triangle inequality).
    """
    where = f"link {link!r}: <inertial>"
    _check_origin(path, f"{where} <origin>", inertial)
    mass_el = inertial.find("mass")
    if mass_el is None:
        raise RobotError(f"malformed URDF {path}: {where} has no <mass> element")
    mass = _float_attr(path, f"{where} <mass>", mass_el, "value")
    inertia_el = inertial.find("inertia")
    if inertia_el is None:
        raise RobotError(f"malformed URDF {path}: {where} has no <inertia> element")
    ixx, ixy, ixz, iyy, iyz, izz = (
        _float_attr(path, f"{where} <inertia>", inertia_el, k) for k in _INERTIA_KEYS
    )
    values = (ixx, ixy, ixz, iyy, iyz, izz)
    shown = ", ".join(f"{k}={v:g}" for k, v in zip(_INERTIA_KEYS, values, strict=True))
    if not math.isfinite(mass):
        raise RobotError(f"physically impossible URDF {path}: {where} mass {mass} is not finite")
    if not all(math.isfinite(v) for v in values):
        raise RobotError(
            f"physically impossible URDF {path}: {where} inertia has a non-finite entry ({shown})"
        )
    if mass < 0.0:
        raise RobotError(
            f"physically impossible URDF {path}: {where} mass = {mass:g} kg; a link's mass "
            "must be >= 0 (0 with an all-zero inertia, or no <inertial>, for a massless frame)"
        )
    if all(v == 0.0 for v in values):
        return []  # a massless frame (mass 0) or a point mass (mass > 0): module docstring
    matrix = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=float)
    moments = np.linalg.eigvalsh(matrix)  # ascending principal moments [kg m²]
    largest = float(np.max(np.abs(moments)))
    principal = ", ".join(f"{m:.6g}" for m in moments)
    if moments[0] < -(_PSD_REL_TOL * largest + _ABS_TOL):
        raise RobotError(
            f"physically impossible URDF {path}: {where} inertia is not positive "
            f"semi-definite ({shown}; principal moments {principal} kg m²): a negative "
            "moment is a negative kinetic energy, which the dynamics cannot integrate"
        )
    findings = []
    if mass == 0.0:
        findings.append("mass 0 with a non-zero inertia (simulated as an inertia without mass)")
    # With sorted moments I1 <= I2 <= I3, the only inequality that can fail is I1 + I2 >= I3.
    short = float(moments[2] - moments[0] - moments[1])
    if short > _TRI_REL_TOL * float(moments[2]) + _ABS_TOL:
        findings.append(
            f"I1 + I2 falls short of I3 by {short:.3g} kg m² "
            f"({100 * short / float(moments[2]):.3g} % of I3): the triangle inequality every "
            "rigid body meets is broken"
        )
    if not findings:
        return []
    return [
        f"<inertial> mass {mass:g} kg, inertia {shown} kg m² (principal moments {principal})",
        *findings,
    ]


def check_arm_model(
    model: pin.Model, path: Path | str, *, tip: str, mimic: Mapping[str, str] | None = None
) -> None:
    """Refuse a built model the toolkit cannot simulate (see the module docstring).

    Runs no Pinocchio algorithm. The mass matrix is checked by
    :class:`~hybrid_force.model.robot.Robot` (:func:`check_mass_matrix`), for every model.

    Args:
        model: the Pinocchio model as the loader will use it (continuous joints already
            unbounded revolute ones, locked joints removed).
        path: the URDF file (named in the messages).
        tip: the tip frame (must exist in ``model``).
        mimic: ``{mimic joint: its master}`` as declared by the URDF's ``<mimic>`` elements.

    Raises:
        RobotError: nv = 0, a joint that is not one-coordinate revolute or prismatic, or a
            mimic joint on the chain from the root to ``tip``; the message names the file, the
            joints and the cause.
    """
    where = f"unsupported URDF {path}"
    if model.nv == 0:
        raise RobotError(
            f"{where}: the model has no moving joint left (nv = 0); an arm needs at least "
            "one revolute, continuous or prismatic joint"
        )
    for jid in range(1, model.njoints):
        joint = model.joints[jid]
        if joint.nq != 1 or joint.nv != 1:
            raise RobotError(
                f"{where}: joint {model.names[jid]!r} is a {joint.shortname()} "
                f"(nq = {joint.nq}, nv = {joint.nv}); only one-coordinate revolute and "
                f"prismatic joints are supported: {_FIXED_BASE_ONLY}"
            )
    mimic = dict(mimic or {})
    chain = list(model.supports[model.frames[model.getFrameId(tip)].parentJoint])[1:]
    on_chain = [model.names[j] for j in chain if model.names[j] in mimic]
    if on_chain:
        listed = ", ".join(f"{j!r} (mimics {mimic[j]!r})" for j in on_chain)
        raise RobotError(
            f"{where}: mimic joints on the arm's chain are not supported: Pinocchio 4's "
            f"forward and impulse dynamics refuse them; joint {listed} lies on the chain from "
            f"the root to the tip frame {tip!r} (choose another tip, or replace the mimic "
            "joint by an independent or a fixed joint)"
        )
    # M(q0) positive definite: checked by Robot() for every model, hand-built ones included


def check_mass_matrix(model: pin.Model, where: str) -> None:
    """M(q0) positive definite, scale-aware; name the joints that move nothing with inertia."""
    M = pin.crba(model, model.createData(), pin.neutral(model))
    M = np.triu(M) + np.triu(M, 1).T
    eig, vec = np.linalg.eigh(M)
    floor = _MASS_REL_TOL * max(float(eig[-1]), 0.0) + _MASS_ABS_TOL
    if eig[0] > floor:
        return
    names = [model.names[j] for j in range(1, model.njoints)]
    empty = [
        model.names[j]
        for j in range(1, model.njoints)
        if all(
            model.inertias[k].mass == 0.0 and not np.any(model.inertias[k].inertia)
            for k in model.subtrees[j]
        )
    ]
    if empty:
        cause = (
            f"joint(s) {', '.join(map(repr, empty))} carry no inertia (every link they move "
            "has zero mass and zero inertia)"
        )
    else:
        # v_j = column of each joint in v (nv = njoints − 1, one coordinate per joint here)
        null = np.abs(vec[:, 0])
        moved = [names[i] for i in np.flatnonzero(null > 0.1 * null.max())]
        cause = (
            f"moving joint(s) {', '.join(map(repr, moved))} together move nothing with inertia "
            "(e.g. a point mass on a joint's axis)"
        )
    raise RobotError(
        f"{where}: the mass matrix M(q0) at the neutral configuration is singular "
        f"(smallest eigenvalue {eig[0]:.3g}, largest {eig[-1]:.3g}): {cause}; give the links "
        "these joints move a positive mass and inertia"
    )
