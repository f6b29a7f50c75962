"""A URDF arm and its tip: the robot-model layer (paper eq. 2, 21–24).

:func:`load_robot` builds a :class:`Robot` from a bundled name (``"rtr"``), an arm of
example-robot-data (``"ur5"``, ``"panda"``, …) or any URDF file. The robot answers, from
Pinocchio, the terms of the manipulator equation

    M(q) q̈ + C(q, q̇) q̇ + g(q) = u + J_Φnᵀ f        (paper eq. 2, D(q) there is g(q) here)

and the kinematics of its tip frame: p(q), J(q) = ∂p/∂q (world-aligned, 3×n), J̇(q, q̇) and
J̇ q̇. :meth:`Robot.terms` computes everything one control/simulation step needs in one pass.

Conventions: SI units; q and v are Pinocchio's configuration and velocity vectors (nq, nv).
Every moving joint of an arm loaded by :func:`load_robot` has one coordinate (nq = nv = 1:
a URDF ``continuous`` joint becomes a revolute joint with unbounded range, its angle in rad
never wrapped), so nq = nv = n. Revolute joints in rad, prismatic in m.

Models the toolkit cannot simulate (no moving joint, a floating or planar joint, a mimic
joint on the tip's chain, a mass matrix singular at q0) are refused with a
:class:`~hybrid_force.errors.URDFError` naming the file and the cause, before any Pinocchio
algorithm runs on them: the checks are in :mod:`hybrid_force.urdf_check`, the loading steps
in :func:`load_robot`.

Names and paths: ``load_robot("ur5")`` is always the registry's arm; a path is a
:class:`~pathlib.Path`, or a text ending with ``.urdf`` or holding a path separator.
:attr:`Robot.source` is what re-loads the same arm from any working directory (the registry
name, or the absolute path of the URDF file).
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import warnings
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from hybrid_force._lazy import kernels
from hybrid_force.errors import DimensionError, FrameError, ModelWarning, RobotError, URDFError

__all__ = ["Robot", "RobotTerms", "load_robot"]

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
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
    """A fixed-base arm from a URDF file, with a tip frame that touches the surface.

    Attributes:
        name: registry name, or the URDF path as given.
        source: (read-only) the registry name for a named arm, else the absolute resolved
            path of the URDF file: ``load_robot(robot.source)`` gives the same arm from any
            working directory (what results store).
        urdf_path: the URDF file.
        package_dirs: folders that resolve ``package://`` mesh URIs.
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
        """
        if not isinstance(model, pin.Model):
            raise RobotError(f"robot '{name}': model must be a pinocchio.Model, got {model!r}")
        if model.nv == 0:  # before any algorithm: Pinocchio's assume nv > 0 (segfault)
            raise RobotError(
                f"robot '{name}': the model has no moving joint (nv = 0); an arm needs at least "
                "one revolute or prismatic joint"
            )
        from hybrid_force.urdf_check import check_mass_matrix

        check_mass_matrix(model, f"unsupported model of robot '{name}' ({urdf_path})")
        self.model = model
        self.data = model.createData()
        self.name = name
        self.urdf_path = Path(urdf_path)
        self._source = str(self.urdf_path.resolve()) if source is None else source
        self.package_dirs = tuple(package_dirs)
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
        """The registry name of a named arm, else the absolute resolved URDF path."""
        return self._source

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
        term, is ``hybrid_force.simulate._reference_terms``; the tests compare the two.

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
        elif out._packs is None:
            raise DimensionError("out must come from RobotTerms.zeros(n)")
        mats, vecs, jac, tip = out._packs
        Mu = pin.crba(model, data, q)
        g = pin.computeGeneralizedGravity(model, data, q)
        C = pin.computeCoriolisMatrix(model, data, q, v)
        kernels().robot_terms(
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
        )

    def __repr__(self) -> str:
        return f"Robot(name={self.name!r}, n={self.nv}, tip={self.tip!r})"


def load_robot(model: str | Path, tip: str | None = None) -> Robot:
    """Load an arm by name or URDF path, refusing models the toolkit cannot simulate.

    Name or path: a :class:`~pathlib.Path` is always a path; a text is a path when it ends with
    ``.urdf`` or contains a path separator (``/``, ``\\``), and a registry name otherwise, even
    when a file of that name exists in the working directory (give ``./ur5`` to use such a
    file).

    Loading (see :mod:`hybrid_force.urdf_check` for every refusal):

    1. :func:`~hybrid_force.urdf_check.check_urdf` (structure, inertial data, no floating or
       planar joint, at least one moving joint), before Pinocchio sees the file;
    2. a ``continuous`` joint is rewritten as a ``revolute`` one (same axis; its ``<limit>``
       effort and velocity are kept) and the model built with ``pin.buildModelFromXML``
       (``mimic=False``); its position limits are then set to ∓inf, and its effort and
       velocity limits to +inf when its ``<limit>`` does not give them. It has one real
       coordinate, the angle in rad, never wrapped (not Pinocchio's (cos, sin) pair);
    3. joints held at their neutral value: the registry's ``locked_joints``, and every mimic
       joint that is not on the chain from the root to the tip frame (e.g. a mimicking
       gripper finger), which is held where its master's neutral value puts it
       (offset + multiplier · q_master(q0)); ``pin.buildReducedModel`` merges their links
       into their parents;
    4. :func:`~hybrid_force.urdf_check.check_arm_model` (nv > 0, one coordinate per joint, no
       mimic joint on the tip's chain, M(q0) positive definite).

    Every moving joint of a loaded arm then has nq = nv = 1, so q and v are (n,).

    Args:
        model: a bundled name (``"rtr"``), an example-robot-data arm (``"ur5"``, ``"panda"``,
            … see ``hybrid-force robots``), or a path to a URDF file.
        tip: frame touching the surface; default: the arm's documented default tip, or for a
            plain URDF file the last body frame of the model.

    Raises:
        UnknownRobotError: a name that is not known (lists the known names).
        URDFError: the file is missing, malformed, physically impossible, or outside the
            toolkit's scope (the message names the file and the cause).
        FrameError: ``tip`` is not a frame of the model (lists the frames).
    """
    from hybrid_force._registry import resolve_robot
    from hybrid_force.urdf_check import check_arm_model, check_urdf

    locked: tuple[str, ...] = ()
    if _is_path(model):
        path = Path(model)
        if not path.is_file():
            raise URDFError(f"URDF file not found: {path}")
        check_urdf(path)
        name, package_dirs, default_tip = str(model), (str(path.resolve().parent),), None
        source = str(path.resolve())
    else:
        entry = resolve_robot(str(model))
        path, package_dirs, default_tip, name = (
            entry.urdf_path,
            tuple(entry.package_dirs),
            entry.default_tip,
            entry.name,
        )
        locked, source = entry.locked_joints, entry.name
        check_urdf(path)
    pin_model, mimic = _build_model(path)
    tip_name = tip if tip is not None else default_tip or _default_tip(pin_model)
    _require_frame(pin_model, tip_name, path)
    chain = {
        pin_model.names[j]
        for j in pin_model.supports[pin_model.frames[pin_model.getFrameId(tip_name)].parentJoint]
    }
    locked += tuple(j for j in mimic if j not in chain and j not in locked)
    if locked:
        q_ref = pin.neutral(pin_model)
        for joint, (master, multiplier, offset) in mimic.items():
            q_ref[_q_index(pin_model, joint)] = (
                offset + multiplier * q_ref[_q_index(pin_model, master)]
            )
        ids = [pin_model.getJointId(j) for j in locked]
        pin_model = pin.buildReducedModel(pin_model, ids, q_ref)
    check_arm_model(pin_model, path, tip=tip_name, mimic={j: m[0] for j, m in mimic.items()})
    return Robot(
        pin_model,
        name=name,
        urdf_path=path,
        package_dirs=package_dirs,
        tip=tip_name,
        source=source,
    )


@contextlib.contextmanager
def _native_stderr(source: object) -> Iterator[Callable[[], list[str]]]:
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
            f"{source}: Pinocchio's URDF parser reported: {text}", ModelWarning, stacklevel=3
        )


def _is_path(model: str | os.PathLike[str]) -> bool:
    """True for a Path (any os.PathLike), or a text ending with ``.urdf`` or holding a path
    separator (``/``, ``\\``, and the platform's own)."""
    if isinstance(model, os.PathLike):
        return True
    text = str(model)
    separators = {"/", "\\", os.sep} | ({os.altsep} if os.altsep else set())
    return text.endswith(".urdf") or any(sep in text for sep in separators)


def _build_model(path: Path) -> tuple[pin.Model, dict[str, tuple[str, float, float]]]:
    """Pinocchio model of a checked URDF, continuous joints as unbounded revolute ones.

    Returns:
        the model, and ``{mimic joint: (master, multiplier, offset)}`` from its ``<mimic>``
        elements (Pinocchio builds them as independent joints: ``mimic=False``).
    """
    root = ET.parse(path).getroot()
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
