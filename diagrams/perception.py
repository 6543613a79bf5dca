"""Wires the perception stages to a station: camera -> Segmenter -> PoseEstimator."""

from pathlib import Path

from pydrake.systems.framework import Diagram, DiagramBuilder

from diagrams.scenario import Scenario
from systems.pose_estimator import PoseEstimator
from systems.segmenter import DEFAULT_WEIGHTS, Segmenter


def MakePoseEstimator(scenario: Scenario) -> PoseEstimator:
    """A PoseEstimator with the intrinsics and mounting of the scenario's depth camera."""
    _, depth_camera = scenario.camera.MakeCameras()
    core = depth_camera.core()
    return PoseEstimator(core.intrinsics(), core.sensor_pose_in_camera_body())


def AddPerception(builder: DiagramBuilder, station: Diagram, scenario: Scenario, weights: Path = DEFAULT_WEIGHTS):
    """Adds and connects the segmenter and the pose estimator to the station's camera ports.

    Returns:
        (segmenter, pose_estimator)
    """
    camera = scenario.camera.name
    segmenter = builder.AddNamedSystem("segmenter", Segmenter(weights))
    pose_estimator = builder.AddNamedSystem("pose_estimator", MakePoseEstimator(scenario))
    builder.Connect(station.GetOutputPort(f"{camera}.rgb_image"), segmenter.GetInputPort("color_image"))
    builder.Connect(segmenter.GetOutputPort("segmentation"), pose_estimator.GetInputPort("segmentation"))
    builder.Connect(station.GetOutputPort(f"{camera}.depth_image"), pose_estimator.GetInputPort("depth_image"))
    builder.Connect(station.GetOutputPort(f"{camera}.pose"), pose_estimator.GetInputPort("camera_pose"))
    return segmenter, pose_estimator
