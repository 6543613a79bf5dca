"""The camera latch: holds one RGB-D frame, taken when asked, so that perception sees it alone.

The segmenter, pose estimator and registrar compute from their inputs only (not from time), so
downstream of the latch a frame is perceived once, however often its results are read.

The latch also keeps the wall time at which it took its frame (time.perf_counter() of the process, s): the
start of perception's latency, reported only (nothing the pick does reads it).
"""

import math
import time

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import EventStatus, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from systems.robot_io.lcm_safety import LinkHealth


class CameraLatch(LeafSystem):
    """Latches the camera's images and pose when ``trigger`` rises above the latched frame's id.

    .. pydrake_system::

        name: CameraLatch
        input_ports:
        - color_image
        - depth_image
        - camera_pose
        - trigger
        - robot_position (optional)
        - image_health (optional)
        output_ports:
        - color_image
        - depth_image
        - camera_pose
        - frame_id
        - robot_position
        - latched_wall_s

    ``trigger`` (1): the id of the frame wanted (a counter). ``frame_id`` (1): the id of the frame held
    (0 before the first). The image and pose outputs hold that frame (empty images before the first).
    ``robot_position`` (robot_positions, rad): the planned joints' measured positions when the frame was
    taken (the robot in view of the camera; zeros before the first, or where the input is not connected).
    ``latched_wall_s`` (1): the process's time.perf_counter() when the frame was taken, s (NaN before the first).
    ``image_health`` (LinkHealth): a frame asked for is taken from images received at or after the asking (the
    latch waits for them; unconnected: the images are always new).
    """

    def __init__(self, period_s: float = 0.01, robot_positions: int = 14, offset_s: float = 0.0):
        """Args:
        period_s, offset_s: when the trigger is read, s. Put the offset where no other system of the diagram
            updates its state (e.g. between the plant's steps): at a time where any unrestricted update changed
            something, Drake writes back the state of every system that had one, the held frame unchanged
            included, and everything perceived from it is computed again (6 times a pick at offset 0).
        robot_positions: the size of robot_position.
        """
        super().__init__()
        self.DeclareAbstractInputPort("color_image", AbstractValue.Make(ImageRgba8U()))
        self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F()))
        self.DeclareAbstractInputPort("camera_pose", AbstractValue.Make(RigidTransform()))
        self.DeclareVectorInputPort("trigger", 1)
        self.DeclareVectorInputPort("robot_position", robot_positions)
        self.health_port = self.DeclareAbstractInputPort("image_health", AbstractValue.Make(LinkHealth()))
        # (Separate states: Drake copies its own image and pose types natively.)
        self._frame_id = self.DeclareDiscreteState(1)
        self._held = {}
        for name, model in (
            ("color_image", ImageRgba8U()),
            ("depth_image", ImageDepth32F()),
            ("camera_pose", RigidTransform()),
        ):
            self._held[name] = self.DeclareAbstractState(AbstractValue.Make(model))
            self.DeclareStateOutputPort(name, self._held[name])
        self.DeclareStateOutputPort("frame_id", self._frame_id)
        self._robot_position = self.DeclareDiscreteState(robot_positions)
        self.DeclareStateOutputPort("robot_position", self._robot_position)
        self._asked = self.DeclareDiscreteState([0.0, math.nan])  # the frame asked for last, and when (s)
        self._latched_wall_s = self.DeclareDiscreteState([float("nan")])
        self.DeclareStateOutputPort("latched_wall_s", self._latched_wall_s)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, offset_s, self._update)

    def _update(self, context, state) -> EventStatus:
        wanted = self.GetInputPort("trigger").Eval(context)[0]
        if wanted <= context.get_discrete_state(self._frame_id).get_value()[0]:
            return EventStatus.DidNothing()
        if self.health_port.HasValue(context):  # (only an image received since the asking)
            asked_id, asked_at_s = context.get_discrete_state(self._asked).get_value()
            if asked_id != wanted:
                asked_at_s = context.get_time()
                state.get_mutable_discrete_state(self._asked).set_value([wanted, asked_at_s])
            health = self.health_port.Eval(context)
            if health.received == 0 or health.received_at < asked_at_s:
                return EventStatus.Succeeded() if asked_id != wanted else EventStatus.DidNothing()
        for name, index in self._held.items():
            state.get_mutable_abstract_state(index).SetFrom(AbstractValue.Make(self.GetInputPort(name).Eval(context)))
        state.get_mutable_discrete_state(self._frame_id).set_value([wanted])
        if self.GetInputPort("robot_position").HasValue(context):
            robot = self.GetInputPort("robot_position").Eval(context)
            state.get_mutable_discrete_state(self._robot_position).set_value(robot)
        state.get_mutable_discrete_state(self._latched_wall_s).set_value([time.perf_counter()])
        return EventStatus.Succeeded()
