"""Plausibility checks of a URDF file, run before Pinocchio parses it.

Neither Pinocchio's URDF parser nor yourdfpy's ``validate()`` rejects physically impossible
inertial data, and Pinocchio's parser (urdfdom) reports structural errors only on stderr
before raising a bare ``ValueError``. :func:`check_urdf` raises a
:class:`~hybrid_force.errors.URDFError` that names the file, the link or joint, and the
offending values, for:

* a missing file (or a directory);
* malformed XML (with the XML parser's reason, line and column), or XML that is not a URDF
  (root element not ``<robot>``, links or joints without names, duplicate names, joints of
  unknown type, a revolute/prismatic joint without ``<limit effort=.. velocity=..>``,
  parent/child naming a link that does not exist, a link with two parents, no single root);
* physically impossible inertial data on a link that declares ``<inertial>``:
  mass missing, not finite or ``<= 0``; an inertia matrix with a non-finite entry, that is not
  positive semi-definite, or whose principal moments break the triangle inequality
  ``I1 + I2 >= I3`` (for every permutation).

Allowed on purpose: a link without ``<inertial>`` (a massless frame), and a link whose
``<inertial>`` has mass exactly 0 together with an all-zero inertia matrix (some URDF
exporters write that for dummy frames; it is the same massless frame). A thin rod
(principal moments ``0, I, I``) meets the triangle inequality with equality and passes.

Tolerances: PSD and triangle checks accept a violation up to
``_REL_TOL * max(|principal moments|) + _ABS_TOL`` [kg m²] (rounding in CAD exports).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from hybrid_force.errors import URDFError

__all__ = ["check_urdf"]

_REL_TOL = 1e-6
_ABS_TOL = 1e-12
_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
_INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def check_urdf(path: Path | str) -> None:
    """Raise :class:`URDFError` if the URDF at ``path`` is missing, malformed or impossible.

    Args:
        path: path of a ``.urdf`` file.

    Raises:
        URDFError: the message names the file and, where relevant, the link or joint and
            the offending values.
    """
    path = Path(path)
    if not path.exists():
        raise URDFError(f"URDF file not found: {path}")
    if not path.is_file():
        raise URDFError(f"URDF path is not a file: {path}")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise URDFError(f"malformed URDF {path}: XML parse error: {exc}") from exc
    except OSError as exc:
        raise URDFError(f"cannot read URDF {path}: {exc}") from exc
    if root.tag != "robot":
        raise URDFError(f"not a URDF: {path}: root element is <{root.tag}>, expected <robot>")
    links = _check_links(path, root)
    _check_joints(path, root, links)
    for link in root.findall("link"):
        inertial = link.find("inertial")
        if inertial is not None:
            _check_inertial(path, link.get("name", "?"), inertial)


def _check_links(path: Path, root: ET.Element) -> set[str]:
    """Return the set of link names; every link has a unique, non-empty name."""
    names: set[str] = set()
    elements = root.findall("link")
    if not elements:
        raise URDFError(f"not a URDF: {path}: <robot> has no <link> element")
    for i, link in enumerate(elements):
        name = link.get("name")
        if not name:
            raise URDFError(f"malformed URDF {path}: <link> number {i + 1} has no name")
        if name in names:
            raise URDFError(f"malformed URDF {path}: duplicate link name {name!r}")
        names.add(name)
    return names


def _check_joints(path: Path, root: ET.Element, links: set[str]) -> None:
    """Joints have names, known types, limits where required, and make one tree of links."""
    joint_names: set[str] = set()
    parent_of: dict[str, str] = {}
    for i, joint in enumerate(root.findall("joint")):
        name = joint.get("name")
        if not name:
            raise URDFError(f"malformed URDF {path}: <joint> number {i + 1} has no name")
        if name in joint_names:
            raise URDFError(f"malformed URDF {path}: duplicate joint name {name!r}")
        joint_names.add(name)
        jtype = joint.get("type")
        if jtype not in _JOINT_TYPES:
            raise URDFError(
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
                raise URDFError(
                    f"malformed URDF {path}: {jtype} joint {name!r} lacks "
                    f"{', '.join(missing)} (required by URDF)"
                )
        ends = {}
        for tag in ("parent", "child"):
            element = joint.find(tag)
            link = element.get("link") if element is not None else None
            if not link:
                raise URDFError(f"malformed URDF {path}: joint {name!r} has no <{tag} link=...>")
            if link not in links:
                raise URDFError(
                    f"malformed URDF {path}: joint {name!r} names {tag} link {link!r}, "
                    "which is not defined"
                )
            ends[tag] = link
        child = ends["child"]
        if child in parent_of:
            raise URDFError(
                f"malformed URDF {path}: link {child!r} is the child of two joints "
                f"({parent_of[child]!r} and {name!r})"
            )
        parent_of[child] = name
    roots = sorted(links - parent_of.keys())
    if len(roots) != 1:
        detail = "none (the joints form a cycle)" if not roots else ", ".join(map(repr, roots))
        raise URDFError(
            f"malformed URDF {path}: the links must form one tree with one root link; "
            f"root links found: {detail}"
        )


def _float_attr(path: Path, where: str, element: ET.Element, key: str) -> float:
    raw = element.get(key)
    if raw is None:
        raise URDFError(f"malformed URDF {path}: {where} lacks attribute {key!r}")
    try:
        return float(raw)
    except ValueError:
        raise URDFError(
            f"malformed URDF {path}: {where} attribute {key}={raw!r} is not a number"
        ) from None


def _check_inertial(path: Path, link: str, inertial: ET.Element) -> None:
    """Mass > 0 (or the massless exception), inertia PSD and meeting the triangle inequality."""
    where = f"link {link!r}: <inertial>"
    mass_el = inertial.find("mass")
    if mass_el is None:
        raise URDFError(f"malformed URDF {path}: {where} has no <mass> element")
    mass = _float_attr(path, f"{where} <mass>", mass_el, "value")
    inertia_el = inertial.find("inertia")
    if inertia_el is None:
        raise URDFError(f"malformed URDF {path}: {where} has no <inertia> element")
    ixx, ixy, ixz, iyy, iyz, izz = (
        _float_attr(path, f"{where} <inertia>", inertia_el, k) for k in _INERTIA_KEYS
    )
    values = (ixx, ixy, ixz, iyy, iyz, izz)
    shown = ", ".join(f"{k}={v:g}" for k, v in zip(_INERTIA_KEYS, values, strict=True))
    if not math.isfinite(mass):
        raise URDFError(f"physically impossible URDF {path}: {where} mass {mass} is not finite")
    if not all(math.isfinite(v) for v in values):
        raise URDFError(
            f"physically impossible URDF {path}: {where} inertia has a non-finite entry ({shown})"
        )
    if mass == 0.0 and all(v == 0.0 for v in values):
        return  # massless frame written as an explicit zero inertial (allowed, see module doc)
    if mass <= 0.0:
        raise URDFError(
            f"physically impossible URDF {path}: {where} mass = {mass:g} kg; "
            "a link with <inertial> needs mass > 0 (or mass 0 with an all-zero inertia)"
        )
    matrix = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], dtype=float)
    moments = np.linalg.eigvalsh(matrix)  # ascending principal moments [kg m²]
    tol = _REL_TOL * float(np.max(np.abs(moments))) + _ABS_TOL
    principal = ", ".join(f"{m:.6g}" for m in moments)
    if moments[0] < -tol:
        raise URDFError(
            f"physically impossible URDF {path}: {where} inertia is not positive "
            f"semi-definite ({shown}; principal moments {principal} kg m²)"
        )
    # With sorted moments I1 <= I2 <= I3, the only inequality that can fail is I1 + I2 >= I3.
    if moments[0] + moments[1] < moments[2] - tol:
        raise URDFError(
            f"physically impossible URDF {path}: {where} principal moments {principal} kg m² "
            f"break the triangle inequality I1 + I2 >= I3 ({shown})"
        )
