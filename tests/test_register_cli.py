"""scripts/register.py: a user's single-view cloud file in, pose and grasps out."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
import trimesh
from pydrake.math import RigidTransform, RotationMatrix

from diagrams.generation.objects import catalog
from diagrams.generation.objects.library import load_info
from systems.perception.shape_registrar import shape_space_file
from systems.shape_space.visibility import visible_from

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_register_cli_places_the_grasps_of_an_unseen_drill_seen_from_one_side(tmp_path):
    directory = catalog.instance_directory("drill", "test_1")
    mesh = trimesh.load(directory / "visual.obj", force="mesh")
    X_WO = RigidTransform(RotationMatrix.MakeZRotation(catalog.presentation_yaw("drill")), [0.73, 0.0, 0.76])
    surface_W = X_WO.multiply(trimesh.sample.sample_surface_even(mesh, 6000, seed=4)[0].T).T
    camera = [0.2, 0.0, 1.6]
    seen = surface_W[visible_from(surface_W, np.array(camera))]
    cloud_file = tmp_path / "view.ply"
    o3d.io.write_point_cloud(str(cloud_file), o3d.geometry.PointCloud(o3d.utility.Vector3dVector(seen)))
    x, y, z = X_WO.translation()
    yaw = catalog.presentation_yaw("drill")
    command = [sys.executable, "scripts/register.py", "--space", str(shape_space_file("drill")), "--cloud"]
    command += [str(cloud_file), "--initial-xyz-yaw", str(x + 0.01), str(y), str(z), str(yaw + 0.1), "--json"]
    command += [str(tmp_path / "out.json"), "--viewpoint", *map(str, camera)]
    run = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    report = json.loads((tmp_path / "out.json").read_text())
    truth = load_info(directory / "info.yaml").control_poses()
    for name, X_OG in truth.items():
        error = np.linalg.norm(np.array(report["grasp_poses_W"][name])[:3, 3] - (X_WO @ X_OG).translation())
        assert error < 0.02, (name, error)
    tool = load_info(directory / "info.yaml").tool_frame().moved(X_WO)  # the bit's tip and axis, carried too
    assert np.linalg.norm(np.array(report["tool_W"]["tip"]) - tool.tip) < 0.02 and report["tool_W"]["axis"][0] > 0.99

    bad = subprocess.run(command[:-4] + ["--viewpoint", "0", "nan", "1"], cwd=REPO, capture_output=True, text=True)
    assert bad.returncode == 2 and "viewpoint" in bad.stderr

    millimetres = tmp_path / "view_mm.ply"
    o3d.io.write_point_cloud(str(millimetres), o3d.geometry.PointCloud(o3d.utility.Vector3dVector(1000 * seen)))
    command[command.index(str(cloud_file))] = str(millimetres)
    run = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert run.returncode == 2 and "looks like millimetres" in run.stderr, run.stderr
