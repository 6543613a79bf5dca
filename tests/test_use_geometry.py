"""The cores of using what is held (issue 80): a container's opening and a board's target found in the points seen
of them, and the poses that pour a held can into the container and aim a held drill at the target."""

import numpy as np
import pytest
import trimesh
from pydrake.math import RigidTransform, RotationMatrix

from diagrams.generation.objects import catalog
from diagrams.generation.objects.bowl import bowl_mesh
from systems.perception.board_target import board_of
from systems.perception.container_finder import points_over
from systems.perception.container_opening import Opening, opening_of
from systems.planning.aim_goals import AIM_STANDOFF_M, aim_pose
from systems.planning.pour_goals import POUR_CLEARANCE_M, outflow_elevation, pour_poses
from systems.shape_space.tool_frame import ToolFrame
from systems.shape_space.visibility import visible_from

CAMERA_W = np.array([0.1, 0.0, 1.6])  # m: about where the station's camera looks from


def seen_points(mesh: trimesh.Trimesh, xyz, seed: int = 0) -> np.ndarray:
    """The points of a mesh (moved to xyz, W) a camera at CAMERA_W sees: an even sampling, its hidden points out."""
    points = trimesh.sample.sample_surface_even(mesh, 8000, seed=seed)[0] + xyz
    return points[visible_from(points, CAMERA_W)]


@pytest.mark.parametrize(
    ("diameter", "height", "xyz"), [(0.16, 0.07, (0.6, 0.25, 0.76)), (0.25, 0.1, (0.8, -0.2, 0.76))]
)
def test_a_bowls_opening_is_found_from_one_view(diameter, height, xyz):
    """Seen from the camera's side: the centre within 5 mm, at the rim's height within 5 mm, the radius between the
    rim's inner and outer one."""
    opening = opening_of(seen_points(bowl_mesh(diameter, height), xyz))
    np.testing.assert_allclose(opening.centre_W[:2], xyz[:2], atol=0.005)
    assert opening.centre_W[2] == pytest.approx(xyz[2] + height, abs=0.005)
    assert diameter / 2 - 0.008 <= opening.radius <= diameter / 2 + 0.002


@pytest.mark.parametrize("pot", [False, True])
def test_an_opening_is_found_from_a_third_of_its_round(pot):
    """Only the far third of the container seen (cut by the image's edge, or by the can in front of it): its axis
    from its walls within 7 mm (about half a wall's thickness of it a bias: the far wall seen from inside, the near
    one from outside), the radius between the rim's inner and outer one. A circle fitted to that arc of rim alone
    came out 5-45 mm off on rendered frames."""
    xyz = np.array([0.6, 0.25, 0.76])
    points = seen_points(bowl_mesh(0.16, 0.07, pot), xyz)
    far = points[points[:, 1] > xyz[1] + 0.03]
    opening = opening_of(far)
    np.testing.assert_allclose(opening.centre_W[:2], xyz[:2], atol=0.007)
    assert 0.08 - 0.008 <= opening.radius <= 0.08 + 0.002


def test_an_opening_with_something_over_it_is_none():
    """points_over counts what the camera saw over an opening (a lid, the rest of a round body it is a piece of), not
    beside it, nor far above it (a hand at the robot's start)."""
    opening = Opening(np.array([0.6, 0.25, 0.83]), 0.08, 100)
    grid = np.stack(np.meshgrid(np.linspace(-0.04, 0.04, 9), np.linspace(-0.04, 0.04, 9)), -1).reshape(-1, 2)
    lid = np.column_stack([grid + [0.6, 0.25], np.full(len(grid), 0.88)])
    assert points_over(opening, lid) == len(lid)
    assert points_over(opening, lid + [0.2, 0.0, 0.0]) == 0  # (beside it)
    assert points_over(opening, lid + [0.0, 0.0, 0.2]) == 0  # (high above it)
    assert points_over(opening, lid - [0.0, 0.0, 0.04]) == 0  # (the rim's own band)


def test_what_is_no_opening_is_said_so():
    with pytest.raises(ValueError, match="points seen"):
        opening_of(np.full((10, 3), 0.5))
    box = trimesh.creation.box([0.2, 0.1, 0.08])
    box.apply_translation([0.0, 0.0, 0.04])
    with pytest.raises(ValueError, match="no opening|no circle|across its radius"):
        opening_of(seen_points(box, (0.7, 0.0, 0.76)), "the box")
    with pytest.raises(ValueError, match="the box"):
        opening_of(seen_points(box, (0.7, 0.0, 0.76)), "the box")
    cylinder = trimesh.creation.cylinder(0.05, 0.12)
    cylinder.apply_translation([0.0, 0.0, 0.06])
    with pytest.raises(ValueError, match="closed top"):  # (a disc, not a rim)
        opening_of(seen_points(cylinder, (0.7, 0.0, 0.76)), "the cylinder")
    bowl = seen_points(bowl_mesh(0.16, 0.07), (0.6, 0.25, 0.76))
    with pytest.raises(ValueError, match="too little of its round seen"):  # (a sliver of its far side)
        opening_of(bowl[bowl[:, 1] > 0.25 + 0.07], "the bowl's far edge")


@pytest.mark.parametrize("yaw", [0.3, -0.6])
def test_the_pour_poses_put_the_spout_tip_over_the_opening_pointing_down(yaw):
    can = catalog.generate("watering_can", "test_0")
    tool, grasps = can.tool_frame(), can.info().control_poses()
    pivot_O = 0.5 * (grasps["left_grasp"].translation() + grasps["right_grasp"].translation())
    X_WO = RigidTransform(RotationMatrix.MakeZRotation(yaw), [0.7, 0.0, 0.86])
    opening = Opening(np.array([0.7, -0.3, 0.85]), 0.08, 100)
    poses = pour_poses(X_WO, tool, pivot_O, opening, np.radians(40))
    assert outflow_elevation(poses.poured_W, tool) == pytest.approx(np.radians(-40))
    np.testing.assert_allclose(tool.moved(poses.poured_W).tip, opening.centre_W + [0, 0, POUR_CLEARANCE_M], atol=1e-9)
    # Over the container the can stands upright, at its yaw; the tilt turns it about the pivot, which stays.
    np.testing.assert_allclose(poses.over_W.rotation().matrix(), X_WO.rotation().matrix(), atol=1e-12)
    np.testing.assert_allclose(poses.over_W.multiply(pivot_O), poses.poured_W.multiply(pivot_O), atol=1e-9)
    motion = poses.tilt_motion_W @ poses.over_W
    np.testing.assert_allclose(motion.GetAsMatrix4(), poses.poured_W.GetAsMatrix4(), atol=1e-12)
    # The tilt's axis is horizontal: the spout turns down in its own vertical plane, never sideways.
    axis = poses.tilt_motion_W.rotation().ToAngleAxis().axis()
    assert abs(axis[2]) < 1e-9 and abs(axis @ tool.moved(X_WO).axis) < 1e-9


def test_a_vertical_outflow_has_no_direction_to_pour_in():
    with pytest.raises(ValueError, match="nearly vertical"):
        pour_poses(RigidTransform(), ToolFrame([0, 0, 0.3], [0, 0, 1]), np.zeros(3), Opening(np.zeros(3), 0.1, 50), 0.7)


@pytest.mark.slow
def test_the_arms_tilt_a_held_can_some_way_but_not_to_a_steep_pour():
    """benchmark_use_reach.py --task pour's rows: with the paper's grasps the arms reach a 15 deg tilt about the grasps'
    midpoint, not a 90 deg one (which a pour 40 deg below the horizontal needs from a spout 35-47 deg up)."""
    from diagrams.benchmarks.use_reach import pour_reach_rows
    from diagrams.generation.planning_problems import DRAWN_WITH
    from diagrams.planning_scene import make_pick_motions
    from diagrams.scenario import load_scenario

    motions = make_pick_motions(load_scenario(), DRAWN_WITH)
    (row,) = pour_reach_rows(motions, ["test_1"], [0.25], [45.0], [15.0, 90.0])
    assert row["tilts"]["15.0"] == "reached" and row["tilts"]["90.0"] != "reached"
    assert row["largest_tilt_deg"] == 15.0 and row["outflow_at_largest_deg"] == pytest.approx(35 - 15, abs=1)


def board_points(rng: np.random.Generator, centre, normal, count: int, radius: float | None = None) -> np.ndarray:
    """Points on a vertical board's face (a 40 x 30 cm patch about `centre`, m, W) with 1 mm noise, or on a disc of
    `radius` about it; `normal`: the face's, horizontal."""
    along = np.cross([0.0, 0.0, 1.0], normal)
    if radius is None:
        u, v = rng.uniform(-0.2, 0.2, count), rng.uniform(-0.15, 0.15, count)
    else:
        r, a = radius * np.sqrt(rng.uniform(0, 1, count)), rng.uniform(0, 2 * np.pi, count)
        u, v = r * np.cos(a), r * np.sin(a)
    noise = rng.normal(0.0, 0.001, (count, 1)) * normal
    return np.asarray(centre) + u[:, None] * along + v[:, None] * [0.0, 0.0, 1.0] + noise


def test_a_boards_plane_and_target_are_found_with_the_normal_towards_the_camera():
    rng = np.random.default_rng(4)
    normal = np.array([-1.0, 0.0, 0.0])
    target = np.array([1.25, 0.1, 0.96])
    board = np.vstack([board_points(rng, [1.25, 0.0, 0.95], normal, 2000), rng.uniform(-1, 1, (50, 3)) + [1.25, 0, 1]])
    found = board_of(board, board_points(rng, target, normal, 200, radius=0.03), CAMERA_W)
    np.testing.assert_allclose(found.normal_W, normal, atol=0.01)
    np.testing.assert_allclose(found.target_W, target, atol=0.004)
    with pytest.raises(ValueError, match="target"):
        board_of(board, board[:3], CAMERA_W)
    with pytest.raises(ValueError, match="no plane"):
        board_of(rng.uniform(-0.2, 0.2, (500, 3)) + [1.2, 0, 1], board[:50], CAMERA_W)


@pytest.mark.parametrize("normal", [(-1.0, 0.0, 0.0), (0.0, 1.0, 0.0)])
def test_the_aim_pose_puts_the_bit_along_the_boards_normal_its_tip_off_the_target(normal):
    drill = catalog.generate("drill", "test_0")
    tool, grasps = drill.tool_frame(), drill.info().control_poses()
    pivot_O = 0.5 * (grasps["left_grasp"].translation() + grasps["right_grasp"].translation())
    X_WO = RigidTransform(RotationMatrix.MakeZRotation(0.2), [0.7, 0.0, 0.86])
    target = np.array([1.25, 0.1, 0.96])
    X_aim = aim_pose(X_WO, tool, pivot_O, target, np.array(normal))
    aimed = tool.moved(X_aim)
    np.testing.assert_allclose(aimed.axis, -np.array(normal), atol=1e-9)
    np.testing.assert_allclose(aimed.tip, target + AIM_STANDOFF_M * np.array(normal), atol=1e-9)
    assert X_aim.rotation().matrix()[2, 2] == pytest.approx(1.0)  # an upright drill at a vertical board stays upright
