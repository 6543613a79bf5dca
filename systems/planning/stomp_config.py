"""STOMP's settings (systems/planning/stomp.py), one frozen dataclass per part of the planner.

The measurements behind the defaults are in docs/history/planning_parameters.md, one section per parameter.
"""

from dataclasses import dataclass, field


@dataclass(frozen=True)
class CostConfig:
    """The cost terms (systems/planning/stomp_costs.py) and the clearance a solution needs."""

    margin: float = 0.02  # m: clearance below which the collision cost starts
    required_clearance: float = 0.005  # m: a plan counts as collision-free above this (covers model errors)
    # rad: between keyframes the sphere model is checked at states no joint turns more than this apart (at least 4 per
    # segment): checked sparser, a finger pad or the palm passed through a box corner between two checked states.
    segment_step_rad: float = 0.02
    limit_margin: float = 0.1  # rad: q_l grows from 0 to 1 over the last limit_margin before a joint's limit
    torque_limit_penalty: float = 100.0  # per unit of |tau| / tau_max beyond 1, besides (tau / tau_max)^2
    segment_s: float = 0.25  # s: the shortest time between keyframes, for the torque term's velocities
    # Weights of the terms in their units (stomp_costs.TERM_UNITS), in stomp_costs.TERMS' order.
    weights: tuple = (1.0, 0.05, 0.01, 0.05, 1.0, 1.0)


@dataclass(frozen=True)
class SamplingConfig:
    """The rollouts drawn about the current trajectory each iteration, and the update made from them."""

    rollouts: int = 16
    reused_rollouts: int = 4  # the best rollouts kept for the next iteration
    noise_std: float = 0.8  # rad, initial; shrinks by noise_decay per iteration
    noise_decay: float = 0.97
    # rad, initial, with hand constraints: the noise lies in their tangent space and a held move is short.
    constrained_noise_std: float = 0.4
    sensitivity: float = 10.0  # h in exp(-h * normalised cost)
    projection_steps: int = 3  # Gauss-Newton steps projecting each update onto the hand constraints
    rollout_projection_steps: int = 2  # ... and each rollout, before it is scored


@dataclass(frozen=True)
class FirstTrajectoryConfig:
    """Where the optimisation starts (systems/planning/stomp_starts.py)."""

    # A held move's first trajectories (the projected straight line, then the detours) are drawn first with this many
    # keyframes (every check is per keyframe or per segment, and a held move's first trajectory is mostly already a
    # solution); where one is a solution, the plan is that path at StompConfig.keyframes keyframes. Not for a plan from
    # an initial path (the pick's held moves): there, drawn coarse, a set-down object stood turned by 5 degrees.
    keyframes: int = 10
    # Gauss-Newton steps projecting that coarse straight line: after 2, far within the dense check's thresholds.
    projection_steps: int = 2
    via_candidates: int = 128  # random via points tried for the first trajectory of an unconstrained plan
    via_std: float = 1.0  # rad: their spread about the straight line's middle


@dataclass(frozen=True)
class DetourConfig:
    """With hand constraints, first trajectories with the held object moved up and sideways along the way (over or
    around a box in its path), tried where the given one is no solution (m; no heights: none)."""

    heights: tuple = (0.0, 0.06, 0.12, 0.18)
    sideways: tuple = (-0.12, -0.06, 0.0, 0.06, 0.12)
    ramps: tuple = (1.0, 2.0)  # the detours' profiles along the way, tried in turn (stomp_detours.Detours.targets)
    # m: where no detour above is collision-free, these heights too (turns of a held object among tall boxes)
    high_heights: tuple = (0.24, 0.30)
    wide_sideways: tuple = (-0.24, -0.18, 0.18, 0.24)  # m: ... and these farther sideways
    # The detours are ranked by how clear of the scene the part of the robot that moves with the held object (the
    # hands' spheres and every len // proxy_points-th carried sphere) would be, moved rigidly by each detour's offsets;
    # the best `checks` of each stage are then built (moved_steps Gauss-Newton steps) and checked one at a time. Only
    # where none of them is a solution are all of them built and scored: the ranking finds the same solutions for a
    # fraction of the time.
    checks: int = 4
    proxy_points: int = 64
    moved_steps: int = 3  # (fewer leave some set-downs' first trajectories unsolved)


@dataclass(frozen=True)
class RestartConfig:
    """What a plan without a solution after `after` iterations (and every `after` after) starts again from."""

    after: int = 100  # iterations without a solution before a plan starts again
    # rad: a held move (no first trajectories to start again from) samples again about its trajectory with this noise
    # (its own has shrunk away), and from then on its collision cost also watches each transition where the dense
    # check finds it least clear (a turn stalled with a segment deep in collision between clear keyframes); 0: neither.
    held_noise_std: float = 1.2
    # An unconstrained plan stuck at its first restart first tries a path RRT-Connect samples in the sphere model
    # (systems/planning/rrt_connect.py), this many random draws at most (0: none).
    sampled_draws: int = 1000
    # m: then paths through Cartesian via points of both hands: pulled back towards the robot (along -x_W) by each of
    # hand_via_backs and raised to each of hand_via_heights above the higher goal hand, then carried across at that
    # height above their goals (out from under the table and over what stands at its edge; no heights: none).
    hand_via_heights: tuple = (0.05, 0.15, 0.25, 0.35)
    hand_via_backs: tuple = (0.0, 0.12, 0.25)


@dataclass(frozen=True)
class StompConfig:
    """A STOMP planner's settings, fixed for its life."""

    keyframes: int = 16
    max_iterations: int = 600  # 0: the first trajectory (straight line, detours, via points) alone
    time_limit_s: float = 2.0
    seed: int = 0
    costs: CostConfig = field(default_factory=CostConfig)
    sampling: SamplingConfig = field(default_factory=SamplingConfig)
    first_trajectories: FirstTrajectoryConfig = field(default_factory=FirstTrajectoryConfig)
    detours: DetourConfig = field(default_factory=DetourConfig)
    restarts: RestartConfig = field(default_factory=RestartConfig)
