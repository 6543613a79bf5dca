"""Perception's one result: the stages' outputs gathered, or the first stage that found nothing."""

import time

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

from systems.messages import GraspPoses, ObjectEstimate, PerceptionResult, Segmentation, Stage


class PerceptionResultCollector(LeafSystem):
    """Reads segmentation, pose estimate and registration in order and says what perception found.

    .. pydrake_system::

        name: PerceptionResultCollector
        input_ports:
        - segmentation
        - estimate
        - grasp_poses
        - reconstructed_cloud_W
        - X_WO
        - latched_wall_s (optional)
        output_ports:
        - result

    Inputs: the segmenter's Segmentation, the pose estimator's ObjectEstimate, the registrar's GraspPoses,
    reconstruction (N x 3 in W, m) and X_WO; ``latched_wall_s`` (1): the camera latch's wall time of the frame
    (s, time.perf_counter()), copied into the result beside the wall time the result was complete (reported
    only). ``result`` (PerceptionResult): found, or the first stage that found nothing and its message (the
    later stages are then not run); each stage's wall seconds are the ones its own result reports. Computed
    from the inputs alone: a latched frame is perceived once.
    """

    def __init__(self):
        super().__init__()
        self.segmentation_port = self.DeclareAbstractInputPort("segmentation", AbstractValue.Make(Segmentation(False)))
        self.estimate_port = self.DeclareAbstractInputPort("estimate", AbstractValue.Make(ObjectEstimate(False)))
        self.grasps_port = self.DeclareAbstractInputPort("grasp_poses", AbstractValue.Make(GraspPoses(False)))
        self.cloud_port = self.DeclareAbstractInputPort("reconstructed_cloud_W", AbstractValue.Make(np.zeros((0, 3))))
        self.X_WO_port = self.DeclareAbstractInputPort("X_WO", AbstractValue.Make(RigidTransform()))
        self.latched_wall_port = self.DeclareVectorInputPort("latched_wall_s", 1)
        self.DeclareAbstractOutputPort(
            "result", lambda: AbstractValue.Make(PerceptionResult()), self._calc, {self.all_input_ports_ticket()}
        )

    def _calc(self, context, output):
        result = self._perceived(context)
        if self.latched_wall_port.HasValue(context):
            result.latched_wall_s = float(self.latched_wall_port.Eval(context)[0])
        result.finished_wall_s = time.perf_counter()
        output.set_value(result)

    def _perceived(self, context) -> PerceptionResult:
        result = PerceptionResult()
        for stage, port in (
            (Stage.SEGMENTATION, self.segmentation_port),
            (Stage.POSE, self.estimate_port),
            (Stage.REGISTRATION, self.grasps_port),
        ):
            found = port.Eval(context)
            result.stage_seconds[stage.value] = found.compute_s
            if stage == Stage.SEGMENTATION:
                result.network_category = found.network_category
            if stage == Stage.POSE:
                result.category, result.points_W = found.category, found.points_W
            if not found.found:
                result.failed_stage, result.message = stage, found.message
                return result
        result.found, result.grasps, result.message = True, found, found.message
        result.reconstruction_W = self.cloud_port.Eval(context)
        result.X_WO_seen = self.X_WO_port.Eval(context)
        return result
