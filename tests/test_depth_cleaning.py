"""A real sensor's artefacts out of the points: flying pixels in the image, strays in space; and what the shape
registration makes of a cloud that still holds them."""

import numpy as np
import trimesh
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix

from diagrams.generation.objects import catalog
from diagrams.generation.objects.library import load_info
from systems.messages import ObjectEstimate
from systems.perception.depth_cleaning import AGREE_M, AGREE_PER_M2, dense_inliers, flying_pixels
from systems.perception.shape_registrar import ShapeRegistrar, shape_space_file
from systems.shape_space.registration import Registrar
from systems.shape_space.space import ShapeSpace
from systems.shape_space.visibility import visible_from


def test_flying_pixels_agree_in_float32_exactly_where_float64_would():
    """One image row of groups (b, b, c, far): the second b agrees with the first for sure, and with c, a few
    float32 steps either side of b's agreement tolerance, or not; so it is a flying pixel exactly where c
    disagrees. The float32 path counts every pair as the tolerance's float64 definition does."""
    rng = np.random.default_rng(0)
    b = rng.uniform(0.3, 5.0, 2000).astype(np.float32)
    tolerance = AGREE_M + AGREE_PER_M2 * np.square(b, dtype=float)
    c = (b + rng.choice([-1, 1], b.shape) * tolerance).astype(np.float32)
    c = (c.view(np.int32) + rng.integers(-2, 3, c.shape).astype(np.int32)).view(np.float32)
    depth = np.stack([b, b, c, b + 1.0], axis=1).reshape(1, -1)
    c_agrees = np.abs(c.astype(float) - b.astype(float)) <= tolerance
    assert 0.2 < c_agrees.mean() < 0.8
    np.testing.assert_array_equal(flying_pixels(depth)[0, 1::4], ~c_agrees)


def test_flying_pixels_between_two_surfaces_are_found_and_a_steep_surface_is_kept():
    depth = np.full((60, 80), 1.0, np.float32)
    depth[:, 40:] = 1.5  # a step between columns 39 and 40
    depth[::2, 39] = 1.25  # flying pixels: half of the edge column, halfway between the surfaces
    depth[:, 60:] = 1.5 + 0.02 * np.arange(20)  # a ramp steeper than the agreement tolerance along the rows
    flying = flying_pixels(depth)
    np.testing.assert_array_equal(np.nonzero(flying[1:-1].any(axis=0))[0], [39])  # (the image's border rows aside)
    assert flying[2:-2:2, 39].all() and not flying[1::2, 39].any()
    holes = depth.copy()
    holes[10:20, 10:20] = 0.0
    holes[30, 30] = np.nan
    assert not flying_pixels(holes)[~np.isfinite(holes) | (holes == 0)].any()  # a hole is no flying pixel


def test_dense_inliers_drop_points_floating_off_a_surface():
    rng = np.random.default_rng(0)
    surface = np.column_stack([rng.uniform(0, 0.2, 3000), rng.uniform(0, 0.2, 3000), rng.normal(0, 0.001, 3000)])
    strays = np.column_stack([rng.uniform(0, 0.2, 750), rng.uniform(0, 0.2, 750), rng.uniform(0.03, 0.3, 750)])
    inliers = dense_inliers(np.vstack([surface, strays]))
    assert inliers[:3000].mean() > 0.99 and inliers[3000:].mean() < 0.05


def seen_drill_with_flying_pixels(share: float, seed: int = 0):
    """test_1 drill seen from a chest camera, with `share` of its seen points flown towards the table 0.2-0.4 m
    behind them along their rays (a time-of-flight sensor's mixtures at the silhouette). Returns the points (W),
    the true X_WO and the camera's position."""
    rng = np.random.default_rng(seed)
    X_WO = RigidTransform(RotationMatrix.MakeZRotation(catalog.presentation_yaw("drill") - 0.25), [0.73, 0.0, 0.76])
    mesh = trimesh.load(catalog.instance_directory("drill", "test_1") / "visual.obj", force="mesh")
    surface_W = X_WO.multiply(trimesh.sample.sample_surface_even(mesh, 6000, seed=5)[0].T).T
    camera = np.array([0.2, 0.0, 1.6])
    seen = surface_W[visible_from(surface_W, camera)]
    count = int(share / (1 - share) * len(seen))
    base = seen[rng.integers(len(seen), size=count)]
    rays = (base - camera) / np.linalg.norm(base - camera, axis=1, keepdims=True)
    flying = base + rays * rng.uniform(0.01, 1.0, (count, 1)) * rng.uniform(0.2, 0.4, (count, 1))
    return np.vstack([seen, flying]), X_WO, camera


def test_a_cloud_with_a_fifth_flying_pixels_registers_within_a_centimetre():
    """20 % of the points off the surface (after farthest point thinning they would be most of what the fit
    sees): the strays are removed before the thinning and the grasps come out where they belong."""
    points, X_WO, camera = seen_drill_with_flying_pixels(0.2)
    registrar = Registrar(ShapeSpace.load(shape_space_file("drill")))
    result = registrar.register(points, X_WO, camera)
    assert not result.poor_fit, result.poor_fit
    info = load_info(catalog.instance_directory("drill", "test_1") / "info.yaml")
    for side in ("left", "right"):
        X_true = X_WO @ info.grasps[side].grasp.GetDeterministicValue()
        assert np.linalg.norm(result.grasp_poses_W[f"{side}_grasp"].translation() - X_true.translation()) < 0.01


def test_a_shape_the_space_cannot_fit_is_a_named_registration_failure():
    """A box seen where a drill was expected: the registrar's fit leaves most of the points off the shape, and
    the stage says so instead of handing on grasps."""
    rng = np.random.default_rng(1)
    box = trimesh.creation.box([0.35, 0.35, 0.25], trimesh.transformations.translation_matrix([0.73, 0.0, 0.885]))
    surface = trimesh.sample.sample_surface_even(box, 8000, seed=2)[0]
    camera = np.array([0.2, 0.0, 1.6])
    seen = surface[visible_from(surface, camera)] + rng.normal(0, 0.001, (1, 3))
    X_WO = RigidTransform(RotationMatrix.MakeZRotation(catalog.presentation_yaw("drill")), [0.73, 0.0, 0.76])
    dut = ShapeRegistrar(("drill",))
    context = dut.CreateDefaultContext()
    estimate = ObjectEstimate(True, "drill", X_WO, seen, "a box", camera)
    dut.GetInputPort("estimate").FixValue(context, AbstractValue.Make(estimate))
    grasps = dut.GetOutputPort("grasp_poses").Eval(context)
    assert not grasps.found and "a poor fit" in grasps.message, grasps.message
    assert len(dut.GetOutputPort("reconstructed_cloud_W").Eval(context)) == 0
