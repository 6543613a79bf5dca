"""The sphere model's scene (systems/planning/obstacles.py): a carried object's clearances by clusters, and the
held part's along the detours (systems/planning/stomp_detours.py)."""

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw

from systems.planning.obstacles import CLUSTER_RADIUS, CarriedPoints, Groups, Obstacles, clusters
from systems.planning.stomp_detours import HeldPart


def test_a_carried_objects_clearances_are_exact_wherever_they_count():
    """Placing only the spheres of clusters near the scene changes nothing below the cost's margin: there every
    clearance is the sphere's own, and elsewhere the value given is at least the margin and at most the truth."""
    rng = np.random.default_rng(3)
    points_B = rng.uniform([-0.15, -0.05, -0.1], [0.15, 0.05, 0.1], (400, 3))  # a can-sized object, m
    carried = CarriedPoints(slot=0, points_B=points_B, radius=0.015)
    scene = Obstacles().add_box(RigidTransform([0.0, 0.0, -0.05]).GetAsMatrix4(), [1.0, 1.0, 0.1])  # a table
    scene.add_box(RigidTransform(RollPitchYaw(0, 0, 0.4), [0.3, 0.1, 0.15]).GetAsMatrix4(), [0.1, 0.3, 0.3])
    scene = scene.carrying(carried)
    X_WB = np.array(
        [
            RigidTransform(
                RollPitchYaw(rng.uniform(-0.5, 0.5, 3)), rng.uniform([0.0, -0.2, 0.1], [0.4, 0.3, 0.4])
            ).GetAsMatrix4()
            for _ in range(60)
        ]
    )
    margin = 0.02
    clearances = scene.carried_clearances(X_WB, margin)
    points_W = points_B @ np.swapaxes(X_WB[:, :3, :3], 1, 2) + X_WB[:, None, :3, 3]
    exact = scene.distance(points_W) - carried.radius
    near = exact < margin
    assert 0.02 < near.mean() < 0.9  # the poses put some of the object near the boxes, not all
    np.testing.assert_array_equal(clearances[near], exact[near])
    assert np.all(clearances[~near] >= margin)
    assert np.all(clearances <= exact + 1e-12)
    assert len(carried.cluster_centres_B) < len(points_B) / 4


def test_the_held_parts_clearances_along_detours_are_exact_wherever_they_count():
    """The detours' ranking places only the held part's clusters near the scene sphere by sphere: below the
    margin every clearance is the sphere's own (so the ranking's shortfalls are the same to the bit), elsewhere
    the value given is at least the margin and at most the truth."""
    rng = np.random.default_rng(5)
    keyframes = 6
    part_B = rng.uniform([-0.2, -0.1, -0.1], [0.2, 0.1, 0.1], (120, 3))  # two hands and an object, m
    path = np.linspace([0.0, -0.2, 0.15], [0.3, 0.2, 0.2], keyframes)  # where the part is at each keyframe
    labels = clusters(part_B, CLUSTER_RADIUS)[1]
    part = HeldPart(part_B[None] + path[:, None], rng.uniform(0.01, 0.03, len(part_B)), labels)
    scene = Obstacles().add_box(RigidTransform([0.0, 0.0, -0.05]).GetAsMatrix4(), [1.0, 1.0, 0.1])
    scene.add_box(RigidTransform(RollPitchYaw(0, 0, 0.3), [0.2, 0.0, 0.1]).GetAsMatrix4(), [0.1, 0.2, 0.2])
    offsets = (
        rng.uniform([-0.1, -0.1, 0.0], [0.1, 0.1, 0.2], (20, 1, 3))
        * np.sin(np.linspace(0, np.pi, keyframes))[None, :, None]
    )
    margin = 0.02
    gaps = part.gaps(scene, offsets, margin)
    exact = scene.distance(part.centres[None] + offsets[:, :, None]) - part.radii
    near = exact < margin
    assert 0.02 < near.mean() < 0.9  # some of the part passes near the boxes, not all of it
    np.testing.assert_array_equal(gaps[near], exact[near])
    assert np.all(gaps[~near] >= margin)
    assert np.all(gaps <= exact)
    shortfall = np.maximum(margin - gaps, 0.0).sum(axis=(1, 2))
    np.testing.assert_array_equal(shortfall, np.maximum(margin - exact, 0.0).sum(axis=(1, 2)))
    assert len(part.cluster_centres[0]) < len(part_B) / 2


def test_groups_expand_to_every_member_of_the_chosen_groups_in_each_row():
    """Groups.expand gives the (row, member) pairs that np.nonzero gives on the groups' mask spread to members."""
    rng = np.random.default_rng(5)
    group_of = rng.integers(0, 7, 50)
    chosen = rng.random((9, 7)) < 0.3  # rows x groups
    rows, members = Groups(group_of, 7).expand(*np.nonzero(chosen))
    expected = np.nonzero(chosen[:, group_of])
    assert sorted(zip(rows, members, strict=True)) == sorted(zip(*expected, strict=True))
    assert np.all(np.diff(rows) >= 0)  # row by row, as np.nonzero


def test_a_box_added_after_a_query_counts_in_the_next():
    """The boxes' float32 arrays are made again when the list grows or is replaced (they are kept between calls)."""
    point = np.array([[0.0, 0.0, 0.25]])
    scene = Obstacles().add_box(np.eye(4), [0.2, 0.2, 0.2])  # its top 0.15 m below the point
    assert np.isclose(scene.distance(point)[0], 0.15, atol=1e-6)
    scene.add_box(RigidTransform([0.0, 0.0, 0.45]).GetAsMatrix4(), [0.2, 0.2, 0.2])  # its bottom 0.1 m above it
    assert np.isclose(scene.distance(point)[0], 0.1, atol=1e-6)
    scene.boxes = scene.boxes[:1]
    assert np.isclose(scene.distance(point)[0], 0.15, atol=1e-6)
