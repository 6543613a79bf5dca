"""Part perception end to end on rendered frames: the part network labels the handles, the grasps are built on
them. The shop family's validation members were never trained on."""

import functools
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from diagrams.benchmarks.part_perception import perceive_view
from diagrams.benchmarks.registration import true_grasps
from diagrams.generation.objects import catalog
from diagrams.generation.synthetic_scenes import SyntheticScene
from systems.messages import PartRole
from systems.perception import part_crop, segmentation_network
from systems.perception.part_segmenter import DEFAULT_PART_WEIGHTS, PartSegmenter


def test_the_part_network_is_shipped_and_names_the_roles():
    network = PartSegmenter()
    assert DEFAULT_PART_WEIGHTS.is_file() and network.metadata["classes"] == [r.name for r in PartRole]
    assert network.parts_of(np.zeros((48, 64, 3), np.uint8), np.zeros((48, 64), bool)).max() == 0


def test_the_best_class_at_the_masks_pixels_comes_from_the_window_resized_also_where_it_leaves_the_image():
    mask = np.zeros((40, 60), bool)
    mask[0:10, 50:60] = True  # the image's top-right corner: the window about it reaches past the image
    window = part_crop.window_about(mask)
    assert window.row < 0 and window.column + window.side > 60
    scores = np.zeros((2, 8, 8), np.float32)
    scores[1, :4, :] = 1.0  # class 1 best in the window's top half, class 0 in its bottom half
    best = part_crop.best_class_at(scores, window, mask)
    rows = np.nonzero(mask)[0] - window.row  # in the window
    top, bottom = rows < window.side / 2 - 1, rows > window.side / 2 + 1
    assert top.any() and bottom.any() and (best[top] == 1).all() and (best[bottom] == 0).all()
    with pytest.raises(ValueError, match="outside the window"):
        part_crop.best_class_at(scores, part_crop.Window(20, 0, 10), mask)


def test_the_part_network_in_bfloat16_labels_a_rendered_can_as_in_float32(scenario):
    """bfloat16 runs where the CPU has it natively (PartSegmenter's default there): the same parts, near enough."""
    scene = SyntheticScene(scenario, np.random.default_rng(3), classes=("background", "watering_can"),
                           instances=("train_0",), cameras=1, camera_jitter=False)  # fmt: skip
    frame = scene.render(placement=("watering_can", "train_0", 0.4, np.array([0.75, 0.05])))
    mask = frame.labels == 1
    float32 = PartSegmenter(bfloat16=False).parts_of(frame.rgb, mask)
    bfloat16 = PartSegmenter(bfloat16=True).parts_of(frame.rgb, mask)
    assert np.count_nonzero(mask) > 2000 and len(np.unique(float32[mask])) >= 3
    assert np.mean(float32[mask] == bfloat16[mask]) > 0.97


def test_the_part_scores_sum_the_window_and_its_mirror_image_as_the_trained_network_scores_them():
    """The frozen network, the image and its mirror image on two threads: the trained network's scores."""
    network = PartSegmenter(bfloat16=False)
    window = np.random.default_rng(4).integers(0, 256, (part_crop.PART_INPUT, part_crop.PART_INPUT, 3), np.uint8)
    trained, _ = segmentation_network.load(DEFAULT_PART_WEIGHTS)
    x = segmentation_network.to_input(window)
    with torch.no_grad():
        expected = trained(x)[0] + trained(x.flip(-1))[0].flip(-1)
    scores = network.scores(window)
    assert scores.shape == (len(PartRole), part_crop.PART_INPUT, part_crop.PART_INPUT)
    np.testing.assert_allclose(scores, expected.numpy(), atol=1e-3)


@pytest.mark.slow
def test_a_can_whose_top_handle_runs_across_its_body_is_grasped_on_it_from_above_closing_across_it(scenario):
    # shop_104: its top handle across the body (along y_O); a validation member of the shop family.
    assert catalog.generate("watering_can", "shop_104").parameters["top_across"] == 1.0
    view = perceive_view(scenario, "watering_can", "shop_104", 0.0)
    X_WO, segmentation, estimate, grasps = view.X_WO, view.segmentation, view.estimate, view.grasps
    assert segmentation.parts is not None and PartRole.LEFT_HANDLE in estimate.parts
    assert grasps.found and "left grasp from the seen part" in grasps.message, grasps.message
    X_WG = grasps.poses_W["left_grasp"]
    X_WG_true = X_WO @ true_grasps("watering_can", "shop_104")["left_grasp"]
    assert np.linalg.norm(X_WG.translation() - X_WG_true.translation()) < 0.01
    R, handle_axis_W = X_WG.rotation().matrix(), X_WO.rotation().matrix()[:, 1]
    assert R[:, 2] @ [0.0, 0.0, -1.0] > np.cos(np.radians(30))  # approaching from above
    assert abs(R[:, 0] @ handle_axis_W) > np.cos(np.radians(10))  # along the handle: the fingers close across it


@pytest.mark.slow
def test_draw_part_grasps_takes_a_users_mesh_with_its_true_grasps_beside_it(tmp_path):
    scripts = Path(__file__).resolve().parents[1] / "scripts"
    run = functools.partial(subprocess.run, capture_output=True, text=True, timeout=600)
    made = run([sys.executable, scripts / "make_unfamiliar_objects.py", "--out", tmp_path, "--split", "tune"])
    assert made.returncode == 0, made.stderr
    mesh = sorted((tmp_path / "watering_can").glob("*.obj"))[0]
    out = tmp_path / "parts.png"
    drawn = run([sys.executable, scripts / "draw_part_grasps.py", "--object-file", mesh, "--yaw", "0.25", "--out", out])
    assert drawn.returncode == 0, drawn.stderr
    assert "grasp" in drawn.stdout and out.stat().st_size > 10_000
    missing = run([sys.executable, scripts / "draw_part_grasps.py", "--object-file", tmp_path / "none.obj"])
    assert missing.returncode == 2 and "no such file" in missing.stderr
