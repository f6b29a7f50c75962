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
:class:`~hybrid_force.errors.RobotError` naming the file and the cause, before any Pinocchio
algorithm runs on them: the checks are in :mod:`hybrid_force.model.urdf_check`, the loading steps
in :func:`load_robot`.

Names and paths: ``load_robot("ur5")`` is always the registry's arm; a path is a
:class:`~pathlib.Path`, or a text ending with ``.urdf``, ``.xacro`` or ``.xml`` or holding a
path separator. :attr:`Robot.source` is what re-loads the same arm from any working directory
(the registry name, or the absolute path of the model file), and :attr:`Robot.reference`
everything :func:`load_robot` needs for it (package folders, xacro arguments, locking).

This module holds the arm (:class:`Robot`, :class:`RobotTerms`); the loading steps are in
:mod:`hybrid_force.model.loading`, xacro's expansion in :mod:`hybrid_force.model.xacro_files`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from hybrid_force._jit import entry
from hybrid_force._lazy import LazyKernels
from hybrid_force.errors import BadInputError, ControlError, RobotError
from hybrid_force.model.urdf_check import check_mass_matrix
from hybrid_force.model.urdf_text import urdf_text

__all__ = ["LWA", "Robot", "RobotTerms", "check_same_joints", "default_tip_frame"]
_K = LazyKernels("hybrid_force.model._kernels")


def default_tip_frame(model: pin.Model) -> str:
    """The tip frame of a model that names none: its last body frame (the end of the last link
    in the URDF)."""
    for frame in reversed(model.frames):
        if frame.type == pin.FrameType.BODY:
            return frame.name
    return model.frames[-1].name


#: The frame convention of every Jacobian here: the tip's velocity in world axes.
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_LWA = LWA
# Joints whose configuration space is R (revolute with one coordinate, bounded or not, and
# prismatic): for them
# pinocchio.integrate(q, dq) is exactly q + dq and difference(q0, q1) is q1 − q0.
Vector = np.ndarray
"""A float64 (nq,) or (nv,) array."""
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
    # the packs' one buffer (2n² + 8n + 9,), in their order, when made by zeros(): what
    # Robot.terms's kernel writes (one argument instead of four)
    _flat: np.ndarray | None = field(default=None, repr=False, compare=False)

    @classmethod
    def zeros(cls, n: int) -> RobotTerms:
        """Terms of an n-joint arm with every array zero (a buffer for :meth:`Robot.terms`).

        The fields are views of four arrays: mats = [M, C], vecs = [g, nle], jac = [J, J̇],
        tip = [p, J̇ v, J v], themselves consecutive views of one buffer.
        """
        flat = np.zeros(2 * n * n + 2 * n + 6 * n + 9)
        a, b, c = 2 * n * n, 2 * n * n + 2 * n, 2 * n * n + 8 * n
        mats, vecs, jac, tip = (
            flat[:a].reshape(2, n, n),
            flat[a:b].reshape(2, n),
            flat[b:c].reshape(2, 3, n),
            flat[c:].reshape(3, 3),
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
            _flat=flat,
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
            "lock_off_chain"}`` (and ``"locked_positions"`` when given):
            ``load_robot(**robot.reference)`` loads the same arm from any working directory
            (JSON-able; package folders absolute). ``xacro_trust`` is not part of it: what a
            result file records never grants trust.
        urdf_path: the model file (a URDF, a ``.xacro`` or an MJCF ``.xml`` file).
        kind: ``"urdf"``, ``"xacro"`` or ``"mjcf"``: how the model file was read (a
            registry arm is ``"urdf"``).
        urdf_xml: the URDF text the model was built from (the file's text, or xacro's
            expansion); None for an MJCF model. The replay reads its visuals from it.
        model_xml: (read-only) the XML text the model was built from: :attr:`urdf_xml`, or
            an MJCF model's file text (what a result file stores: :func:`robot_from_text`
            rebuilds the arm from it).
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
        locked_joints: (read-only) ``{joint: position}`` of the model file's joints the loader
            locked; file_joints: (read-only) every joint of the model file, locked or not.
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
        mjcf_xml: str | None = None,
        locked_joints: Mapping[str, float] | None = None,
        file_joints: tuple[str, ...] | None = None,
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
            mjcf_xml: an MJCF model's text (None: read ``urdf_path`` when needed).
                (``package_dirs``, ``xacro_args``, ``lock_off_chain``, and
                ``locked_positions`` when given); default: none.
            locked_joints: ``{joint: position}`` of the model file's joints the loader
                locked (see :attr:`locked_joints`); default: none.
            file_joints: every joint of the model file, locked ones included, in the order
                of the model Pinocchio built before locking; default: the model's joints.
        """
        if not isinstance(model, pin.Model):
            raise RobotError(f"robot '{name}': model must be a pinocchio.Model, got {model!r}")
        if model.nv == 0:  # before any algorithm: Pinocchio's assume nv > 0 (segfault)
            raise RobotError(
                f"robot '{name}': the model has no moving joint (nv = 0); an arm needs at least "
                "one revolute or prismatic joint"
            )

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
        self._mjcf_xml = mjcf_xml
        extra = dict(reference or {})
        self._reference_extra: dict[str, Any] = {
            "package_dirs": [str(d) for d in extra.get("package_dirs", ())],
            "xacro_args": {str(k): str(v) for k, v in dict(extra.get("xacro_args") or {}).items()},
            "lock_off_chain": extra.get("lock_off_chain"),
        }
        if extra.get("locked_positions"):
            self._reference_extra["locked_positions"] = {
                str(k): float(v) for k, v in dict(extra["locked_positions"]).items()
            }
        self._locked = {str(k): float(v) for k, v in dict(locked_joints or {}).items()}
        moving = tuple(model.names[j] for j in range(1, model.njoints))
        self._file_joints = moving if file_joints is None else tuple(file_joints)
        if tip is None:
            tip = default_tip_frame(model)
        if not isinstance(tip, str) or not model.existFrame(tip):  # not Boost.Python's error
            frames = [f.name for f in model.frames]
            raise RobotError(
                f"tip frame {tip!r} not found in {self.urdf_path}; frames are: {', '.join(frames)}",
                key="tip",
                value=tip,
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
        ``lock_off_chain``: as given (None: the default); ``locked_positions``: only when
        the load was given some (``{joint: position}``).
        """
        extra = self._reference_extra
        out: dict[str, Any] = {
            "model": self.source,
            "tip": self.tip,
            "package_dirs": list(extra["package_dirs"]),
            "xacro_args": dict(extra["xacro_args"]),
            "lock_off_chain": extra["lock_off_chain"],
        }
        if "locked_positions" in extra:
            out["locked_positions"] = dict(extra["locked_positions"])
        return out

    @property
    def locked_joints(self) -> dict[str, float]:
        """``{joint: position [rad or m]}`` of the model file's joints that the loader locked
        (removed from the model, held at that position), in the file's joint order; {} when
        none is locked (a new dict)."""
        return dict(self._locked)

    @property
    def file_joints(self) -> tuple[str, ...]:
        """Every joint of the model file, the locked ones included, in the order of the model
        Pinocchio built before locking (root to leaves; a scenario's full-length
        ``initial.q`` follows it)."""
        return self._file_joints

    @property
    def urdf_xml(self) -> str | None:
        """The URDF text the model was built from (None for an MJCF model): the file's text
        as :func:`~hybrid_force.model.urdf_text.urdf_text` reads it, or xacro's expansion."""
        if self._urdf_xml is None and self.kind != "mjcf":
            self._urdf_xml = urdf_text(self.urdf_path)
        return self._urdf_xml

    @property
    def model_xml(self) -> str:
        """The XML text the model was built from: :attr:`urdf_xml`, or the MJCF file's text
        (read once, when first asked for, unless given)."""
        if self.kind != "mjcf":
            xml = self.urdf_xml
            assert xml is not None  # a URDF model always has its text
            return xml
        if self._mjcf_xml is None:
            self._mjcf_xml = self.urdf_path.read_text(encoding="utf-8")
        return self._mjcf_xml

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
        """Return q as a float (nq,) array; BadInputError if its length or values are wrong."""
        return _check_vector(q, self.nq, what, self.name)

    def check_v(self, v: object, what: str = "v") -> np.ndarray:
        """Return v as a float (nv,) array; BadInputError if its length or values are wrong."""
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
        (:func:`hybrid_force._kernels.robot_terms`). The tests compare them with one public
        method per term (tests/oracles/terms.py).

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
        flat = out._flat
        if flat is None:
            raise BadInputError("out must come from RobotTerms.zeros(n)")
        Mu = pin.crba(model, data, q)
        g = pin.computeGeneralizedGravity(model, data, q)
        C = pin.computeCoriolisMatrix(model, data, q, v)
        _K.robot_terms(
            Mu, C, g, pin.updateFramePlacement(model, data, fid).translation,
            pin.getFrameJacobian(model, data, fid, _LWA),
            pin.getFrameJacobianTimeVariation(model, data, fid, _LWA), v, flat,
        )  # fmt: skip
        return out

    def terms_into(self, data: pin.Data, out: RobotTerms) -> Callable[[Vector, Vector], RobotTerms]:
        """:meth:`terms` with ``data`` and ``out`` bound: ``terms_into(data, out)(q, v)`` is
        ``terms(q, v, data, out)``, the same Pinocchio calls in the same order and the same
        kernel, with every lookup but q and v made here once (the plant's step, issue 32).

        The tip position is read from a view of ``data.oMf`` (which updateFramePlacement
        writes in place) instead of a copy of the placement it returns: the same numbers.

        Args:
            data: the Pinocchio data the calls fill. out: terms from :meth:`RobotTerms.zeros`.
        """
        flat = out._flat
        if flat is None:
            raise BadInputError("out must come from RobotTerms.zeros(n)")
        model, fid, frame = self.model, self.tip_id, _LWA
        crba, gravity, coriolis = pin.crba, pin.computeGeneralizedGravity, pin.computeCoriolisMatrix
        place, jacobian = pin.updateFramePlacement, pin.getFrameJacobian
        variation = pin.getFrameJacobianTimeVariation
        p = data.oMf[fid].translation  # a view: data's placement of the tip, updated in place
        # the kernel for the argument types of every call (entry): Pinocchio's results of
        # this model (fixed shapes, whatever q), the view p, an (n,) velocity and out's pack
        q0, v0 = pin.neutral(model), np.zeros(model.nv)
        Mu, g, C = crba(model, data, q0), gravity(model, data, q0), coriolis(model, data, q0, v0)
        place(model, data, fid)
        J, dJ = jacobian(model, data, fid, frame), variation(model, data, fid, frame)
        kernel = entry(_K.robot_terms, Mu, C, g, p, J, dJ, v0, flat)

        def terms(q: Vector, v: Vector) -> RobotTerms:
            Mu = crba(model, data, q)
            g = gravity(model, data, q)
            C = coriolis(model, data, q, v)
            place(model, data, fid)
            kernel(
                Mu, C, g, p, jacobian(model, data, fid, frame),
                variation(model, data, fid, frame), v, flat,
            )  # fmt: skip
            return out

        return terms

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
            raise BadInputError(f"mass factor must be a positive finite number, got {factor!r}")
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
            locked_joints=self._locked,
            file_joints=self._file_joints,
        )

    def __repr__(self) -> str:
        return f"Robot(name={self.name!r}, n={self.nv}, tip={self.tip!r})"


def _check_vector(x: object, size: int, what: str, robot: str) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:  # "abc", [1, [2]], 10**400
        raise BadInputError(
            f"{what} for robot '{robot}' must be {size} real numbers, got {x!r:.80} ({exc})"
        ) from None
    if arr.shape != (size,):
        raise BadInputError(
            f"{what} for robot '{robot}' must have shape ({size},), got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise BadInputError(f"{what} for robot '{robot}' has non-finite values: {arr}")
    return arr


def check_same_joints(plant: Robot, model: Robot, what: str = "control.model") -> None:
    """The controller's model must move the same joints as the plant (names and order).

    Raises:
        ControlError: naming ``what``, both models and the joints that differ.
    """
    names = [str(n) for n in plant.model.names[1:]]
    others = [str(n) for n in model.model.names[1:]]
    if names != others or plant.nq != model.nq or plant.nv != model.nv:
        raise ControlError(
            f"{what} = {model.source!r} must have the plant's joints {names} "
            f"(nq = {plant.nq}), got {others} (nq = {model.nq})"
        )
