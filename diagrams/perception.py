"""Wires the perception stages to a camera: colour image -> Segmenter -> PoseEstimator <- depth, pose."""

from pathlib import Path

from pydrake.systems.framework import DiagramBuilder, OutputPort

from diagrams.scenario import Scenario
from systems.pose_estimator import PoseEstimator
from systems.segmenter import DEFAULT_WEIGHTS, Segmenter


def MakePoseEstimator(scenario: Scenario) -> PoseEstimator:
    """A PoseEstimator with the intrinsics and mounting of the scenario's depth camera."""
    _, depth_camera = scenario.camera.MakeCameras()
    core = depth_camera.core()
    return PoseEstimator(core.intrinsics(), core.sensor_pose_in_camera_body())


def AddPerception(
    builder: DiagramBuilder,
    color_image: OutputPort,
    depth_image: OutputPort,
    camera_pose: OutputPort,
    scenario: Scenario,
    weights: Path = DEFAULT_WEIGHTS,
):
    """Adds the segmenter and the pose estimator, fed by a camera's (or a camera latch's) ports.

    Returns:
        (segmenter, pose_estimator)
    """
    segmenter = builder.AddNamedSystem("segmenter", Segmenter(weights))
    pose_estimator = builder.AddNamedSystem("pose_estimator", MakePoseEstimator(scenario))
    builder.Connect(color_image, segmenter.GetInputPort("color_image"))
    builder.Connect(segmenter.GetOutputPort("segmentation"), pose_estimator.GetInputPort("segmentation"))
    builder.Connect(depth_image, pose_estimator.GetInputPort("depth_image"))
    builder.Connect(camera_pose, pose_estimator.GetInputPort("camera_pose"))
    return segmenter, pose_estimator
