"""The simulated station: ports by name, a short simulation, the camera sees the object."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from diagrams.scenario import load_scenario
from diagrams.station import MakeStation, true_label_image
from systems.gravity_compensation import GravityCompensation

INPUTS = {"centauro.position", "left_hand.position", "right_hand.position"}
OUTPUTS = {
    "centauro.position_commanded",
    "centauro.position_measured",
    "centauro.velocity_estimated",
    "centauro.state_estimated",
    "centauro.torque_commanded",
    "left_hand.state_measured",
    "right_hand.state_measured",
    "camera0.rgb_image",
    "camera0.depth_image",
    "camera0.pose",
}


@pytest.fixture(scope="module")
def station(scenario):
    return MakeStation(scenario)


def fix_inputs(station, context, scenario):
    station.GetInputPort("centauro.position").FixValue(context, np.array(scenario.initial_arm_positions))
    for hand in ("left_hand", "right_hand"):
        station.GetInputPort(f"{hand}.position").FixValue(context, [scenario.initial_hand_width])


def test_ports_exist_by_name(station):
    inputs = {station.get_input_port(i).get_name() for i in range(station.num_input_ports())}
    outputs = {station.get_output_port(i).get_name() for i in range(station.num_output_ports())}
    assert inputs == INPUTS
    assert outputs == OUTPUTS
    for name in ("plant", "scene_graph", "centauro.gravity_compensation", "camera0.sensor"):
        assert station.HasSubsystemNamed(name)


def test_short_simulation_holds_the_arms_still(station, scenario):
    simulator = Simulator(station)
    context = simulator.get_mutable_context()
    fix_inputs(station, context, scenario)
    simulator.AdvanceTo(0.3)
    q = station.GetOutputPort("centauro.position_measured").Eval(context)
    # Gravity feed-forward + PD: the arms stay within 0.01 rad of the command.
    np.testing.assert_allclose(q, scenario.initial_arm_positions, atol=0.01)
    width, _ = station.GetOutputPort("left_hand.state_measured").Eval(context)
    assert width == pytest.approx(scenario.initial_hand_width, abs=0.005)
    torque = station.GetOutputPort("centauro.torque_commanded").Eval(context)
    assert np.all(np.isfinite(torque)) and np.abs(torque[0]) > 0.1


def test_camera_sees_the_object(station):
    context = station.CreateDefaultContext()
    plant = station.GetSubsystemByName("plant")
    object_body = plant.GetBodyIndices(plant.GetModelInstanceByName("object"))[0]
    labels = true_label_image(station, context)
    object_pixels = np.count_nonzero(labels == int(object_body))
    assert object_pixels > 2000, f"the object covers only {object_pixels} pixels"
    depth = np.asarray(station.GetOutputPort("camera0.depth_image").Eval(context).data)[:, :, 0]
    object_depth = depth[labels == int(object_body)]
    assert 0.4 < np.median(object_depth) < 1.2  # metres from the chest camera


def test_drill_station_builds():
    scenario = load_scenario(scenario_text="object: {category: drill, instance: train_3}")
    station = MakeStation(scenario)
    plant = station.GetSubsystemByName("plant")
    assert plant.HasModelInstanceNamed("object")


def test_gravity_compensation_alone_cancels_gravity(station):
    plant = station.GetSubsystemByName("plant")
    robot = plant.GetModelInstanceByName("centauro")
    dut = GravityCompensation(plant, robot)
    context = dut.CreateDefaultContext()
    plant_context = plant.CreateDefaultContext()
    x = plant.GetPositionsAndVelocities(plant_context)
    dut.GetInputPort("state").FixValue(context, x)
    tau = dut.GetOutputPort("actuation").Eval(context)
    tau_g = plant.CalcGravityGeneralizedForces(plant_context)
    arm_dofs = [plant.GetJointByName(f"j_arm{a}_{i}").velocity_start() for a in (1, 2) for i in range(1, 8)]
    np.testing.assert_allclose(tau, -tau_g[arm_dofs], atol=1e-9)
    assert np.linalg.norm(tau) > 1.0
