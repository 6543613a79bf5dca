"""The planner benchmark's peers on a PlanningProblem (diagrams/generation/planning_problems.py), each returning a
path for the same dense checker as STOMP's:

  OMPL:  held moves in a ProjectedStateSpace (or AtlasStateSpace) over the planned joints, the closure and the
         left hand's orientation (a turn: its tilt) as an ompl.base.Constraint with the analytic Jacobian of
         systems/planning/hand_constraints.py, RRTConnect, then path simplification; reaches with plain
         RRTConnect. States are valid where STOMP's sphere model (and the carried object's points) clear the
         scene by its required_clearance: the same collision model.
  KTO:   Drake's KinematicTrajectoryOptimization: a B-spline with the closure and hand orientation (held moves)
         and Drake's minimum-distance constraint over the exact geometry at samples along it, solved by SNOPT.
"""

import time
from dataclasses import dataclass

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou
from pydrake.math import RotationMatrix
from pydrake.multibody import inverse_kinematics as drake_ik
from pydrake.multibody.tree import BodyIndex, JacobianWrtVariable
from pydrake.planning import KinematicTrajectoryOptimization
from pydrake.solvers import SnoptSolver, Solve, SolverOptions
from pydrake.trajectories import BsplineTrajectory

from diagrams.generation.planning_problems import PlanningProblem, hand_constraints, projected_straight_line
from systems.planning.closure import ClosureConstraint
from systems.planning.hand_constraints import HandConstraints
from systems.planning.stomp import Stomp

ou.setLogLevel(ou.LogLevel.LOG_WARN)
# OMPL draws from one process-wide generator whose seed cannot change after its first draw: seeded once here, a
# run is repeatable, and a problem's outcome depends on the problems solved before it in the same run.
OMPL_SEED = 1
ou.RNG.setSeed(OMPL_SEED)


@dataclass
class PeerResult:
    solved: bool  # the planner says it found a path (the dense checker judges it after)
    path: np.ndarray  # K x n configurations, joined by straight lines
    seconds: float
    message: str = ""


@dataclass(frozen=True)
class OmplConfig:
    """The OMPL peer's parameters (chosen on the tuning range: see docs/planning.md)."""

    space: str = "projected"  # or "atlas"
    range: float = 0.0  # RRTConnect's step (rad in joint space); 0: OMPL's default (a fifth of the space's extent)
    delta: float = 0.2  # the constrained space's step along the manifold (OMPL's default 0.05)
    tolerance: float = 1e-3  # the constraint's projection tolerance (m and rad)
    projection_iterations: int = 50  # Newton steps of a projection at most (OMPL's default)
    # > 0: held moves sample within the start's and goal's joint range widened by this (rad); over the joints'
    # whole range, samples rarely project onto the manifold (no state added in 10 s)
    bounds_margin: float = 0.3
    simplify_s: float = 1.0  # the most spent simplifying a found path


class SingleStates:
    """The planning world's kinematics one configuration at a time through Drake's plant (C++): OMPL asks for one
    state at a time, where the batched numpy kinematics costs about 120 us a call against Drake's 10 us. The
    same bodies, grasp frames and Jacobians (rows angular then translational velocity in W)."""

    def __init__(self, stomp: Stomp):
        world = stomp.world
        self.world, self.plant, self.context = world, world.plant, world.plant_context
        self.bodies = [self.plant.get_body(BodyIndex(link.body_index)) for link in world.kinematics.links]
        self.frames = [world.grasp_frames[side] for side in ("left", "right")]
        self.positions = world.q_default.copy()

    def _set(self, q: np.ndarray) -> None:
        self.positions[self.world.arm_indices] = q
        self.plant.SetPositions(self.context, self.positions)

    def body_poses(self, q: np.ndarray) -> np.ndarray:
        """X_WB of the kinematics' tracked bodies (1 x L x 4 x 4), as BatchedKinematics.body_poses."""
        self._set(q)
        return np.array([[self.plant.EvalBodyPoseInWorld(self.context, body).GetAsMatrix4() for body in self.bodies]])

    def hands(self, q: np.ndarray):
        """((X_WE1, X_WE2), (J_E1, J_E2)) as EndEffectors.jacobians() for one configuration (batches of 1)."""
        self._set(q)
        world, plant = self.world, self.plant
        poses, jacobians = [], []
        for frame in self.frames:
            poses.append(frame.CalcPoseInWorld(self.context).GetAsMatrix4()[None])
            J = plant.CalcJacobianSpatialVelocity(
                self.context, JacobianWrtVariable.kQDot, frame, np.zeros(3), plant.world_frame(), plant.world_frame()
            )
            jacobians.append(J[:, world.arm_indices][None])
        return tuple(poses), tuple(jacobians)


class HandConstraint(ob.Constraint):
    """The closure (6 rows) and the left hand's world orientation where one is kept (3 rows, or with upright_only
    its tilt, 2 rows across the vertical seen from the hand): the right hand's orientation follows from these two.
    The errors and
    their analytic Jacobian are HandConstraints' (systems/planning/hand_constraints.py), from Drake's poses and
    frame Jacobians."""

    def __init__(self, constraints: HandConstraints, states: SingleStates):
        self.constraints, self.states = constraints, states
        self._last = None
        if constraints.R_WE is None:  # the closure alone
            self.rows = np.eye(6)
        elif constraints.upright_only:  # two directions across the desired vertical seen from the left hand
            up = constraints.R_WE[0][2]
            basis = np.linalg.svd(np.eye(3) - np.outer(up, up))[0][:, :2]
            self.rows = np.zeros((8, 9))
            self.rows[:6, :6] = np.eye(6)
            self.rows[6:, 6:] = basis.T
        else:
            self.rows = np.eye(9)
        super().__init__(constraints.end_effectors.kinematics.dof, len(self.rows))

    def _evaluate(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(error, Jacobian) at x; OMPL's projection asks for both at each state in turn: computed once."""
        x = np.array(x, float)
        if self._last is None or not np.array_equal(self._last[0], x):
            error, jacobian = self.constraints.error_and_jacobian_from(*self.states.hands(x))
            used = self.rows.shape[1]
            self._last = (x, self.rows @ error[0, :used], self.rows @ jacobian[0, :used])
        return self._last[1], self._last[2]

    def function(self, x, out):
        out[:] = self._evaluate(x)[0]

    def jacobian(self, x, out):
        out[:, :] = self._evaluate(x)[1]


def ompl_plan(problem: PlanningProblem, stomp: Stomp, time_limit_s: float, config: OmplConfig) -> PeerResult:
    """OMPL on the problem: constrained RRTConnect for a held move, RRTConnect for a reach; then simplified."""
    start_time = time.perf_counter()
    dof = len(problem.q_start)
    lower, upper = stomp.lower.copy(), stomp.upper.copy()
    if config.bounds_margin > 0 and problem.held:
        ends = np.stack([problem.q_start, problem.q_goal])
        lower = np.maximum(lower, ends.min(axis=0) - config.bounds_margin)
        upper = np.minimum(upper, ends.max(axis=0) + config.bounds_margin)
    space = ob.RealVectorStateSpace(dof)
    bounds = ob.RealVectorBounds(dof)
    for i in range(dof):
        bounds.setLow(i, float(lower[i]))
        bounds.setHigh(i, float(upper[i]))
    space.setBounds(bounds)
    held = problem.held
    required = stomp.config.costs.required_clearance

    kinematics = SingleStates(stomp)

    def valid(state) -> bool:
        q = np.fromiter((state[i] for i in range(dof)), float, dof)
        if np.any(q < stomp.lower) or np.any(q > stomp.upper):  # a projected state may leave the bounds
            return False
        return bool(stomp.clearance(q[None], problem.obstacles, held, kinematics.body_poses(q))[0] > required)

    if held:
        constraint = HandConstraint(hand_constraints(stomp, problem), kinematics)
        constraint.setTolerance(config.tolerance)
        constraint.setMaxIterations(config.projection_iterations)
        if config.space == "atlas":
            state_space = ob.AtlasStateSpace(space, constraint)
        else:
            state_space = ob.ProjectedStateSpace(space, constraint)
        state_space.setDelta(config.delta)
        information = ob.ConstrainedSpaceInformation(state_space)
    else:
        state_space = space
        information = ob.SpaceInformation(space)
    setup = og.SimpleSetup(information)
    setup.setStateValidityChecker(valid)
    start, goal = state_space.allocState(), state_space.allocState()
    for state, q in ((start, problem.q_start), (goal, problem.q_goal)):
        if held:
            state.copy([float(v) for v in q])
        else:
            for i, v in enumerate(q):
                state[i] = float(v)
    setup.setStartAndGoalStates(start, goal)
    if held and config.space == "atlas":
        state_space.anchorChart(start)
        state_space.anchorChart(goal)
    planner = og.RRTConnect(information)
    if config.range > 0:
        planner.setRange(config.range)
    setup.setPlanner(planner)
    setup.setup()
    status = setup.solve(time_limit_s)
    solved = bool(setup.haveExactSolutionPath())
    if not solved:
        return PeerResult(
            False, np.stack([problem.q_start, problem.q_goal]), time.perf_counter() - start_time, str(status)
        )
    left = time_limit_s - (time.perf_counter() - start_time)
    if left > 0:
        setup.simplifySolution(min(config.simplify_s, left))
    path = setup.getSolutionPath()
    if held:
        path.interpolate()  # the manifold's geodesics between the waypoints, as states delta apart
    waypoints = np.array([[path.getState(k)[i] for i in range(dof)] for k in range(path.getStateCount())])
    return PeerResult(True, waypoints, time.perf_counter() - start_time, str(status))


@dataclass(frozen=True)
class KtoConfig:
    """The KTO peer's parameters (tuned on the earlier three lift and carry problems; see docs/planning.md)."""

    control_points: int = 12
    samples: int = 24  # path points where the constraints are imposed
    min_distance: float = 0.01  # m, at the samples: less lets a held can pass into a box between two of them
    keyframes: int = 32  # the solved B-spline's states handed to the dense checker


def kto_plan(problem: PlanningProblem, stomp: Stomp, time_limit_s: float, config: KtoConfig) -> PeerResult:
    """KinematicTrajectoryOptimization in the problem's exact scene (check_world: the held object welded to the
    left hand, boxes), started from STOMP's first trajectory without detours (the projected straight line)."""
    start_time = time.perf_counter()
    world = problem.check_world
    plant = world.plant
    context = plant.GetMyMutableContextFromRoot(world.diagram.CreateDefaultContext())
    guess = projected_straight_line(problem, stomp)
    trajopt = KinematicTrajectoryOptimization(plant.num_positions(), config.control_points)
    full_start, full_goal = world.full_positions(problem.q_start), world.full_positions(problem.q_goal)
    lower, upper = full_start.copy(), full_start.copy()
    lower[world.arm_indices], upper[world.arm_indices] = world.lower, world.upper
    trajopt.AddPositionBounds(lower, upper)
    velocity = np.zeros(plant.num_positions())
    velocity[world.arm_indices] = world.velocity_limits
    trajopt.AddVelocityBounds(-velocity, velocity)
    trajopt.AddDurationConstraint(0.5, 10.0)
    trajopt.AddDurationCost(1.0)
    trajopt.AddPathLengthCost(1.0)
    trajopt.AddPathPositionConstraint(full_start, full_start, 0)
    trajopt.AddPathPositionConstraint(full_goal, full_goal, 1)
    path = np.array([world.full_positions(q) for q in guess])
    along = np.linspace(0, 1, len(path))
    control = np.array([np.interp(np.linspace(0, 1, config.control_points), along, column) for column in path.T])
    trajopt.SetInitialGuess(BsplineTrajectory(trajopt.basis(), control))
    constraints = [drake_ik.MinimumDistanceLowerBoundConstraint(plant, config.min_distance, context, None, 0.05)]
    if problem.held:
        constraints += _hand_constraints(problem, plant, context)
    for s in np.linspace(0, 1, config.samples)[1:-1]:
        for constraint in constraints:
            trajopt.AddPathPositionConstraint(constraint, s)
    options = SolverOptions()
    # SNOPT's default limits end the held problems early; a path, not an optimum: a loose optimality tolerance.
    options.SetOption(SnoptSolver.id(), "Major iterations limit", 2000)
    options.SetOption(SnoptSolver.id(), "Iterations limit", 200000)
    options.SetOption(SnoptSolver.id(), "Major optimality tolerance", 1e-3)
    options.SetOption(SnoptSolver.id(), "Time limit", float(time_limit_s))
    result = Solve(trajopt.get_mutable_prog(), solver_options=options)
    spline = trajopt.ReconstructTrajectory(result)
    times = np.linspace(spline.start_time(), spline.end_time(), config.keyframes)
    keyframes = np.array([spline.value(t).ravel()[world.arm_indices] for t in times])
    keyframes[0], keyframes[-1] = problem.q_start, problem.q_goal  # the path constraints hold them to 1e-6
    message = str(result.get_solution_result())
    return PeerResult(result.is_success(), keyframes, time.perf_counter() - start_time, message)


def _hand_constraints(problem: PlanningProblem, plant, context) -> list:
    """Drake's closure (the right grasp frame within half of t_max and o_max of its pose in the left one) and the
    hands' world orientation (or tilt) within half of o_max, at q_start's."""
    world = problem.check_world
    left, right = (plant.GetFrameByName("grasp_frame", world.scene.hands[side]) for side in ("left", "right"))
    X_WG = world.grasp_frame_poses(problem.q_start)
    X_LR = X_WG["left"].InvertAndCompose(X_WG["right"])
    limits = ClosureConstraint()
    p_LR, tolerance = X_LR.translation(), np.full(3, 0.5 * limits.t_max)
    constraints = [
        drake_ik.PositionConstraint(plant, left, p_LR - tolerance, p_LR + tolerance, right, np.zeros(3), context),
        drake_ik.OrientationConstraint(
            plant, left, X_LR.rotation(), right, RotationMatrix(), 0.5 * limits.o_max, context
        ),
    ]
    if problem.orientation is None:  # the closure alone
        return constraints
    half = 0.5 * problem.orientation.o_max
    for frame, side in ((left, "left"), (right, "right")):
        if problem.orientation.upright_only:
            up = X_WG[side].rotation().inverse() @ np.array([0, 0, 1.0])
            constraints.append(
                drake_ik.AngleBetweenVectorsConstraint(
                    plant, plant.world_frame(), [0, 0, 1.0], frame, up, 0, half, context
                )
            )
        else:
            R = X_WG[side].rotation()
            constraints.append(
                drake_ik.OrientationConstraint(plant, plant.world_frame(), R, frame, RotationMatrix(), half, context)
            )
    return constraints
