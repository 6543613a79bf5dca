"""A new category taught from a user's folder (scripts/add_category.py): a tiny end to end run on pots
(scripts/make_pot_models.py: plain meshes, one annotated), and the pieces it rests on."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from pydrake.math import RigidTransform, RotationMatrix

from diagrams.generation import teaching
from diagrams.generation.objects import catalog
from diagrams.generation.objects.library import load_info, recentred
from diagrams.perception import category_priors
from systems import categories
from systems.perception import segmentation_network
from systems.perception.pose_estimator import folded_yaw
from systems.perception.shape_registrar import ShapeRegistrar
from systems.shape_space.file_frame import Y_UP_TO_Z_UP
from systems.shape_space.registration import Registrar
from systems.shape_space.space import ShapeSpace

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def taught(tmp_path_factory):
    """Three training pots (one annotated) and one test pot; `pot` taught with a few frames and one epoch."""
    pots = tmp_path_factory.mktemp("pots")
    root = tmp_path_factory.mktemp("categories")
    run = [sys.executable, "scripts/make_pot_models.py", "--out", str(pots), "--train", "3", "--test", "1"]
    subprocess.run(run, cwd=REPO, check=True, capture_output=True, timeout=120)
    command = [sys.executable, "scripts/add_category.py", "--folder", str(pots / "train"), "--name", "pot"]
    command += ["--poses", str(pots / "train" / "poses.yaml"), "--symmetric", "--components", "2"]
    command += ["--frames", "6", "--frames-per-scene", "3", "--epochs", "1", "--validation-frames", "3"]
    env = {**os.environ, "DUALARM_CATEGORIES": str(root)}
    result = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=900, env=env)
    assert result.returncode == 0, result.stderr[-3000:]
    return root, pots, result


@pytest.mark.slow
def test_teaching_writes_the_category_and_a_segmenter_that_knows_it(taught, monkeypatch):
    root, _, result = taught
    monkeypatch.setenv("DUALARM_CATEGORIES", str(root))
    assert "[5/5]" in result.stderr and "taught 'pot': 3 models, 1 annotated" in result.stdout
    for name in ("category.yaml", "shape_space.npz", "shape_space.png", "template.obj"):
        assert (root / "pot" / name).is_file(), name
    assert len(list((root / "pot" / "training").glob("*.sdf"))) == 3
    assert categories.known_categories() == ["watering_can", "drill", "pot"]
    record = categories.load_record("pot")
    assert record.half_turn_symmetric and record.annotated_models == 1
    assert categories.active_segmenter() == root / "segmenter.pt"
    model, metadata = segmentation_network.load(root / "segmenter.pt")
    assert metadata["classes"] == ["background", "watering_can", "drill", "pot"] and model.num_classes == 4
    assert catalog.presentation_yaw("pot") == 0.0
    with pytest.raises(ValueError, match="taught category: it has no generated instances"):
        catalog.instance_names("pot")
    assert category_priors()["pot"].symmetric_about_yaw == 0.0
    # The template is the canonical model in O: on the table, centred on its extent.
    lo, hi = trimesh.load(root / "pot" / "template.obj", force="mesh").bounds
    np.testing.assert_allclose([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]], 0.0, atol=2e-3)


def test_an_unseen_pot_placed_as_a_pick_places_it_gets_its_true_grasps(taught, monkeypatch):
    """The test pot's mesh moved as `--object-file` moves it, seen whole at a known pose, turned 0.3 rad off
    in the initial guess: each hand's grasp lands on its own handle (the other is 20 cm away), within 3 cm of the
    truth (a space of 3 pots, 2 components: 23.1 and 23.7 mm when written; a frame off or a flip: 5-20 cm)."""
    root, pots, _ = taught
    monkeypatch.setenv("DUALARM_CATEGORIES", str(root))
    mesh = recentred(trimesh.load(pots / "test" / "pot_test_0.obj", force="mesh"), catalog.mean_box_centre("pot"))
    truth = load_info(pots / "test" / "pot_test_0.info.yaml").control_poses()
    surface, _ = trimesh.sample.sample_surface_even(mesh, 3000, seed=1)
    X_WO = RigidTransform(RotationMatrix.MakeZRotation(0.25), [0.7, 0.0, 0.76])
    X_guess = RigidTransform(RotationMatrix.MakeZRotation(0.55), [0.71, 0.01, 0.76])
    registrar = ShapeRegistrar(("pot",)).registrars["pot"]
    assert np.pi not in registrar.yaw_hypotheses  # half-turn symmetric: no end-for-end hypothesis
    result = registrar.register(X_WO.multiply(surface.T).T, X_guess)
    for name in ("left_grasp", "right_grasp"):
        error = np.linalg.norm(result.grasp_poses_W[name].translation() - (X_WO @ truth[name]).translation())
        assert error < 0.03, (name, error)


def test_a_symmetric_pose_is_folded_towards_the_presentation():
    assert folded_yaw(3.0, 0.0) == pytest.approx(3.0 - np.pi)
    assert folded_yaw(-2.0, 0.0) == pytest.approx(-2.0 + np.pi)
    assert folded_yaw(0.4, 0.0) == pytest.approx(0.4)
    assert folded_yaw(0.0, np.pi) == pytest.approx(np.pi)


def test_a_generated_category_keeps_the_end_for_end_hypothesis():
    registrar = Registrar(ShapeSpace.load(categories.shape_space_file("drill")))
    assert np.pi in registrar.yaw_hypotheses


def test_widening_the_segmenter_keeps_what_it_knew():
    model, _ = segmentation_network.load(categories.SHIPPED_SEGMENTER)
    image = torch.rand(1, 3, 96, 128) - 0.5
    widened = segmentation_network.with_classes(model, 4)
    with torch.no_grad():
        before = model(image)
        after = widened(image)
    assert model.num_classes == 3 and before.shape[1] == 3  # a copy: the segmenter it came from is untouched
    torch.testing.assert_close(after[:, :3], before)
    assert torch.equal(after.argmax(1), before.argmax(1))  # the new class wins no pixel before it is learnt
    with pytest.raises(ValueError, match="narrow"):
        segmentation_network.with_classes(widened, 3)


def test_an_unknown_category_names_the_known_ones_and_how_to_teach_one(tmp_path, monkeypatch):
    monkeypatch.setenv("DUALARM_CATEGORIES", str(tmp_path))
    with pytest.raises(ValueError, match=r"known categories: \['watering_can', 'drill'\].*add_category"):
        catalog.presentation_yaw("pan")
    assert categories.active_segmenter() == categories.SHIPPED_SEGMENTER


@pytest.mark.parametrize("name", ["Pot", "drill", "background", "2pots", "my-pot"])
def test_a_bad_category_name_is_refused(name):
    with pytest.raises(ValueError, match="--name"):
        teaching.check_name(name)


@pytest.mark.slow
def test_a_point_cloud_canonical_model_gets_a_surface_in_the_categorys_frame(tmp_path):
    """A folder whose canonical model is a scan (a .pcd point cloud, lifted 5 cm off its frame's origin), all of it
    in millimetres with y up: the folder is read in metres, z up; the template is a reconstructed surface standing
    on z = 0 of O, centred on its extent; the poses are turned with it."""
    import argparse

    import open3d as o3d
    import yaml

    from diagrams.generation.objects.pot import build, sample_parameters
    from systems.shape_space.folder import pose_entries

    folder = tmp_path / "pots"
    folder.mkdir()
    X_FM = RigidTransform(RotationMatrix(Y_UP_TO_Z_UP.T), np.zeros(3))  # the files are y up, in millimetres
    for i in range(3):
        instance = build(f"pot_{i}", sample_parameters(np.random.default_rng([5, i])))
        mesh = instance.visual_mesh()
        mesh.apply_translation([0.0, 0.0, 0.05])
        if i == 0:
            points, _ = trimesh.sample.sample_surface_even(mesh, 3000, seed=0)
            points = 1000.0 * X_FM.multiply(points.T).T
            o3d.io.write_point_cloud(
                str(folder / "pot_0.pcd"), o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
            )
            poses = {n: X_FM @ RigidTransform([0.0, 0.0, 0.05]) @ X for n, X in instance.info().control_poses().items()}
            poses = {n: RigidTransform(X.rotation(), 1000.0 * X.translation()) for n, X in poses.items()}
            spec = {"canonical": "pot_0.pcd", "poses": pose_entries(poses)}
            (folder / "poses.yaml").write_text(yaml.safe_dump(spec))
        else:
            mesh.apply_transform(1000.0 * X_FM.GetAsMatrix4())
            mesh.export(folder / f"pot_{i}.obj")
    args = argparse.Namespace(
        folder=folder, poses=folder / "poses.yaml", name="pot", components=2, align="none", presentation_yaw=0.0,
        symmetric=True, mesh_units=None, mesh_up=None,
    )  # fmt: skip
    record = teaching.write_models(args, tmp_path)
    assert record.models == ["pot_0.pcd", "pot_1.obj", "pot_2.obj"] and record.annotated_models == 1
    lo, hi = trimesh.load(tmp_path / "template.obj", force="mesh").bounds
    # The Poisson surface through the scan bulges past its points by a few mm (5.1 mm in y here).
    np.testing.assert_allclose([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]], 0.0, atol=6e-3)
    pot = build("pot_0", sample_parameters(np.random.default_rng([5, 0])))
    np.testing.assert_allclose(hi - lo, pot.visual_mesh().extents, atol=0.02)  # metres, z up (a Poisson surface)
    grasp, true = ShapeSpace.load(tmp_path / "shape_space.npz").control_poses["left_grasp"], pot.info().control_poses()
    np.testing.assert_allclose(grasp.rotation().matrix(), true["left_grasp"].rotation().matrix(), atol=1e-6)  # turned
    assert grasp.translation()[2] == pytest.approx(true["left_grasp"].translation()[2], abs=5e-3)
    assert len(list((tmp_path / "training").glob("*.sdf"))) == 3


def test_a_failed_reteach_keeps_the_category_taught_before(taught, tmp_path, monkeypatch):
    """Teaching `pot` again from a poses file that lacks poses stops with the error, and the pot taught before
    is back as it was: known, with the same record."""
    root, pots, _ = taught
    copy = tmp_path / "categories"
    shutil.copytree(root, copy)
    monkeypatch.setenv("DUALARM_CATEGORIES", str(copy))
    before = (copy / "pot" / "category.yaml").read_text()
    (tmp_path / "bad.yaml").write_text("canonical: pot_train_0.obj\nposes: {}\n")
    command = [sys.executable, "scripts/add_category.py", "--folder", str(pots / "train"), "--name", "pot"]
    command += ["--poses", str(tmp_path / "bad.yaml")]
    env = {**os.environ, "DUALARM_CATEGORIES": str(copy)}
    failed = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=300, env=env)
    assert failed.returncode != 0 and "lacks poses" in failed.stderr, failed.stderr[-3000:]
    assert categories.known_categories() == ["watering_can", "drill", "pot"]
    assert (copy / "pot" / "category.yaml").read_text() == before
    assert not (copy / ".previous" / "pot").exists()
