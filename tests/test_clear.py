"""The clear task: the drop zone's spots, the next object chosen in the image, the supervisor's loop over objects,
the seeded tables to clear, and a table with nothing familiar on it."""

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator

from diagrams.autonomous_pick import run_pick
from diagrams.benchmarks.zone_reach import carry_reach
from diagrams.generation.clear_scenes import ZONE_CLEARANCE_M, arms_reach, clear_scene
from diagrams.generation.clutter_scenes import robot_at_start, scene_outlines
from diagrams.generation.objects.library import resolve_object
from diagrams.paths import REPO_ROOT
from diagrams.perception import MakeSegmenter
from diagrams.planning_scene import make_pick_motions
from diagrams.scenario import ClutterObjectConfig, load_scenario, overlay_scenario, replace_object
from diagrams.station import clear_home, drop_zone, object_pose_on_table, settled_frame
from systems.clear_progress import chosen_spots, left_out, next_pass, placed, set_down_shapes, summary
from systems.messages import (
    ClearedObject,
    LeftOut,
    Mode,
    MoveKind,
    ObjectBelief,
    PerceptionResult,
    PickStatus,
    PlanResult,
    Stage,
    TaskName,
)
from systems.perception.pose_estimator import depth_to_points
from systems.pick_supervisor import PickSupervisor
from systems.pick_tasks import clear_pick
from systems.planning.drop_zone import (
    DROP_ALTERNATIVES,
    DROP_CENTRE_INSET_M,
    DROP_GAP_M,
    DROP_OVERHANG_M,
    HAND_GAP_M,
    TABLE_EDGE_MARGIN_M,
    DropZone,
    base_O,
    drop_spots,
    footprint_at,
    footprint_O,
    hands_footprint_O,
)
from systems.planning.outlines import gap_between, inside, outlines_apart

ZONE = DropZone((0.6, -0.38), (0.4, 0.4))
Q0 = np.linspace(-0.5, 0.5, 14)


def _box_footprint(x: float, y: float, X_WO: RigidTransform) -> np.ndarray:
    corners = np.array([[sx * x, sy * y, 0.0] for sx in (-1, 1) for sy in (-1, 1)])
    return footprint_O(X_WO.multiply(corners.T).T, X_WO)


def test_the_drop_zone_takes_objects_apart_inside_it_until_none_fits():
    X_WO = RigidTransform(RotationMatrix.MakeZRotation(0.2), [0.7, 0.1, 0.8])
    outline_O = _box_footprint(0.13, 0.04, X_WO)  # a drill's size, 26 x 8 cm
    dropped = []
    while spots := drop_spots(ZONE, dropped, outline_O, X_WO):
        spot = spots[0]
        assert 1 <= len(spots) <= DROP_ALTERNATIVES and not any(s.IsNearlyEqualTo(spot, 1e-9) for s in spots[1:])
        footprint = footprint_at(outline_O, spot)
        assert ZONE.contains(footprint, DROP_OVERHANG_M + 1e-9).all()
        assert ZONE.contains(footprint.mean(axis=0), -DROP_CENTRE_INSET_M + 1e-9)
        assert spot.translation()[2] == X_WO.translation()[2]
        assert all(outlines_apart(footprint, other, DROP_GAP_M - 1e-9) for other in dropped)
        dropped.append(footprint)
        assert len(dropped) < 10
    assert len(dropped) >= 3  # three drills side by side in a 40 cm square
    big = _box_footprint(0.3, 0.3, X_WO)  # 60 cm across: fits nowhere
    assert drop_spots(ZONE, [], big, X_WO) == []


def test_an_object_goes_where_its_base_stands_on_the_table_whatever_its_outline_reaches_past_the_zone():
    """A can (a body 14 cm across, a spout reaching 12 cm out at 20 cm high): its outline may reach past the zone's
    marks (the spout), but where the zone knows the table top, the can's base stays TABLE_EDGE_MARGIN_M inside it.
    A zone drawn across the table's edge takes it nowhere; one inside it, where its base stays on."""
    X_WO = RigidTransform([0.8, 0.2, 0.76])
    angle = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    ring = np.stack([0.07 * np.cos(angle), 0.07 * np.sin(angle)], axis=1)
    body = np.concatenate([np.column_stack([ring, np.full(24, z)]) for z in (0.0, 0.01, 0.1, 0.25)])
    spout = np.column_stack([np.linspace(0.07, 0.19, 6), np.zeros(6), np.full(6, 0.2)])
    shape_W = X_WO.multiply(np.concatenate([body, spout]).T).T
    outline, base = footprint_O(shape_W, X_WO), base_O(shape_W, X_WO)
    np.testing.assert_allclose(np.abs(base).max(axis=0), [0.07, 0.07], atol=0.002)  # the body's foot, not the spout
    line = X_WO.multiply(np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.1, 0.0, 0.3]]).T).T
    np.testing.assert_allclose(base_O(line, X_WO), [[0.0, 0.0], [0.05, 0.0]], atol=1e-12)  # (no area: the points)
    table_W = ((0.45, -0.6), (1.25, 0.6))
    across = DropZone((0.7, -0.6), (0.4, 0.16))  # half of it past the table's side (y -0.6 m)
    unknown = drop_spots(across, [], outline, X_WO, base_outline_O=base)
    assert unknown and all(footprint_at(base, X).min(axis=0)[1] < table_W[0][1] for X in unknown)
    assert drop_spots(dataclasses.replace(across, table_W=table_W), [], outline, X_WO, base_outline_O=base) == []
    inside_table = DropZone((0.7, -0.4), (0.4, 0.4), table_W=table_W)
    spots = drop_spots(inside_table, [], outline, X_WO, count=50, base_outline_O=base)
    assert spots
    for X in spots:
        foot = footprint_at(base, X)
        assert np.all(foot >= np.add(table_W[0], TABLE_EDGE_MARGIN_M) - 1e-9)
        assert np.all(foot <= np.subtract(table_W[1], TABLE_EDGE_MARGIN_M) + 1e-9)


def test_the_hands_holding_an_object_stay_clear_of_the_objects_in_the_zone():
    strip = DropZone((0.6, -0.38), (0.8, 0.1))  # objects stand in a row along x, packed from low x
    X_WO = RigidTransform([0.7, 0.1, 0.8])
    outline_O = _box_footprint(0.04, 0.04, X_WO)  # a can's body, 8 cm across
    # A hand on a handle 8 cm behind it (-x in O), from behind: its palm and wrist stand out past the body, towards
    # the objects set down before it.
    X_OG = RigidTransform(RotationMatrix.MakeYRotation(np.pi / 2), [-0.08, 0.0, 0.1])
    hands_O = hands_footprint_O([X_WO @ X_OG], X_WO)
    assert inside(np.array([[-0.25, 0.0]]), hands_O[0])[0]  # the wrist, 17 cm behind the grasp
    first = drop_spots(strip, [], outline_O, X_WO, hands_O=hands_O)[0]
    dropped = [footprint_at(outline_O, first)]
    spots = drop_spots(strip, dropped, outline_O, X_WO, hands_O=hands_O)
    assert spots
    for spot in spots:
        assert all(outlines_apart(footprint_at(hand, spot), dropped[0], HAND_GAP_M - 1e-9) for hand in hands_O)
    # Without the hands the next spot stands where the hand would be on the first object.
    beside = drop_spots(strip, dropped, outline_O, X_WO)[0]
    assert not outlines_apart(footprint_at(hands_O[0], beside), dropped[0], 0.0)


def test_outlines_apart_tells_a_gap_from_an_overlap_one_inside_another_and_a_crossing():
    bar = np.array([[-1.0, -0.1], [1.0, -0.1], [1.0, 0.1], [-1.0, 0.1]])
    assert not outlines_apart(bar, bar[:, ::-1], 0.0)  # a cross: no corner of either inside the other
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    assert outlines_apart(square, square + [1.05, 0], 0.04)
    assert not outlines_apart(square, square + [1.03, 0], 0.04)
    assert not outlines_apart(square, 0.2 * square + 0.4, 0.01)  # inside


@pytest.mark.slow
def test_the_segmenter_takes_the_familiar_object_nearest_the_zone_and_leaves_out_those_given_up(scenario):
    table = clear_scene(scenario, 0, "tune")
    frame = settled_frame(table)
    zone_centre = np.array(drop_zone(table).centre_W)
    segmenter = MakeSegmenter(table, first_near_W=zone_centre)
    labels = segmenter.segment(frame.rgb)
    familiar = [np.array(table.object.xy)] + [np.array(o.xy) for o in table.clutter if o.instance]
    familiar = [xy + table.table_xyz[:2] for xy in familiar]
    by_distance = sorted(familiar, key=lambda xy: np.linalg.norm(xy - zone_centre))

    def chosen(left_out: LeftOut):
        segmentation = segmenter.object_of(labels, frame.depth, frame.X_WB, left_out)
        if not segmentation.found:
            return segmentation, None
        points = depth_to_points(frame.depth, segmentation.mask, segmenter.intrinsics)
        centre = (frame.X_WB @ segmenter.X_BC).multiply(points.mean(axis=0))[:2]
        return segmentation, centre

    def nearest(centre) -> int:  # which familiar object a mask's points' centre belongs to (not at its origin)
        return int(np.argmin([np.linalg.norm(centre - xy) for xy in by_distance]))

    segmentation, centre = chosen(LeftOut())
    assert segmentation.found and "the nearest of 2 left" in segmentation.message, segmentation.message
    assert nearest(centre) == 0
    first = _around(centre)
    segmentation, centre = chosen(LeftOut(given_up_W=(first,)))
    assert segmentation.found and nearest(centre) == 1, segmentation.message
    assert "1 given up" in segmentation.message
    segmentation, _ = chosen(LeftOut(given_up_W=(first, _around(centre))))
    assert not segmentation.found and segmentation.message.startswith("nothing to clear"), segmentation.message
    # Set down in the zone, but seen with its points' centre 2.5 cm off the footprint at its spot: still placed.
    placed = _around(first.mean(axis=0) + [0.0, -0.025 - 0.01], half_size=0.01)
    segmentation, centre = chosen(LeftOut(placed_W=(placed,)))
    assert segmentation.found and nearest(centre) == 1 and "1 in the drop zone" in segmentation.message


@pytest.mark.slow
def test_the_object_taken_on_is_completed_without_its_neighbours_parts(scenario):
    """Report table 15: two drills side by side, the farther one's side handle reaching towards the nearer one. The
    completion in 3D (object_completion) joined the nearer drill's housing (a body floating nearer the camera) to the
    farther drill taken first, and the two were one object: its outline covered both, and the second was left out as
    the same object given up, never taken on. Now the mask of the drill taken first holds none of its neighbour."""
    table = clear_scene(scenario, 15)
    frame = settled_frame(table)
    segmenter = MakeSegmenter(table, first_near_W=np.array(drop_zone(table).centre_W))
    labels = segmenter.segment(frame.rgb)
    mask = segmenter.object_of(labels, frame.depth, frame.X_WB, LeftOut()).mask
    # The drill taken first is the clutter's, nearer the zone; the scenario's own drill is the neighbour.
    bodies, counts = np.unique(frame.labels[mask], return_counts=True)
    assert bodies[np.argmax(counts)] != frame.object_label and counts.max() > 0.85 * mask.sum()
    assert np.count_nonzero(frame.labels[mask] == frame.object_label) < 0.001 * mask.sum()


def _around(xy, half_size: float = 0.01) -> np.ndarray:
    """A small square outline about a point (x, y, m)."""
    return np.asarray(xy) + half_size * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])


def _clear_supervisor(result: PerceptionResult, max_objects: int = 4, home_q: np.ndarray | None = None):
    dut = PickSupervisor(
        clear_pick(), perceive_at_s=0.1, looks=True, drop_zone=ZONE, max_objects=max_objects, home_q=home_q
    )
    context = dut.CreateDefaultContext()
    dut.GetInputPort("position_measured").FixValue(context, Q0)
    for side in ("left", "right"):
        dut.GetInputPort(f"{side}_hand_state").FixValue(context, [0.0, 0.0])
    dut.GetInputPort("frame_id").FixValue(context, [1.0])
    dut.GetInputPort("perception").FixValue(context, AbstractValue.Make(result))
    dut.GetInputPort("look_frame_id").FixValue(context, [0.0])
    dut.GetInputPort("plan").FixValue(context, AbstractValue.Make(PlanResult()))
    return dut, context, Simulator(dut, context)


def test_a_table_with_nothing_familiar_ends_the_clear_at_once():
    nothing = PerceptionResult(False, Stage.SEGMENTATION, "nothing to clear: no familiar object left (0 in the drop "
                               "zone, 0 given up)")  # fmt: skip
    dut, context, simulator = _clear_supervisor(nothing)
    simulator.AdvanceTo(0.2)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.mode == Mode.DONE and status.objects == ()
    assert status.message == "cleared 0 of 0 objects taken on; " + nothing.message


@pytest.mark.parametrize("home_q", [None, Q0 + 0.2])
def test_an_object_that_fails_is_given_up_left_out_and_the_next_one_looked_for(home_q):
    """(With a home between objects that is not the start, too: nothing moved, so nothing goes home.)"""
    points = np.array([[0.7, 0.1, 0.8], [0.72, 0.12, 0.9]])
    poor = PerceptionResult(False, Stage.REGISTRATION, "a poor fit", category="drill", points_W=points)
    dut, context, simulator = _clear_supervisor(poor, max_objects=2, home_q=home_q)
    simulator.AdvanceTo(0.15)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.mode == Mode.PERCEIVING and status.perceive_id == 2  # nothing moved: it looks again at once
    assert np.array_equal(status.q_start, Q0) and np.array_equal(status.q_home, Q0 if home_q is None else home_q)
    (given_up,) = status.objects
    assert not given_up.cleared and given_up.category == "drill" and given_up.failed_stage == "registration"
    assert given_up.seen_xy_W == pytest.approx((0.71, 0.11))
    left_out = dut.GetOutputPort("left_out").Eval(context)
    (outline,) = left_out.given_up_W
    assert left_out.zone == ZONE and np.array_equal(outline, given_up.seen_outline_W)
    assert inside(np.array([given_up.seen_xy_W]), outline).all()
    dut.GetInputPort("frame_id").FixValue(context, [2.0])  # the same again: the second object, the last one allowed
    simulator.AdvanceTo(0.3)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.mode == Mode.DONE and len(status.objects) == 2
    assert status.message.startswith("cleared 0 of 2 objects taken on; given up: drill at (0.71, 0.11): ")
    assert status.message.endswith("took on 2 objects, the most")


def test_an_object_retried_and_not_seen_again_is_given_up_by_name_and_the_clear_goes_on():
    """Attempt 1 failed (the can fell over in the carry); attempt 2's frame finds no familiar object: the can is
    recorded as given up (it was lost from the record before), and the clear ends on the next look's "nothing left"."""
    nothing = PerceptionResult(False, Stage.SEGMENTATION, "nothing to clear: no familiar object left (0 in the drop "
                               "zone, 0 given up)")  # fmt: skip
    dut, context, simulator = _clear_supervisor(nothing)
    under_way = ClearedObject("watering_can", (0.7, -0.06), attempts=1, target_xy_W=(0.67, -0.22))
    retried = PickStatus(Mode.PERCEIVING, perceive_id=1, plan_end_q=Q0, q_home=Q0, attempt=2, current=under_way)
    context.get_mutable_abstract_state(0).set_value(retried)
    simulator.AdvanceTo(0.1)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.mode == Mode.PERCEIVING and status.perceive_id == 2  # (given up where nothing moved: a new look)
    (given_up,) = status.objects
    assert given_up.message.startswith("segmentation: not seen again after attempt 1 (") and given_up.attempts == 2
    assert given_up.message.endswith("(0 in the drop zone, 0 given up))")  # (what the frame saw, kept)
    assert given_up.target_xy_W == (0.67, -0.22) and not given_up.cleared
    dut.GetInputPort("frame_id").FixValue(context, [2.0])
    simulator.AdvanceTo(0.2)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.mode == Mode.DONE
    assert status.message.startswith("cleared 0 of 1 objects taken on; given up: watering_can at (0.70, -0.06)")


def test_a_perceived_object_gets_a_spot_in_the_zone_and_the_place_task_carries_it_there():
    X_WO = RigidTransform([0.7, 0.1, 0.8])
    shape = X_WO.multiply(np.array([[x, y, z] for x in (-0.1, 0.1) for y in (-0.05, 0.05) for z in (0, 0.2)]).T).T
    seen = PerceptionResult(True, category="drill", X_WO_seen=X_WO, points_W=shape, reconstruction_W=shape)
    dut, context, simulator = _clear_supervisor(seen)
    simulator.AdvanceTo(0.15)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.mode == Mode.REACH and status.task == TaskName.PLACE
    assert ZONE.contains(status.place_target_W.translation()[:2]) and status.current.target_xy_W is not None
    assert ZONE.contains(status.current.footprint_W, DROP_OVERHANG_M + 1e-9).all()


@pytest.mark.parametrize("found", [True, False])
def test_after_an_object_is_cleared_the_frame_of_the_scene_sends_the_arms_home_with_no_object_believed(found):
    """Between two objects the supervisor believes no object (the next is not seen yet): the move home needs none.
    (A move's place target was read from the belief on every move once: the second object of every table ended
    the clear with an AttributeError.) Whatever that frame finds, the arms go home: over the table they hide it, and
    "nothing to clear" in it ended the clear of report tables 0, 3 and 5 with their second object never looked for."""
    X_WO = RigidTransform([0.7, 0.1, 0.8])
    shape = X_WO.multiply(np.array([[x, y, z] for x in (-0.1, 0.1) for y in (-0.05, 0.05) for z in (0, 0.2)]).T).T
    seen = PerceptionResult(True, category="drill", X_WO_seen=X_WO, points_W=shape, reconstruction_W=shape)
    nothing = PerceptionResult(False, Stage.SEGMENTATION, "nothing to clear: no familiar object left (0 in the drop "
                               "zone, 0 given up)")  # fmt: skip
    dut, context, simulator = _clear_supervisor(seen if found else nothing)
    where = np.array([[0.66, -0.24, 0.8], [0.68, -0.2, 0.9]])  # (its shape where it stands)
    cleared = ClearedObject("watering_can", (0.7, -0.06), 1, cleared=True, target_xy_W=(0.67, -0.22), shape_W=where)
    backed_off = Q0 + 0.1
    between = PickStatus(Mode.PERCEIVING, perceive_id=1, plan_end_q=backed_off, q_home=Q0, objects=(cleared,))
    context.get_mutable_abstract_state(0).set_value(dataclasses.replace(between, homing=True))
    simulator.AdvanceTo(0.1)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.task == TaskName.HOME and status.belief is None and not status.homing
    assert np.array_equal(status.request.q_goal, Q0) and np.array_equal(status.request.q_start, backed_off)
    assert np.array_equal(status.request.set_down_W, where)  # the move home plans around what stands in the zone


def test_the_carry_and_the_set_down_plan_around_the_objects_already_in_the_zone_too():
    """The object carried hides the zone from the look before its set-down as the arms hide it after one: the held
    moves plan around the shapes set down as the free ones do (tune tables 0-3, 2026-12-07: 6 of 8 cleared against
    5 of 8 with the free moves alone; docs/clear.md)."""
    X_WO = RigidTransform([0.7, 0.1, 0.8])
    shape = X_WO.multiply(np.array([[x, y, z] for x in (-0.1, 0.1) for y in (-0.05, 0.05) for z in (0, 0.2)]).T).T
    seen = PerceptionResult(True, category="drill", X_WO_seen=X_WO, points_W=shape, reconstruction_W=shape)
    dut, context, simulator = _clear_supervisor(seen)
    where = np.array([[0.66, -0.24, 0.8], [0.68, -0.2, 0.9]])
    footprint = np.array([[0.64, -0.26], [0.7, -0.26], [0.7, -0.18], [0.64, -0.18]])
    cleared = ClearedObject("watering_can", (0.7, -0.06), 1, cleared=True, target_xy_W=(0.67, -0.22),
                            footprint_W=footprint, shape_W=where)  # fmt: skip
    state = context.get_mutable_abstract_state(0)
    state.set_value(dataclasses.replace(state.get_value(), objects=(cleared,)))
    simulator.AdvanceTo(0.15)
    status = dut.GetOutputPort("status").Eval(context)
    assert status.mode == Mode.REACH and status.task == TaskName.PLACE
    assert np.array_equal(status.request.set_down_W, where)
    held = [k for k, phase in enumerate(dut.tasks[TaskName.PLACE].phases) if phase.path == MoveKind.HELD]
    assert len(held) >= 3  # the lift, the carry, the set-down
    for index in held:
        dut._start_phase(context, status, index, 0.2)
        assert status.request.path == MoveKind.HELD and np.array_equal(status.request.set_down_W, where)


def test_an_object_set_down_keeps_its_shape_where_it_is_believed_to_stand():
    """The record of a cleared object carries its inferred shape moved as the belief moved the object (the carry,
    the set-down, the look after it); the objects given up add none to what the free moves plan around."""
    X_WO_seen = RigidTransform([0.7, 0.1, 0.8])
    shape = X_WO_seen.multiply(np.array([[x, y, 0.1] for x in (-0.1, 0.1) for y in (-0.05, 0.05)]).T).T
    seen = PerceptionResult(True, category="drill", X_WO_seen=X_WO_seen, points_W=shape, reconstruction_W=shape)
    status = PickStatus(objects=(ClearedObject("drill", (0.7, 0.4), 1, shape_W=np.zeros((1, 3))),))  # (given up)
    _, record = chosen_spots(ZONE, status, seen)
    assert record.shape_W.shape == (4, 3) and set_down_shapes(status) is None
    X_WO_now = RigidTransform(RotationMatrix.MakeZRotation(-0.5), [0.67, -0.22, 0.8])
    done = placed(record, ObjectBelief(X_WO_seen, X_WO_now), attempts=2)
    assert done.cleared and done.attempts == 2
    np.testing.assert_allclose(done.shape_W, X_WO_now.multiply(X_WO_seen.inverse().multiply(record.shape_W.T)).T)
    status.objects += (done,)
    np.testing.assert_array_equal(set_down_shapes(status), done.shape_W)


@pytest.mark.slow
def test_the_tables_to_clear_are_seeded_and_keep_their_promises(scenario):
    for k in range(3):
        table = clear_scene(scenario, k, "tune")
        assert table == clear_scene(scenario, k, "tune") and table.task == "clear"
        familiar = 1 + sum(bool(other.instance) for other in table.clutter)
        assert 2 <= familiar <= 3 and 1 <= len(table.clutter) - familiar + 1 <= 2
        (cx, cy), (sx, sy) = table.clear.zone_xy, table.clear.zone_size
        zone = np.array([[cx - sx / 2, cy - sy / 2], [cx + sx / 2, cy - sy / 2], [cx + sx / 2, cy + sy / 2],
                         [cx - sx / 2, cy + sy / 2]])  # fmt: skip
        for outline in scene_outlines(table):
            assert gap_between(outline, zone) >= ZONE_CLEARANCE_M - 1e-9
    assert clear_scene(scenario, 0) != clear_scene(scenario, 0, "tune")
    # (the validation tables' familiar objects are unseen instances of their own: neither training nor report ones)
    validation = clear_scene(scenario, 0, "validation")
    instances = [validation.object.instance, *(other.instance for other in validation.clutter if other.instance)]
    assert all(name in ("extra_2600", "extra_2601", "extra_2602") for name in instances), instances
    with pytest.raises(ValueError, match="unknown split"):
        clear_scene(scenario, 0, "test")


@pytest.mark.slow
def test_the_tables_stand_familiar_objects_only_where_the_arms_reach_them(scenario):
    """Report table 4 was drawn with a drill whose true grasps' approach is out of the arms' reach (the ground-truth
    pick failed there too); the table now has it where the arms reach it, and keeps the rest as it was."""
    motions = make_pick_motions(scenario)
    drawn_before = replace_object(scenario, category="drill", instance="extra_2313", file="", xy=[-0.0999, 0.1938],
                                  yaw=-0.1936)  # fmt: skip
    assert not arms_reach(motions, drawn_before)
    table = clear_scene(scenario, 4)
    familiar = [table.object] + [other for other in table.clutter if other.instance]
    can, drill = familiar
    assert can.instance == "extra_2312" and np.allclose(can.xy, [-0.0748, -0.037], atol=1e-3)  # kept as it was
    assert drill.instance == "extra_2313" and not np.allclose(drill.xy, drawn_before.object.xy, atol=0.01)  # moved
    for category, other in (("watering_can", can), ("drill", drill)):
        alone = replace_object(
            scenario, category=category, instance=other.instance, file="", xy=other.xy, yaw=other.yaw
        )
        assert arms_reach(motions, alone), other


@pytest.mark.slow
def test_the_zone_reach_tells_a_spot_the_arms_carry_to_from_one_beyond_them(scenario):
    """benchmark_use_reach.py --task clear's core: a carry of no length is reached, one 1.2 m to the robot's right is
    not, and an object the arms do not lift has no answer (the drill report table 4 was first drawn with)."""
    motions = make_pick_motions(scenario)
    assert scenario.object.category == "watering_can"
    X_WO = object_pose_on_table(scenario, resolve_object(scenario.object))
    here = X_WO.translation()[:2]
    reached = carry_reach(motions, scenario, np.array([here, here - [0.0, 1.2]]), [0.0])
    assert reached.tolist() == [[True], [False]]
    out_of_reach = replace_object(scenario, category="drill", instance="extra_2313", file="", xy=[-0.0999, 0.1938],
                                  yaw=-0.1936)  # fmt: skip
    assert carry_reach(motions, out_of_reach, np.array([here]), [0.0]) is None


def test_scenario_checks_the_drop_zone():
    for text, message in (
        ("{clear: {zone_xy: [0.1]}}", "clear.zone_xy"),
        ("{clear: {zone_size: [0.05, 0.4]}}", "clear.zone_size"),
        ("{clear: {max_objects: 0}}", "clear.max_objects"),
        ("{clear: {home_arm_positions: [0.9, 0.2]}}", "clear.home_arm_positions must have 14 entries"),
    ):
        with pytest.raises(ValueError, match=message):
            overlay_scenario(load_scenario(), text, "--scenario_text")


def test_the_clear_home_leaves_the_whole_zone_to_the_objects_where_the_start_keeps_its_near_rows_out(scenario):
    """At the start the right hand hangs 15 cm above the zone's near rows, where the arms carry every object; the
    clear's home between objects raises it over ZONE_KEEP_OUT_HEIGHT_M, and nothing of the robot keeps objects out."""
    scenario = dataclasses.replace(scenario, task="clear")
    near_rows = np.array([[x, y] for x in (0.5, 0.56, 0.62) for y in (-0.43, -0.37)])  # (W, m: docs/clear.md)

    def kept_out(zone: DropZone) -> np.ndarray:
        return np.array([any(np.hypot(*(p - (x, y))) < r for x, y, r in zone.keep_out_W) for p in near_rows])

    at_start = drop_zone(scenario, robot_at_start(scenario))
    assert kept_out(at_start).any()
    at_home = drop_zone(scenario, robot_at_start(clear_home(scenario)))
    assert not kept_out(at_home).any()
    (cx, cy), (sx, sy) = at_home.centre_W, at_home.size
    for x, y, r in at_home.keep_out_W:  # (the left hand's, over the table's other side, alone)
        assert abs(x - cx) > sx / 2 + r or abs(y - cy) > sy / 2 + r
    start = overlay_scenario(scenario, "{clear: {home_arm_positions: []}}", "--scenario_text")
    assert clear_home(start).initial_arm_positions == scenario.initial_arm_positions


@pytest.mark.slow
def test_a_table_of_distractors_alone_is_cleared_at_once_and_nothing_moves(scenario):
    """Sensor on: no familiar object in view, the clear ends on its first frame with "nothing to clear"."""
    outcome = run_pick(_distractors_only(scenario))
    assert outcome.success and outcome.clear["familiar_objects"] == 0, outcome.message
    assert outcome.clear["summary"].endswith(
        "nothing to clear: no familiar object left (0 in the drop zone, 0 given up)"
    )
    assert outcome.clear["others_moved_m_max"] < 0.005 and outcome.sim_time_s < 2.0


@pytest.mark.slow
def test_endurance_measures_memory_growth_and_the_task_time_trend_from_the_tasks_run(scenario):
    """run_endurance with a stand-in for the pick (a PickOutcome of its own): the figures come from what it ran."""
    from diagrams.benchmarks.endurance import resident_memory_mb, run_endurance, task_time_slope
    from diagrams.pick_simulation import PickOutcome

    assert task_time_slope([1.0, 2.0, 3.0, 4.0]) == pytest.approx((1.0, 0.0), abs=1e-9)
    assert np.isnan(task_time_slope([1.0, 2.0])[0]) and resident_memory_mb() > 10
    seen = []

    def run_task(table):
        seen.append(table.object.instance)
        outcome = PickOutcome(True, 0.0, 0.0, sim_time_s=30.0)
        outcome.clear = {"objects_cleared": 2, "familiar_objects": 2}
        return outcome

    report = run_endurance(scenario, 10.0, run_task, tables=2, split="tune", max_tasks=6)
    assert [t["table"] for t in report["tasks"]] == [0, 1, 0, 1, 0, 1] and seen[0] == seen[2] != seen[1]
    assert report["failures"] == 0 and report["command_gap_ms_max"] is None
    assert abs(report["memory_growth_share"]) < 0.5 and np.isfinite(report["task_time_slope_s_per_task"])


@pytest.fixture(scope="module")
def can_cleared(scenario):
    """The default scenario's clear (the unseen can alone, sensor on), run in this process after another task (a
    table of distractors: a whole diagram built, its camera frame segmented, released)."""
    run_pick(_distractors_only(scenario))
    return run_pick(dataclasses.replace(scenario, task="clear"))


def _distractors_only(scenario):
    """A table to clear with a box and a cylinder on it, nothing familiar."""
    boxes = [
        ClutterObjectConfig(kind="box", size=[0.08, 0.1, 0.1], xy=[-0.1, 0.1]),
        ClutterObjectConfig(kind="cylinder", size=[0.08, 0.08, 0.12], color=[0.2, 0.5, 0.8], xy=[0.05, -0.1]),
    ]
    return dataclasses.replace(
        scenario, task="clear", clutter=boxes, object=dataclasses.replace(scenario.object, present=False)
    )


@pytest.mark.slow
def test_a_can_alone_is_cleared_into_the_zone_and_the_clear_ends_when_the_table_is_empty(scenario, can_cleared):
    """Sensor on, the default unseen can: placed in the drop zone, a look for the scene, home, a look that finds
    nothing left; judged on the plant: in the zone, upright, let go."""
    outcome = can_cleared
    assert outcome.success and outcome.clear["objects_cleared"] == 1, outcome.message
    (taken,) = outcome.clear["taken_on"]
    assert taken["cleared"] and taken["attempts"] == 1 and taken["category"] == "watering_can"
    (judged,) = outcome.clear["objects"]
    assert judged["in_zone"] and judged["tilt_rad"] < np.radians(5.0) and judged["let_go"]
    assert np.linalg.norm(np.subtract(judged["end_xy_W"], taken["target_xy_W"])) < 0.05
    assert outcome.clear["summary"].startswith("cleared 1 of 1 objects taken on; nothing to clear")
    end = np.array(judged["end_footprint_W"])  # (the true footprint where it ended: in the zone, about its centre)
    assert drop_zone(scenario).contains(end.mean(axis=0)) and inside(np.array([judged["end_xy_W"]]), end).all()
    assert outcome.clear["zone"]["size"] == list(scenario.clear.zone_size)


@pytest.mark.slow
def test_a_clear_run_after_other_tasks_in_one_process_ends_as_it_does_alone(can_cleared, tmp_path):
    """Determinism across tasks: the clear run in this process after others ends exactly as the same clear run alone
    in a fresh process (scripts/pick.py): nothing a task leaves behind changes the next."""
    alone = tmp_path / "alone.json"
    command = [sys.executable, str(REPO_ROOT / "scripts" / "pick.py"), "--task", "clear", "--json", str(alone)]
    subprocess.run(command, cwd=REPO_ROOT, check=True, capture_output=True, timeout=900)
    alone = json.loads(alone.read_text())
    assert alone["message"] == can_cleared.message and alone["attempts_made"] == can_cleared.attempts_made
    assert alone["clear"]["taken_on"] == json.loads(json.dumps(can_cleared.clear["taken_on"]))
    for key in ("start_xy_W", "end_xy_W", "tilt_rad"):
        np.testing.assert_allclose(alone["clear"]["objects"][0][key], can_cleared.clear["objects"][0][key], atol=1e-9)
    assert alone["min_hold_height_m"] == pytest.approx(can_cleared.min_hold_height_m, abs=1e-9)


def test_objects_given_up_before_another_was_cleared_get_a_later_pass_over_the_table():
    seen = _around((0.7, 0.1), 0.03)
    given_up = ClearedObject("drill", (0.7, 0.1), 1, failed_stage="planning", message="no plan", seen_outline_W=seen)
    cleared = ClearedObject("watering_can", (0.75, -0.1), attempts=1, cleared=True)
    assert next_pass(PickStatus(objects=(cleared, given_up))) is None  # (nothing changed since it was given up)
    status = PickStatus(objects=(given_up, cleared))
    assert len(left_out(ZONE, status).given_up_W) == 1
    status.pass_from = next_pass(status)
    assert status.pass_from == 2 and left_out(ZONE, status).given_up_W == ()  # perception sees it again
    again = dataclasses.replace(given_up, attempts=2, later_pass=True)
    status.objects += (again,)
    assert next_pass(status) is None  # once: nothing was cleared since
    assert len(left_out(ZONE, status).given_up_W) == 1
    assert summary(status, "done") == (
        "cleared 1 of 3 objects taken on; given up: drill at (0.70, 0.10): no plan; drill at (0.70, 0.10) (a later "
        "pass): no plan; done"
    )
