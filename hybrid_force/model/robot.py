"""A robot arm and its tip: the robot-model layer (paper eq. 2, 21–24).

:func:`load_robot` builds a :class:`Robot` from a bundled name (``"rtr"``), an arm of
example-robot-data (``"ur5"``, ``"panda"``, …), a URDF file, a xacro file (``*.xacro``,
expanded with the ``xacro`` package) or a MuJoCo MJCF file (``*.xml``). The robot answers,
from Pinocchio, the terms of the manipulator equation

    M(q) q̈ + C(q, q̇) q̇ + g(q) = u + J_Φnᵀ f        (paper eq. 2, D(q) there is g(q) here)

and the kinematics of its tip frame: p(q), J(q) = ∂p/∂q (world-aligned, 3×n), J̇(q, q̇) and
J̇ q̇. :meth:`Robot.terms` computes everything one control/simulation step needs in one pass.

Conventions: SI units; q and v are Pinocchio's configuration and velocity vectors (nq, nv).
Every moving joint of an arm loaded by :func:`load_robot` has one coordinate (nq = nv = 1:
a URDF ``continuous`` joint becomes a revolute joint with unbounded range, its angle in rad
never wrapped), so nq = nv = n. Revolute joints in rad, prismatic in m.

Models the toolkit cannot simulate (no moving joint, a floating, planar, free or ball joint,
a mimic joint on the tip's chain, a mass matrix singular at q0) are refused with a
:class:`~hybrid_force.errors.URDFError` naming the file and the cause, before any Pinocchio
algorithm runs on them: the checks are in :mod:`hybrid_force.model.urdf_check`, the loading steps
in :func:`load_robot`.

Names and paths: ``load_robot("ur5")`` is always the registry's arm; a path is a
:class:`~pathlib.Path`, or a text ending with ``.urdf``, ``.xacro`` or ``.xml`` or holding a
path separator. :attr:`Robot.source` is what re-loads the same arm from any working directory
(the registry name, or the absolute path of the model file), and :attr:`Robot.reference`
everything :func:`load_robot` needs for it (package folders, xacro arguments, locking).
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
import threading
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from hybrid_force._lazy import LazyKernels
from hybrid_force.errors import DimensionError, FrameError, ModelWarning, RobotError, URDFError

_K = LazyKernels("hybrid_force.model._kernels")

__all__ = ["Robot", "RobotTerms", "load_robot", "reference_terms"]

#: The frame convention of every Jacobian here: the tip's velocity in world axes.
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_LWA = LWA
# Joints whose configuration space is R (revolute with one coordinate, bounded or not, and
# prismatic): for them
# pinocchio.integrate(q, dq) is exactly q + dq and difference(q0, q1) is q1 − q0.
_VECTOR_SPACE_JOINTS = frozenset(
    f"JointModel{kind}"
    for kind in ("RX", "RY", "RZ", "PX", "PY", "PZ", "RevoluteUnaligned", "PrismaticUnaligned")
)


@dataclass(frozen=True)
class RobotTerms:
    """Everything one step needs about the arm at (q, v), computed in one pass.

    Attributes:
        M: (n, n) mass matrix [kg, kg·m, kg·m²].
        C: (n, n) Coriolis matrix, Ṁ − 2C skew-symmetric.
        g: (n,) gravity torques [N or N·m] (the paper's D(q), eq. 23).
        nle: (n,) C(q, v) v + g(q).
        p: (3,) tip position [m].
        J: (3, n) tip position Jacobian, world-aligned [m/rad or m/m].
        Jdot: (3, n) its time derivative J̇(q, v).
        Jdot_v: (3,) tip drift acceleration J̇ v [m/s²].
        pdot: (3,) tip velocity J v [m/s].
    """

    M: np.ndarray
    C: np.ndarray
    g: np.ndarray
    nle: np.ndarray
    p: np.ndarray
    J: np.ndarray
    Jdot: np.ndarray
    Jdot_v: np.ndarray
    pdot: np.ndarray
    # (mats (2, n, n), vecs (2, n), jac (2, 3, n), tip (3, 3)) whose slices are the fields
    # above, when made by zeros(): what the compiled code reads and writes
    _packs: tuple[np.ndarray, ...] | None = field(default=None, repr=False, compare=False)

    @classmethod
    def zeros(cls, n: int) -> RobotTerms:
        """Terms of an n-joint arm with every array zero (a buffer for :meth:`Robot.terms`).

        The fields are views of four arrays: mats = [M, C], vecs = [g, nle], jac = [J, J̇],
        tip = [p, J̇ v, J v].
        """
        mats, vecs, jac, tip = (
            np.zeros((2, n, n)),
            np.zeros((2, n)),
            np.zeros((2, 3, n)),
            np.zeros((3, 3)),
        )
        return cls(
            M=mats[0],
            C=mats[1],
            g=vecs[0],
            nle=vecs[1],
            p=tip[0],
            J=jac[0],
            Jdot=jac[1],
            Jdot_v=tip[1],
            pdot=tip[2],
            _packs=(mats, vecs, jac, tip),
        )

    def packed(self) -> RobotTerms:
        """These terms with their packs: self when made by :meth:`zeros`, else a copy."""
        if self._packs is not None:
            return self
        out = RobotTerms.zeros(self.M.shape[0])
        for name in ("M", "C", "g", "nle", "p", "J", "Jdot", "Jdot_v", "pdot"):
            getattr(out, name)[...] = getattr(self, name)
        return out


class Robot:
    """A fixed-base arm from a model file, with a tip frame that touches the surface.

    Attributes:
        name: registry name, or the model path as given.
        source: (read-only) the registry name for a named arm, else the absolute resolved
            path of the model file (URDF, xacro or MJCF): ``load_robot(robot.source)`` gives
            the same arm from any working directory (what results store), with the
            arguments of :attr:`reference` for a xacro file or extra package folders.
        reference: (read-only) ``{"model", "tip", "package_dirs", "xacro_args",
            "lock_off_chain"}``: ``load_robot(**robot.reference)`` loads the same arm from
            any working directory (JSON-able; package folders absolute).
        urdf_path: the model file (a URDF, a ``.xacro`` or an MJCF ``.xml`` file).
        kind: ``"urdf"``, ``"xacro"`` or ``"mjcf"``: how the model file was read (a
            registry arm is ``"urdf"``).
        urdf_xml: the URDF text the model was built from (the file's text, or xacro's
            expansion); None for an MJCF model. The replay reads its visuals from it.
        package_dirs: folders that resolve ``package://NAME/...`` mesh URIs (each holds a
            folder NAME), in search order: the ones given to :func:`load_robot`, then
            ``ROS_PACKAGE_PATH``'s, then the model file's own folder (or the registry's).
        model: the Pinocchio model (gravity (0, 0, −9.81) m/s²).
        data: a Pinocchio data object owned by this robot (one per purpose: the simulator
            and viewer make their own with :meth:`new_data`).
        tip: tip frame name; tip_id its frame index.
        euclidean: True when every joint has one real coordinate (revolute, bounded or not,
            or prismatic), so that q ⊕ dq = q + dq (the fast loop then integrates without
            Pinocchio calls). True for every arm :func:`load_robot` returns (continuous joints
            included); False only for a model built by hand with e.g. a JointModelRUBZ.
        position_limits, effort_limits: (read-only) the joint limits of the model.
    """

    def __init__(
        self,
        model: pin.Model,
        *,
        name: str,
        urdf_path: Path,
        package_dirs: tuple[str, ...] = (),
        tip: str | None = None,
        source: str | None = None,
        kind: str = "urdf",
        urdf_xml: str | None = None,
        reference: Mapping[str, Any] | None = None,
    ) -> None:
        """Wrap a Pinocchio model: nv > 0 and M(q0) positive definite are checked here (so a
        hand-built model cannot crash Pinocchio); :func:`load_robot` makes the other checks.

        Args:
            model: the arm's Pinocchio model.
            name: how messages name the arm.
            urdf_path: the URDF file the model comes from.
            package_dirs: folders that resolve ``package://`` URIs.
            tip: tip frame (default: the last body frame).
            source: see :attr:`source`; default: the absolute resolved ``urdf_path``.
            kind: ``"urdf"``, ``"xacro"`` or ``"mjcf"`` (see :attr:`kind`).
            urdf_xml: the URDF text of the model (None: read ``urdf_path`` when needed).
            reference: the extra :func:`load_robot` arguments of :attr:`reference`
                (``package_dirs``, ``xacro_args``, ``lock_off_chain``); default: none.
        """
        if not isinstance(model, pin.Model):
            raise RobotError(f"robot '{name}': model must be a pinocchio.Model, got {model!r}")
        if model.nv == 0:  # before any algorithm: Pinocchio's assume nv > 0 (segfault)
            raise RobotError(
                f"robot '{name}': the model has no moving joint (nv = 0); an arm needs at least "
                "one revolute or prismatic joint"
            )
        from hybrid_force.model.urdf_check import check_mass_matrix

        check_mass_matrix(model, f"unsupported model of robot '{name}' ({urdf_path})")
        self.model = model
        self.data = model.createData()
        self.name = name
        self.urdf_path = Path(urdf_path)
        self._source = str(self.urdf_path.resolve()) if source is None else source
        self.package_dirs = tuple(package_dirs)
        if kind not in ("urdf", "xacro", "mjcf"):
            raise RobotError(
                f"robot '{name}': kind must be 'urdf', 'xacro' or 'mjcf', got {kind!r}"
            )
        self.kind = kind
        self._urdf_xml = urdf_xml
        extra = dict(reference or {})
        self._reference_extra: dict[str, Any] = {
            "package_dirs": [str(d) for d in extra.get("package_dirs", ())],
            "xacro_args": {str(k): str(v) for k, v in dict(extra.get("xacro_args") or {}).items()},
            "lock_off_chain": extra.get("lock_off_chain"),
        }
        if tip is None:
            tip = _default_tip(model)
        if not model.existFrame(tip):
            frames = [f.name for f in model.frames]
            raise FrameError(
                f"tip frame '{tip}' not found in {self.urdf_path}; frames are: {', '.join(frames)}"
            )
        self.tip = tip
        self.tip_id = model.getFrameId(tip)
        self._lower = np.tril_indices(model.nv, -1)
        self.euclidean = all(j.shortname() in _VECTOR_SPACE_JOINTS for j in list(model.joints)[1:])

    # --- identity, sizes, limits and validation ------------------------------------
    @property
    def source(self) -> str:
        """The registry name of a named arm, else the absolute resolved model file path."""
        return self._source

    @property
    def reference(self) -> dict[str, Any]:
        """What re-loads this arm anywhere: ``load_robot(**robot.reference)`` (a new dict).

        ``model``: :attr:`source`; ``tip``: the tip frame; ``package_dirs``: the absolute
        folders given to :func:`load_robot` (not ``ROS_PACKAGE_PATH``'s nor the model's own
        folder, which the loader adds again); ``xacro_args``: ``{name: value}`` texts;
        ``lock_off_chain``: as given (None: the default).
        """
        extra = self._reference_extra
        return {
            "model": self.source,
            "tip": self.tip,
            "package_dirs": list(extra["package_dirs"]),
            "xacro_args": dict(extra["xacro_args"]),
            "lock_off_chain": extra["lock_off_chain"],
        }

    @property
    def urdf_xml(self) -> str | None:
        """The URDF text the model was built from (None for an MJCF model): the file's text
        as :func:`~hybrid_force.model.urdf_check.urdf_text` reads it, or xacro's expansion."""
        if self._urdf_xml is None and self.kind != "mjcf":
            from hybrid_force.model.urdf_check import urdf_text

            self._urdf_xml = urdf_text(self.urdf_path)
        return self._urdf_xml

    @property
    def position_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower (nq,), upper (nq,)) joint position limits [rad or m], read-only copies.

        From the URDF's ``<limit lower upper>`` (Pinocchio's model); ∓inf for a continuous
        joint, and for a joint whose range is empty (lower = upper: URDF's default 0, 0 when a
        ``<limit>`` gives only effort and velocity, which hand-written files use to mean "no
        range"; a joint that truly cannot move is a fixed joint).
        """
        lower = np.array(self.model.lowerPositionLimit, dtype=float)
        upper = np.array(self.model.upperPositionLimit, dtype=float)
        unspecified = ~(lower < upper)  # also NaN
        lower[unspecified], upper[unspecified] = -np.inf, np.inf
        lower.flags.writeable = upper.flags.writeable = False
        return lower, upper

    @property
    def effort_limits(self) -> np.ndarray:
        """(nv,) joint effort limits [N·m or N], a read-only copy; +inf where unspecified.

        From the URDF's ``<limit effort>``. +inf where the URDF gives none (a continuous
        joint without ``<limit>``) or gives 0 (URDF's conventional "unspecified", so 0 never
        means "no force allowed"), or a value that is not a positive number.
        """
        effort = np.array(self.model.effortLimit, dtype=float)
        effort[~(effort > 0)] = np.inf  # also NaN
        effort.flags.writeable = False
        return effort

    @property
    def velocity_limits(self) -> np.ndarray:
        """(nv,) joint velocity limits [rad/s or m/s], a read-only copy; +inf where unspecified.

        From the URDF's ``<limit velocity>``; +inf where it gives none, 0 (unspecified, as for
        the effort) or a value that is not a positive number.
        """
        velocity = np.array(self.model.velocityLimit, dtype=float)
        velocity[~(velocity > 0)] = np.inf  # also NaN
        velocity.flags.writeable = False
        return velocity

    @property
    def nq(self) -> int:
        """Size of the configuration vector q."""
        return self.model.nq

    @property
    def nv(self) -> int:
        """Size of the velocity vector v (= number of degrees of freedom n)."""
        return self.model.nv

    def frames(self) -> list[str]:
        """Names of all frames of the model."""
        return [f.name for f in self.model.frames]

    def neutral(self) -> np.ndarray:
        """The neutral configuration (nq,)."""
        return pin.neutral(self.model)

    def new_data(self) -> pin.Data:
        """A fresh Pinocchio data object for this model."""
        return self.model.createData()

    def check_q(self, q: object, what: str = "q") -> np.ndarray:
        """Return q as a float (nq,) array; DimensionError if its length or values are wrong."""
        return _check_vector(q, self.nq, what, self.name)

    def check_v(self, v: object, what: str = "v") -> np.ndarray:
        """Return v as a float (nv,) array; DimensionError if its length or values are wrong."""
        return _check_vector(v, self.nv, what, self.name)

    # --- dynamics (eq. 2, 21–23) ----------------------------------------------
    def mass_matrix(self, q: object) -> np.ndarray:
        """M(q): (n, n) symmetric positive definite mass matrix (eq. 21)."""
        q = self.check_q(q)
        return self._full(pin.crba(self.model, self.data, q))

    def coriolis(self, q: object, v: object) -> np.ndarray:
        """C(q, v): (n, n) Coriolis matrix with Ṁ − 2C skew-symmetric (eq. 22)."""
        q, v = self.check_q(q), self.check_v(v)
        return pin.computeCoriolisMatrix(self.model, self.data, q, v).copy()

    def gravity(self, q: object) -> np.ndarray:
        """g(q): (n,) gravity torques [N or N·m] (the paper's D(q), eq. 23)."""
        q = self.check_q(q)
        return pin.computeGeneralizedGravity(self.model, self.data, q).copy()

    # --- tip kinematics (p(q), eq. 24) -------------------------------------------
    def tip_position(self, q: object) -> np.ndarray:
        """p(q): (3,) tip position in the world frame [m]."""
        q = self.check_q(q)
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, self.tip_id).translation.copy()

    def jacobian(self, q: object) -> np.ndarray:
        """J(q) = ∂p/∂q: (3, n) world-aligned tip position Jacobian [m/rad or m/m] (eq. 24)."""
        q = self.check_q(q)
        J = pin.computeFrameJacobian(self.model, self.data, q, self.tip_id, _LWA)
        return J[:3].copy()

    def drift(self, q: object, v: object) -> np.ndarray:
        """J̇(q, v) v: (3,) tip acceleration at zero joint acceleration [m/s²]."""
        q, v = self.check_q(q), self.check_v(v)
        pin.forwardKinematics(self.model, self.data, q, v, np.zeros(self.nv))
        acc = pin.getFrameClassicalAcceleration(self.model, self.data, self.tip_id, _LWA)
        return acc.linear.copy()

    def terms(
        self,
        q: np.ndarray,
        v: np.ndarray,
        data: pin.Data | None = None,
        out: RobotTerms | None = None,
    ) -> RobotTerms:
        """All terms of one step at (q, v) in one Pinocchio pass (no validation: hot path).

        Six Pinocchio calls: crba, computeGeneralizedGravity, computeCoriolisMatrix (which
        also fills the joint Jacobians, their time variation and the placements),
        updateFramePlacement, getFrameJacobian, getFrameJacobianTimeVariation; the rest
        (symmetric M, nle = C v + g, J v, J̇ v) is one compiled call
        (:func:`hybrid_force._kernels.robot_terms`). The reference, one public method per
        term, is :func:`reference_terms`; the tests compare the two.

        Args:
            q: (nq,) configuration. v: (nv,) velocity.
            data: the Pinocchio data to use (default: this robot's own).
            out: terms whose arrays are overwritten (see :meth:`RobotTerms.zeros`); default:
                fresh arrays.
        """
        model, fid = self.model, self.tip_id
        data = self.data if data is None else data
        if out is None:
            out = RobotTerms.zeros(model.nv)
        if out._packs is None:
            raise DimensionError("out must come from RobotTerms.zeros(n)")
        mats, vecs, jac, tip = out._packs
        Mu = pin.crba(model, data, q)
        g = pin.computeGeneralizedGravity(model, data, q)
        C = pin.computeCoriolisMatrix(model, data, q, v)
        _K.robot_terms(
            Mu, C, g, pin.updateFramePlacement(model, data, fid).translation,
            pin.getFrameJacobian(model, data, fid, _LWA),
            pin.getFrameJacobianTimeVariation(model, data, fid, _LWA), v, mats, vecs, jac, tip,
        )  # fmt: skip
        return out

    def _full(self, M_upper: np.ndarray) -> np.ndarray:
        """A copy of crba's result with its upper triangle mirrored onto the lower one."""
        M = M_upper.copy()
        M[self._lower] = M.T[self._lower]
        return M

    def with_mass_factor(self, factor: float) -> Robot:
        """A copy whose link masses and inertias are scaled by ``factor`` (model mismatch).

        The kinematics are unchanged; M, C and g scale by ``factor``.
        """
        if not (np.isfinite(factor) and factor > 0):
            raise DimensionError(f"mass factor must be a positive finite number, got {factor!r}")
        model = self.model.copy()
        for i in range(model.njoints):
            inertia = model.inertias[i]
            model.inertias[i] = pin.Inertia(
                inertia.mass * factor, inertia.lever.copy(), inertia.inertia * factor
            )
        return Robot(
            model,
            name=self.name,
            urdf_path=self.urdf_path,
            package_dirs=self.package_dirs,
            tip=self.tip,
            source=self.source,
            kind=self.kind,
            urdf_xml=self._urdf_xml,
            reference=self._reference_extra,
        )

    def __repr__(self) -> str:
        return f"Robot(name={self.name!r}, n={self.nv}, tip={self.tip!r})"


MODEL_SUFFIXES: tuple[str, ...] = (".urdf", ".xacro", ".xml")
"""Endings that make a text a model path, not a registry name (also: a path separator)."""

_KIND_LABELS = {"urdf": "URDF file", "xacro": "xacro file", "mjcf": "MJCF file"}
_XACRO_LOCK = threading.Lock()  # xacro keeps its state in module globals


def load_robot(
    model: str | os.PathLike[str],
    tip: str | None = None,
    package_dirs: Sequence[str | os.PathLike[str]] = (),
    *,
    xacro_args: Mapping[str, str] | None = None,
    lock_off_chain: bool | None = None,
) -> Robot:
    """Load an arm by name or model file, refusing models the toolkit cannot simulate.

    Name or path: a :class:`~pathlib.Path` is always a path; a text is a path when it ends with
    ``.urdf``, ``.xacro`` or ``.xml`` or contains a path separator (``/``, ``\\``), and a
    registry name otherwise, even when a file of that name exists in the working directory
    (give ``./ur5`` to use such a file).

    Model files: a ``*.xacro`` file is expanded with the ``xacro`` package (arguments
    ``xacro_args``; ``$(find NAME)`` is the folder NAME inside the first package folder that
    holds one), then read as a URDF. A ``*.xml`` file whose root element is ``<mujoco>`` is
    read by Pinocchio's MJCF parser (one whose root is ``<robot>`` is a URDF). Anything else
    is a URDF.

    Loading (see :mod:`hybrid_force.model.urdf_check` for every refusal):

    1. a URDF is read by :func:`~hybrid_force.model.urdf_check.urdf_text` (undeclared namespace
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
       bound when the other is infinite);
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
        lock_off_chain: lock every joint off the chain from the root to the tip (step 3).
            Default (None): True for a model file, False for a registry arm (whose entry
            names what it locks: the Panda's fingers; ``z1`` keeps its gripper joint and
            ``g1`` its 29 joints). Mimic joints off the chain are locked whatever this says.

    Raises:
        UnknownRobotError: a name that is not known (lists the known names).
        URDFError: the file is missing, malformed, physically impossible, outside the
            toolkit's scope, or xacro cannot expand it (the message names the file and the
            cause; for xacro, its own message).
        FrameError: ``tip`` is not a frame of the model (lists the frames), or no moving
            joint lies between the root and it while the joints off its chain are locked.
    """
    from hybrid_force.model.registry import resolve_robot
    from hybrid_force.model.urdf_check import check_arm_model, urdf_text

    given = _absolute_dirs(package_dirs)
    args = _xacro_arguments(xacro_args)
    if lock_off_chain is not None and not isinstance(lock_off_chain, bool):
        raise RobotError(f"lock_off_chain must be True, False or None, got {lock_off_chain!r}")
    locked: tuple[str, ...] = ()
    if _is_path(model):
        path = Path(model)
        kind = model_kind(path)
        if not path.is_file():
            raise URDFError(f"{_KIND_LABELS[kind]} not found: {path}")
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
        raise URDFError(
            f"xacro arguments ({', '.join(sorted(args))}) are given for {name}, which is not a "
            ".xacro file"
        )
    xml: str | None = None
    mimic: dict[str, tuple[str, float, float]] = {}
    if kind == "mjcf":
        pin_model = _build_mjcf(path)
    else:
        if kind == "xacro":
            xml = expand_xacro(path, args, given, check=True)
        else:
            xml = urdf_text(path)
            _check_urdf_text(path, xml, expanded=False)
        pin_model, mimic = _build_model(path, xml)
    tip_name = tip if tip is not None else default_tip or _default_tip(pin_model)
    _require_frame(pin_model, tip_name, path)
    pin_model = _lock_joints(pin_model, path, tip_name, locked, mimic, lock_all)
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
        reference={"package_dirs": given, "xacro_args": args, "lock_off_chain": lock_off_chain},
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


def _absolute_dirs(dirs: Sequence[str | os.PathLike[str]]) -> tuple[str, ...]:
    """The package folders as absolute paths (a single text is refused: it is no list)."""
    if isinstance(dirs, (str, bytes, os.PathLike)):
        raise RobotError(f"package_dirs must be a list of folders, got the single value {dirs!r}")
    out = []
    for d in dirs:
        if not isinstance(d, (str, os.PathLike)) or not str(d):
            raise RobotError(f"package_dirs must hold folder paths, got {d!r}")
        out.append(os.path.abspath(d))  # absolute, ".." resolved (not symlinks)
    return tuple(out)


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


def _ros_package_path() -> tuple[str, ...]:
    """The folders of the ``ROS_PACKAGE_PATH`` environment variable, absolute, in order."""
    text = os.environ.get("ROS_PACKAGE_PATH", "")
    return tuple(os.path.abspath(d) for d in text.split(os.pathsep) if d)


def find_package(name: str, package_dirs: Sequence[str]) -> Path | None:
    """The folder ``NAME`` inside the first of ``package_dirs`` that holds one, else None.

    What ``package://NAME/...`` and xacro's ``$(find NAME)`` resolve against.
    """
    if not name or name in (".", "..") or "/" in name or "\\" in name:
        return None
    for folder in package_dirs:
        candidate = Path(folder) / name
        if candidate.is_dir():
            return candidate
    return None


class _FindError(Exception):
    """``$(find NAME)`` found no folder NAME (raised inside xacro, reported by expand_xacro)."""


def expand_xacro(
    path: str | os.PathLike[str],
    args: Mapping[str, str],
    package_dirs: Sequence[str | os.PathLike[str]],
    *,
    check: bool = False,
) -> str:
    """The URDF text that the xacro file ``path`` expands to, with the arguments ``args``.

    ``$(find NAME)`` is the folder NAME in the first folder that holds one, of
    ``package_dirs``, then ``ROS_PACKAGE_PATH``'s, then the xacro file's own folder (xacro's
    own ``$(find)`` needs ROS 2's ament index, which is not used). Includes are read relative
    to the including file. What xacro prints as warnings becomes one :class:`ModelWarning`
    naming the file.

    Args:
        path: the ``.xacro`` file.
        args: ``{name: text}`` values of its ``<xacro:arg>`` (``$(arg name)``).
        package_dirs: folders that hold package folders (see :func:`load_robot`).
        check: also check the expansion as :func:`load_robot` does
            (:func:`~hybrid_force.model.urdf_check.check_urdf`; its messages and warnings name
            ``<path> (as expanded by xacro)``).

    Raises:
        URDFError: the ``xacro`` package is missing, or xacro cannot expand the file (XML
            syntax, an undefined argument or property, a missing include, ``$(find NAME)``
            with no folder NAME); the message names the file (and the included file where it
            happened) and xacro's own message. With ``check``: an expansion that is not a
            URDF the toolkit can simulate.
    """
    path = Path(path)
    try:
        import xacro
        from xacro import substitution_args
    except ImportError as exc:
        raise URDFError(
            f"cannot expand {path}: the 'xacro' package is missing ({exc}); pip install xacro"
        ) from None
    import xml.parsers.expat

    dirs = tuple(
        dict.fromkeys(
            (*_absolute_dirs(package_dirs), *_ros_package_path(), str(path.resolve().parent))
        )
    )

    def find(name: str) -> str:
        found = find_package(name, dirs)
        if found is None:
            raise _FindError(
                f"$(find {name}): no folder '{name}' in the package folders "
                f"({', '.join(dirs) or 'none'}); add the folder that holds it to "
                "robot.package_dirs (load_robot's package_dirs) or ROS_PACKAGE_PATH"
            )
        return str(found)

    said = io.StringIO()
    target = str(path.resolve())
    with _XACRO_LOCK, contextlib.redirect_stderr(said), contextlib.redirect_stdout(said):
        saved_find = getattr(substitution_args, "_eval_find", None)
        saved_eval = substitution_args._eval_dict.get("find")
        substitution_args._eval_find = find
        substitution_args._eval_dict["find"] = find
        xacro.all_includes = []  # xacro's record of every file it read: never emptied by it
        try:
            doc = xacro.process_file(target, mappings=dict(args), verbosity=0)
            text = doc.toxml()
        except Exception as exc:
            stack = [f for f in (getattr(xacro, "filestack", None) or []) if f]
            where = f" (in {stack[-1]})" if stack and stack[-1] != target else ""
            macros = getattr(xacro, "macrostack", None) or []
            if macros:
                with contextlib.suppress(Exception):
                    where += f" (in macro '{macros[-1].body.getAttribute('name')}')"
            cause: BaseException | None = exc  # xacro wraps our $(find) error: unwrap it
            for _ in range(10):
                if cause is None or isinstance(cause, _FindError):
                    break
                cause = getattr(cause, "exc", None) or cause.__cause__ or cause.__context__
            cause = cause if isinstance(cause, _FindError) else None
            if isinstance(exc, xml.parsers.expat.ExpatError):
                why = f"XML syntax error: {exc}"
            elif cause is not None:
                why = str(cause)
            else:
                why = " ".join(str(exc).split()) or type(exc).__name__
            raise URDFError(f"xacro cannot expand {path}{where}: {why}") from None
        finally:
            if saved_find is not None:
                substitution_args._eval_find = saved_find
            if saved_eval is not None:
                substitution_args._eval_dict["find"] = saved_eval
    messages = [" ".join(x.split()) for x in said.getvalue().splitlines() if x.strip()]
    if messages:
        warnings.warn(f"{path}: xacro reported: {'; '.join(messages)}", ModelWarning, stacklevel=3)
    if check:
        _check_urdf_text(path, text, expanded=True)
    return text


def _check_urdf_text(path: Path, xml: str, *, expanded: bool) -> None:
    """:func:`~hybrid_force.model.urdf_check.check_urdf` on the URDF text of ``path``; for xacro's
    expansion (``expanded``) its messages say ``<path> (as expanded by xacro)``."""
    from hybrid_force.model.urdf_check import check_urdf

    if not expanded:
        check_urdf(path, text=xml)
        return
    shown = f"{path} (as expanded by xacro)"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ModelWarning)
        try:
            check_urdf(path, text=xml)
        except URDFError as exc:
            raise URDFError(str(exc).replace(str(path), shown, 1)) from None
    for w in caught:
        message = str(w.message)
        if issubclass(w.category, ModelWarning):
            message = message.replace(str(path), shown, 1)
        warnings.warn(message, w.category, stacklevel=4)


def _lock_joints(
    model: pin.Model,
    path: Path,
    tip: str,
    locked: Sequence[str],
    mimic: Mapping[str, tuple[str, float, float]],
    lock_all: bool,
) -> pin.Model:
    """The model with ``locked``, the mimic joints off the tip's chain and, with
    ``lock_all``, every joint off that chain, removed (see :func:`load_robot`, step 3)."""
    chain_ids = set(model.supports[model.frames[model.getFrameId(tip)].parentJoint])
    off_chain = [model.names[j] for j in range(1, model.njoints) if j not in chain_ids]
    if lock_all and off_chain and chain_ids <= {0}:
        raise FrameError(
            f"tip frame '{tip}' of {path} is on the base: no joint lies between the root and "
            "it, so locking the joints off its chain would leave none; choose a tip on the arm"
        )
    extra = [j for j in off_chain if (lock_all or j in mimic) and j not in locked]
    to_lock = [*locked, *extra]
    if not to_lock:
        return model
    q_ref = pin.neutral(model)
    for joint in to_lock:
        if joint not in mimic:
            q_ref[_q_index(model, joint)] = _lock_position(model, joint)
    for joint, (master, multiplier, offset) in mimic.items():
        q_ref[_q_index(model, joint)] = offset + multiplier * q_ref[_q_index(model, master)]
    ids = [model.getJointId(j) for j in to_lock]
    return pin.buildReducedModel(model, ids, q_ref)


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
        xml: the URDF text (:func:`~hybrid_force.model.urdf_check.urdf_text` of ``path``, or
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
            raise URDFError(f"Pinocchio cannot parse {path}: {exc}{detail}") from exc
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


def _build_mjcf(path: Path) -> pin.Model:
    """Pinocchio model of an MJCF file (``pin.buildModelFromMJCF``), fixed-base arms only.

    Refused before the parser runs (URDFError naming the file): malformed XML, a root
    element other than ``<mujoco>``, an ``<include>`` (Pinocchio's parser silently ignores
    it: the included bodies would be missing), a free or ball joint. Warned
    (:class:`ModelWarning`): a body without ``<inertial>`` whose inertia would come from a
    mesh geom (Pinocchio does not compute a mesh's inertia as MuJoCo does), and
    ``<equality>`` constraints (ignored: the joints they couple move independently).
    Meshes and other assets are not read to build the model.
    """
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise URDFError(f"malformed MJCF {path}: XML parse error: {exc}") from None
    except OSError as exc:
        raise URDFError(f"cannot read MJCF {path}: {exc}") from None
    if root.tag != "mujoco":
        raise URDFError(
            f"not an MJCF file: {path}: root element is <{root.tag}>, expected <mujoco> "
            "(or <robot> for a URDF)"
        )
    include = root.find(".//include")
    if include is not None:
        raise URDFError(
            f"unsupported MJCF {path}: <include file={include.get('file')!r}>: Pinocchio's "
            "MJCF parser ignores includes (the included bodies would be missing); write the "
            "included file's content in place of the <include>"
        )
    mesh_bodies = []
    for body in root.iter("body"):
        where = f"body {body.get('name', '?')!r}"
        for child in body:
            jtype = "free" if child.tag == "freejoint" else child.get("type", "hinge")
            if child.tag in ("joint", "freejoint") and jtype in ("free", "ball"):
                raise URDFError(
                    f"unsupported MJCF {path}: {where} has a {jtype} joint "
                    f"{child.get('name', '(unnamed)')!r}; {_MJCF_SCOPE}"
                )
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
    with _native_stderr(path, "MJCF") as said:
        try:
            model = pin.buildModelFromMJCF(str(path))
        except (RuntimeError, ValueError, IndexError) as exc:
            why = said()
            detail = f" ({why[0]})" if why else ""
            raise URDFError(
                f"Pinocchio cannot parse MJCF {path}: {_pinocchio_message(exc)}{detail}"
            ) from None
    for note in notes:
        warnings.warn(f"{path}: {note}", ModelWarning, stacklevel=3)
    return model


_MJCF_SCOPE = (
    "hybrid_force simulates fixed-base arms with one-coordinate joints (hinge, slide) only: "
    "remove the joint (the body is then welded to its parent) or replace it"
)


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
    """FrameError listing the model's frames if ``tip`` is not one of them."""
    if not model.existFrame(tip):
        frames = [f.name for f in model.frames]
        raise FrameError(f"tip frame '{tip}' not found in {path}; frames are: {', '.join(frames)}")


def _default_tip(model: pin.Model) -> str:
    """The last body frame of the model (the end of the last link in the URDF)."""
    for frame in reversed(model.frames):
        if frame.type == pin.FrameType.BODY:
            return frame.name
    return model.frames[-1].name


def _check_vector(x: object, size: int, what: str, robot: str) -> np.ndarray:
    arr = np.asarray(x, dtype=float)
    if arr.shape != (size,):
        raise DimensionError(
            f"{what} for robot '{robot}' must have shape ({size},), got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise DimensionError(f"{what} for robot '{robot}' has non-finite values: {arr}")
    return arr


def reference_terms(robot: Robot, q: np.ndarray, v: np.ndarray) -> RobotTerms:
    """The robot terms from one public method each: the reference :meth:`Robot.terms` is
    tested against, and the terms of the simulator's reference step."""
    M, C, g = robot.mass_matrix(q), robot.coriolis(q, v), robot.gravity(q)
    J = robot.jacobian(q)
    data = robot.new_data()
    pin.computeJointJacobiansTimeVariation(robot.model, data, q, v)
    Jdot = pin.getFrameJacobianTimeVariation(robot.model, data, robot.tip_id, _LWA)[:3].copy()
    return RobotTerms(
        M=M,
        C=C,
        g=g,
        nle=C @ v + g,
        p=robot.tip_position(q),
        J=J,
        Jdot=Jdot,
        Jdot_v=robot.drift(q, v),
        pdot=J @ v,
    )
