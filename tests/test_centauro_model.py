"""The Centauro SDF matches the spec's kinematics, limits and masses."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import MultibodyPlant

from diagrams.generation.centauro_description import centauro_sdf
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


def test_sdf_file_is_up_to_date():
    assert (SDF_DIR / "centauro" / "centauro.sdf").read_text() == centauro_sdf(), "run scripts/generate_centauro_sdf.py"


@pytest.mark.parametrize("arm,limits", [(1, LEFT_LIMITS), (2, RIGHT_LIMITS)])
def test_joint_limits_velocities_efforts_masses(plant, arm, limits):
    assert plant.num_positions() == 14
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
