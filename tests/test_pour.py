"""The pour task: its container, the container finder on a rendered frame, the pour's held moves, and whole pours
judged on the plant (issue 80)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pydrake.math import RigidTransform

from diagrams.autonomous_pick import run_pick
from diagrams.evaluation import random_placements
from diagrams.generation.objects.library import resolve_object
from diagrams.perception import depth_camera
from diagrams.pour_container import CONTAINER_SIZES, pour_container, table_clutter, true_opening
from diagrams.scenario import load_scenario
from diagrams.station import object_pose_on_table, settled_frame
from systems.messages import ContainerSeen, GraspPoses, ObjectBelief, PlaceGoal
from systems.perception.container_finder import find_container
from systems.pick_tasks import PLACE_LIFT_HEIGHT
from systems.planning.pour_goals import (
    POUR_CLEARANCE_M,
    POUR_HEADING_W,
    POUR_ROLLS_DEG,
    POUR_TILT_MARGIN_RAD,
    inside_left_out,
    outflow_elevation,
    outside_of,
    pour_motion,
    pour_rolls,
    pour_target,
)


def _pour_scenario(text: str = "", instance: str = "test_0", yaw: float = 0.0):
    """The pour task at a test can (sensor: the default scenario's, kinect_v2); text: more scenario fields."""
    can = f"object: {{category: watering_can, instance: {instance}, yaw: {yaw}}}"
    return load_scenario(scenario_text=f"{{task: pour, {can}{text}}}")


def _held_can(scenario):
    """The can's true pose, tool frame (O) and grasps (W), and its pour target."""
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    poses = {name: X_WO @ X for name, X in model.info.control_poses().items()}
    grasps = GraspPoses(True, poses, "ground truth", tool_W=model.info.tool_frame().moved(X_WO))
    opening = true_opening(scenario)
    container = ContainerSeen(True, opening.centre_W, opening.radius, "ground truth")
    return X_WO, model.info.tool_frame(), pour_target(container, grasps, X_WO, np.radians(scenario.pour.tilt_deg))


def test_the_container_is_drawn_from_the_seed_beside_the_can_and_is_the_last_object_on_the_table():
    drawn = [pour_container(_pour_scenario(f", random_seed: {seed}")) for seed in range(6)]
    assert pour_container(_pour_scenario(", random_seed: 4")) == drawn[4]
    assert {c.kind for c in drawn} == {"bowl", "pot"}
    for container in drawn:
        (low, high), (lowest, highest) = CONTAINER_SIZES[container.kind]
        assert low <= container.size[0] <= high and lowest <= container.size[2] <= highest
        assert container.xy[1] - container.size[0] / 2 > 0.05  # (to the can's left, clear of it: the can is at y 0)
    scenario = _pour_scenario(", clutter: [{kind: box, xy: [-0.1, -0.3]}]")
    assert [c.kind for c in table_clutter(scenario)] == ["box", pour_container(scenario).kind]
    assert pour_container(load_scenario()) is None
    with pytest.raises(ValueError, match="pour.target_category"):
        load_scenario(scenario_text="{pour: {target_category: vase}}")
    with pytest.raises(ValueError, match="pour.tilt_deg"):
        load_scenario(scenario_text="{pour: {tilt_deg: 95}}")


def test_the_container_finder_finds_the_opening_in_a_rendered_frame_beside_the_can_and_nothing_without_it():
    scenario = _pour_scenario()  # (the default sensor: kinect_v2)
    frame = settled_frame(scenario)
    intrinsics, X_BC = depth_camera(scenario)
    no_mask = np.zeros(frame.depth.shape, bool)
    seen = find_container(frame.depth, no_mask, intrinsics, frame.X_WB @ X_BC, 0.76)
    truth = true_opening(scenario)
    assert seen.found, seen.message
    assert np.linalg.norm(seen.centre_W[:2] - truth.centre_W[:2]) < 0.005
    assert abs(seen.centre_W[2] - truth.centre_W[2]) < 0.006
    assert truth.radius - 0.002 <= seen.radius <= truth.radius + 0.008  # (between the rim's inner and outer edge)
    lift = load_scenario(scenario_text="{object: {category: watering_can, instance: test_0}}")
    frame = settled_frame(lift)
    refused = find_container(frame.depth, no_mask, intrinsics, frame.X_WB @ X_BC, 0.76)
    assert not refused.found and refused.message.startswith("no container seen"), refused.message


def test_a_container_at_the_images_edge_is_found_from_the_part_of_it_seen():
    """The issue's first random placement (`evaluate.py --task pour --placement random`): a bowl 16 cm across at the
    image's left edge, a third of its rim in view. A circle fitted to that arc alone said "no opening" (33% of its
    round seen); the axis fitted to its walls puts the centre within 5 mm. (The can's mask is the true one here; the
    pick's is the segmenter's.)"""
    scenario = random_placements(_pour_scenario(), "watering_can", 1)[0].scenario
    frame = settled_frame(scenario)
    intrinsics, X_BC = depth_camera(scenario)
    seen = find_container(frame.depth, frame.labels == frame.object_label, intrinsics, frame.X_WB @ X_BC, 0.76)
    truth = true_opening(scenario)
    assert seen.found, seen.message
    assert np.linalg.norm(seen.centre_W[:2] - truth.centre_W[:2]) < 0.005
    assert truth.radius - 0.004 <= seen.radius <= truth.radius + 0.008


def test_the_pour_moves_turn_the_outflow_left_tilt_it_down_over_the_opening_then_bring_the_can_upright():
    scenario = _pour_scenario()
    X_WO, tool_O, pour = _held_can(scenario)
    lifted = RigidTransform([0.0, 0.0, PLACE_LIFT_HEIGHT]) @ X_WO
    belief = ObjectBelief(X_WO, lifted)
    motion, carried = pour_motion(PlaceGoal.POUR_APPROACH, belief, pour)
    over = motion @ lifted
    outflow = tool_O.moved(over).axis
    assert np.allclose(outflow[:2] / np.linalg.norm(outflow[:2]), POUR_HEADING_W, atol=1e-6)
    assert np.isclose(over.rotation().matrix()[2, 2], 1.0)  # (upright)
    assert carried is not None  # (the can kept clear of the scene, the container's inside left out of it)
    motion, carried = pour_motion(PlaceGoal.POUR, ObjectBelief(X_WO, over), pour)
    poured = motion @ over
    tip = tool_O.moved(poured).tip
    assert np.allclose(tip, pour.centre_W + [0.0, 0.0, POUR_CLEARANCE_M], atol=1e-6)
    assert np.isclose(-outflow_elevation(poured, tool_O), pour.tilt_below_rad + POUR_TILT_MARGIN_RAD)
    motion, _ = pour_motion(PlaceGoal.POUR_BACK, ObjectBelief(X_WO, poured), pour)
    back = motion @ poured
    assert np.allclose(back.GetAsMatrix4(), over.GetAsMatrix4(), atol=1e-6)  # (the tilt undone, about the pivot)
    with pytest.raises(ValueError, match="no pour goal"):
        pour_motion(PlaceGoal.CARRY, belief, pour)


def test_the_tilts_rolled_about_the_outflow_keep_the_tip_and_the_outflow_and_turn_the_cans_top():
    """pour_rolls: each puts the spout's tip at the same point as pour_motion's tilt, with the same outflow, the can
    turned about that line by its roll (its top towards the robot, -x_W, for a negative roll)."""
    scenario = _pour_scenario()
    X_WO, tool_O, pour = _held_can(scenario)
    over = pour_motion(PlaceGoal.POUR_APPROACH, ObjectBelief(X_WO, X_WO), pour)[0] @ X_WO
    belief = ObjectBelief(X_WO, over)
    tilt, _ = pour_motion(PlaceGoal.POUR, belief, pour)
    rolls = pour_rolls(tilt, belief, pour)
    assert len(rolls) == len(POUR_ROLLS_DEG)
    unturned = tilt @ over
    first = tool_O.moved(unturned)
    for motion, roll in zip(rolls, POUR_ROLLS_DEG, strict=True):
        poured = motion @ over
        np.testing.assert_allclose(tool_O.moved(poured).tip, first.tip, atol=1e-9)
        np.testing.assert_allclose(tool_O.moved(poured).axis, first.axis, atol=1e-9)
        turn = poured.rotation().multiply(unturned.rotation().inverse()).ToAngleAxis()
        assert np.degrees(turn.angle()) == pytest.approx(abs(roll), abs=1e-6)
        up, first_up = poured.rotation().matrix()[:, 2], unturned.rotation().matrix()[:, 2]
        assert np.sign(up[0] - first_up[0]) == np.sign(roll)  # (negative: the top towards -x_W)


def test_the_containers_inside_is_left_out_of_the_scene_below_its_rim_and_the_rim_kept():
    _, _, pour = _held_can(_pour_scenario())
    centre, radius = inside_left_out(pour)
    assert np.allclose(centre, pour.centre_W) and radius == pytest.approx(pour.radius - 0.005)
    inside = centre + [0.5 * radius, 0.0, -0.03]
    above = centre + [0.0, 0.0, 0.01]
    rim = centre + [pour.radius, 0.0, 0.0]
    beside = centre + [radius + 0.05, 0.0, -0.03]
    kept = outside_of(np.array([inside, above, rim, beside]), centre, radius)
    np.testing.assert_array_equal(kept, [above, rim, beside])


def test_a_pour_with_the_true_grasps_and_tool_frame_passes_the_plant_judge(tmp_path):
    """The spout's tip over the opening (within its radius less 1 cm) and above the rim, the outflow at least the
    scenario's 15 deg down, through a 2 s hold; the container not moved; the can set down where it stood. The tip's
    path is recorded and drawn (scripts/draw_use.py)."""
    scenario = _pour_scenario()
    outcome = run_pick(scenario, perception="ground_truth")
    use = outcome.use
    assert outcome.success, outcome.message
    assert use["poured"] and use["held_s"] >= 1.5 and use["container_moved_m"] < 0.005
    assert -use["outflow_elevation_rad"] >= np.radians(15.0) and use["tip_above_rim_m"] > 0.0
    assert use["tip_from_centre_m"] <= use["opening_radius_m"] - 0.01
    assert outcome.place["error_m"] <= 0.02 and outcome.place["tilt_rad"] <= np.radians(5.0)
    # The path starts at the resting can's spout tip, and its points in the hold lie over the opening.
    path, (first, last) = np.array(use["tip_path_W"]), use["hold_t_s"]
    model = resolve_object(scenario.object)
    rest_tip = model.info.tool_frame().moved(object_pose_on_table(scenario, model)).tip
    assert np.linalg.norm(path[0, 1:] - rest_tip) < 0.01 and last - first >= 1.5
    held = path[(path[:, 0] >= first) & (path[:, 0] <= last), 1:]
    assert len(held) >= 6
    assert np.linalg.norm(held[:, :2] - use["opening_centre_W"][:2], axis=1).max() <= use["tip_from_centre_m"] + 1e-3
    outcome_file, figure = tmp_path / "pour.json", tmp_path / "pour.png"
    outcome_file.write_text(json.dumps({"use": use, "message": outcome.message}))
    script = Path(__file__).resolve().parents[1] / "scripts" / "draw_use.py"
    drawn = subprocess.run([sys.executable, script, outcome_file, "--out", figure], capture_output=True, text=True)
    assert drawn.returncode == 0, drawn.stderr
    assert figure.stat().st_size > 10_000


def test_a_container_out_of_reach_is_named_and_the_can_is_set_back_where_it_stood():
    """A pot at the table's far left corner: the arms do not carry the can over it."""
    scenario = _pour_scenario(", pour: {target_xy: [0.3, 0.5], target_category: pot}")
    outcome = run_pick(scenario, perception="ground_truth")
    assert not outcome.success and outcome.failed_stage == "planning"
    assert outcome.message.startswith("planning: pour_approach:"), outcome.message
    assert outcome.use["held_s"] == 0.0 and outcome.use["container_moved_m"] < 0.005
    assert outcome.place["error_m"] <= 0.02 and outcome.place["tilt_rad"] <= np.radians(5.0)
    assert not outcome.hands_in_contact
