"""Checks and retries: the supervisor's recovery from a failed attempt, the injected grasp offset, and a
pick whose first grasps are off that lifts the object on its second attempt; the look before the approach,
a pick whose object is nudged while the arms reach for it, and a place whose object is nudged off its target
once the hands let go of it."""

import dataclasses

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.trajectories import PiecewisePolynomial

from diagrams.autonomous_pick import run_pick
from diagrams.scenario import FaultConfig, load_scenario, replace_object
from systems.messages import (
    OPEN_WIDTH,
    ClearedObject,
    GraspPoses,
    Mode,
    MoveKind,
    ObjectEstimate,
    PerceptionResult,
    PhaseKind,
    PickStatus,
    PlanResult,
    Targets,
    TaskName,
)
from systems.perception.grasp_offset import GraspOffset
from systems.pick_goals import move_request
from systems.pick_supervisor import PickSupervisor
from systems.pick_tasks import (
    AIM_RELEASE_MARGIN,
    RELEASE_MARGIN,
    aim_task,
    lift_pick,
    place_pick,
    place_task,
    pour_task,
    recovery_task,
    replace_task,
    set_back_task,
)

Q0 = np.linspace(-0.5, 0.5, 14)
# The injected fault: every grasp 5 cm back along its approach axis. The hands grip 3 cm off: this drill
# (test_1, yaw 0.25) was lifted with its grasps 3 cm back, sideways or along the handle.
GRASP_OFFSET_G = [0.0, 0.0, -0.05]


def _supervisor(max_attempts: int, looks: bool = False):
    dut = PickSupervisor(lift_pick(), perceive_at_s=0.1, max_attempts=max_attempts, looks=looks)
    context = dut.CreateDefaultContext()
    dut.GetInputPort("position_measured").FixValue(context, Q0)
    _hands(dut, context, 0.0)  # they will close on nothing
    dut.GetInputPort("frame_id").FixValue(context, [1.0])
    found = PerceptionResult(True, X_WO_seen=RigidTransform([0.7, 0.0, 0.8]))
    dut.GetInputPort("perception").FixValue(context, AbstractValue.Make(found))
    dut.GetInputPort("plan").FixValue(context, AbstractValue.Make(PlanResult()))
    dut.GetInputPort("look_frame_id").FixValue(context, [0.0])
    return dut, context, Simulator(dut, context)


def _hands(dut, context, width: float):
    for side in ("left", "right"):
        dut.GetInputPort(f"{side}_hand_state").FixValue(context, [width, 0.0])


def _answer(dut, context, duration=0.1):
    """Plays the planner: answers the current request with a trajectory that holds at its q_start."""
    request = dut.GetOutputPort("plan_request").Eval(context)
    t = context.get_time()
    trajectory = PiecewisePolynomial.FirstOrderHold([t, t + duration], np.column_stack([request.q_start] * 2))
    dut.GetInputPort("plan").FixValue(
        context, AbstractValue.Make(PlanResult(request.id, request.phase, True, trajectory))
    )
    return request


def _status(dut, context):
    return dut.GetOutputPort("status").Eval(context)


def test_an_empty_hand_starts_the_next_attempt_from_a_new_frame():
    dut, context, simulator = _supervisor(max_attempts=2)
    simulator.AdvanceTo(0.15)
    _answer(dut, context)  # reach
    simulator.AdvanceTo(0.3)
    _answer(dut, context)  # approach
    simulator.AdvanceTo(2.0)  # closed on nothing, checked
    status = _status(dut, context)
    assert status.mode == "recover_open" and status.attempt == 1 and status.task == TaskName.RECOVER
    assert status.attempt_failures == (("grasp", "grasp: the left hand closed on nothing (opening 0.0 mm)"),)
    assert dut.GetOutputPort("hand_command").Eval(context).width == OPEN_WIDTH
    _hands(dut, context, OPEN_WIDTH)
    simulator.AdvanceTo(3.6)
    request = _answer(dut, context)
    assert _status(dut, context).mode == "recover_retreat" and request.targets == Targets.RETREAT
    simulator.AdvanceTo(3.8)
    request = _answer(dut, context)
    assert _status(dut, context).mode == "recover_home" and request.targets == Targets.HOME
    np.testing.assert_array_equal(request.q_goal, Q0)  # where the pick began
    simulator.AdvanceTo(4.0)
    status = _status(dut, context)
    assert status.mode == "perceiving" and status.attempt == 2 and status.task is None
    assert dut.GetOutputPort("trigger").Eval(context)[0] == 2  # a new frame
    assert dut.GetOutputPort("attempt").Eval(context)[0] == 2
    dut.GetInputPort("frame_id").FixValue(context, [2.0])
    simulator.AdvanceTo(4.1)
    status = _status(dut, context)
    assert status.mode == "reach" and status.task == TaskName.LIFT


def test_the_last_attempt_fails_the_pick_and_a_plan_failure_is_not_retried():
    dut, context, simulator = _supervisor(max_attempts=1)
    simulator.AdvanceTo(0.15)
    _answer(dut, context)
    simulator.AdvanceTo(0.3)
    _answer(dut, context)
    simulator.AdvanceTo(2.0)
    status = _status(dut, context)
    assert status.mode == "failed" and status.failed_stage == "grasp" and len(status.attempt_failures) == 1

    dut, context, simulator = _supervisor(max_attempts=3)
    simulator.AdvanceTo(0.15)
    request = dut.GetOutputPort("plan_request").Eval(context)
    dut.GetInputPort("plan").FixValue(context, AbstractValue.Make(PlanResult(request.id, "reach", False, None, "no")))
    simulator.AdvanceTo(0.2)
    status = _status(dut, context)  # another attempt would plan the same: none is spent
    assert status.mode == "failed" and status.failed_stage == "planning" and status.attempt == 1


def test_a_hand_that_did_not_close_fails_the_check():
    dut, context, simulator = _supervisor(max_attempts=1)
    _hands(dut, context, OPEN_WIDTH)
    simulator.AdvanceTo(0.15)
    _answer(dut, context)
    simulator.AdvanceTo(0.3)
    _answer(dut, context)
    simulator.AdvanceTo(2.0)
    assert "did not close" in _status(dut, context).message


def test_grasp_offset_moves_each_grasp_in_its_frame_on_one_objects_first_attempts_only():
    dut = GraspOffset([0.0, 0.0, -0.03], attempts=1, object_index=1)
    context = dut.CreateDefaultContext()
    X_WG = RigidTransform([0.5, 0.2, 0.9])
    dut.GetInputPort("grasp_poses").FixValue(context, AbstractValue.Make(GraspPoses(True, {"left_grasp": X_WG})))

    def left_grasp_at(attempt: int, objects_before: int) -> np.ndarray:
        done = (ClearedObject("drill", (0.7, 0.1), attempts=1),) * objects_before
        dut.GetInputPort("status").FixValue(context, AbstractValue.Make(PickStatus(attempt=attempt, objects=done)))
        return dut.GetOutputPort("grasp_poses").Eval(context).poses_W["left_grasp"].translation()

    np.testing.assert_allclose(left_grasp_at(attempt=1, objects_before=1), [0.5, 0.2, 0.87])
    np.testing.assert_array_equal(left_grasp_at(attempt=2, objects_before=1), X_WG.translation())
    np.testing.assert_array_equal(left_grasp_at(attempt=1, objects_before=0), X_WG.translation())
    np.testing.assert_array_equal(left_grasp_at(attempt=1, objects_before=2), X_WG.translation())


def test_scenario_checks_attempts_and_faults():
    with pytest.raises(ValueError, match="max_attempts"):
        load_scenario(scenario_text="{max_attempts: 0}")
    with pytest.raises(ValueError, match="grasp_offset_G"):
        load_scenario(scenario_text="{faults: {grasp_offset_G: [0, 0, 3]}}")  # 3 m: centimetres meant
    with pytest.raises(ValueError, match="nudge_xy"):
        load_scenario(scenario_text="{faults: {nudge_xy: [0.03]}}")
    with pytest.raises(ValueError, match="grasp_offset_object"):
        load_scenario(scenario_text="{faults: {grasp_offset_object: -1}}")


@pytest.mark.slow
def test_grasps_off_by_5_cm_the_empty_hand_is_found_and_the_next_attempt_lifts(scenario):
    """The first attempt's grasps are moved 5 cm back (injected): a hand closes on nothing, the robot backs
    off, looks again and lifts the object with the grasps perceived anew."""
    faulty = dataclasses.replace(
        replace_object(scenario, category="drill", instance="test_1", yaw=0.25),
        faults=FaultConfig(grasp_offset_G=GRASP_OFFSET_G),
    )
    outcome = run_pick(faulty)
    assert outcome.success, outcome.message
    assert outcome.attempts_made == 2
    assert [failure["stage"] for failure in outcome.attempt_failures] == ["grasp"]
    assert "closed on nothing" in outcome.attempt_failures[0]["message"]


def test_a_look_before_the_approach_finds_the_moved_object_and_reaches_for_it_again():
    dut, context, simulator = _supervisor(max_attempts=1, looks=True)
    seen = RigidTransform([0.7, 0.0, 0.8])
    simulator.AdvanceTo(0.15)
    _answer(dut, context)  # reach
    simulator.AdvanceTo(0.3)
    assert _status(dut, context).mode == "check" and dut.GetOutputPort("look_trigger").Eval(context)[0] == 1
    np.testing.assert_array_equal(dut.GetOutputPort("expected_X_WO").Eval(context).translation(), seen.translation())
    nudged = RigidTransform([0.7, 0.03, 0.8])
    dut.GetInputPort("look").FixValue(context, AbstractValue.Make(ObjectEstimate(True, "drill", nudged)))
    dut.GetInputPort("look_frame_id").FixValue(context, [1.0])
    simulator.AdvanceTo(0.35)
    request = dut.GetOutputPort("plan_request").Eval(context)
    assert _status(dut, context).mode == "back_off" and request.targets == Targets.RETREAT
    assert request.object_motion_W is None  # backing off moves the hands, not to the object
    _answer(dut, context)
    simulator.AdvanceTo(0.5)
    request = dut.GetOutputPort("plan_request").Eval(context)
    assert _status(dut, context).mode == "reach" and request.targets == Targets.PREGRASP
    np.testing.assert_allclose(request.object_motion_W.translation(), [0.0, 0.03, 0.0], atol=1e-12)
    _answer(dut, context)
    simulator.AdvanceTo(0.65)  # looked again: where the belief has it now
    dut.GetInputPort("look_frame_id").FixValue(context, [2.0])
    simulator.AdvanceTo(0.7)
    request = dut.GetOutputPort("plan_request").Eval(context)
    assert _status(dut, context).mode == "approach" and _status(dut, context).corrections == 1
    np.testing.assert_allclose(request.object_motion_W.translation(), [0.0, 0.03, 0.0], atol=1e-12)


def test_a_look_that_finds_the_object_where_it_was_changes_nothing():
    dut, context, simulator = _supervisor(max_attempts=1, looks=True)
    simulator.AdvanceTo(0.15)
    _answer(dut, context)
    nearly = RigidTransform([0.705, 0.0, 0.8])  # 5 mm: within what one look tells
    dut.GetInputPort("look").FixValue(context, AbstractValue.Make(ObjectEstimate(True, "drill", nearly)))
    dut.GetInputPort("look_frame_id").FixValue(context, [1.0])
    simulator.AdvanceTo(0.4)
    request = dut.GetOutputPort("plan_request").Eval(context)
    assert _status(dut, context).mode == "approach" and request.object_motion_W is None


def _place_supervisor(target: RigidTransform, max_attempts: int = 1):
    """The place task's supervisor, the object seen at its place target (the test plans no motion)."""
    dut = PickSupervisor(place_pick(), perceive_at_s=0.1, place_target_W=target, looks=True, max_attempts=max_attempts)
    context = dut.CreateDefaultContext()
    for port, value in (("position_measured", Q0), ("frame_id", [1.0]), ("look_frame_id", [0.0])):
        dut.GetInputPort(port).FixValue(context, value)
    _hands(dut, context, 0.03)  # holding a 3 cm handle
    dut.GetInputPort("perception").FixValue(context, AbstractValue.Make(PerceptionResult(True, X_WO_seen=target)))
    dut.GetInputPort("plan").FixValue(context, AbstractValue.Make(PlanResult()))
    return dut, context, Simulator(dut, context)


def _play_until(dut, context, simulator, mode: str, confirm_look: RigidTransform):
    """Plays the planner and the tracker (the object where it is expected, except in the confirm look: at
    confirm_look; None: it finds nothing) until the supervisor is in `mode` (or done or failed): the status, and
    the modes passed."""
    answered, looked, modes = -1, 0, []
    for _ in range(400):
        status = _status(dut, context)
        if not modes or modes[-1] != status.mode:
            modes.append(str(status.mode))
        if status.mode == mode and len(modes) > 1 or status.mode in ("done", "failed"):
            return status, modes
        request = dut.GetOutputPort("plan_request").Eval(context)
        if request.id > answered:
            answered = _answer(dut, context).id
        wanted = int(dut.GetOutputPort("look_trigger").Eval(context)[0])
        if wanted > looked:
            X_WO = confirm_look if status.mode == "confirm" else dut.GetOutputPort("expected_X_WO").Eval(context)
            found = ObjectEstimate(True, "drill", X_WO) if X_WO is not None else ObjectEstimate(False, message="none")
            dut.GetInputPort("look").FixValue(context, AbstractValue.Make(found))
            dut.GetInputPort("look_frame_id").FixValue(context, [float(wanted)])
            looked = wanted
        simulator.AdvanceTo(context.get_time() + 0.05)
    raise AssertionError(f"stuck in {_status(dut, context).mode}")


def test_a_look_after_the_place_takes_an_object_off_its_target_again_once():
    target = RigidTransform([0.7, 0.0, 0.8])
    dut, context, simulator = _place_supervisor(target)
    off = RigidTransform([0.7, 0.03, 0.8])  # 3 cm off the target
    status, modes = _play_until(dut, context, simulator, "confirm", off)
    assert modes[-4:] == ["set_down", "release", "retreat", "confirm"]
    status, modes = _play_until(dut, context, simulator, "confirm", off)
    assert status.task == TaskName.REPLACE and status.place_corrections == 1 and status.attempt == 1
    assert modes == ["confirm", "reach", "approach", "close", "look", "lift", "set_down", "release", "retreat",
                     "confirm"]  # fmt: skip
    status, _ = _play_until(dut, context, simulator, "done", off)
    assert status.mode == "done" and status.place_corrections == 1  # still off after one: it ends as it stands

    dut, context, simulator = _place_supervisor(target)
    near = RigidTransform([0.712, 0.012, 0.8])  # 1.7 cm off, within 2 cm: confirmed at once
    status, modes = _play_until(dut, context, simulator, "done", near)
    assert status.mode == "done" and status.place_corrections == 0 and modes[-2:] == ["confirm", "done"]

    dut, context, simulator = _place_supervisor(target)
    turned = RigidTransform(RotationMatrix.MakeZRotation(np.radians(8.0)), [0.7, 0.0, 0.8])  # on it, turned 8 deg
    _play_until(dut, context, simulator, "confirm", turned)
    status, _ = _play_until(dut, context, simulator, "reach", turned)
    assert status.task == TaskName.REPLACE and status.place_corrections == 1

    dut, context, simulator = _place_supervisor(target)
    status, _ = _play_until(dut, context, simulator, "done", None)  # the look finds nothing: nothing to correct
    assert status.mode == "done" and status.place_corrections == 0


def test_a_set_down_with_no_plan_tries_the_place_target_half_a_centimetre_and_a_centimetre_off_it():
    """No plan sets the object down on the target: it is carried 5 mm off it (towards the robot first, then away,
    then to either side), then 1 cm, and set down there; where no nudge has a plan either, the pick fails at
    planning."""
    target = RigidTransform([0.7, 0.0, 0.8])
    dut, context, simulator = _place_supervisor(target)
    tried = []
    for _ in range(9):
        status, _ = _play_until(dut, context, simulator, "set_down", target)
        assert status.mode == "set_down"
        tried.append(dut.GetOutputPort("status").Eval(context).place_target_W)
        request = dut.GetOutputPort("plan_request").Eval(context)
        failed = PlanResult(request.id, request.phase, False, None, "STOMP: the goal configuration is near the box")
        dut.GetInputPort("plan").FixValue(context, AbstractValue.Make(failed))
        simulator.AdvanceTo(context.get_time() + 0.05)
        status = _status(dut, context)
        if status.mode == "failed":
            break
        assert status.mode == "carry" and status.task == TaskName.PLACE
    assert tried[0] is None  # the target itself first
    offsets = [np.round(X.translation() - target.translation(), 6).tolist() for X in tried[1:]]
    directions = [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 0.0]]
    assert offsets == [[n * c for c in d] for n in (0.005, 0.01) for d in directions]
    assert status.mode == "failed" and status.failed_stage == "planning" and "near the box" in status.message


def test_an_aim_relaxes_before_letting_go_and_the_other_set_downs_do_not():
    """The aim's letting go: set down, relax (a straight move of the command to where the arms are), release wider
    than the others; the place, pour, re-place and set-back open the hands straight after the set-down."""
    names = [phase.name for phase in aim_task().phases]
    assert names[names.index(Mode.SET_DOWN) : names.index(Mode.SET_DOWN) + 3] == [Mode.SET_DOWN, Mode.RELAX,
                                                                                  Mode.RELEASE]  # fmt: skip
    relax = aim_task().phases[names.index(Mode.RELAX)]
    assert relax.kind == PhaseKind.MOVE and relax.path == MoveKind.STRAIGHT and relax.targets == Targets.MEASURED
    release = aim_task().phases[names.index(Mode.RELEASE)]
    assert release.beyond_grasp and release.hand_width == AIM_RELEASE_MARGIN > RELEASE_MARGIN
    for task in (place_task(), pour_task(), replace_task(), set_back_task()):
        names = [phase.name for phase in task.phases]
        assert Mode.RELAX not in names and names[names.index(Mode.SET_DOWN) + 1] == Mode.RELEASE, task.name
        assert task.phases[names.index(Mode.RELEASE)].hand_width == RELEASE_MARGIN, task.name


def test_a_relax_asks_for_the_command_to_go_where_the_arms_are_measured():
    status = PickStatus(plan_end_q=Q0, q_home=np.zeros(14))
    relax = next(phase for phase in aim_task().phases if phase.name == Mode.RELAX)
    pressed = Q0 + 0.004 * np.sign(np.arange(14) - 6.5)  # the arms short of the set-down's command
    request = move_request(relax, status, RigidTransform(), pressed)
    assert request.path == MoveKind.STRAIGHT and request.targets == Targets.MEASURED
    np.testing.assert_array_equal(request.q_start, Q0)
    np.testing.assert_array_equal(request.q_goal, pressed)
    home = next(phase for phase in recovery_task().phases if phase.targets == Targets.HOME)
    np.testing.assert_array_equal(move_request(home, status, RigidTransform(), pressed).q_goal, status.q_home)


def test_the_retaken_object_is_reached_where_the_look_found_it():
    dut, context, simulator = _place_supervisor(RigidTransform([0.7, 0.0, 0.8]))
    _play_until(dut, context, simulator, "confirm", RigidTransform([0.7, 0.03, 0.8]))
    _play_until(dut, context, simulator, "reach", RigidTransform([0.7, 0.03, 0.8]))
    request = dut.GetOutputPort("plan_request").Eval(context)
    assert request.targets == Targets.PREGRASP
    np.testing.assert_allclose(request.object_motion_W.translation(), [0.0, 0.03, 0.0], atol=1e-12)


def test_a_grasp_lost_while_taking_the_object_again_starts_the_next_attempt_at_the_place_task():
    dut, context, simulator = _place_supervisor(RigidTransform([0.7, 0.0, 0.8]), max_attempts=2)
    off = RigidTransform([0.7, 0.03, 0.8])
    _play_until(dut, context, simulator, "confirm", off)
    _play_until(dut, context, simulator, "reach", off)  # taking it again
    _hands(dut, context, 0.0)  # they will close on nothing
    status, modes = _play_until(dut, context, simulator, "perceiving", off)
    assert modes == ["reach", "approach", "close", "recover_open", "recover_retreat", "recover_home", "perceiving"]
    assert status.attempt == 2 and status.place_corrections == 0
    dut.GetInputPort("frame_id").FixValue(context, [2.0])
    _hands(dut, context, 0.03)
    status, modes = _play_until(dut, context, simulator, "confirm", off)
    assert status.task == TaskName.PLACE and modes[1:4] == ["reach", "check", "approach"]


@pytest.mark.slow
def test_an_object_nudged_3_cm_while_the_arms_reach_is_found_and_lifted(scenario):
    """The drill is moved 3 cm sideways at 1 s (injected), while the arms reach for where it was seen. The look
    before the approach finds it moved; the hands back off and reach for it where it is. (Without the look,
    a hand closes on nothing.)"""
    nudged = dataclasses.replace(
        replace_object(scenario, category="drill", instance="test_1", yaw=0.25),
        faults=FaultConfig(nudge_xy=[0.0, 0.03], nudge_at_s=1.0),
    )
    outcome = run_pick(nudged)
    assert outcome.success, outcome.message
    assert outcome.attempts_made == 1 and "look" in outcome.stages


@pytest.mark.slow
def test_an_object_nudged_off_its_place_target_is_taken_again_and_set_down_on_it(scenario):
    """The can is set down on the place target, let go, and moved 3 cm sideways (injected at 23.9 s, as the hands
    finish backing off: the look after the place comes at 24.0 s). The look finds it off the target; the hands
    take it again and set it down on the target (the judge's tolerance is 2 cm)."""
    nudged = dataclasses.replace(
        replace_object(scenario, category="watering_can", instance="test_1", yaw=0.25),
        task="place",
        faults=FaultConfig(nudge_xy=[0.0, 0.03], nudge_at_s=23.9),
    )
    outcome = run_pick(nudged)
    assert outcome.success, outcome.message
    assert outcome.place["corrections"] == 1 and outcome.attempts_made == 1
    assert outcome.place["error_m"] < 0.01 and not outcome.place["dropped"]  # taken again: not a slip


@pytest.mark.slow
def test_an_object_dropped_in_the_carry_is_found_where_it_fell_and_placed(scenario):
    """Both hands open 1 s into the first carry (injected): the hands' widths show it during the carry, the carry
    stops where the arms are, the recovery backs off and goes home, and the next attempt picks the can again from a
    new frame, where it fell, and places it."""
    dropped = dataclasses.replace(scenario, task="place", faults=FaultConfig(drop_in_carry_after_s=1.0), max_attempts=2)
    outcome = run_pick(dropped)
    assert outcome.attempts_made == 2 and outcome.attempt_failures[0]["stage"] == "grasp"
    assert "during the carry" in outcome.attempt_failures[0]["message"]
    assert outcome.success, outcome.message


@pytest.mark.slow
def test_the_perceived_grasps_are_judged_where_the_object_stood_when_it_was_perceived(scenario):
    """The drill is moved 3 cm after it settled and before the camera's first frame: the grasps perceived of it are
    judged on where it stood then (the perception's own error, under 1.5 cm), not where it first settled (3 cm
    away, which would judge them at least 1.5 cm off)."""
    nudged = dataclasses.replace(
        replace_object(scenario, category="drill", instance="test_1", yaw=0.25),
        faults=FaultConfig(nudge_xy=[0.0, 0.03], nudge_at_s=0.45),
    )
    outcome = run_pick(nudged)
    assert outcome.success, outcome.message
    assert max(outcome.perception["grasp_errors_m"].values()) < 0.015, outcome.perception
    assert outcome.perception["position_error_m"] < 0.015, outcome.perception
