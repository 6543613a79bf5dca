"""Wires the perception stages to a camera: colour image -> Segmenter -> PoseEstimator <- depth, pose."""

from pathlib import Path

from pydrake.systems.framework import DiagramBuilder, OutputPort

from diagrams.generation.objects import catalog
from diagrams.scenario import Scenario
from systems import categories
from systems.perception.object_tracker import ObjectTracker
from systems.perception.pose_estimator import CategoryPrior, PoseEstimator
from systems.perception.segmenter import Segmenter

# The training instance whose shape is each category's pose template.
TEMPLATE_INSTANCE = "train_0"


def category_priors() -> dict[str, CategoryPrior]:
    """The pose estimator's prior of every known category: a template mesh and where O sits in the extent.

    A generated category's template is a training instance; a taught one's its canonical model.
    """
    priors = {}
    for category in categories.known_categories():
        if category in catalog.CATEGORIES:
            template = catalog.instance_directory(category, TEMPLATE_INSTANCE) / "visual.obj"
            box_centre = tuple(float(v) for v in catalog.mean_box_centre(category))
            priors[category] = CategoryPrior(template, box_centre)
            continue
        record = categories.load_record(category)
        template = categories.category_directory(category) / "template.obj"
        symmetric_about_yaw = record.presentation_yaw if record.half_turn_symmetric else None
        priors[category] = CategoryPrior(template, tuple(record.box_centre), symmetric_about_yaw)
    return priors


def _depth_camera(scenario: Scenario):
    """(intrinsics, X_BC: the depth sensor in the camera body) of the scenario's depth camera."""
    _, depth_camera = scenario.camera.MakeCameras()
    core = depth_camera.core()
    return core.intrinsics(), core.sensor_pose_in_camera_body()


def MakePoseEstimator(scenario: Scenario) -> PoseEstimator:
    """A PoseEstimator with the intrinsics and mounting of the scenario's depth camera and the catalog's priors."""
    intrinsics, X_BC = _depth_camera(scenario)
    return PoseEstimator(intrinsics, category_priors(), X_BC)


def MakeObjectTracker(scenario: Scenario) -> ObjectTracker:
    """An ObjectTracker with the intrinsics and mounting of the scenario's depth camera."""
    return ObjectTracker(*_depth_camera(scenario))


def AddPerception(
    builder: DiagramBuilder,
    color_image: OutputPort,
    depth_image: OutputPort,
    camera_pose: OutputPort,
    scenario: Scenario,
    weights: Path | None = None,
):
    """Adds the segmenter and the pose estimator, fed by a camera's (or a camera latch's) ports.

    weights: the segmenter's; None: the one that knows every taught category (categories.active_segmenter).

    Returns:
        (segmenter, pose_estimator)
    """
    segmenter = builder.AddNamedSystem("segmenter", Segmenter(weights or categories.active_segmenter()))
    pose_estimator = builder.AddNamedSystem("pose_estimator", MakePoseEstimator(scenario))
    builder.Connect(color_image, segmenter.GetInputPort("color_image"))
    builder.Connect(segmenter.GetOutputPort("segmentation"), pose_estimator.GetInputPort("segmentation"))
    builder.Connect(depth_image, pose_estimator.GetInputPort("depth_image"))
    builder.Connect(camera_pose, pose_estimator.GetInputPort("camera_pose"))
    return segmenter, pose_estimator
