"""The clear task's bookkeeping between objects, for the PickSupervisor (systems/pick_supervisor.py): where the next
object goes in the drop zone, what perception leaves out when it looks for the next one, which objects given up are
taken on again, and each object's record."""

import dataclasses
import logging

import numpy as np
from pydrake.math import RigidTransform
from scipy.spatial import QhullError

from systems.messages import SIDES, ClearedObject, LeftOut, Mode, ObjectBelief, PerceptionResult, PickStatus
from systems.perception.pose_estimator import voxel_thin
from systems.planning.drop_zone import DropZone, base_O, drop_spots, footprint_at, footprint_O, hands_footprint_O
from systems.planning.outlines import convex_outline

SEEN_POINT_HALF_SIZE_M = 0.02  # m: an object seen as points on a line is given this outline about their centre
SHAPE_CELL_M = 0.01  # m: an object's inferred shape kept as one point per cube of this side (the scene's cell)


def not_seen_again(result: PerceptionResult, attempts: int) -> PerceptionResult:
    """A retry's frame that finds nothing to clear: the object under way fell over, off the table, or into the drop
    zone (where perception leaves everything out); the frame's own account (how many stand in the zone) is kept."""
    where = "fallen over, off the table or into the drop zone"
    return dataclasses.replace(result, message=f"not seen again after attempt {attempts} ({where}; {result.message})")


def seen_object(result: PerceptionResult, later_pass: bool = False) -> ClearedObject | None:
    """The record of an object perception saw (its category, the centre of its seen points), before it is taken on;
    None where perception saw no point of it."""
    points = result.points_W
    if points is None or not len(points):
        return None
    centre = np.mean(points, axis=0)
    try:
        outline = convex_outline(points[:, :2])
    except QhullError:  # (its points on a line, or too few)
        outline = centre[:2] + SEEN_POINT_HALF_SIZE_M * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
    xy = (float(centre[0]), float(centre[1]))
    return ClearedObject(result.category, xy, attempts=1, later_pass=later_pass, seen_outline_W=outline)


def chosen_spots(zone: DropZone, status: PickStatus, result: PerceptionResult) -> tuple[list, ClearedObject]:
    """Where in the zone the perceived object may go, best first ((X_WO, its footprint there: M x 2 in W, m) each;
    [] where it fits nowhere), and its record with the first spot: its footprint from the registrar's whole inferred
    shape (the seen points where there is none); the hands holding it (its grasps) kept clear of the objects there,
    its base (that shape's lowest points) on the table."""
    record = seen_object(result, later_pass=status.pass_from > 0)
    shape = result.reconstruction_W if result.reconstruction_W is not None else result.points_W
    outline_O = footprint_O(shape, result.X_WO_seen)
    dropped = [done.footprint_W for done in status.objects if done.cleared]
    grasps_W = [result.grasps.poses_W[f"{side}_grasp"] for side in SIDES] if result.grasps.found else []
    hands_O = hands_footprint_O(grasps_W, result.X_WO_seen)
    base = base_O(shape, result.X_WO_seen)
    spots = drop_spots(zone, dropped, outline_O, result.X_WO_seen, hands_O=hands_O, base_outline_O=base)
    spots = [(X_WO, footprint_at(outline_O, X_WO)) for X_WO in spots]
    if record is not None and result.reconstruction_W is not None and len(result.reconstruction_W):
        record = dataclasses.replace(record, shape_W=voxel_thin(result.reconstruction_W, SHAPE_CELL_M))
    return spots, (with_spot(record, *spots[0]) if spots else record)


def take_spot(zone: DropZone, status: PickStatus, result: PerceptionResult) -> bool:
    """Gives the perceived object (result) its spot in the zone and the spots to try after it (status.current,
    place_target_W, spare_spots); where none is left, records it and ends the clear ("the drop zone is full").
    Whether it got a spot."""
    spots, status.current = chosen_spots(zone, status, result)
    if not spots:
        status.place_target_W, status.spare_spots = None, ()
        status.objects += (dataclasses.replace(status.current, message="no room left in the drop zone"),)
        status.mode, status.message = Mode.DONE, summary(status, "the drop zone is full")
        return False
    status.place_target_W, status.spare_spots = spots[0][0], tuple(spots[1:])
    logging.info("its spot in the drop zone: %s (%d more)", status.current.target_xy_W, len(spots) - 1)
    return True


def nothing_moved(status: PickStatus) -> bool:
    """Whether the robot stands where the pick began or at home, its hands never closed: an object given up there
    needs no letting go or backing off."""
    if status.plan_end_q is None or status.grasp_widths:
        return False
    return any(q is not None and np.allclose(status.plan_end_q, q, atol=1e-3) for q in (status.q_start, status.q_home))


def forget_object(status: PickStatus) -> None:
    """Clears what the status knew of the object just placed or given up, before the next one is looked for."""
    status.task, status.attempt, status.corrections, status.place_corrections = None, 1, 0, 0
    status.belief, status.aim, status.pour, status.pending_failure, status.place_target_W = (None,) * 5
    status.spare_spots, status.grasp_widths, status.grasp_offsets_G, status.attempt_failures = (), (), None, ()


def placed(record: ClearedObject, belief: ObjectBelief | None, attempts: int) -> ClearedObject:
    """The record of the object under way, set down in the zone: cleared, its shape moved to where the belief
    (its pose as seen, and since, after the set-down and the look that confirmed it) says it stands."""
    shape_W = record.shape_W
    if shape_W is not None and belief is not None:
        shape_W = (belief.now_W @ belief.seen_W.inverse()).multiply(shape_W.T).T
    return dataclasses.replace(record, cleared=True, attempts=attempts, shape_W=shape_W)


def set_down_shapes(status: PickStatus) -> np.ndarray | None:
    """The shapes of the objects set down in the zone where they stand (N x 3 in W, m), for a clear's moves to plan
    around (PlanRequest.set_down_W); None where there is none."""
    shapes = [done.shape_W for done in status.objects if done.cleared and done.shape_W is not None]
    return np.vstack(shapes) if shapes else None


def with_spot(record: ClearedObject, X_WO: RigidTransform, footprint_W: np.ndarray) -> ClearedObject:
    """The record with its spot in the zone (X_WO) and its footprint there."""
    xy = X_WO.translation()[:2]
    return dataclasses.replace(record, target_xy_W=(float(xy[0]), float(xy[1])), footprint_W=footprint_W)


def given_up(status: PickStatus, in_zone: bool) -> ClearedObject:
    """The record of the object under way (status.current) given up after its failure (status.failed_stage, .message);
    `in_zone`: taking it again off its spot failed, so it stands in the zone already, near its spot (placed)."""
    return dataclasses.replace(
        status.current,
        attempts=status.attempt,
        cleared=in_zone,
        failed_stage=str(status.failed_stage),
        message=f"set down off its spot; taking it again: {status.message}" if in_zone else status.message,
    )


def left_out(zone: DropZone | None, status: PickStatus) -> LeftOut:
    """What perception leaves out looking for the next object: the zone, where the objects given up stood, and
    where those set down in the zone stand (their footprints at their spots)."""
    given_up = tuple(done.seen_outline_W for done in status.objects[status.pass_from :] if not done.cleared)
    placed = tuple(done.footprint_W for done in status.objects if done.cleared and done.footprint_W is not None)
    return LeftOut(zone, given_up, placed)


def next_pass(status: PickStatus) -> int | None:
    """Once no object is left but those given up: where a new pass over the table begins (status.pass_from), when an
    object was given up in this pass before another was cleared. The table has changed since: a neighbour that took
    away the arms' reach or hid a handle may have gone. None: no new pass. Each pass begins after an object cleared
    in the one before, so the clear ends."""
    last_cleared = max((i for i, done in enumerate(status.objects) if done.cleared), default=-1)
    given_up = [i for i in range(status.pass_from, last_cleared) if not status.objects[i].cleared]
    return last_cleared + 1 if given_up else None


def summary(status: PickStatus, why_ended: str) -> str:
    """The clear's closing line: how many objects went to the zone, which were given up and why (and which were left
    off their spots), and why it ended."""
    cleared = sum(done.cleared for done in status.objects)
    line = f"cleared {cleared} of {len(status.objects)} objects taken on"
    for heading, cleared in (("given up", False), ("placed, not taken again", True)):
        told = [
            f"{done.category} at ({done.seen_xy_W[0]:.2f}, {done.seen_xy_W[1]:.2f})"
            f"{' (a later pass)' * done.later_pass}: {done.message}"
            for done in status.objects
            if done.cleared == cleared and done.message
        ]
        if told:
            line += f"; {heading}: " + "; ".join(told)
    return f"{line}; {why_ended}"
