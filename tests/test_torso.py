"""The torso yaw as a planned joint: the station drives it, the camera rides on it, the IK turns it where the
arms alone cannot reach, and a locked torso is the 14-DOF model."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator

from diagrams.hardware_station import RobotModel
from diagrams.planning_scene import make_pick_motions, true_grasp_poses
from diagrams.scenario import initial_positions, load_scenario, planned_joints
from diagrams.station import MakeStation

TORSO_AXIS = np.array([0.2, 0.0, 0.0])  # the spec's torso joint, pelvis + (0.2, 0, 0.256), in the world's xy


def about_torso(yaw: float) -> RigidTransform:
    return RigidTransform(TORSO_AXIS) @ RigidTransform(RotationMatrix.MakeZRotation(yaw)) @ RigidTransform(-TORSO_AXIS)


def test_locked_torso_is_the_arms_alone():
    locked = load_scenario(scenario_text="{robot: {torso: locked}}")
    assert len(planned_joints(locked)) == 14 and len(initial_positions(locked)) == 14
    station = MakeStation(locked)
    assert station.GetInputPort("centauro.position").size() == 14
    assert planned_joints(load_scenario())[-1] == "torso_yaw"
    with pytest.raises(ValueError, match="robot.torso"):
        load_scenario(scenario_text="{robot: {torso: loose}}")


@pytest.mark.slow
def test_the_station_turns_the_torso_and_the_camera_with_it(scenario):
    station = MakeStation(scenario)
    simulator = Simulator(station)
    context = simulator.get_mutable_context()
    X_before = RigidTransform(station.GetOutputPort("camera0.pose").Eval(context))  # a copy: Eval gives the cache
    command = initial_positions(scenario)
    command[-1] = 0.3
    station.GetInputPort("centauro.position").FixValue(context, command)
    for hand in ("left_hand", "right_hand"):
        station.GetInputPort(f"{hand}.position").FixValue(context, [scenario.initial_hand_width])
    simulator.AdvanceTo(1.5)
    q = station.GetOutputPort("centauro.position_measured").Eval(context)
    np.testing.assert_allclose(q, command, atol=0.01)  # the torso turned, the arms held
    X_after = station.GetOutputPort("camera0.pose").Eval(context)
    assert X_after.IsNearlyEqualTo(about_torso(q[-1]) @ X_before, 1e-6)


def test_the_hardware_camera_pose_follows_the_measured_torso(scenario):
    """The LCM station computes the camera's pose from the measured joints as the simulation places it."""
    q = initial_positions(scenario)
    q[-1] = -0.7
    station = MakeStation(scenario)
    context = station.CreateDefaultContext()
    plant = station.GetSubsystemByName("plant")
    plant_context = plant.GetMyMutableContextFromRoot(context)
    plant.GetJointByName("torso_yaw").set_angle(plant_context, q[-1])
    X_sim = station.GetOutputPort("camera0.pose").Eval(context)
    system = RobotModel(scenario).camera_pose_system()
    system_context = system.CreateDefaultContext()
    system.get_input_port().FixValue(system_context, q)
    X_hw = system.GetOutputPort("camera_pose").Eval(system_context)
    np.testing.assert_allclose(X_hw.GetAsMatrix4(), X_sim.GetAsMatrix4(), atol=1e-12)
    system.get_input_port().FixValue(system_context, np.full(len(q), np.nan))  # no status yet: a finite pose
    assert np.all(np.isfinite(system.GetOutputPort("camera_pose").Eval(system_context).GetAsMatrix4()))


@pytest.mark.parametrize("yaw", [1.6, -1.6])
def test_ik_turns_the_torso_where_the_arms_alone_cannot_reach(scenario, yaw):
    """The test can's pre-grasps turned 1.6 rad about the torso's axis (beside the robot): out of the arms'
    reach with the torso straight, reached with it turned."""
    targets = {side: about_torso(yaw) @ X for side, X in true_grasp_poses(scenario).items() if "pregrasp" in side}
    targets = {side.removesuffix("_pregrasp"): X for side, X in targets.items()}
    locked = load_scenario(scenario_text="{robot: {torso: locked}}")
    assert not make_pick_motions(locked).ik.solve(targets, initial_positions(locked), restarts=12).success
    motions = make_pick_motions(scenario)
    result = motions.ik.solve(targets, initial_positions(scenario), restarts=12)
    assert result.success, result.message
    assert abs(result.q[-1] - yaw) < 0.5
    for side, X in motions.world.grasp_frame_poses(result.q).items():
        np.testing.assert_allclose(X.translation(), targets[side].translation(), atol=0.003)
    assert not motions.world.in_collision(result.q)
