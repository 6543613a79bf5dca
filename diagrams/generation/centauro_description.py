"""The Centauro upper body's kinematics and inertias (public numbers), and its SDF.

Frames: the pelvis is welded to the world by the station; the torso sits at
pelvis + (0.2, 0, 0.256) on its yaw joint (axis z), a planned joint, or welded where
a scenario locks it (`robot: {torso: locked}`, the 14-DOF model of the first rounds). Arm 1 is the left arm, arm 2
the right arm; the right arm mirrors the left's y offsets and roll/yaw signs.
Each arm ends in a flange frame `arm{1,2}_flange` whose z axis points out of the
wrist (the approach direction); the hands are welded there.
"""

from dataclasses import dataclass

import numpy as np

TORSO_IN_PELVIS = (0.2, 0.0, 0.256)
TORSO_JOINT = "torso_yaw"
TORSO_LIMITS = (-2.618, 2.618)  # rad
TORSO_VELOCITY = 1.0  # rad/s: the whole upper body turns, kept slow
TORSO_EFFORT = 147.0  # N m
# Left arm mount in the torso frame: xyz (m), rpy (rad).
LEFT_MOUNT_XYZ = (0.0457, 0.1691, 0.1166)
LEFT_MOUNT_RPY = (0.1745, 0.0, -0.5236)
# Distance from the joint-7 frame to the hand flange along -z, in metres.
FLANGE_OFFSET = 0.05


@dataclass(frozen=True)
class ArmJoint:
    """One arm joint, given for the left arm (arm 1)."""

    # Offset of this joint's frame from the previous link's frame (m), left arm.
    xyz: tuple[float, float, float]
    # Rotation of this joint's frame from the previous link's frame (rad), left arm.
    rpy: tuple[float, float, float]
    axis: str
    left_limits: tuple[float, float]
    right_limits: tuple[float, float]
    velocity: float  # rad/s
    effort: float  # N m
    mass: float  # kg, of the link this joint moves
    radius: float  # m, of the link's collision capsule


ARM_JOINTS = (
    ArmJoint(LEFT_MOUNT_XYZ, LEFT_MOUNT_RPY, "y", (-3.312, 1.615), (-3.346, 1.601), 3.86, 147.0, 1.96, 0.055),
    ArmJoint((-0.0902, 0.062, 0.0), (-0.1745, 0.0, 0.0), "x", (0.02, 3.431), (-3.426, -0.014), 3.86, 147.0, 1.86, 0.05),
    ArmJoint((0.0902, 0.0, -0.2182), (0.0, 0.0, 0.0), "z", (-2.552, 2.566), (-2.561, 2.561), 6.06, 147.0, 1.67, 0.05),
    ArmJoint((0.045, 0.0552, -0.074), (0.0, 0.0, 0.0), "y", (-2.465, 0.28), (-2.479, 0.289), 6.06, 147.0, 1.32, 0.045),
    ArmJoint(
        (-0.015, -0.0552, -0.095), (0.0, 0.0, 0.0), "z", (-2.569, 2.562), (-2.539, 2.555), 11.72, 55.0, 1.49, 0.045
    ),
    ArmJoint((0.0, 0.049, -0.156), (0.0, 0.0, 0.0), "y", (-1.529, 1.509), (-1.515, 1.516), 11.72, 55.0, 1.13, 0.04),
    ArmJoint((0.0, -0.049, -0.174), (0.0, 0.0, 0.0), "z", (-2.565, 2.569), (-2.555, 2.569), 20.35, 28.3, 0.28, 0.04),
)
AXES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}


def mirrored(xyz, rpy, arm: int):
    """Returns (xyz, rpy) for arm 1 (left) as given, or mirrored in y for arm 2 (right)."""
    if arm == 1:
        return tuple(xyz), tuple(rpy)
    return (xyz[0], -xyz[1], xyz[2]), (-rpy[0], rpy[1], -rpy[2])


def joint_names(arm: int) -> list[str]:
    return [f"j_arm{arm}_{i}" for i in range(1, 8)]


def robot_joint_names(torso: bool) -> list[str]:
    """The planned joints in the order of every configuration vector: the left arm's 7, the right arm's 7,
    then the torso yaw when it is free (15), or the arms alone when it is locked (14)."""
    return joint_names(1) + joint_names(2) + ([TORSO_JOINT] if torso else [])


def sdf_name(torso: bool) -> str:
    """The generated SDF's file name under sdf/centauro/."""
    return "centauro.sdf" if torso else "centauro_torso_locked.sdf"


def _capsule_pose(offset) -> tuple[np.ndarray, np.ndarray, float]:
    """Centre, rpy and length of a capsule from the origin to `offset`."""
    offset = np.asarray(offset, dtype=float)
    length = float(np.linalg.norm(offset))
    if length < 1e-9:
        return np.zeros(3), np.zeros(3), 0.0
    direction = offset / length
    # Rotation taking z to `direction`: pitch about y, then yaw about z.
    pitch = np.arccos(np.clip(direction[2], -1.0, 1.0))
    yaw = np.arctan2(direction[1], direction[0])
    return offset / 2, np.array([0.0, pitch, yaw]), length


def _fmt(values) -> str:
    return " ".join(f"{v:.6g}" for v in values)


def _link(name, mass, radius, child_offset, color) -> str:
    center, rpy, length = _capsule_pose(child_offset)
    # Solid-cylinder inertia about the capsule's own axis, rotated coarsely: good enough
    # for dynamics of a position-controlled arm.
    ixx = mass * (3 * radius**2 + length**2) / 12
    izz = mass * radius**2 / 2
    geometry = f"<capsule><radius>{radius}</radius><length>{max(length, 1e-3):.6g}</length></capsule>"
    return f"""    <link name="{name}">
      <inertial>
        <pose>{_fmt(center)} {_fmt(rpy)}</pose>
        <mass>{mass}</mass>
        <inertia><ixx>{ixx:.6g}</ixx><iyy>{ixx:.6g}</iyy><izz>{izz:.6g}</izz><ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia>
      </inertial>
      <visual name="visual"><pose>{_fmt(center)} {_fmt(rpy)}</pose><geometry>{geometry}</geometry>
        <material><diffuse>{color}</diffuse></material></visual>
      <collision name="collision"><pose>{_fmt(center)} {_fmt(rpy)}</pose><geometry>{geometry}</geometry></collision>
    </link>
"""


def _arm(arm: int) -> str:
    side = "left" if arm == 1 else "right"
    text = f"    <!-- Arm {arm} ({side}). -->\n"
    parent = "torso"
    for i, joint in enumerate(ARM_JOINTS):
        link = f"arm{arm}_{i + 1}"
        xyz, rpy = mirrored(joint.xyz, joint.rpy, arm)
        if i + 1 < len(ARM_JOINTS):
            child_offset, _ = mirrored(ARM_JOINTS[i + 1].xyz, (0, 0, 0), arm)
        else:
            child_offset = (0.0, 0.0, -FLANGE_OFFSET)
        lower, upper = joint.left_limits if arm == 1 else joint.right_limits
        color = "0.75 0.75 0.78 1" if i % 2 == 0 else "0.2 0.2 0.22 1"
        text += _link(link, joint.mass, joint.radius, child_offset, color)
        text += f"""    <joint name="j_arm{arm}_{i + 1}" type="revolute">
      <pose relative_to="{parent}">{_fmt(xyz)} {_fmt(rpy)}</pose>
      <parent>{parent}</parent>
      <child>{link}</child>
      <axis>
        <xyz>{_fmt(AXES[joint.axis])}</xyz>
        <limit><lower>{lower}</lower><upper>{upper}</upper><velocity>{joint.velocity}</velocity><effort>{joint.effort}</effort></limit>
        <dynamics><damping>0.5</damping></dynamics>
      </axis>
    </joint>
"""
        # The link frame coincides with its joint frame.
        text = text.replace(
            f'<link name="{link}">', f'<link name="{link}">\n      <pose relative_to="j_arm{arm}_{i + 1}"/>', 1
        )
        parent = link
    text += f"""    <frame name="arm{arm}_flange" attached_to="arm{arm}_7">
      <pose relative_to="arm{arm}_7">0 0 {-FLANGE_OFFSET} 3.14159265358979 0 0</pose>
    </frame>
"""
    members = "".join(f"      <drake:member>arm{arm}_{i}</drake:member>\n" for i in range(1, 8))
    text += f"""    <drake:collision_filter_group name="arm{arm}">
{members}      <drake:ignored_collision_filter_group>arm{arm}</drake:ignored_collision_filter_group>
    </drake:collision_filter_group>
"""
    return text


def _torso_joint(torso: bool) -> str:
    if not torso:
        return f"""    <!-- The torso yaw joint is locked: the arms are the 14 degrees of freedom. -->
    <joint name="{TORSO_JOINT}" type="fixed">
      <parent>pelvis</parent>
      <child>torso</child>
    </joint>
"""
    lower, upper = TORSO_LIMITS
    return f"""    <!-- The torso turns about z: 15 degrees of freedom with the arms. -->
    <joint name="{TORSO_JOINT}" type="revolute">
      <parent>pelvis</parent>
      <child>torso</child>
      <axis>
        <xyz>0 0 1</xyz>
        <limit><lower>{lower}</lower><upper>{upper}</upper><velocity>{TORSO_VELOCITY}</velocity><effort>{TORSO_EFFORT}</effort></limit>
        <dynamics><damping>2.0</damping></dynamics>
      </axis>
    </joint>
"""


def centauro_sdf(torso: bool = True) -> str:
    """SDF text of the Centauro upper body: pelvis, torso (on its yaw joint, or welded where `torso` is
    False), head, camera mount, two arms."""
    arms = _arm(1) + _arm(2)
    shoulders = "".join(f"      <drake:member>arm{a}_{i}</drake:member>\n" for a in (1, 2) for i in (1, 2, 3))
    return f"""<?xml version="1.0"?>
<!-- Generated by scripts/generate_centauro_sdf.py from diagrams/generation/centauro_description.py. -->
<sdf version="1.9" xmlns:drake="http://drake.mit.edu">
  <model name="centauro">
    <link name="pelvis">
      <inertial><mass>10</mass><inertia><ixx>0.2</ixx><iyy>0.2</iyy><izz>0.2</izz><ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial>
      <visual name="visual"><geometry><box><size>0.3 0.35 0.15</size></box></geometry>
        <material><diffuse>0.2 0.2 0.22 1</diffuse></material></visual>
      <collision name="collision"><geometry><box><size>0.3 0.35 0.15</size></box></geometry></collision>
    </link>
    <link name="torso">
      <pose relative_to="pelvis">{_fmt(TORSO_IN_PELVIS)} 0 0 0</pose>
      <inertial><pose>-0.05 0 0.1 0 0 0</pose><mass>12</mass><inertia><ixx>0.3</ixx><iyy>0.3</iyy><izz>0.2</izz><ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial>
      <visual name="chest"><pose>-0.06 0 0.1 0 0 0</pose><geometry><box><size>0.2 0.26 0.3</size></box></geometry>
        <material><diffuse>0.75 0.75 0.78 1</diffuse></material></visual>
      <collision name="chest"><pose>-0.06 0 0.1 0 0 0</pose><geometry><box><size>0.2 0.26 0.3</size></box></geometry></collision>
      <visual name="head"><pose>-0.02 0 0.38 0 0 0</pose><geometry><sphere><radius>0.1</radius></sphere></geometry>
        <material><diffuse>0.2 0.2 0.22 1</diffuse></material></visual>
      <collision name="head"><pose>-0.02 0 0.38 0 0 0</pose><geometry><sphere><radius>0.1</radius></sphere></geometry></collision>
      <visual name="rgbd_sensor"><pose>0.06 0 0.22 0 0 0</pose><geometry><box><size>0.06 0.25 0.07</size></box></geometry>
        <material><diffuse>0.05 0.05 0.05 1</diffuse></material></visual>
    </link>
{_torso_joint(torso)}    <!-- RGB-D sensor on the upper chest (the paper's Kinect v2); z along the optical axis. -->
    <frame name="camera_mount" attached_to="torso">
      <pose relative_to="torso">0.095 0 0.22 -2.30 0 -1.5707963267949</pose>
    </frame>
{arms}    <drake:collision_filter_group name="torso_and_shoulders">
      <drake:member>pelvis</drake:member>
      <drake:member>torso</drake:member>
{shoulders}      <drake:ignored_collision_filter_group>torso_and_shoulders</drake:ignored_collision_filter_group>
    </drake:collision_filter_group>
  </model>
</sdf>
"""
