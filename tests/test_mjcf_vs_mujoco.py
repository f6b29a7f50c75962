"""MJCF models loaded by the toolkit against MuJoCo itself (the ``mujoco`` wheel).

For every model written here (a Menagerie-like UR5e whose base is turned by quat="0 0 0 -1"
and has no joint, a Panda-like 7-joint arm with fingers, files with ``<frame>``,
``<replicate>``, default classes with ``childclass``, degrees and every orientation form,
joint ``ref``, ``limited="false"``), at random q and v (fixed seed), joints matched by name:
the world pose of every body and site (MuJoCo's xpos/xmat, site_xpos/site_xmat against
Pinocchio's frames), M(q) (``mj_fullM``, armature included, against ``crba``) and the bias
forces (``qfrc_bias`` against ``rnea(q, v, 0)``) agree to 1e-10, and the joints' limits,
effort limits, damping, friction and armature are MuJoCo's.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from hybrid_force import load_robot
from hybrid_force.cli import main
from hybrid_force.errors import ModelWarning, RobotError

mujoco = pytest.importorskip("mujoco")

TOL = 1e-10

UR5E = """\
<mujoco model="ur5e">
  <compiler angle="radian" autolimits="true"/>
  <option integrator="implicitfast"/>
  <default>
    <default class="ur5e">
      <joint axis="0 1 0" range="-6.28319 6.28319" armature="0.1" damping="0.5"/>
      <site size="0.001" rgba="0.5 0.5 0.5 0.3" group="4"/>
      <general gaintype="fixed" biastype="affine" ctrlrange="-6.2831 6.2831"
               gainprm="2000" biasprm="0 -2000 -400" forcerange="-150 150"/>
      <default class="size3">
        <joint actuatorfrcrange="-200 200" frictionloss="0.2"/>
        <default class="size3_limited">
          <joint range="-3.1415 3.1415"/>
        </default>
      </default>
      <default class="size1">
        <joint damping="0.1"/>
        <general gainprm="500" biasprm="0 -500 -100" forcerange="-28 28"/>
      </default>
    </default>
  </default>
  <worldbody>
    <light name="spotlight" mode="targetbodycom" target="wrist_2_link" pos="0 -1 2"/>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <site name="world_mark" pos="0.5 0 0"/>
    <body name="base" quat="0 0 0 -1" childclass="ur5e">
      <inertial mass="4.0" pos="0 0 0" diaginertia="0.00443333156 0.00443333156 0.0072"/>
      <body name="shoulder_link" pos="0 0 0.163">
        <inertial mass="3.7" pos="0 0 0" diaginertia="0.0102675 0.0102675 0.00666"/>
        <joint name="shoulder_pan_joint" class="size3" axis="0 0 1"/>
        <body name="upper_arm_link" pos="0 0.138 0" quat="1 0 1 0">
          <inertial mass="8.393" pos="0 0 0.2125" diaginertia="0.133886 0.133886 0.0151074"/>
          <joint name="shoulder_lift_joint" class="size3"/>
          <body name="forearm_link" pos="0 -0.131 0.425">
            <inertial mass="2.275" pos="0 0 0.196" diaginertia="0.0311796 0.0311796 0.004095"/>
            <joint name="elbow_joint" class="size3_limited"/>
            <body name="wrist_1_link" pos="0 0 0.392" quat="1 0 1 0">
              <inertial mass="1.219" pos="0 0.127 0" diaginertia="0.0025599 0.0025599 0.0021942"/>
              <joint name="wrist_1_joint" class="size1"/>
              <body name="wrist_2_link" pos="0 0.127 0">
                <inertial mass="1.219" pos="0 0 0.1" diaginertia="0.0025599 0.0025599 0.0021942"/>
                <joint name="wrist_2_joint" axis="0 0 1" class="size1"/>
                <body name="wrist_3_link" pos="0 0 0.1">
                  <inertial mass="0.1889" pos="0 0.0771683 0" quat="1 0 0 1"
                            diaginertia="0.000132134 9.90863e-05 9.90863e-05"/>
                  <joint name="wrist_3_joint" class="size1" limited="false"/>
                  <site name="attachment_site" pos="0 0.1 0" quat="-1 1 0 0"/>
                </body>
              </body>
            </body>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <general class="size3" name="shoulder_pan" joint="shoulder_pan_joint"/>
    <general class="size3" name="shoulder_lift" joint="shoulder_lift_joint"/>
    <general class="size3_limited" name="elbow" joint="elbow_joint"/>
    <general class="size1" name="wrist_1" joint="wrist_1_joint"/>
    <general class="size1" name="wrist_2" joint="wrist_2_joint"/>
    <motor name="wrist_3" joint="wrist_3_joint" gear="2" ctrlrange="-7 7"/>
    <general name="wrist_3_assist" joint="wrist_3_joint" biastype="none" gainprm="3"
             ctrlrange="-1 1" forcerange="-100 100"/>
  </actuator>
</mujoco>
"""

PANDA = """\
<mujoco model="panda">
 <compiler angle="radian" autolimits="true"/>
 <default>
  <default class="panda">
   <joint armature="0.1" damping="1" axis="0 0 1" range="-2.8973 2.8973"/>
   <default class="finger">
    <joint axis="0 1 0" type="slide" range="0 0.04" damping="3" armature="0.01"/>
   </default>
  </default>
 </default>
 <worldbody>
  <body name="table" pos="0.5 0 -0.4">
   <inertial mass="20" pos="0 0 0" diaginertia="1 1 1"/>
   <site name="table_corner" pos="0.3 0.3 0.4"/>
  </body>
  <body name="link0" childclass="panda" pos="0.2 -0.1 0.05">
   <inertial mass="0.629769" pos="-0.041018 -0.00014 0.049974"
        fullinertia="0.00315 0.00388 0.004285 8.2904e-07 0.00015 8.2299e-06"/>
   <body name="link1" pos="0 0 0.333">
    <inertial mass="4.970684" pos="0.003875 0.002081 -0.04762"
         fullinertia="0.70337 0.70661 0.0091170 -0.00013900 0.0067720 0.019169"/>
    <joint name="joint1" actuatorfrcrange="-87 87"/>
    <body name="link2" quat="1 -1 0 0">
     <inertial mass="0.646926" pos="-0.003141 -0.02872 0.003495"
          fullinertia="0.0079620 2.8110e-02 2.5995e-02 -3.925e-03 1.0254e-02 7.04e-04"/>
     <joint name="joint2" range="-1.7628 1.7628" actuatorfrcrange="-87 87"/>
     <body name="link3" pos="0 -0.316 0" quat="1 1 0 0">
      <joint name="joint3" actuatorfrcrange="-87 87"/>
      <inertial mass="3.228604" pos="2.7518e-02 3.9252e-02 -6.6502e-02"
           fullinertia="3.7242e-02 3.6155e-02 1.0830e-02 -4.761e-03 -1.1396e-02 -1.2805e-02"/>
      <body name="link4" pos="0.0825 0 0" quat="1 1 0 0">
       <inertial mass="3.587895" pos="-5.317e-02 1.04419e-01 2.7454e-02"
            fullinertia="2.5853e-02 1.9552e-02 2.8323e-02 7.796e-03 -1.332e-03 8.641e-03"/>
       <joint name="joint4" range="-3.0718 -0.0698" actuatorfrcrange="-87 87"/>
       <body name="link5" pos="-0.0825 0.384 0" quat="1 -1 0 0">
        <inertial mass="1.225946" pos="-1.1953e-02 4.1065e-02 -3.8437e-02"
             fullinertia="3.5549e-02 2.9474e-02 8.627e-03 -2.117e-03 -4.037e-03 2.29e-04"/>
        <joint name="joint5" actuatorfrcrange="-12 12"/>
        <body name="link6" quat="1 1 0 0">
         <inertial mass="1.666555" pos="6.0149e-02 -1.4117e-02 -1.0517e-02"
              fullinertia="1.964e-03 4.354e-03 5.433e-03 1.09e-04 -1.158e-03 3.41e-04"/>
         <joint name="joint6" range="-0.0175 3.7525" actuatorfrcrange="-12 12"/>
         <body name="link7" pos="0.088 0 0" quat="1 1 0 0">
          <inertial mass="7.35522e-01" pos="1.0517e-02 -4.252e-03 6.1597e-02"
               fullinertia="1.2516e-02 1.0027e-02 4.815e-03 -4.28e-04 -1.196e-03 -7.41e-04"/>
          <joint name="joint7" actuatorfrcrange="-12 12"/>
          <body name="hand" pos="0 0 0.107" quat="0.9238795 0 0 -0.3826834">
           <inertial mass="0.73" pos="-0.01 0 0.03" diaginertia="0.001 0.0025 0.0017"/>
           <site name="tcp" pos="0 0 0.1034"/>
           <body name="left_finger" pos="0 0 0.0584">
            <inertial mass="0.015" pos="0 0 0" diaginertia="2.375e-06 2.375e-06 7.5e-07"/>
            <joint name="finger_joint1" class="finger"/>
           </body>
           <body name="right_finger" pos="0 0 0.0584" quat="0 0 0 1">
            <inertial mass="0.015" pos="0 0 0" diaginertia="2.375e-06 2.375e-06 7.5e-07"/>
            <joint name="finger_joint2" class="finger"/>
           </body>
          </body>
         </body>
        </body>
       </body>
      </body>
     </body>
    </body>
   </body>
  </body>
 </worldbody>
</mujoco>
"""

#: Degrees (the default), eulerseq, every orientation form, a joint pos, a ref, a slide.
ORIENTATIONS = """\
<mujoco model="orientations">
  <compiler eulerseq="zYx"/>
  <worldbody>
    <body name="base" pos="0.1 0.2 0.3" euler="10 20 30">
      <inertial mass="4" pos="0 0 0.05" diaginertia="0.01 0.01 0.01"/>
      <body name="l1" pos="0 0 0.16" axisangle="1 1 0 30">
        <inertial mass="3.7" pos="0 0.01 0" euler="5 -10 15" diaginertia="0.01 0.012 0.006"/>
        <joint name="j1" axis="0 0 1" range="-90 90" pos="0.01 0.02 0.03"/>
        <body name="l2" pos="0 0.13 0" xyaxes="0 1 0 -1 0 1">
          <inertial mass="8.4" pos="0 0 0.2" quat="0.9 0.1 0.2 0.3" diaginertia="0.13 0.13 0.015"/>
          <joint name="j2" axis="0 1 1" ref="20" damping="0.3"/>
          <body name="l3" pos="0 -0.1 0.42" zaxis="1 2 3">
            <inertial mass="2.3" pos="0 0 0.2" diaginertia="0.03 0.03 0.004"/>
            <joint name="j3" axis="1 0 0" type="slide" range="-0.1 0.2" ref="0.05"/>
            <site name="tip" pos="0 0 0.1" euler="0 90 0"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

#: A 3-joint arm of 4.5 kg whose bodies sit in frames (nested, turned, with a childclass); a
#: joint and a site placed by their class inside a turned frame.
FRAMES = """\
<mujoco model="frames">
  <compiler angle="radian"/>
  <default>
    <joint damping="0.2" axis="1 0 0"/>
    <default class="soft">
      <joint damping="2" armature="0.05" frictionloss="0.1"/>
      <site pos="0 0.01 0.02"/>
    </default>
  </default>
  <worldbody>
    <frame pos="0.3 0 0.1" euler="0 0 1.5707963267948966">
      <body name="base">
        <inertial pos="0 0 0.05" mass="1" diaginertia="0.01 0.01 0.01"/>
        <frame pos="0 0 0.1" quat="0.9 0 0.1 0.2" childclass="soft">
          <site name="mark" pos="0.01 0 0"/>
          <site name="mark2"/>
          <body name="l1">
            <joint name="j1" axis="0 0 1"/>
            <inertial pos="0 0 0.1" mass="1.5" diaginertia="0.02 0.02 0.004"/>
            <frame pos="0 0 0.3">
              <frame euler="0.3 0 0">
                <body name="l2">
                  <joint name="j2" axis="0 1 0" class="main" range="-2 2"/>
                  <inertial pos="0 0 0.15" mass="1.2" diaginertia="0.03 0.03 0.003"/>
                  <body name="l3" pos="0 0 0.3">
                    <frame pos="0 0.02 0" axisangle="0 0 1 0.5">
                      <joint name="j3" pos="0 0 0.01"/>
                    </frame>
                    <inertial pos="0 0 0.1" mass="0.8" diaginertia="0.01 0.01 0.002"/>
                    <frame pos="0 0 0.2" zaxis="0 1 1">
                      <site name="tip"/>
                    </frame>
                  </body>
                </body>
              </frame>
            </frame>
          </body>
        </frame>
      </body>
    </frame>
  </worldbody>
</mujoco>
"""

#: A turned base, an arm joint and three replicated fingers (nested replicate: 2 × 2 pads).
REPLICATE = """\
<mujoco model="replicate">
  <compiler angle="degree"/>
  <default><joint damping="0.4" armature="0.02"/></default>
  <worldbody>
    <body name="base" pos="0 0 0.2" quat="0 0 0 -1">
      <inertial pos="0 0 0" mass="2" diaginertia="0.01 0.01 0.01"/>
      <joint name="wrist" axis="0 0 1"/>
      <replicate count="3" euler="0 0 120" sep="-">
        <body name="finger" pos="0.05 0 0.02">
          <joint name="knuckle" axis="0 1 0" range="-30 60"/>
          <inertial pos="0.02 0 0" mass="0.1" diaginertia="1e-4 1e-4 5e-5"/>
          <replicate count="2" offset="0.01 0 0.005">
            <replicate count="2" offset="0 0.004 0" euler="0 0 10">
              <site name="pad" pos="0.03 0 0"/>
            </replicate>
          </replicate>
        </body>
      </replicate>
    </body>
  </worldbody>
</mujoco>
"""

#: Inertias from primitive geoms (no <inertial>), a fromto geom in a frame, two joints in
#: one body (a chain of one-joint bodies here), the second with a ref.
GEOMS = """\
<mujoco model="geoms">
  <compiler angle="radian"/>
  <default><geom density="800"/></default>
  <worldbody>
    <body name="a">
      <joint name="j1" axis="0 0 1"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      <frame pos="0 0 0.05" euler="0.2 0 0">
        <geom type="box" pos="0.3 0 0" size="0.02 0.03 0.04" mass="0.5" euler="0.1 0.2 0.3"/>
        <geom type="cylinder" fromto="0 0 0 0 0.2 0.1" size="0.01"/>
      </frame>
      <body name="b" pos="0.3 0 0">
        <joint name="j2" axis="0 1 0"/>
        <geom type="sphere" size="0.05" pos="0.1 0 0"/>
        <geom type="cylinder" size="0.02 0.1" pos="0.2 0 0" quat="1 0 1 0"/>
        <geom type="ellipsoid" size="0.02 0.03 0.05" pos="0.3 0 0"/>
        <body name="c" pos="0.3 0 0" euler="0 0.4 0">
          <joint name="j3a" axis="0 1 0" damping="0.7"/>
          <joint name="j3b" axis="1 0 1" pos="0 0 0.05" ref="0.3" armature="0.01"/>
          <inertial pos="0.1 0 0" mass="1" diaginertia="0.01 0.012 0.014"/>
          <site name="tip" pos="0.2 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

MODELS = {
    "geoms": GEOMS,
    "ur5e": UR5E,
    "panda": PANDA,
    "orientations": ORIENTATIONS,
    "frames": FRAMES,
    "replicate": REPLICATE,
}


def _write(folder: Path, name: str, text: str) -> Path:
    path = folder / f"{name}.xml"
    path.write_text(text)
    return path


def _effort_limits(mj: object) -> np.ndarray:
    """The bound of each joint's torque by MuJoCo's compiled model: its actuatorfrcrange
    when limited, and the sum over the actuators acting on it of |gear| times their force
    bound (forcerange; gain × ctrlrange when the force is a fixed gain times the control)."""
    joint_limit = np.where(mj.jnt_actfrclimited, mj.jnt_actfrcrange[:, 1], np.inf)
    total = np.full(mj.njnt, np.inf)
    acted = np.zeros(mj.njnt, dtype=bool)
    sums = np.zeros(mj.njnt)
    for a in range(mj.nu):
        joint_types = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))
        if int(mj.actuator_trntype[a]) not in joint_types:
            continue
        joint = mj.actuator_trnid[a, 0]
        bound = mj.actuator_forcerange[a, 1] if mj.actuator_forcelimited[a] else np.inf
        plain = (
            int(mj.actuator_gaintype[a]) == int(mujoco.mjtGain.mjGAIN_FIXED)
            and int(mj.actuator_biastype[a]) == int(mujoco.mjtBias.mjBIAS_NONE)
            and int(mj.actuator_dyntype[a]) == int(mujoco.mjtDyn.mjDYN_NONE)
        )
        if plain and mj.actuator_ctrllimited[a]:
            bound = min(bound, abs(mj.actuator_gainprm[a, 0]) * mj.actuator_ctrlrange[a, 1])
        sums[joint] += abs(mj.actuator_gear[a, 0]) * bound
        acted[joint] = True
    total[acted] = sums[acted]
    return np.minimum(joint_limit, total)


def _compare(path: Path, seed: int = 7) -> dict[str, float]:
    """Max differences to MuJoCo at 3 random states; asserts the joint data are MuJoCo's."""
    robot = load_robot(path, lock_off_chain=False)
    model, data = robot.model, robot.model.createData()
    mj = mujoco.MjModel.from_xml_path(str(path))
    md = mujoco.MjData(mj)
    names = [mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(mj.njnt)]
    assert sorted(model.names[1:]) == sorted(names)
    iq = np.array([model.idx_qs[model.getJointId(n)] for n in names])
    iv = np.array([model.idx_vs[model.getJointId(n)] for n in names])
    limited = mj.jnt_limited.astype(bool)
    np.testing.assert_array_equal(
        model.lowerPositionLimit[iq], np.where(limited, mj.jnt_range[:, 0], -np.inf)
    )
    np.testing.assert_array_equal(
        model.upperPositionLimit[iq], np.where(limited, mj.jnt_range[:, 1], np.inf)
    )
    np.testing.assert_array_equal(model.effortLimit[iv], _effort_limits(mj))
    np.testing.assert_array_equal(model.damping[iv], mj.dof_damping)
    np.testing.assert_array_equal(model.friction[iv], mj.dof_frictionloss)
    np.testing.assert_array_equal(model.armature[iv], mj.dof_armature)
    rng = np.random.default_rng(seed)
    errors = {"pose": 0.0, "M": 0.0, "bias": 0.0}
    objects = (
        (mujoco.mjtObj.mjOBJ_BODY, mj.nbody, "xpos", "xmat"),
        (mujoco.mjtObj.mjOBJ_SITE, mj.nsite, "site_xpos", "site_xmat"),
    )
    for _ in range(3):
        md.qpos[:] = rng.uniform(-1.0, 1.0, mj.nq)
        md.qvel[:] = rng.uniform(-2.0, 2.0, mj.nv)
        mujoco.mj_forward(mj, md)
        q, v = np.zeros(model.nq), np.zeros(model.nv)
        q[iq], v[iv] = md.qpos, md.qvel
        pin.framesForwardKinematics(model, data, q)
        for kind, count, xpos, xmat in objects:
            for i in range(count):
                name = mujoco.mj_id2name(mj, kind, i)
                assert model.existFrame(name), f"{name} of {path.name} is not a frame"
                placement = data.oMf[model.getFrameId(name)]
                errors["pose"] = max(
                    errors["pose"],
                    float(np.abs(placement.translation - getattr(md, xpos)[i]).max()),
                    float(np.abs(placement.rotation - getattr(md, xmat)[i].reshape(3, 3)).max()),
                )
        full = np.zeros((mj.nv, mj.nv))
        mujoco.mj_fullM(mj, md, full)
        mass = pin.crba(model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        errors["M"] = max(errors["M"], float(np.abs(mass[np.ix_(iv, iv)] - full).max()))
        bias = pin.rnea(model, data, q, v, np.zeros(model.nv))
        errors["bias"] = max(errors["bias"], float(np.abs(bias[iv] - md.qfrc_bias).max()))
    return errors


@pytest.mark.parametrize("name", sorted(MODELS))
def test_bodies_mass_matrix_and_bias_forces_are_mujocos(tmp_path: Path, name: str) -> None:
    errors = _compare(_write(tmp_path, name, MODELS[name]))
    assert max(errors.values()) <= TOL, errors


def test_the_ur5e_base_turn_is_kept(tmp_path: Path) -> None:
    """Pinocchio 4.1 alone drops quat="0 0 0 -1" of the jointless base (issue #2782): the
    tip would be at (-x, -y, z) of MuJoCo's. Here it is at MuJoCo's."""
    path = _write(tmp_path, "ur5e", UR5E)
    robot = load_robot(path, tip="attachment_site")
    mj = mujoco.MjModel.from_xml_path(str(path))
    md = mujoco.MjData(mj)
    mujoco.mj_forward(mj, md)
    site = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_SITE, "attachment_site")
    np.testing.assert_allclose(robot.tip_position(np.zeros(6)), md.site_xpos[site], atol=1e-12)
    tip = robot.tip_position(np.zeros(6))
    raw = pin.buildModelFromMJCF(str(path))  # Pinocchio's parser on the file as it is
    raw_data = raw.createData()
    pin.framesForwardKinematics(raw, raw_data, np.zeros(6))
    raw_tip = raw_data.oMf[raw.getFrameId("attachment_site")].translation
    if not np.allclose(raw_tip, tip, atol=1e-12):  # pin 4.1.0: the base's turn is dropped
        np.testing.assert_allclose(raw_tip, tip * [-1, -1, 1], atol=1e-12)
    lower, upper = robot.position_limits
    assert math.isinf(lower[5]) and math.isinf(upper[5])  # limited="false"
    assert lower[2] == -3.1415 and upper[0] == 6.28319
    # actuators: forcerange 150 (actuatorfrcrange 200 is looser), 28, and on the last joint a
    # motor (gear 2 × ctrl 7) plus a general actuator (gain 3 × ctrl 1): 14 + 3
    np.testing.assert_array_equal(robot.effort_limits, [150, 150, 150, 28, 28, 17])


def test_robots_check_counts_the_frames_arms_joints_and_mass(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The bodies inside <frame> are all there: 3 joints, 4.5 kg, no warning."""
    path = _write(tmp_path, "frames", FRAMES)
    assert main(["robots", "--check", str(path), "--tip", "tip"]) == 0
    out = capsys.readouterr().out
    assert "joints: 3 moving" in out and "total mass: 4.5 kg" in out
    assert "warnings: none" in out


def test_replicated_names_are_mujocos(tmp_path: Path) -> None:
    robot = load_robot(_write(tmp_path, "replicate", REPLICATE), lock_off_chain=False)
    assert list(robot.model.names[1:]) == ["wrist", "knuckle-0", "knuckle-1", "knuckle-2"]
    pads = [f.name for f in robot.model.frames if f.name.startswith("pad")]
    assert pads == [f"pad{i}{j}-{k}" for k in range(3) for j in range(2) for i in range(2)]


def test_locked_fingers_keep_each_joints_damping(tmp_path: Path) -> None:
    """Locking the Panda's fingers (off the chain to 'tcp') keeps each remaining joint's
    damping, friction, armature and limits, in order."""
    path = _write(tmp_path, "panda", PANDA)
    robot = load_robot(path, tip="tcp")
    assert robot.nv == 7
    np.testing.assert_array_equal(robot.model.damping, np.ones(7))
    np.testing.assert_array_equal(robot.model.armature, np.full(7, 0.1))
    np.testing.assert_array_equal(robot.effort_limits, [87, 87, 87, 87, 12, 12, 12])
    lower, upper = robot.position_limits
    assert (lower[3], upper[3]) == (-3.0718, -0.0698)


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (
            ('<joint name="j1" axis="0 0 1"/>', '<joint name="j1" actuatorfrcrange="-1 2"/>'),
            r"frames.xml: joint 'j1': the torque MuJoCo lets act on it .* is \[-1, 2\], not symm",
        ),
        (
            (
                "</worldbody>",
                '</worldbody><actuator><motor joint="j2" ctrlrange="0 1"/></actuator>',
            ),
            r"frames.xml: joint 'j2': the torque MuJoCo lets act on it .* is \[0, 1\], not symm",
        ),
        (
            ('<compiler angle="radian"/>', '<compiler angle="radian" settotalmass="10"/>'),
            r"frames.xml: <compiler settotalmass='10'>: MuJoCo changes the bodies' masses",
        ),
        (
            (
                '<compiler angle="radian"/>',
                '<compiler angle="radian"/><option gravity="0 0 -1.62"/>',
            ),
            r"frames.xml: <option gravity='0 0 -1.62'>: the toolkit simulates gravity",
        ),
        (
            ('<compiler angle="radian"/>', '<compiler angle="radian" autolimits="false"/>'),
            r"frames.xml: joint 'j2' has range but no limited, and <compiler autolimits=\"false\">",
        ),
        (
            ('<site name="mark" pos="0.01 0 0"/>', '<attach model="hand" prefix="h_"/>'),
            r"frames.xml: <attach model='hand' prefix='h_'>: the attached model",
        ),
        (
            (
                '<site name="mark" pos="0.01 0 0"/>',
                '<site name="mark" quat="1 0 0 0" euler="0 0 1"/>',
            ),
            r"frames.xml: <site name='mark'> gives several orientations \(quat, euler\)",
        ),
    ],
)
def test_what_cannot_be_honoured_is_refused(
    tmp_path: Path, edit: tuple[str, str], match: str
) -> None:
    assert edit[0] in FRAMES
    path = _write(tmp_path, "frames", FRAMES.replace(*edit))
    with pytest.raises(RobotError, match=match):
        load_robot(path, lock_off_chain=False)


def test_springs_are_warned_about(tmp_path: Path) -> None:
    text = FRAMES.replace('<joint name="j1" axis="0 0 1"/>', '<joint name="j1" stiffness="3"/>')
    with pytest.warns(ModelWarning, match=r"joint stiffness \(springs\) of 'j1' is not modelled"):
        load_robot(_write(tmp_path, "frames", text))


def test_the_replay_draws_the_geoms_where_mujoco_puts_them(tmp_path: Path) -> None:
    """The visual geometry is built from the same rewritten file: a box on the UR5e's last
    link and one inside a frame are where MuJoCo places them, the base's turn included."""
    pytest.importorskip("coal")
    from hybrid_force.viz.robot_visuals import visual_geometry

    text = UR5E.replace(
        '<site name="attachment_site"',
        '<geom name="tool" type="box" size="0.01 0.02 0.03" pos="0 0.05 0" contype="0"/>'
        '<frame pos="0 0.02 0" euler="0.3 0 0"><geom name="fin" type="box" size="0.01 0.01 0.01"'
        ' pos="0.02 0 0" contype="0"/></frame><site name="attachment_site"',
    )
    path = _write(tmp_path, "ur5e", text)
    robot = load_robot(path, tip="attachment_site")
    geometry = visual_geometry(robot)
    q = np.array([0.3, -1.0, 0.8, -0.4, 0.9, 0.2])
    data, geometry_data = robot.model.createData(), geometry.createData()
    pin.updateGeometryPlacements(robot.model, data, geometry, geometry_data, q)
    mj = mujoco.MjModel.from_xml_path(str(path))
    md = mujoco.MjData(mj)
    md.qpos[:] = q
    mujoco.mj_forward(mj, md)
    for name in ("tool", "fin"):
        (index,) = [i for i, g in enumerate(geometry.geometryObjects) if g.name.startswith(name)]
        g = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_GEOM, name)
        placement = geometry_data.oMg[index]
        np.testing.assert_allclose(placement.translation, md.geom_xpos[g], atol=1e-12)
        np.testing.assert_allclose(placement.rotation, md.geom_xmat[g].reshape(3, 3), atol=1e-12)


def test_an_uneven_torque_range_is_refused_unless_its_joint_is_locked(tmp_path: Path) -> None:
    """A gripper's motor that only closes (ctrlrange 0 1): fine once its finger is locked
    (off the chain to 'tcp'); refused when the finger is kept moving."""
    text = PANDA.replace(
        "</worldbody>",
        '</worldbody><actuator><motor joint="finger_joint1" ctrlrange="0 1"/></actuator>',
    )
    path = _write(tmp_path, "panda", text)
    assert load_robot(path, tip="tcp").nv == 7
    with pytest.raises(RobotError, match=r"joint 'finger_joint1': .* is \[0, 1\], not symmetric"):
        load_robot(path, tip="tcp", lock_off_chain=False)
