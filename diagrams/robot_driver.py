"""The robot driver emulator: the simulated station behind LCM, as a real Centauro's driver would be.

MakeRobotDriver(scenario, lcm) speaks only LCM (the channels of scenario.hardware): it takes
arm and hand commands and publishes the arms' and hands' status and the chest camera's
images. No ground truth is published. Like a robot's own controller it checks what it
receives: malformed or non-finite commands are counted and dropped (the last good command
is held), every command is saturated to the joint limits, and before the first command, or
when commands stop, it holds its last command (at first the scenario's initial pose).

A driver process can be killed and started again (issue 81's driver restart): DriverState is what it writes as it
runs and what a new driver goes on from, the world (every body's positions and velocities: the robot's, the
fingers', the objects') and the last commands. A real robot's world does not vanish with its driver process; the
emulator's is kept in that file. The controllers inside the station start afresh, from the commands.
"""

import functools
import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from drake import lcmt_iiwa_status, lcmt_image_array, lcmt_schunk_wsg_status
from pydrake.geometry import Meshcat
from pydrake.lcm import DrakeLcmInterface
from pydrake.manipulation import IiwaStatusSender, SchunkWsgStatusSender
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.lcm import LcmInterfaceSystem, LcmPublisherSystem, LcmSubscriberSystem
from pydrake.systems.primitives import ConstantVectorSource, Saturation
from pydrake.systems.sensors import ImageToLcmImageArrayT, PixelType

from diagrams.hardware_station import RobotModel
from diagrams.pick_simulation import SETTLED_S, LiftJudge, station_plant
from diagrams.scenario import Scenario, initial_positions
from diagrams.station import HAND_INSTANCES, MakeStation
from systems.robot_io.lcm_messages import RawMessage, decode_arm_command, decode_hand_command
from systems.robot_io.lcm_safety import MessageMonitor

# The driver's command monitors: the arms' and each hand's (their last commands go into a DriverState).
COMMAND_MONITORS = ("centauro.command", *(f"{name}.command" for name in HAND_INSTANCES.values()))


@dataclass
class DriverState:
    """A driver's world and commands at one moment of its clock (module docstring). SI units: s, m, rad."""

    time_s: float
    plant_state: list[float]  # the plant's positions then velocities
    commands: dict[str, list[float]]  # COMMAND_MONITORS -> the last command (arms: rad; a hand: its opening, m)
    settled_state: list[float] | None = None  # plant_state once the scene had settled (the judge's references)


def world_state(driver: Diagram, context) -> list[float]:
    """The driver's world now (its root context): the plant's positions then velocities."""
    plant = station_plant(driver)
    return plant.GetPositionsAndVelocities(plant.GetMyContextFromRoot(context)).tolist()


def driver_state(driver: Diagram, context, settled_state: list[float] | None) -> DriverState:
    """The driver's state now (its root context)."""
    commands = {}
    for name in COMMAND_MONITORS:
        monitor = driver.GetSubsystemByName(name)
        commands[name] = monitor.GetOutputPort("values").Eval(monitor.GetMyContextFromRoot(context)).tolist()
    return DriverState(context.get_time(), world_state(driver, context), commands, settled_state)


def set_plant_state(driver: Diagram, context, plant_state: list[float], time_s: float):
    """The driver's world put in plant_state, its clock at time_s."""
    plant = station_plant(driver)
    context.SetTime(time_s)
    plant.SetPositionsAndVelocities(plant.GetMyContextFromRoot(context), np.asarray(plant_state, float))


def resume_driver(driver: Diagram, context, state: DriverState, judge: LiftJudge):
    """A new driver (built with state.commands) put where `state` left off: its judge's references taken from the
    scene as the first driver saw it settle (where saved), then its world and clock."""
    if state.settled_state is not None:
        set_plant_state(driver, context, state.settled_state, SETTLED_S)
        judge.sample(SETTLED_S)
    set_plant_state(driver, context, state.plant_state, state.time_s)


def write_driver_state(path: Path, state: DriverState):
    """Written whole or not at all (a driver killed mid-write leaves the last state)."""
    partial = path.with_suffix(".partial")
    partial.write_text(json.dumps(asdict(state)))
    os.replace(partial, path)


def read_driver_state(path: Path, scenario: Scenario) -> DriverState:
    """The state a driver of this scenario wrote; ValueError if it is not one."""
    try:
        state = DriverState(**json.loads(Path(path).read_text()))
    except (OSError, ValueError, TypeError) as error:
        raise ValueError(f"{path}: not a robot driver's state file ({error})") from error
    missing = set(COMMAND_MONITORS) - set(state.commands)
    if missing:
        raise ValueError(f"{path}: a driver state without the commands of {sorted(missing)}")
    joints = len(initial_positions(scenario))
    if len(state.commands["centauro.command"]) != joints:
        raise ValueError(f"{path}: arm commands of {len(state.commands['centauro.command'])} joints, not {joints}")
    return state


def MakeRobotDriver(
    scenario: Scenario,
    lcm: DrakeLcmInterface,
    meshcat: Meshcat | None = None,
    commands: dict[str, list[float]] | None = None,
) -> Diagram:
    """The simulated station wired to LCM; the station is the subsystem "station". commands: what each command
    monitor holds before the first command arrives (a restarted driver's last commands; default: the scenario's
    initial pose and hand opening)."""
    commands = commands or {}
    config = scenario.hardware
    period = config.control_period_s
    model = RobotModel(scenario)
    builder = DiagramBuilder()
    builder.AddNamedSystem("lcm", LcmInterfaceSystem(lcm))
    station = builder.AddNamedSystem("station", MakeStation(scenario, meshcat))

    def publish(source, channel, lcm_type, publish_period):
        publisher = builder.AddNamedSystem(
            f"{channel}.publisher",
            LcmPublisherSystem.Make(channel, lcm_type, lcm, publish_period=publish_period, use_cpp_serializer=True),
        )
        builder.Connect(source, publisher.get_input_port())

    def receive(name, channel, decode, default, lower, upper, station_input):
        subscriber = builder.AddNamedSystem(f"{name}_subscriber", LcmSubscriberSystem.Make(channel, RawMessage, lcm))
        monitor = builder.AddNamedSystem(name, MessageMonitor(channel, decode, default, config.watchdog_s, period))
        limits = builder.AddNamedSystem(f"{name}_limits", Saturation(lower, upper))
        builder.Connect(subscriber.get_output_port(), monitor.GetInputPort("raw"))
        builder.Connect(monitor.GetOutputPort("values"), limits.get_input_port())
        builder.Connect(limits.get_output_port(), station.GetInputPort(station_input))

    # Arms.
    receive(
        "centauro.command", config.arm_command_channel, functools.partial(decode_arm_command, joints=model.n),
        np.asarray(commands.get("centauro.command", initial_positions(scenario)), float), model.lower, model.upper,
        "centauro.position",
    )  # fmt: skip
    status = builder.AddNamedSystem("centauro.status_sender", IiwaStatusSender(model.n))
    for port in ("position_commanded", "position_measured", "velocity_estimated", "torque_commanded"):
        builder.Connect(station.GetOutputPort(f"centauro.{port}"), status.GetInputPort(port))
    publish(status.get_output_port(), config.arm_status_channel, lcmt_iiwa_status, period)

    # Hands.
    no_force = builder.AddNamedSystem("hands.force", ConstantVectorSource([0.0]))
    for side, name in HAND_INSTANCES.items():
        receive(
            f"{name}.command", getattr(config, f"{side}_hand_command_channel"), decode_hand_command,
            np.asarray(commands.get(f"{name}.command", [scenario.initial_hand_width]), float), [0.0],
            [model.hand_upper], f"{name}.position",
        )  # fmt: skip
        hand_status = builder.AddNamedSystem(f"{name}.status_sender", SchunkWsgStatusSender())
        builder.Connect(station.GetOutputPort(f"{name}.state_measured"), hand_status.get_input_port(0))
        builder.Connect(no_force.get_output_port(), hand_status.get_input_port(1))
        publish(
            hand_status.get_output_port(),
            getattr(config, f"{side}_hand_status_channel"),
            lcmt_schunk_wsg_status,
            period,
        )

    # Camera: colour and depth only (the label image is the simulator's ground truth). Not compressed: a real
    # sensor's noisy images hardly compress, and zlib took 0.23 s a frame on them (the camera sends ten a second).
    camera = scenario.camera.name
    images = builder.AddNamedSystem(f"{camera}.image_array", ImageToLcmImageArrayT(do_compress=False))
    color = images.DeclareImageInputPort[PixelType.kRgba8U](f"{camera}_color")
    depth = images.DeclareImageInputPort[PixelType.kDepth32F](f"{camera}_depth")
    builder.Connect(station.GetOutputPort(f"{camera}.rgb_image"), color)
    builder.Connect(station.GetOutputPort(f"{camera}.depth_image"), depth)
    publish(images.image_array_t_msg_output_port(), config.camera_channel, lcmt_image_array, config.camera_period_s)

    diagram = builder.Build()
    diagram.set_name("robot_driver")
    return diagram
