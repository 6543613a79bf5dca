"""Part perception end to end on rendered frames: the part network labels the handles, the grasps are built on
them. The shop family's validation members were never trained on."""

import functools
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from diagrams.benchmarks.part_perception import perceive_view
from diagrams.benchmarks.registration import true_grasps
from diagrams.generation.objects import catalog
from systems.messages import PartRole
from systems.perception.part_segmenter import DEFAULT_PART_WEIGHTS, PartSegmenter


def test_the_part_network_is_shipped_and_names_the_roles():
    network = PartSegmenter()
    assert DEFAULT_PART_WEIGHTS.is_file() and network.metadata["classes"] == [r.name for r in PartRole]
    assert network.parts_of(np.zeros((48, 64, 3), np.uint8), np.zeros((48, 64), bool)).max() == 0


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
