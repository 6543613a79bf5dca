"""Part perception end to end on rendered frames: the part network labels the handles, the grasps are built on
them. The shop family's validation members were never trained on."""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue

from diagrams.benchmarks.registration import NOMINAL_XY, true_grasps
from diagrams.generation.objects import catalog
from diagrams.generation.synthetic_scenes import SyntheticScene
from diagrams.perception import MakePoseEstimator, MakeSegmenter
from systems.messages import PartRole
from systems.perception.images import to_depth_image, to_rgba_image
from systems.perception.part_segmenter import DEFAULT_PART_WEIGHTS, PartSegmenter
from systems.perception.rgbd_noise import noisy_color, noisy_depth, sensor_model
from systems.perception.shape_registrar import ShapeRegistrar


def perceive(scenario, category: str, instance: str, yaw: float, seed: int = 3):
    """A kinect_v2 frame of the instance on the table at `yaw` (from its presentation) through the pick's
    segmenter, pose estimator and shape registrar: (its true pose, the segmentation, the estimate, the grasps)."""
    scene = SyntheticScene(
        scenario,
        np.random.default_rng(seed),
        cameras=1,
        camera_jitter=False,
        instances=(instance,),
        classes=("background", category),
    )
    frame = scene.render(placement=(category, instance, catalog.presentation_yaw(category) + yaw, np.array(NOMINAL_XY)))
    sensor, noise = sensor_model("kinect_v2"), np.random.default_rng(seed)
    intrinsics = scenario.camera.MakeCameras()[1].core().intrinsics()
    depth = noisy_depth(frame.depth, frame.rgb, intrinsics, sensor, noise)
    rgb = noisy_color(frame.rgb, sensor, noise)
    segmenter = MakeSegmenter(scenario, category=category)
    context = segmenter.CreateDefaultContext()
    segmenter.GetInputPort("color_image").FixValue(context, to_rgba_image(rgb))
    segmentation = segmenter.GetOutputPort("segmentation").Eval(context)
    estimator = MakePoseEstimator(scenario)
    context = estimator.CreateDefaultContext()
    estimator.GetInputPort("segmentation").FixValue(context, AbstractValue.Make(segmentation))
    estimator.GetInputPort("depth_image").FixValue(context, to_depth_image(depth))
    estimator.GetInputPort("camera_pose").FixValue(context, AbstractValue.Make(frame.X_WC))
    estimate = estimator.GetOutputPort("estimate").Eval(context)
    registrar = ShapeRegistrar((category,))
    context = registrar.CreateDefaultContext()
    registrar.GetInputPort("estimate").FixValue(context, AbstractValue.Make(estimate))
    return frame.objects[0][2], segmentation, estimate, registrar.GetOutputPort("grasp_poses").Eval(context)


def test_the_part_network_is_shipped_and_names_the_roles():
    network = PartSegmenter()
    assert DEFAULT_PART_WEIGHTS.is_file() and network.metadata["classes"] == [r.name for r in PartRole]
    assert network.parts_of(np.zeros((48, 64, 3), np.uint8), np.zeros((48, 64), bool)).max() == 0


@pytest.mark.slow
def test_a_can_whose_top_handle_runs_across_its_body_is_grasped_on_it_from_above_closing_across_it(scenario):
    # shop_104: its top handle across the body (along y_O); a validation member of the shop family.
    assert catalog.generate("watering_can", "shop_104").parameters["top_across"] == 1.0
    X_WO, segmentation, estimate, grasps = perceive(scenario, "watering_can", "shop_104", 0.0)
    assert segmentation.parts is not None and PartRole.LEFT_HANDLE in estimate.parts
    assert grasps.found and "left grasp from the seen part" in grasps.message, grasps.message
    X_WG = grasps.poses_W["left_grasp"]
    X_WG_true = X_WO @ true_grasps("watering_can", "shop_104")["left_grasp"]
    assert np.linalg.norm(X_WG.translation() - X_WG_true.translation()) < 0.01
    R, handle_axis_W = X_WG.rotation().matrix(), X_WO.rotation().matrix()[:, 1]
    assert R[:, 2] @ [0.0, 0.0, -1.0] > np.cos(np.radians(30))  # approaching from above
    assert abs(R[:, 0] @ handle_axis_W) > np.cos(np.radians(10))  # along the handle: the fingers close across it
