"""Where in the clear task's drop zone the arms carry each familiar object of the clear tables
(scripts/benchmark_use_reach.py --task clear): the question a zone's placement and the spots' order answer.

Each familiar object of a table stands alone on it, picked with its true grasps as the pick moves and lifted
(clear_scenes.lifted_configuration); then, for each spot of a grid over the zone and each turn about the vertical
from how it stood, whether the carry's held path reaches the spot (HeldMotions.held_path: the hands walked there in
steps, each solved from the one before, as the pick's carry finds its goal). The carry is place_goals.place_motion's
(over the spot, turned to its yaw, at the carried height). Ground truth places the object: this measures the arms'
reach, not perception; nothing else on the table is in the way.
"""

from collections.abc import Callable

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from diagrams.generation.clear_scenes import clear_scene, lifted_configuration
from diagrams.generation.objects.library import resolve_object
from diagrams.scenario import Scenario, replace_object
from diagrams.station import drop_zone, object_pose_on_table
from systems.messages import ObjectBelief, PlaceGoal
from systems.pick_tasks import PLACE_LIFT_HEIGHT
from systems.planning.pick_motions import PickMotions
from systems.planning.place_goals import place_motion
from systems.planning.straight_motions import PlanningError


def zone_grid(scenario: Scenario, step: float) -> tuple[np.ndarray, np.ndarray]:
    """The spots' centres along x and y of W (m): `step` apart, half a step in from the zone's marks."""
    zone = drop_zone(scenario)
    xs = np.arange(zone.low[0] + step / 2, zone.high[0] - step / 2 + 1e-9, step)
    ys = np.arange(zone.low[1] + step / 2, zone.high[1] - step / 2 + 1e-9, step)
    return xs, ys


def carry_reach(
    motions: PickMotions, scenario: Scenario, spots_xy: np.ndarray, turns_rad: list[float]
) -> np.ndarray | None:
    """Whether the arms carry the scenario's object, alone on the table and lifted with its true grasps, over each
    spot (K x 2, x, y in W, m) turned by each of turns_rad about the vertical (K x T booleans); None where they do
    not lift it."""
    q_lift = lifted_configuration(motions, scenario)
    if q_lift is None:
        return None
    X_WO = object_pose_on_table(scenario, resolve_object(scenario.object))
    belief = ObjectBelief(X_WO, RigidTransform([0.0, 0.0, PLACE_LIFT_HEIGHT]) @ X_WO)
    reached = np.zeros((len(spots_xy), len(turns_rad)), bool)
    for i, (x, y) in enumerate(spots_xy):
        for j, turn in enumerate(turns_rad):
            spot = RigidTransform(RotationMatrix.MakeZRotation(turn) @ X_WO.rotation(), [x, y, X_WO.translation()[2]])
            motion, _ = place_motion(PlaceGoal.CARRY, belief, spot)
            try:
                motions.held_path(q_lift, motion, 1.0)
                reached[i, j] = True
            except PlanningError:
                pass
    return reached


def zone_reach_rows(
    motions: PickMotions,
    base: Scenario,
    tables: int,
    split: str,
    turns_rad: list[float],
    step: float,
    progress: Callable[[dict], None] | None = None,
) -> list[dict]:
    """One row per familiar object of clear tables 0..tables-1 of `split`: where it stands, and per turn the zone's
    spots (zone_grid) it is carried to (`reached`: one list per x, one boolean per y; None where it is not lifted).
    progress: called with each row as it is done."""
    xs, ys = zone_grid(base, step)
    spots = np.array([(x, y) for x in xs for y in ys])
    rows = []
    for k in range(tables):
        table = clear_scene(base, k, split)
        familiar = [(table.object.category, table.object.instance, table.object.xy, table.object.yaw)]
        familiar += [(o.kind, o.instance, o.xy, o.yaw) for o in table.clutter if o.instance]  # (not distractors)
        for category, instance, xy, yaw in familiar:
            alone = replace_object(base, category=category, instance=instance, file="", xy=list(xy), yaw=yaw)
            reached = carry_reach(motions, alone, spots, turns_rad)
            rows.append({
                "table": k, "split": split, "category": category, "instance": instance,
                "xy_W": [float(v) for v in np.add(base.table_xyz[:2], xy)], "yaw_rad": float(yaw),
                "xs_W": xs.tolist(), "ys_W": ys.tolist(), "turns_rad": list(turns_rad),
                "reached": None if reached is None else {
                    str(turn): reached[:, j].reshape(len(xs), len(ys)).tolist() for j, turn in enumerate(turns_rad)
                },
            })  # fmt: skip
            if progress is not None:
                progress(rows[-1])
    return rows
