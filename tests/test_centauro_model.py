"""The Centauro SDF matches the spec's kinematics, limits and masses."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import MultibodyPlant

from diagrams.generation.centauro_description import centauro_sdf, sdf_name
from diagrams.paths import SDF_DIR
from diagrams.station import make_parser

# From ../shared/SPEC.md, typed here independently of diagrams/generation/centauro_description.py.
LEFT_LIMITS = [
    (-3.312, 1.615),
    (0.02, 3.431),
    (-2.552, 2.566),
    (-2.465, 0.28),
    (-2.569, 2.562),
    (-1.529, 1.509),
    (-2.565, 2.569),
]
RIGHT_LIMITS = [
    (-3.346, 1.601),
    (-3.426, -0.014),
    (-2.561, 2.561),
    (-2.479, 0.289),
    (-2.539, 2.555),
    (-1.515, 1.516),
    (-2.555, 2.569),
]
VELOCITY = [3.86, 3.86, 6.06, 6.06, 11.72, 11.72, 20.35]
EFFORT = [147, 147, 147, 147, 55, 55, 28.3]
MASS = [1.96, 1.86, 1.67, 1.32, 1.49, 1.13, 0.28]
AXES = ["y", "x", "z", "y", "z", "y", "z"]
LEFT_OFFSETS = [
    (-0.0902, 0.062, 0),
    (0.0902, 0, -0.2182),
    (0.045, 0.0552, -0.074),
    (-0.015, -0.0552, -0.095),
    (0, 0.049, -0.156),
    (0, -0.049, -0.174),
]


@pytest.fixture(scope="module")
def plant():
    plant = MultibodyPlant(0.0)
    make_parser(plant).AddModels(url="package://dualarm/centauro/centauro.sdf")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("pelvis"))
    plant.Finalize()
    return plant


@pytest.mark.parametrize("torso", [True, False])
def test_sdf_files_are_up_to_date(torso):
    path = SDF_DIR / "centauro" / sdf_name(torso)
    assert path.read_text() == centauro_sdf(torso), "run scripts/generate_centauro_sdf.py"


def test_torso_yaw_is_planned_or_locked(plant):
    """The spec's torso: a revolute joint about z at pelvis + (0.2, 0, 0.256), +-2.618 rad, turning both arms
    and the camera; welded in the locked model."""
    joint = plant.GetJointByName("torso_yaw")
    np.testing.assert_allclose(joint.revolute_axis(), [0, 0, 1])
    assert joint.position_lower_limits()[0] == pytest.approx(-2.618)
    assert joint.position_upper_limits()[0] == pytest.approx(2.618)
    context = plant.CreateDefaultContext()
    mount = plant.GetFrameByName("camera_mount")
    before = [plant.GetBodyByName(f"arm{a}_1").EvalPoseInWorld(context) for a in (1, 2)]
    camera_before = mount.CalcPoseInWorld(context)
    joint.set_angle(context, 0.5)
    turn = (
        RigidTransform([0.2, 0, 0.256])
        @ RigidTransform(RollPitchYaw(0, 0, 0.5).ToRotationMatrix())
        @ RigidTransform([-0.2, 0, -0.256])
    )
    for arm, X_before in zip((1, 2), before, strict=True):
        X_after = plant.GetBodyByName(f"arm{arm}_1").EvalPoseInWorld(context)
        assert X_after.IsNearlyEqualTo(turn @ X_before, 1e-9)
    assert mount.CalcPoseInWorld(context).IsNearlyEqualTo(turn @ camera_before, 1e-9)
    locked = MultibodyPlant(0.0)
    make_parser(locked).AddModels(url=f"package://dualarm/centauro/{sdf_name(False)}")
    locked.WeldFrames(locked.world_frame(), locked.GetFrameByName("pelvis"))
    locked.Finalize()
    assert locked.num_positions() == 14


@pytest.mark.parametrize("arm,limits", [(1, LEFT_LIMITS), (2, RIGHT_LIMITS)])
def test_joint_limits_velocities_efforts_masses(plant, arm, limits):
    assert plant.num_positions() == 15  # the arms and the torso yaw
    for i in range(7):
        joint = plant.GetJointByName(f"j_arm{arm}_{i + 1}")
        assert joint.position_lower_limits()[0] == pytest.approx(limits[i][0])
        assert joint.position_upper_limits()[0] == pytest.approx(limits[i][1])
        assert joint.velocity_upper_limits()[0] == pytest.approx(VELOCITY[i])
        actuator = plant.GetJointActuatorByName(f"j_arm{arm}_{i + 1}")
        assert actuator.effort_limit() == pytest.approx(EFFORT[i])
        assert plant.GetBodyByName(f"arm{arm}_{i + 1}").default_mass() == pytest.approx(MASS[i])
        axis = {"x": [1, 0, 0], "y": [0, 1, 0], "z": [0, 0, 1]}[AXES[i]]
        np.testing.assert_allclose(joint.revolute_axis(), axis)


@pytest.mark.parametrize("arm", [1, 2])
def test_joint_offsets_mirror_the_left_arm(plant, arm):
    context = plant.CreateDefaultContext()
    sign = 1 if arm == 1 else -1
    X_TM = plant.GetBodyByName(f"arm{arm}_1").EvalPoseInWorld(context)
    X_WT = plant.GetBodyByName("torso").EvalPoseInWorld(context)
    expected_mount = RigidTransform(RollPitchYaw(sign * 0.1745, 0, sign * -0.5236), [0.0457, sign * 0.1691, 0.1166])
    assert (X_WT.inverse() @ X_TM).IsNearlyEqualTo(expected_mount, 1e-9)
    for i, offset in enumerate(LEFT_OFFSETS):
        parent = plant.GetBodyByName(f"arm{arm}_{i + 1}").EvalPoseInWorld(context)
        child = plant.GetBodyByName(f"arm{arm}_{i + 2}").EvalPoseInWorld(context)
        expected = np.array(offset) * [1, sign, 1]
        np.testing.assert_allclose((parent.inverse() @ child).translation(), expected, atol=1e-9)
    torso_in_pelvis = plant.GetBodyByName("torso").EvalPoseInWorld(context).translation()
    np.testing.assert_allclose(torso_in_pelvis, [0.2, 0, 0.256])
