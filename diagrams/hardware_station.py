"""The hardware station: the simulated station's ports, served over LCM by a robot (or scripts/robot_driver.py).

MakeHardwareStation(scenario) has exactly the ports of diagrams/station.py's MakeStation
(a test asserts it). Channels, periods and safety limits are scenario.hardware fields; the
bus is scenario.lcm.

  centauro.position      -> CommandGuard -> CommandStreamSender ~> a streamer process -> arm_command_channel
                            (lcmt_iiwa_command every control period, whatever this process is doing; on an
                            in-process memq:// bus, IiwaCommandSender -> LcmPublisherSystem)
  arm_status_channel     -> MessageMonitor -> centauro.position_measured, ... (lcmt_iiwa_status)
  <side>_hand.position   -> CommandGuard -> SchunkWsgCommandSender -> <side>_hand_command_channel
  <side>_hand_status_channel -> MessageMonitor -> <side>_hand.state_measured (width m, rate m/s)
  camera_channel         -> ImageMonitor -> camera0.rgb_image, camera0.depth_image (lcmt_image_array)
  camera0.pose           <- the robot model at the measured joints: the camera rides on the torso

Received messages are decoded with checks (malformed ones are counted and dropped); commands
leave only after a status has arrived, within the position and velocity limits, and hold when
the status stops (systems/robot_io/lcm_safety.py). Call wait_for_robot() before starting a simulator.
"""

import contextlib
import functools
import math
import time

import numpy as np
from drake import lcmt_iiwa_command, lcmt_schunk_wsg_command
from pydrake.lcm import DrakeLcm, DrakeLcmInterface
from pydrake.manipulation import IiwaCommandSender, IiwaControlMode, SchunkWsgCommandSender
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.lcm import LcmInterfaceSystem, LcmPublisherSystem, LcmSubscriberSystem
from pydrake.systems.primitives import Demultiplexer, Multiplexer

from diagrams.scenario import Scenario, planned_joints
from diagrams.station import HAND_INSTANCES, AddCentauro
from systems.robot_io.camera_pose import CameraPoseFromJoints
from systems.robot_io.command_stream import CommandStream, CommandStreamSender
from systems.robot_io.lcm_messages import (
    MalformedMessage,
    RawMessage,
    decode_arm_status,
    decode_hand_status,
    decode_images,
)
from systems.robot_io.lcm_safety import CommandGuard, ImageMonitor, MessageMonitor

# The first command leaves this many control periods after the start, once the guards have seen a status.
COMMAND_OFFSET_PERIODS = 3


class RobotNotResponding(RuntimeError):
    """No status (or no images) from the robot within the scenario's status_timeout_s."""


class RobotModel:
    """What the hardware station needs from the robot's model: the planned joints (n), their limits, and where
    the camera is mounted."""

    def __init__(self, scenario: Scenario):
        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
        robot, hands = AddCentauro(plant, scene_graph, scenario)
        plant.Finalize()
        self.plant = plant
        self.joints = [plant.GetJointByName(n, robot) for n in planned_joints(scenario)]
        self.n = len(self.joints)
        self.lower = np.array([j.position_lower_limits()[0] for j in self.joints])
        self.upper = np.array([j.position_upper_limits()[0] for j in self.joints])
        self.velocity_limits = np.array([j.velocity_upper_limits()[0] for j in self.joints])
        finger = plant.GetJointByName("finger_1_joint", hands["left"])
        # Opening width = both fingers' travel.
        self.hand_upper = 2 * finger.position_upper_limits()[0]
        self.hand_velocity = 2 * finger.velocity_upper_limits()[0]
        self.camera_mount = plant.GetFrameByName("camera_mount")
        self.X_MountCameraBody = scenario.camera.X_PB.GetDeterministicValue()

    def camera_pose_system(self) -> CameraPoseFromJoints:
        return CameraPoseFromJoints(self.plant, self.joints, self.camera_mount, self.X_MountCameraBody)


def MakeHardwareStation(scenario: Scenario, lcm: DrakeLcmInterface | None = None) -> Diagram:
    """The LCM station; see the module docstring.

    Args:
        scenario: channels, periods and limits (scenario.hardware), bus (scenario.lcm), camera.
        lcm: the bus to use instead of a new DrakeLcm on scenario.lcm (e.g. a shared memq:// one).
    """
    config = scenario.hardware
    lcm = lcm or DrakeLcm(scenario.lcm)
    model = RobotModel(scenario)
    builder = DiagramBuilder()
    builder.AddNamedSystem("lcm", LcmInterfaceSystem(lcm))
    period = config.control_period_s

    # Arms.
    n = model.n
    decode_status = functools.partial(decode_arm_status, joints=n)
    status = _AddMonitor(builder, lcm, "centauro.status", config.arm_status_channel, decode_status, 4 * n, config)
    fields = builder.AddNamedSystem("centauro.status_fields", Demultiplexer([n] * 4))
    builder.Connect(status.GetOutputPort("values"), fields.get_input_port())
    for index, name in enumerate(("position_commanded", "position_measured", "velocity_estimated", "torque_commanded")):
        builder.ExportOutput(fields.get_output_port(index), f"centauro.{name}")
    state = builder.AddNamedSystem("centauro.state", Multiplexer([n, n]))
    builder.Connect(fields.get_output_port(1), state.get_input_port(0))
    builder.Connect(fields.get_output_port(2), state.get_input_port(1))
    builder.ExportOutput(state.get_output_port(), "centauro.state_estimated")
    guard = builder.AddNamedSystem(
        "centauro.command_guard",
        CommandGuard(model.lower, model.upper, model.velocity_limits, period, "centauro", config.status_lost_s),
    )
    builder.Connect(fields.get_output_port(1), guard.GetInputPort("measured"))
    builder.Connect(status.GetOutputPort("health"), guard.GetInputPort("status_health"))
    builder.ExportOutput(status.GetOutputPort("health"), "centauro.status_health")
    builder.ExportInput(guard.GetInputPort("desired"), "centauro.position")
    if lcm.get_lcm_url().startswith("memq://"):
        # In-process bus: the robot driver steps in lockstep with this diagram, so nothing can stall it.
        sender = builder.AddNamedSystem("centauro.command_sender", IiwaCommandSender(n, IiwaControlMode.kPositionOnly))
        builder.Connect(guard.GetOutputPort("command"), sender.GetInputPort("position"))
        _AddPublisher(builder, lcm, sender, config.arm_command_channel, lcmt_iiwa_command, period)
    else:  # a real bus: the commands leave from a process of their own, never stalled by perceiving or planning
        stream = CommandStream(lcm.get_lcm_url(), config.arm_command_channel, n, period)
        streamer = builder.AddNamedSystem(
            "centauro.command_stream", CommandStreamSender(stream, period, COMMAND_OFFSET_PERIODS * period)
        )
        builder.Connect(guard.GetOutputPort("command"), streamer.get_input_port())

    # Hands.
    for side, name in HAND_INSTANCES.items():
        status_channel = getattr(config, f"{side}_hand_status_channel")
        hand_status = _AddMonitor(builder, lcm, f"{name}.status", status_channel, decode_hand_status, 2, config)
        builder.ExportOutput(hand_status.GetOutputPort("values"), f"{name}.state_measured")
        width = builder.AddNamedSystem(f"{name}.width", Demultiplexer([1, 1]))
        builder.Connect(hand_status.GetOutputPort("values"), width.get_input_port())
        hand_guard = builder.AddNamedSystem(
            f"{name}.command_guard",
            CommandGuard([0.0], [model.hand_upper], [model.hand_velocity], period, name, config.status_lost_s),
        )
        builder.Connect(width.get_output_port(0), hand_guard.GetInputPort("measured"))
        builder.Connect(hand_status.GetOutputPort("health"), hand_guard.GetInputPort("status_health"))
        builder.ExportInput(hand_guard.GetInputPort("desired"), f"{name}.position")
        hand_sender = builder.AddNamedSystem(f"{name}.command_sender", SchunkWsgCommandSender())
        builder.Connect(hand_guard.GetOutputPort("command"), hand_sender.GetInputPort("position"))
        channel = getattr(config, f"{side}_hand_command_channel")
        _AddPublisher(builder, lcm, hand_sender, channel, lcmt_schunk_wsg_command, period)

    # Camera.
    camera = scenario.camera.name
    images = builder.AddNamedSystem(
        f"{camera}.images",
        ImageMonitor(config.camera_channel, decode_images, image_stale_after_s(config), config.control_period_s),
    )
    subscriber = builder.AddNamedSystem(
        f"{camera}.subscriber", LcmSubscriberSystem.Make(config.camera_channel, RawMessage, lcm)
    )
    builder.Connect(subscriber.get_output_port(), images.GetInputPort("raw"))
    builder.ExportOutput(images.GetOutputPort("color_image"), f"{camera}.rgb_image")
    builder.ExportOutput(images.GetOutputPort("depth_image"), f"{camera}.depth_image")
    builder.ExportOutput(images.GetOutputPort("health"), f"{camera}.image_health")
    pose = builder.AddNamedSystem(f"{camera}.pose_from_joints", model.camera_pose_system())
    builder.Connect(fields.get_output_port(1), pose.get_input_port())
    builder.ExportOutput(pose.GetOutputPort("camera_pose"), f"{camera}.pose")
    diagram = builder.Build()
    diagram.set_name("hardware_station")
    return diagram


def image_stale_after_s(config) -> float:
    """The camera's images go stale after this long without one (10 camera periods), s."""
    return 10 * config.camera_period_s


def command_stream(station: Diagram) -> CommandStream | None:
    """The hardware station's arm command stream (None on an in-process memq:// bus)."""
    if not station.HasSubsystemNamed("centauro.command_stream"):
        return None
    return station.GetSubsystemByName("centauro.command_stream").stream


def _AddMonitor(builder, lcm, name, channel, decode, size, config) -> MessageMonitor:
    """Subscriber (raw bytes) -> MessageMonitor with NaN values until the first valid message."""
    subscriber = builder.AddNamedSystem(f"{name}_subscriber", LcmSubscriberSystem.Make(channel, RawMessage, lcm))
    monitor = builder.AddNamedSystem(
        name, MessageMonitor(channel, decode, np.full(size, np.nan), config.watchdog_s, config.control_period_s)
    )
    builder.Connect(subscriber.get_output_port(), monitor.GetInputPort("raw"))
    return monitor


def _AddPublisher(builder, lcm, sender, channel, lcm_type, period):
    publisher = builder.AddNamedSystem(
        f"{channel}.publisher",
        LcmPublisherSystem.Make(
            channel,
            lcm_type,
            lcm,
            publish_period=period,
            publish_offset=COMMAND_OFFSET_PERIODS * period,
            use_cpp_serializer=True,
        ),
    )
    builder.Connect(sender.get_output_port(), publisher.get_input_port())


def wait_for_robot(scenario: Scenario, lcm: DrakeLcmInterface, robot_time_s: float = 0.0) -> None:
    """Blocks until the robot's status channels and its camera have each delivered a message, and
    the robot's own clock (its arm status time stamp) reads at least robot_time_s.

    The station's own subscribers receive the same messages, so the first status is in the
    Context once the simulator is initialised. (A simulated robot's clock starts at 0 and may run
    behind ours: robot_time_s lets its scene settle first; a real robot's clock is far past it.)

    Raises:
        RobotNotResponding: naming the silent channels, after scenario.hardware.status_timeout_s.
    """
    config = scenario.hardware
    decoders = {
        config.arm_status_channel: functools.partial(decode_arm_status, joints=len(planned_joints(scenario))),
        config.left_hand_status_channel: decode_hand_status,
        config.right_hand_status_channel: decode_hand_status,
        config.camera_channel: decode_images,
    }
    counts = dict.fromkeys(decoders, 0)  # valid messages only: a malformed one is no sign of a working robot
    robot_clock = {"s": -math.inf}
    waiting = True  # (DrakeLcm cannot unsubscribe: afterwards the callbacks return at once)

    def count(channel, data):
        if not waiting:
            return
        with contextlib.suppress(MalformedMessage):
            utime, _ = decoders[channel](RawMessage(data, counts[channel] + 1))
            counts[channel] += 1
            if channel == config.arm_status_channel:
                robot_clock["s"] = utime / 1e6

    for channel in counts:
        lcm.Subscribe(channel, functools.partial(count, channel))
    deadline = time.monotonic() + config.status_timeout_s
    try:
        while (silent := sorted(c for c, n in counts.items() if n == 0)) or robot_clock["s"] < robot_time_s:
            if time.monotonic() > deadline:
                problem = (
                    f"no valid message on {', '.join(silent)}" if silent else f"its clock not yet at {robot_time_s} s"
                )
                raise RobotNotResponding(
                    f"after {config.status_timeout_s:.1f} s, {problem} ({lcm.get_lcm_url()}): "
                    "is the robot (or scripts/robot_driver.py) running on this LCM bus?"
                )
            lcm.HandleSubscriptions(10)
    finally:
        waiting = False
