"""The motions of a pick, planned from Cartesian goals of both hands' grasp frames G; one kind per module.

  reach:     to given hand poses (the pre-grasps), around the obstacles (systems/planning/reach_motions.py).
  straight:  each hand along a straight line to its goal, keeping its orientation: approach, retreat
             (systems/planning/straight_motions.py).
  held move: both hands hold one object and move it by a rigid motion in W: lift, carry, set down
             (systems/planning/held_motions.py).

Each returns joint-space keyframes (K x n, the start first); time parameterisation and the dense check of the played
trajectory are time_parameterise() below and PickMotions.closure_deviations().

PickMotions is built once from a PlanningWorld (systems/planning/world.py) and a PlannerConfig; it keeps nothing
between motions. What changes from one motion to the next (the object as seen, the points of a carried object) is
each motion's argument.
"""

import itertools
from dataclasses import dataclass, field

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from systems.planning.held_motions import HELD_MASS_KG, HeldMotions, HeldMove
from systems.planning.ik import DualArmIk
from systems.planning.reach_motions import Reach, ReachMotions
from systems.planning.stomp import Stomp
from systems.planning.stomp_config import StompConfig
from systems.planning.straight_motions import PlanningError, StraightMotions
from systems.planning.world import PlanningWorld
from systems.robot_io.joint_plan import move_duration

__all__ = [
    "SPARSE_SEGMENT_S",
    "STOMP_SEGMENT_S",
    "HeldMove",
    "PickMotions",
    "PlannerConfig",
    "PlanningError",
    "Reach",
    "time_parameterise",
]

# Shortest duration of one move between sparse (IK) keyframes, and between STOMP's dense ones, s.
SPARSE_SEGMENT_S = 0.8
STOMP_SEGMENT_S = 0.1


@dataclass(frozen=True)
class PlannerConfig:
    """The planning core's settings, given once when it is built."""

    stomp: StompConfig = field(default_factory=StompConfig)
    held_mass_kg: float = HELD_MASS_KG  # what STOMP's torque term assumes a held object weighs (HELD_MASS_KG)
    # Each arm's IK by batched Gauss-Newton first (SNOPT as the last resort); False: SNOPT alone, as the planning
    # benchmark's problems were drawn (diagrams/generation/planning_problems.py).
    batched_ik: bool = True


class PickMotions:
    """Plans the motions of a pick in a PlanningWorld (robot and table; the object as points when given): one
    IK and one STOMP shared by the three kinds of motion, each kind's methods offered here.

    Attributes:
        world: the robot and the fixed scene. ik, stomp: the IK and STOMP built from it.
        config: the PlannerConfig it was built with.
        reaches, straights, held: the planners of each kind of motion.
        closure, orientation: the constraints a held move keeps.
    """

    def __init__(self, world: PlanningWorld, config: PlannerConfig | None = None):
        self.world, self.config = world, config or PlannerConfig()
        self.ik = DualArmIk(world, self.config.batched_ik)
        self.stomp = Stomp(world, self.config.stomp)
        self.straights = StraightMotions(world, self.ik)
        self.reaches = ReachMotions(world, self.ik, self.stomp, self.straights)
        self.held = HeldMotions(world, self.ik, self.stomp, self.config.held_mass_kg)
        self.closure, self.orientation = self.held.closure, self.held.orientation
        self.reach, self.reach_configuration = self.reaches.reach, self.reaches.reach_configuration
        self.reach_pregrasps = self.reaches.reach_pregrasps
        self.segment_is_free = self.reaches.segment_is_free
        self.straight, self.track = self.straights.straight, self.straights.track
        self.held_move, self.held_path = self.held.held_move, self.held.held_path
        self.payload, self.carried = self.held.payload, self.held.carried
        self.held_segment_durations = self.held.held_segment_durations
        self.closure_deviations, self.onto_closure = self.held.closure_deviations, self.held.onto_closure


def time_parameterise(
    keyframes: np.ndarray, velocity_limits: np.ndarray, start_time: float, min_segment_s: float | np.ndarray
) -> PiecewisePolynomial:
    """A shape-preserving cubic through the keyframes (no overshoot: it stays within their range),
    each segment long enough to move at SPEED_FRACTION of the velocity limits (at least min_segment_s: one
    value, or one per segment), at rest at both ends."""
    shortest = np.broadcast_to(np.asarray(min_segment_s, float), (len(keyframes) - 1,))
    durations = [
        move_duration(a, b, velocity_limits, m)
        for (a, b), m in zip(itertools.pairwise(keyframes), shortest, strict=True)
    ]
    times = start_time + np.concatenate([[0.0], np.cumsum(durations)])
    return PiecewisePolynomial.CubicShapePreserving(times, np.asarray(keyframes).T, zero_end_point_derivatives=True)
