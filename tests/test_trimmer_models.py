"""The hedge trimmers of scripts/make_trimmer_models.py, a family to teach and judge on: sound meshes, grasps on
their handles, standing on their own."""

import numpy as np
import pytest
import trimesh
from scipy.spatial import Delaunay

from diagrams.generation.objects.trimmer import build, sample_parameters


@pytest.fixture(scope="module", params=[0, 1, 2])
def trimmer(request):
    instance = build("trimmer", sample_parameters(np.random.default_rng([7, request.param])))
    return instance, instance.visual_mesh()


def test_each_part_is_watertight_and_the_object_stands_on_its_body(trimmer):
    instance, mesh = trimmer
    assert all(part.mesh.is_watertight for part in instance.parts)
    assert mesh.bounds[0][2] == pytest.approx(0.0, abs=1e-9)
    com, _ = instance.mass_properties()
    footprint = mesh.vertices[mesh.vertices[:, 2] < 1e-6][:, :2]
    assert Delaunay(footprint).find_simplex(com[:2]) >= 0, "centre of mass outside the body's footprint"


def test_each_grasp_lies_inside_its_handle_with_room_for_the_fingers(trimmer):
    instance, mesh = trimmer
    tube = instance.parameters["tube_radius"]
    for side, grasp in instance.grasps.items():
        X_OG = grasp.grasp.GetDeterministicValue()
        point = X_OG.translation()
        # On the handle's centre line: a tube radius inside the surface.
        depth = trimesh.proximity.signed_distance(mesh, point[None])[0]
        assert depth == pytest.approx(tube, abs=1e-3), f"{side} grasp is {depth:.4f} m inside the surface"
        # The fingers close along y_G: 3 cm either side is free space.
        y = X_OG.rotation().matrix()[:, 1]
        outside = trimesh.proximity.signed_distance(mesh, np.array([point + 0.03 * y, point - 0.03 * y]))
        assert np.all(outside < 0), f"{side}: a finger's place is inside the object"
        # The handle runs along x_G: 1 cm either way is still inside it (the arch bends away beyond).
        x = X_OG.rotation().matrix()[:, 0]
        along = trimesh.proximity.signed_distance(mesh, np.array([point + 0.01 * x, point - 0.01 * x]))
        assert np.all(along > 0), f"{side}: the handle does not run along x_G"
