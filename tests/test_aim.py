"""The aim task (issue 80): the board and target the camera finds, the aim's held moves, the supervisor's aim task and
its set-back when the aim is out of reach, and whole aims judged on the plant."""

import dataclasses

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator

from diagrams.aim_board import AIM_TARGET_RANGE, board_placement
from diagrams.autonomous_pick import run_pick
from diagrams.perception import depth_camera
from diagrams.scenario import AimConfig, load_scenario
from diagrams.station import settled_frame
from systems.messages import (
    BoardSeen,
    GraspPoses,
    MoveKind,
    ObjectBelief,
    PerceptionResult,
    PhaseKind,
    PlaceGoal,
    PlanResult,
    TaskName,
)
from systems.perception.board_finder import find_board
from systems.perception.board_target import TARGET_RGB, target_pixels
from systems.pick_supervisor import PickSupervisor
from systems.pick_tasks import Phase, aim_pick
from systems.planning.aim_goals import (
    AIM_APPROACH_M,
    AIM_ROLLS_DEG,
    AIM_STANDOFF_M,
    aim_motion,
    aim_rolls,
    aim_target,
    level,
)
from systems.shape_space.tool_frame import ToolFrame
from tests.test_recovery import Q0, _answer, _hands, _status


def _aim_scenario(text: str = "", instance: str = "test_0", yaw: float = 0.0):
    """The aim task at a test drill (sensor: the default scenario's, kinect_v2); text: more scenario fields."""
    drill = f"object: {{category: drill, instance: {instance}, yaw: {yaw}}}"
    return load_scenario(scenario_text=f"{{task: aim, {drill}{text}}}")


def test_the_board_and_its_target_are_found_in_a_rendered_frame_and_a_frame_without_the_target_is_refused():
    scenario = _aim_scenario()  # (the default sensor: kinect_v2)
    frame = settled_frame(scenario)
    intrinsics, X_BC = depth_camera(scenario)
    seen = find_board(frame.rgb, frame.depth, intrinsics, frame.X_WB @ X_BC)
    truth = board_placement(scenario)
    assert seen.found, seen.message
    assert np.linalg.norm(seen.target_W - truth.target_W) < 0.004
    assert np.degrees(np.arccos(seen.normal_W @ truth.normal_W)) < 1.0
    painted = frame.rgb.copy()
    painted[target_pixels(frame.rgb)] = (200, 200, 195)  # the disc painted over in the board's grey
    refused = find_board(painted, frame.depth, intrinsics, frame.X_WB @ X_BC)
    assert not refused.found and refused.message.startswith("the board's target: 0 points seen")


def test_target_pixels_are_the_magenta_blob_not_the_drills_orange():
    image = np.full((40, 60, 3), (217, 115, 25), np.uint8)  # a drill's orange
    image[10:16, 20:28] = np.round(np.array(TARGET_RGB) * 180)  # the disc, shaded
    image[30:32, 50:52] = np.round(np.array(TARGET_RGB) * 255)  # a smaller blob: not the target
    mask = target_pixels(image)
    assert mask.sum() == 48 and mask[10:16, 20:28].all()


def _aim():
    """A drill at X_WO = identity-ish: its bit along x_O, its tip 20 cm ahead; a board facing -x."""
    X_WO = RigidTransform(RotationMatrix.MakeZRotation(0.3), [0.7, 0.0, 0.86])
    tool_W = ToolFrame(np.array([0.2, 0.0, 0.15]), np.array([1.0, 0.0, 0.0])).moved(X_WO)
    grasps = GraspPoses(True, {"left_grasp": X_WO @ RigidTransform([0.0, 0.05, 0.1]),
                               "right_grasp": X_WO @ RigidTransform([-0.1, 0.0, 0.05])}, tool_W=tool_W)  # fmt: skip
    board = BoardSeen(True, np.array([-1.0, 0.0, 0.0]), np.array([1.05, 0.04, 1.02]))
    return X_WO, grasps, board


def test_the_aim_moves_put_the_bit_along_the_normal_short_of_the_target_then_on_it_and_back():
    X_WO, grasps, board = _aim()
    aim = aim_target(board, grasps, X_WO)
    belief = ObjectBelief.seen(X_WO)
    for goal, standoff in ((PlaceGoal.AIM_APPROACH, AIM_STANDOFF_M + AIM_APPROACH_M), (PlaceGoal.AIM, AIM_STANDOFF_M)):
        motion, carried = aim_motion(goal, belief, aim)
        tool = aim.tool_O.moved(motion @ X_WO)
        np.testing.assert_allclose(tool.axis, -board.normal_W, atol=1e-9)
        np.testing.assert_allclose(tool.tip, board.target_W + standoff * board.normal_W, atol=1e-9)
        assert carried.IsNearlyEqualTo(RigidTransform(), 1e-12)  # the object has not moved since it was seen
        assert motion.rotation().matrix()[2, 2] == pytest.approx(1.0)  # a turn about the vertical: it stays upright
    back, _ = aim_motion(PlaceGoal.AIM_BACK, belief, aim)
    np.testing.assert_allclose(back.translation(), AIM_APPROACH_M * board.normal_W, atol=1e-12)
    with pytest.raises(ValueError, match="no tool frame"):
        aim_target(board, dataclasses.replace(grasps, tool_W=None, message="grasps on the seen handles"), X_WO)
    with pytest.raises(ValueError, match="the board: 3 points"):
        aim_target(BoardSeen(False, message="the board: 3 points seen"), grasps, X_WO)


def test_the_aims_rolled_about_the_bit_keep_its_tip_and_axis_and_the_aim_after_a_rolled_approach_keeps_the_roll():
    """aim_rolls: each puts the bit's tip where aim_motion's goal does, along the same axis, the drill turned about
    the bit by its roll; the aim from a rolled approach moves straight in along the normal, its roll kept."""
    X_WO, grasps, board = _aim()
    aim = aim_target(board, grasps, X_WO)
    belief = ObjectBelief.seen(X_WO)
    approach, _ = aim_motion(PlaceGoal.AIM_APPROACH, belief, aim)
    rolls = aim_rolls(approach, belief, aim)
    assert len(rolls) == len(AIM_ROLLS_DEG)
    unturned = approach @ X_WO
    first = aim.tool_O.moved(unturned)
    for motion, roll in zip(rolls, AIM_ROLLS_DEG, strict=True):
        rolled = motion @ X_WO
        np.testing.assert_allclose(aim.tool_O.moved(rolled).tip, first.tip, atol=1e-9)
        np.testing.assert_allclose(aim.tool_O.moved(rolled).axis, first.axis, atol=1e-9)
        turn = rolled.rotation().multiply(unturned.rotation().inverse()).ToAngleAxis()
        assert np.degrees(turn.angle()) == pytest.approx(abs(roll), abs=1e-6)
        assert abs(turn.axis() @ board.normal_W) == pytest.approx(1.0)  # about the bit's axis, the normal
        into, _ = aim_motion(PlaceGoal.AIM, ObjectBelief(X_WO, rolled), aim)
        assert into.rotation().IsNearlyIdentity(1e-9)  # straight in: the roll kept
        np.testing.assert_allclose(into.translation(), -AIM_APPROACH_M * board.normal_W, atol=1e-9)


def test_a_bit_axis_near_level_is_taken_level_and_a_steep_one_as_perceived():
    dipped = ToolFrame(np.array([0.2, 0.0, 0.15]), np.array([np.cos(0.05), 0.0, -np.sin(0.05)]))
    levelled = level(dipped)
    np.testing.assert_allclose(levelled.axis, [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(levelled.tip, dipped.tip)
    steep = ToolFrame(np.zeros(3), np.array([np.cos(0.3), 0.0, np.sin(0.3)]))
    assert level(steep) is steep


def test_only_held_moves_name_a_task_for_a_goal_out_of_reach():
    with pytest.raises(ValueError, match="only held moves"):
        Phase("reach", PhaseKind.MOVE, MoveKind.FREE, if_unreachable=TaskName.SET_BACK)
    tasks = aim_pick()
    unreachable = {phase.name: phase.if_unreachable for phase in tasks[TaskName.AIM].phases if phase.if_unreachable}
    assert unreachable == {"aim_approach": TaskName.SET_BACK, "aim": TaskName.SET_BACK}


def _aim_supervisor(board: BoardSeen, grasps: GraspPoses, X_WO: RigidTransform):
    dut = PickSupervisor(aim_pick(check=False, held_looks=False), perceive_at_s=0.1)
    context = dut.CreateDefaultContext()
    for port, value in (("position_measured", Q0), ("frame_id", [1.0]), ("look_frame_id", [0.0])):
        dut.GetInputPort(port).FixValue(context, value)
    _hands(dut, context, 0.03)
    result = PerceptionResult(True, X_WO_seen=X_WO, grasps=grasps)
    dut.GetInputPort("perception").FixValue(context, AbstractValue.Make(result))
    dut.GetInputPort("board").FixValue(context, AbstractValue.Make(board))
    dut.GetInputPort("plan").FixValue(context, AbstractValue.Make(PlanResult()))
    return dut, context, Simulator(dut, context)


def test_an_aim_out_of_reach_sets_the_drill_back_down_where_it_was_taken_then_fails_naming_the_aim():
    X_WO, grasps, board = _aim()
    dut, context, simulator = _aim_supervisor(board, grasps, X_WO)
    modes = []
    for _ in range(200):
        status = _status(dut, context)
        if not modes or modes[-1] != status.mode:
            modes.append(str(status.mode))
        if status.mode in ("done", "failed"):
            break
        request = dut.GetOutputPort("plan_request").Eval(context)
        if request.id > 0 and request.id != dut.GetInputPort("plan").Eval(context).id:
            if request.phase == "aim_approach":  # out of reach
                no = PlanResult(
                    request.id, request.phase, False, None, "aim_approach: the moved hands are out of reach"
                )
                dut.GetInputPort("plan").FixValue(context, AbstractValue.Make(no))
            else:
                _answer(dut, context)
            if request.phase == "set_down":  # straight down onto where the drill was seen
                down = request.X_motion_W @ status.belief.now_W
                np.testing.assert_allclose(down.translation()[:2], X_WO.translation()[:2], atol=1e-9)
        simulator.AdvanceTo(context.get_time() + 0.05)
    assert modes[-6:] == ["aim_approach", "carry", "set_down", "release", "retreat", "failed"]
    assert status.failed_stage == "planning" and status.message == (
        "planning: aim_approach: the moved hands are out of reach"
    )


def test_a_board_not_seen_fails_the_aim_before_any_move():
    X_WO, grasps, _ = _aim()
    missing = BoardSeen(False, message="the board's target: 0 points seen; at least 10 needed")
    dut, context, simulator = _aim_supervisor(missing, grasps, X_WO)
    simulator.AdvanceTo(0.2)
    status = _status(dut, context)
    assert status.mode == "failed" and status.failed_stage == "board" and "0 points seen" in status.message
    assert dut.GetOutputPort("plan_request").Eval(context).id == -1


def test_the_target_is_drawn_from_the_seed_on_the_board_and_a_target_off_it_is_refused():
    drawn = [board_placement(_aim_scenario(f", random_seed: {seed}")).target_W for seed in range(5)]
    again = board_placement(_aim_scenario(", random_seed: 3")).target_W
    np.testing.assert_array_equal(drawn[3], again)
    scenario = _aim_scenario()
    for target in drawn:
        along = target[1] - scenario.table_xyz[1]
        up = target[2] - 0.76
        assert AIM_TARGET_RANGE[0][0] <= along <= AIM_TARGET_RANGE[0][1]
        assert AIM_TARGET_RANGE[1][0] <= up <= AIM_TARGET_RANGE[1][1]
    assert len({tuple(t) for t in drawn}) == 5
    with pytest.raises(ValueError, match="aim.target_yz"):
        load_scenario(scenario_text="{aim: {target_yz: [0.0, 0.5]}}")
    assert AimConfig().board_xyz == [0.2, 0.0, 0.0]


def test_an_aim_with_the_true_grasps_and_tool_frame_passes_the_plant_judge():
    """The bit within 3 deg of the board's normal, its tip within 1 cm of the target and 2-10 mm off the face through
    a 2 s hold, the board untouched, the drill set down where it stood. (Ground truth perceives: the autonomous
    aim's perceived tool frame is off by more than the judge allows in most picks, docs/use.md.)"""
    outcome = run_pick(_aim_scenario(), perception="ground_truth")
    use = outcome.use
    assert outcome.success, outcome.message
    assert use["aimed"] and not use["board_touched"] and use["held_s"] >= 1.5
    assert use["axis_error_rad"] <= np.radians(3.0) and use["tip_to_target_m"] <= 0.01
    assert outcome.place["error_m"] <= 0.02


def test_a_board_out_of_reach_is_named_and_the_drill_is_set_back_where_it_stood():
    """The board at the table's far edge, its target 15 cm up: the arms do not reach the aim (docs/use.md)."""
    scenario = _aim_scenario(", aim: {board_xyz: [0.4, 0.0, 0.0], target_yz: [0.0, 0.15]}")
    outcome = run_pick(scenario, perception="ground_truth")
    assert not outcome.success and outcome.failed_stage == "planning"
    assert outcome.message.startswith("planning: aim_approach:"), outcome.message
    assert outcome.use["held_s"] == 0.0 and not outcome.use["board_touched"]
    assert outcome.place["error_m"] <= 0.02 and outcome.place["tilt_rad"] <= np.radians(5.0)
    assert not outcome.hands_in_contact
