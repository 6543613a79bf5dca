"""The planner stage: plan requests with Cartesian goals in, timed joint trajectories out.

Each new PlanRequest (a new `id`) is planned once, in a discrete update, from the grasp poses and
the obstacle cloud on the inputs (perception, or a ground-truth source), and the PlanResult is kept
in abstract state. The result becomes current `latency_s` of context time after the request: in
simulation that is the planning latency the scenario asks for (sim time, never wall time, so a
busy machine plans the same), and the trajectory starts then, from the request's q_start.
"""

import dataclasses
import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import EventStatus, LeafSystem
from pydrake.trajectories import PiecewisePolynomial

from systems.messages import GraspPoses, MoveKind, PlanRequest, PlanResult, Targets
from systems.planning.pick_motions import (
    SPARSE_SEGMENT_S,
    STOMP_SEGMENT_S,
    PickMotions,
    PlanningError,
    time_parameterise,
)
from systems.planning.pour_goals import outside_of
from systems.planning.straight_motions import WouldTouch
from systems.planning.world import SIDES

# The reconstruction, thinned to about this many points, is the reach's obstacle: the margin about it
# (world.PERCEIVED_SHAPE_MARGIN) was set for a cloud this dense, and planning cost grows with it.
OBSTACLE_POINTS = 2000
# A held move's played trajectory that leaves the closure thresholds is refined at most this often (onto_closure).
CLOSURE_REFINEMENTS = 3
RETREAT_M = 0.1  # m: how far the hands back off an object they let go of (or as far along it as they reach)


@dataclass
class _Planning:
    current: PlanResult = field(default_factory=PlanResult)
    pending: PlanResult | None = None  # planned, not yet current (its latency has not passed)
    pending_at: float = math.inf  # context time at which `pending` becomes current, s


class StompPlanner(LeafSystem):
    """The pick's motion planner (IK + STOMP) as an event-driven stage.

    .. pydrake_system::

        name: StompPlanner
        input_ports:
        - request
        - grasp_poses
        - obstacle_cloud_W
        - scene_cloud_W (optional)
        output_ports:
        - plan

    Inputs: ``request`` (PlanRequest); ``grasp_poses`` (GraspPoses, X_WG of each hand's pre-grasp and
    grasp); ``obstacle_cloud_W`` (N x 3 points of the object, m, in W: the reach's obstacle); ``scene_cloud_W`` (the
    rest of the scene as the camera saw it: its occupied points, N x 3 in W, m; every motion avoids it).
    Output: ``plan`` (PlanResult of the latest request whose latency has passed).

    Args:
        motions: the planning core (its world, IK and STOMP, built with their PlannerConfig).
        latency_s: context seconds from a request to its result; the trajectory starts then.
        grasp_depth_margin: the "grasp" targets are moved this far along each hand's approach axis z_G, m
            (a perceived grasp can be 1-2 cm off; a hand that stops short closes on a handle's edge).
    """

    def __init__(self, motions: PickMotions, latency_s: float, grasp_depth_margin: float = 0.0, period_s=0.01):
        super().__init__()
        self.motions, self.latency_s = motions, latency_s
        self.deeper = RigidTransform([0.0, 0.0, grasp_depth_margin])
        self.DeclareAbstractInputPort("request", AbstractValue.Make(PlanRequest()))
        self.DeclareAbstractInputPort("grasp_poses", AbstractValue.Make(GraspPoses(False)))
        self.DeclareAbstractInputPort("obstacle_cloud_W", AbstractValue.Make(np.zeros((0, 3))))
        self.DeclareAbstractInputPort("scene_cloud_W", AbstractValue.Make(np.zeros((0, 3))))
        self._state = self.DeclareAbstractState(AbstractValue.Make(_Planning()))
        self.DeclareAbstractOutputPort(
            "plan",
            lambda: AbstractValue.Make(PlanResult()),
            self._calc_plan,
            {self.abstract_state_ticket(self._state)},
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, 0.0, self._update)

    def _update(self, context, state) -> EventStatus:
        planning = context.get_abstract_state(self._state).get_value()
        t = context.get_time()
        request = self.GetInputPort("request").Eval(context)
        known = {planning.current.id, planning.pending.id if planning.pending else None}
        current, pending, pending_at = planning.current, planning.pending, planning.pending_at
        if request.id >= 0 and request.id not in known:
            pending_at = t + self.latency_s
            pending = self.plan(request, pending_at, context)
        if pending is not None and t + 1e-9 >= pending_at:
            current, pending, pending_at = pending, None, math.inf
        if current is planning.current and pending is planning.pending:
            return EventStatus.DidNothing()
        state.get_mutable_abstract_state(self._state).set_value(_Planning(current, pending, pending_at))
        return EventStatus.Succeeded()

    def plan(self, request: PlanRequest, start_s: float, context) -> PlanResult:
        """Plans `request`; the trajectory starts at context time start_s."""
        started = time.perf_counter()
        motions = self.motions
        result = PlanResult(request.id, request.phase)
        scene = self._scene(context)
        if request.set_down_W is not None and len(request.set_down_W):
            scene = request.set_down_W if scene is None else np.vstack([scene, request.set_down_W])
        try:
            if request.path not in tuple(MoveKind):
                raise PlanningError(f"unknown path {request.path!r} (one of {', '.join(MoveKind)})")
            held = None
            if request.path == MoveKind.HELD:
                carried = None
                if request.carried_motion_W is not None:
                    cloud = self.GetInputPort("obstacle_cloud_W").Eval(context)
                    carried = request.carried_motion_W.multiply(cloud.T).T if len(cloud) else None
                if request.inside_left_out is not None and scene is not None:
                    scene = outside_of(scene, *request.inside_left_out)
                held = self._held_option(request, carried, scene)
                keyframes = held.keyframes
                start, end = (motions.world.grasp_frame_poses(q)["left"] for q in (keyframes[0], keyframes[-1]))
                result.achieved_motion_W = end @ start.inverse()
            elif request.targets == Targets.MEASURED:
                keyframes, min_segment = self._to_measured(request), SPARSE_SEGMENT_S
            elif request.targets == Targets.HOME:
                if request.path != MoveKind.FREE or request.q_goal is None:
                    raise PlanningError("going home is a free move to a q_goal")
                keyframes = motions.reach_configuration(
                    request.q_start, request.q_goal, self._thinned(self._object_cloud(request, context)), scene
                )
                min_segment = STOMP_SEGMENT_S if len(keyframes) > 3 else SPARSE_SEGMENT_S
            else:
                targets = self._targets(request, context)
                if request.path == MoveKind.FREE:
                    cloud = self._object_cloud(request, context)
                    keyframes, result.grasp_offsets_G = self._reach(
                        request, context, targets, cloud, self._thinned(cloud), scene
                    )
                    min_segment = STOMP_SEGMENT_S if len(keyframes) > 3 else SPARSE_SEGMENT_S
                elif request.targets == Targets.RETREAT:
                    keyframes, min_segment = self._retreat(request.q_start, targets), SPARSE_SEGMENT_S
                else:  # the approach all the way or not at all
                    keyframes, min_segment = motions.straight(request.q_start, targets), SPARSE_SEGMENT_S
            if held is None:
                trajectory = time_parameterise(keyframes, motions.world.velocity_limits, start_s, min_segment)
            else:
                trajectory = self._held_trajectory(keyframes, held, start_s, result)
                if request.full_back_off:
                    self._check_back_off(trajectory.value(trajectory.end_time()).ravel())
            result.success, result.trajectory, result.message = True, trajectory, f"{len(keyframes)} keyframes"
            result.grasp_paths_W = self._grasp_paths(trajectory)
        except PlanningError as error:
            result.message = f"{request.phase}: {error}"
            logging.warning("planning failed: %s", result.message)
        result.finished_wall_s = time.perf_counter()
        result.planning_s = result.finished_wall_s - started
        return result

    def _held_trajectory(self, keyframes: np.ndarray, held, start_s: float, result: PlanResult) -> PiecewisePolynomial:
        """A held move's keyframes played from start_s, checked every DENSE_CHECK_S against the closure thresholds
        (the deviations go to `result`). Where it leaves them, the keyframes are brought onto the closure manifold
        (held_motions.onto_closure), then also halved, up to CLOSURE_REFINEMENTS times.

        Raises:
            PlanningError: the played trajectory still leaves the closure constraint.
        """
        motions = self.motions
        for refinement in range(CLOSURE_REFINEMENTS + 1):
            if refinement:
                keyframes = motions.onto_closure(keyframes, held, midpoints=refinement > 1)
            durations = motions.held_segment_durations(keyframes)
            trajectory = time_parameterise(keyframes, motions.world.velocity_limits, start_s, durations)
            t_dev, o_dev = motions.closure_deviations(trajectory, held)
            result.closure_translation_dev_m, result.closure_orientation_dev_rad = t_dev, o_dev
            if t_dev < motions.closure.t_max and o_dev < motions.closure.o_max:
                break
        else:
            raise PlanningError(
                f"the played trajectory leaves the closure constraint ({t_dev * 1000:.1f} mm, {o_dev:.3f} rad)"
            )
        if refinement:
            logging.info("held move: brought onto the closure for playing (%d refinements, %d keyframes)", refinement,
                         len(keyframes))  # fmt: skip
        return trajectory

    def _reach(self, request: PlanRequest, context, targets, cloud, points, scene) -> tuple[np.ndarray, dict | None]:
        """The reach's keyframes to `targets`, and for pre-grasps the grasps they lead to (X_GG' per side:
        ReachMotions.reach_pregrasps). cloud: the object's points (N x 3 in W, where it is now), which judge the
        grasp family; points: the obstacle; scene: the rest of the scene as seen (its occupied points, or None)."""
        if request.targets != Targets.PREGRASP:
            return self.motions.reach(request.q_start, targets, points, scene_W=scene).keyframes, None
        grasps = self._targets(dataclasses.replace(request, targets=Targets.GRASP), context, deeper=False)
        return self.motions.reach_pregrasps(request.q_start, targets, grasps, cloud, points, scene, self.deeper)

    def _to_measured(self, request: PlanRequest) -> np.ndarray:
        """A relaxing move's keyframes: from the command to where the arms are measured (q_goal, within the joint
        limits), each hand where it is; what a held move left pressing on the object, the arms pushing against it
        towards a command they do not reach, is let go."""
        if request.path != MoveKind.STRAIGHT or request.q_goal is None:
            raise PlanningError("a move to where the arms are is a straight move to a q_goal")
        if not np.all(np.isfinite(request.q_goal)):
            raise PlanningError("where the arms are is not known (the measured position is not finite)")
        world = self.motions.world
        return np.stack([request.q_start, np.clip(request.q_goal, world.lower, world.upper)])

    def _retreat(self, q_start: np.ndarray, targets: dict[str, RigidTransform]) -> np.ndarray:
        """A back-off's keyframes: as far along its line as the arms reach, at least one step of it; where its
        first step would touch the robot itself (a forearm passing the torso), none: the hands stay where they
        are, and the next free move leaves from there."""
        try:
            return self.motions.straight(q_start, targets, min_steps=1)
        except WouldTouch as error:
            logging.warning("back-off: %s; the hands stay where they are", error)
            return np.stack([q_start, q_start])

    def _held_option(self, request: PlanRequest, carried: np.ndarray | None, scene: np.ndarray | None):
        """The held move (HeldMove) of the first of the request's motions, X_motion_W then its alternatives, that
        reaches and finds a plan. carried: the held object's points (N x 3 in W, at q_start) or None; scene: the
        scene's (or None).

        Raises:
            PlanningError: none does (the first's reason, and how many others were tried).
        """
        options = (request.X_motion_W, *request.alternatives)
        failures = []
        for n, X_motion_W in enumerate(options):
            try:
                held = self.motions.held_move(
                    request.q_start, X_motion_W, request.min_fraction, carried, scene, request.exact_goal
                )
            except PlanningError as error:
                failures.append(error)
                continue
            if n:
                logging.info("%s: option %d of %d (the first: %s)", request.phase, n + 1, len(options), failures[0])
            return held
        if len(options) == 1:
            raise failures[0]
        raise PlanningError(f"{failures[0]}; nor any of {len(options) - 1} other options")

    def _check_back_off(self, q_end: np.ndarray) -> None:
        """Raises PlanningError unless the hands, let go at q_end, can back off the whole RETREAT_M from there."""
        try:
            self.motions.straight(q_end, self._retreat_targets(q_end))
        except PlanningError as error:
            why = f"the hands could not back off {RETREAT_M * 100:.0f} cm from its end ({error})"
            raise PlanningError(why) from error

    def _retreat_targets(self, q: np.ndarray) -> dict[str, RigidTransform]:
        """Each hand's grasp frame at q moved RETREAT_M back along its approach axis z_G, in W."""
        back = RigidTransform([0.0, 0.0, -RETREAT_M])
        return {side: X @ back for side, X in self.motions.world.grasp_frame_poses(q).items()}

    def _scene(self, context) -> np.ndarray | None:
        """The scene as the camera saw it (its occupied points, N x 3 in W), or None where there is none."""
        if not self.GetInputPort("scene_cloud_W").HasValue(context):
            return None
        scene = self.GetInputPort("scene_cloud_W").Eval(context)
        return scene if len(scene) else None

    def _object_cloud(self, request: PlanRequest, context) -> np.ndarray:
        """The obstacle cloud (N x 3 in W) where the object is now: moved by the request's object_motion_W (where
        a look found it moved)."""
        cloud = self.GetInputPort("obstacle_cloud_W").Eval(context)
        if len(cloud) and request.object_motion_W is not None:
            cloud = request.object_motion_W.multiply(cloud.T).T
        return cloud

    @staticmethod
    def _thinned(cloud: np.ndarray) -> np.ndarray | None:
        """A cloud (N x 3) thinned to about OBSTACLE_POINTS, or None when it is empty."""
        return cloud[:: max(1, len(cloud) // OBSTACLE_POINTS)] if len(cloud) else None

    def _targets(self, request: PlanRequest, context, deeper: bool = True) -> dict[str, RigidTransform]:
        if request.targets == Targets.RETREAT:
            return self._retreat_targets(request.q_start)
        grasps = self.GetInputPort("grasp_poses").Eval(context)
        if not grasps.found:
            raise PlanningError(f"no grasp poses ({grasps.message})")
        if request.targets not in (Targets.PREGRASP, Targets.GRASP):
            raise PlanningError(f"unknown targets {request.targets!r} (pregrasp, grasp or retreat)")
        deeper = self.deeper if request.targets == Targets.GRASP and deeper else RigidTransform()
        offsets = request.grasp_offsets_G if request.targets == Targets.GRASP and request.grasp_offsets_G else {}
        targets = {
            side: grasps.poses_W[f"{side}_{request.targets}"] @ offsets.get(side, RigidTransform()) @ deeper
            for side in SIDES
        }
        if request.object_motion_W is not None:  # the object moved since it was seen: the grasps moved with it
            targets = {side: request.object_motion_W @ X for side, X in targets.items()}
        return targets

    def _grasp_paths(self, trajectory: PiecewisePolynomial, samples: int = 60) -> dict[str, np.ndarray]:
        times = np.linspace(trajectory.start_time(), trajectory.end_time(), samples)
        q = np.array([trajectory.value(t).ravel() for t in times])
        poses = self.motions.world.end_effectors.poses(q)
        return {side: X[:, :3, 3] for side, X in zip(SIDES, poses, strict=True)}

    def _calc_plan(self, context, output):
        output.set_value(context.get_abstract_state(self._state).get_value().current)
