"""Dual-arm inverse kinematics for the hands' grasp frames in a PlanningWorld (systems/planning/world.py), started
from a table of collision-free seeds cached on disk.

Each arm alone is solved by damped Gauss-Newton steps on the batched kinematics, from all its starts at once
(SNOPT, Drake's InverseKinematics, only where none of them reaches); both arms together keep that answer where
Drake's exact distance query finds it clear, and SNOPT with the collision constraint moves them apart where not.

With the torso planned, the arms share its yaw: each arm is solved alone with the torso held at a
candidate yaw (where it stands, then turned to face the targets, then as each arm alone would turn it),
and both arms together with the torso free from the first candidate where each arm reaches."""

import itertools
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import SnoptSolver, Solve, SolverOptions
from scipy.spatial.transform import Rotation

from systems.paths import cache_dir, save_npz_atomically
from systems.planning.hand_constraints import bounded_step
from systems.planning.world import SIDES, PlanningWorld

SEED_SAMPLES = 3000
# Torso yaws tried besides where it stands: facing the targets' midpoint, and this much either side of it (rad).
TORSO_SPREAD = 0.35
# With an `accept` test (DualArmIk.solve), each arm's nearest answers paired (the rest are farther from the guess).
ACCEPT_ANSWERS = 12
# A hand is symmetric under a half turn about its approach axis z_G.
HALF_TURN = RigidTransform(RotationMatrix.MakeZRotation(np.pi))
# The batched Gauss-Newton IK: at most this many steps, each joint at most this far a step (rad). A start is done
# within CONVERGED_SHARE of the tolerances once its null-space pull towards the nominal configuration (NULL_SPACE_GAIN
# of it each step) is below NULL_SPACE_SETTLED_RAD; stalled (kept as it was at its best) once its error, outside
# that share, fell by less than a tenth over the last STALL_STEPS steps.
GAUSS_NEWTON_STEPS = 60
GAUSS_NEWTON_STEP_RAD = 0.3
CONVERGED_SHARE = 0.2
NULL_SPACE_GAIN = 0.5
NULL_SPACE_SETTLED_RAD = 0.01
STALL_STEPS = 5
STALL_SHARE = 0.9
# Each step also moves the arm this share of the way to the nominal configuration, a share that shrinks by
# NOMINAL_PULL_DECAY a step: the answers come out near it, as SNOPT's did with its nominal cost (without the pull the
# reaches from them were longer).
NOMINAL_PULL = 0.8
NOMINAL_PULL_DECAY = 0.7
# SNOPT's major iterations in the last resort (its default allows 1000 or more): where it reaches a target it needs
# few, and where it does not, the cap bounds the time it spends failing.
LAST_RESORT_MAJOR_ITERATIONS = 100


@dataclass
class IkResult:
    success: bool
    q: np.ndarray  # the planned joints, rad (arm 1, arm 2, then the torso if planned)
    message: str = ""
    # Per side, which target each hand was solved for: 0 as given, k the k-th of solve()'s alternatives.
    choice: dict[str, int] = field(default_factory=dict)


class DualArmIk:
    """Solves for the planned joints that put both grasp frames at given world poses.

    Its SNOPT solves write into the world's plant context (world.plant_context), as its other queries do.
    """

    def __init__(self, world: PlanningWorld, batched: bool = True):
        """Args:
        world: the robot, table (and welded object) to solve in; its seed table is loaded from the cache under
            world.scene.cache_key, or built and saved there.
        batched: each arm alone by Gauss-Newton on the batched kinematics (SNOPT where it fails), and both arms'
            answer kept where it is clear; False: SNOPT for every solve (as the planning benchmark's problems were
            drawn).
        """
        self.world, self.batched = world, batched
        self._seed_q, self._seed_poses = self._load_or_build_seed_table()

    def _load_or_build_seed_table(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The seed table from the cache when this scene (robot, table, object, seed) was seen before."""
        world = self.world
        path = cache_dir() / "ik_seeds" / f"{world.scene.cache_key}_{SEED_SAMPLES}.npz"
        if path.is_file():
            with np.load(path) as data:
                return data["q"], {side: data[side] for side in SIDES}
        seed_q, seed_poses = self._build_seed_table(world.scene.seed, SEED_SAMPLES)
        save_npz_atomically(path, q=seed_q, **seed_poses)
        # Building left the last sample in the context: back to where a cached table leaves it, so that a
        # pick on a cold cache plans exactly as one on a warm cache (it lifted 1.3e-12 m lower).
        world.plant.SetPositions(world.plant_context, world.q_default)
        return seed_q, seed_poses

    def _build_seed_table(self, seed: int, samples: int = SEED_SAMPLES) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Random collision-free arm configurations (the torso straight) and the grasp frame poses (3 x 4, per
        side) they reach.

        They are IK starting points: SNOPT from a nearby, feasible start converges far more
        often than from the current configuration.
        """
        world = self.world
        rng = np.random.default_rng(seed)
        candidates = rng.uniform(world.lower, world.upper, size=(3 * samples, len(world.lower)))
        if world.torso is not None:
            candidates[:, world.torso] = 0.0
        free = [q for q in candidates if not world.in_collision(q)]
        seed_q = np.array(free[:samples])
        samples = len(seed_q)
        seed_poses = {side: np.empty((samples, 3, 4)) for side in SIDES}
        for i, q in enumerate(seed_q):
            for side, X in world.grasp_frame_poses(q).items():
                seed_poses[side][i] = X.GetAsMatrix34()
        return seed_q, seed_poses

    def _seeds(self, targets: dict[str, RigidTransform], count: int, torso: float = 0.0) -> list[np.ndarray]:
        """Seed-table configurations whose hands lie nearest the targets, per arm, with the torso at `torso`
        (rad; the table's hands are where they are with the torso straight: the targets are turned back)."""
        best = {}
        unturn = self._about_torso(-torso)
        for side, X in targets.items():
            X = unturn @ X
            poses = self._seed_poses[side]
            position_error = np.linalg.norm(poses[:, :, 3] - X.translation(), axis=1)
            # Approach axes must agree; the handle axis only up to sign (the hand is symmetric).
            R = X.rotation().matrix()
            approach_error = 1.0 - poses[:, :, 2] @ R[:, 2]
            handle_error = 1.0 - np.abs(poses[:, :, 0] @ R[:, 0])
            best[side] = np.argsort(position_error + 0.3 * approach_error + 0.1 * handle_error)[:count]
        seeds = []
        for side in SIDES:  # an arm without a target: the same samples as the other's
            best.setdefault(side, next(iter(best.values())))
        for left, right in zip(best["left"], best["right"], strict=True):
            q = self._seed_q[left].copy()
            q[7:14] = self._seed_q[right][7:14]
            if self.world.torso is not None:
                q[self.world.torso] = torso
            seeds.append(q)
        return seeds

    def _about_torso(self, yaw: float) -> RigidTransform:
        """The turn of the world by `yaw` (rad) about the torso's vertical axis."""
        axis = np.append(self.world.torso_axis_W, 0.0)
        return RigidTransform(axis) @ RigidTransform(RotationMatrix.MakeZRotation(yaw)) @ RigidTransform(-axis)

    def torso_candidates(self, X_WG: dict[str, RigidTransform], q_guess: np.ndarray) -> Iterator[float]:
        """Torso yaws to hold while each arm is solved (rad), lazily: where it stands; facing the targets' midpoint
        and TORSO_SPREAD either side of it; then, only if those were not enough, the yaw each arm takes when
        solved alone with the torso free (a turned object wants the torso turned with it), and their mean. All
        within the limits, each once. One value, 0, with the torso locked."""
        world = self.world
        if world.torso is None:
            yield 0.0
            return
        tried = []

        def untried(yaw: float) -> bool:
            if any(abs(yaw - other) < 0.05 for other in tried):
                return False
            tried.append(yaw)
            return True

        lower, upper = world.lower[world.torso], world.upper[world.torso]
        middle = np.mean([X.translation()[:2] for X in X_WG.values()], axis=0) - world.torso_axis_W
        facing = float(np.arctan2(middle[1], middle[0]))
        for yaw in (q_guess[world.torso], facing, facing + TORSO_SPREAD, facing - TORSO_SPREAD):
            if untried(yaw := float(np.clip(yaw, lower, upper))):
                yield yaw
        preferred = [self._arm_torso_yaw(side, X_WG[side], q_guess, facing) for side in SIDES]
        preferred = [yaw for yaw in preferred if yaw is not None]
        if len(preferred) == 2:
            preferred.append(float(np.mean(preferred)))
        for yaw in preferred:
            if untried(yaw):
                yield yaw

    def _arm_torso_yaw(self, side: str, X_WG: RigidTransform, q_guess: np.ndarray, facing: float) -> float | None:
        """The torso yaw (rad) at which one arm reaches X_WG when solved with the torso free, from the torso
        facing the targets (and nearby seeds, either half turn of the hand); None if it reaches from none."""
        guess = q_guess.copy()
        guess[self.world.torso] = facing
        tries = list(itertools.product([guess, *self._seeds({side: X_WG}, 4, facing)], (False, True)))
        targets = [X_WG @ HALF_TURN if flip else X_WG for _, flip in tries]
        if self.batched:
            solved = self._solve_arm(side, targets, [start for start, _ in tries], guess, 0.002, 0.03, torso=True)
            found = next((q for q in solved if q is not None), None)
            return None if found is None else float(found[self.world.torso])
        for (start, _), target in zip(tries, targets, strict=True):
            result = self._solve_once({side: target}, start, start, 0.002, 0.03, None, torso=True)
            if result.success:
                return float(result.q[self.world.torso])
        return None

    def solve(
        self,
        X_WG: dict[str, RigidTransform],
        q_guess: np.ndarray,
        position_tolerance: float = 0.002,
        angle_tolerance: float = 0.03,
        min_distance: float | None = 0.005,
        allow_half_turn: bool = True,
        restarts: int = 4,
        limit_margin: float = 0.0,
        torso_yaws: Iterable[float] | None = None,
        alternatives: dict[str, list[RigidTransform]] | None = None,
        accept: Callable[[np.ndarray], bool] | None = None,
    ) -> IkResult:
        """Arm joints putting each side's grasp frame at X_WG[side], nearest to q_guess.

        Args:
            X_WG: target pose per side ("left", "right") in the world.
            q_guess: the planned joints, the initial guess and the configuration to stay near.
            position_tolerance: metres. angle_tolerance: radians.
            min_distance: if not None, every robot/table geometry pair stays this far apart (m).
            allow_half_turn: also try each target turned by pi about z_G (the hands are symmetric).
            restarts: extra initial guesses from the seed table. With min_distance, all of them are
                solved (the collision stage needs alternatives); without, only when q_guess fails.
            limit_margin: keep every joint this far inside its limits (rad), e.g. to leave room for a
                motion that follows.
            torso_yaws: the torso yaws (rad) to hold while each arm is solved, in turn (default
                torso_candidates()); ignored with the torso locked.
            alternatives: per side, the targets to try in turn (the first usually the identity), as transforms of
                X_WG[side] on the right (e.g. other grasps of the same handle): the next is tried only where the
                ones before leave that hand out of reach; IkResult.choice says which one each hand was solved for
                (default: X_WG alone).
            accept: whether an answer will do (e.g. clear of a scene Drake's geometry does not hold): with it, the
                answers it refuses are passed over for the others the restarts found (each arm's elbow elsewhere).
        """
        q_guess = np.asarray(q_guess, dtype=float)
        options = (
            position_tolerance,
            angle_tolerance,
            min_distance,
            allow_half_turn,
            restarts,
            limit_margin,
            alternatives,
            accept,
        )
        failures = []
        if torso_yaws is None or self.world.torso is None:
            torso_yaws = self.torso_candidates(X_WG, q_guess)
        for torso in torso_yaws:
            result = self._solve_at_torso(X_WG, q_guess, torso, *options)
            if result.success:
                return result
            failures.append(result.message)
        # The message of the candidate that came nearest: both hands reached (a collision) over one out of reach.
        return IkResult(False, q_guess, min(failures, key=lambda message: "out of reach" in message))

    def _solve_at_torso(
        self, X_WG, q_guess, torso, position_tolerance, angle_tolerance, min_distance, allow_half_turn, restarts,
        limit_margin, alternatives, accept,
    ) -> IkResult:  # fmt: skip
        """solve()'s answer with each arm solved alone at the torso yaw `torso` (rad), then both together with
        the torso free (when it is planned)."""
        turns = (RigidTransform(), HALF_TURN) if allow_half_turn else (RigidTransform(),)
        guess = q_guess.copy()
        if self.world.torso is not None:
            guess[self.world.torso] = torso
        seeds = self._seeds(X_WG, restarts, torso) if restarts else []
        # The arms are kinematically independent at a given torso yaw: solve each alone (7 joints, many
        # starts), then both together with the collision constraint, from the per-arm answers.
        per_arm, choice = {}, {}
        for side in SIDES:
            per_arm[side] = []
            for index, alternative in enumerate((alternatives or {}).get(side, [RigidTransform()])):
                targets = [X_WG[side] @ alternative @ turn for turn in turns]
                per_arm[side] = self._arm_answers(
                    side, targets, guess, seeds, q_guess, position_tolerance, angle_tolerance, limit_margin,
                    everywhere=min_distance is not None,
                )  # fmt: skip
                if per_arm[side]:
                    choice[side] = index
                    break  # the alternatives after the first that reaches are not tried
            if not per_arm[side]:
                return IkResult(False, q_guess, f"{side} hand: target out of reach")
            per_arm[side].sort(key=lambda item: np.sum((item[1] - q_guess) ** 2))
        # The nearest pairs of per-arm answers, 8 of them at most; with `accept`, the pairs it refuses are passed over
        # (they cost no solve) for pairs of more answers.
        answers = 4 if accept is None else ACCEPT_ANSWERS
        pairs = itertools.product(per_arm["left"][:answers], per_arm["right"][:answers])
        tried = refused = 0
        for (left_X, left_q), (right_X, right_q) in pairs:
            if tried == 8:
                break
            start = left_q.copy()
            start[7:14] = right_q[7:14]
            if accept is not None and not accept(start):
                refused += 1
                continue
            tried += 1
            if min_distance is None:
                return IkResult(True, start, "solved per arm", choice)
            if self.batched and self.world.clearance(start, max_distance=2 * min_distance) >= min_distance:
                return IkResult(True, start, "solved per arm, clear", choice)
            result = self._solve_once(
                {"left": left_X, "right": right_X}, start, start, position_tolerance, angle_tolerance, min_distance,
                limit_margin, torso=True,
            )  # fmt: skip
            if result.success and (accept is None or accept(result.q)):
                return IkResult(True, result.q, result.message, choice)
        if refused and not tried:
            return IkResult(False, q_guess, f"each hand reaches its target, but the {refused} ways found are refused")
        return IkResult(False, q_guess, "each hand reaches its target, but not without a collision")

    def _arm_answers(
        self, side, targets, guess, seeds, q_guess, position_tolerance, angle_tolerance, limit_margin, everywhere
    ) -> list[tuple[RigidTransform, np.ndarray]]:
        """(target, q) for one arm at each of targets (a grasp and its half turn) from the guess and each seed:
        all of them if `everywhere`, else from the seeds only where the guess reaches none. Batched Gauss-Newton
        first (SNOPT from the guess where it finds none), or SNOPT alone when not self.batched."""
        answers = []
        if not self.batched:
            for start, X in itertools.product([guess, *seeds], targets):
                if answers and not everywhere and start is not guess:
                    break  # solved from the guess: the seeds would only add answers farther from it
                result = self._solve_once({side: X}, start, q_guess, position_tolerance, angle_tolerance, None,
                                          limit_margin)  # fmt: skip
                if result.success:
                    answers.append((X, result.q))
            return answers
        for starts in ([guess, *seeds],) if everywhere else ([guess], seeds):
            tries = list(itertools.product(starts, targets))
            if not tries:
                continue
            solved = self._solve_arm(
                side, [X for _, X in tries], [q for q, _ in tries], q_guess, position_tolerance, angle_tolerance,
                limit_margin,
            )  # fmt: skip
            answers = [(X, q) for (_, X), q in zip(tries, solved, strict=True) if q is not None]
            if answers:
                return answers
        # The last resort: SNOPT from the guess. It reaches some targets the steps do not, many using its tolerances'
        # corners (2 mm on every axis and 0.03 rad at once).
        for X in targets:
            result = self._solve_once(
                {side: X}, guess, q_guess, position_tolerance, angle_tolerance, None, limit_margin,
                major_iterations=LAST_RESORT_MAJOR_ITERATIONS,
            )  # fmt: skip
            if result.success:
                answers.append((X, result.q))
        return answers

    def _solve_arm(
        self, side, targets, starts, q_nominal, position_tolerance, angle_tolerance, limit_margin=0.0, torso=False
    ) -> list[np.ndarray | None]:
        """One arm's grasp frame at each of `targets` (RigidTransforms in W) from the matching one of `starts` (the
        planned joints, rad), all at once: damped Gauss-Newton steps of that arm's joints (and the torso's if
        `torso`) within their limits, limit_margin (rad) inside them, each step also moving towards q_nominal (by
        a shrinking share, NOMINAL_PULL) and then along the arm's self-motion towards it; the other joints stay at
        their start. Each answer, or None where it did not come within position_tolerance (m, per axis) and
        angle_tolerance (rad)."""
        world = self.world
        moving = np.zeros(len(world.lower), dtype=bool)
        moving[slice(0, 7) if side == "left" else slice(7, 14)] = True
        if torso and world.torso is not None:
            moving[world.torso] = True
        q = np.clip(np.array(starts, dtype=float), world.lower, world.upper)
        lower = np.where(moving, world.lower + limit_margin, q)
        upper = np.where(moving, world.upper - limit_margin, q)
        q = np.clip(q, lower, upper)
        X_target = np.array([X.GetAsMatrix4() for X in targets])
        which = SIDES.index(side)
        # The steps solve for the error in tolerances: a target just out of reach is met within them where it can be,
        # the angle's slack taken for the position's (in metres and radians, 0.03 rad weighed as 30 mm).
        in_tolerances = np.repeat([1.0 / angle_tolerance, 1.0 / position_tolerance], 3)

        def scored(rows: np.ndarray, q_rows: np.ndarray):
            """The rows' errors in tolerances (the larger of position and angle), their Jacobians and errors."""
            poses, jacobians = world.end_effectors.jacobians(q_rows)
            X, J = poses[which], jacobians[which] * moving
            R_error = X[:, :3, :3] @ np.swapaxes(X_target[rows, :3, :3], 1, 2)
            rotation, position = Rotation.from_matrix(R_error).as_rotvec(), X[:, :3, 3] - X_target[rows, :3, 3]
            score = np.maximum(
                np.abs(position).max(axis=1) / position_tolerance, np.linalg.norm(rotation, axis=1) / angle_tolerance
            )
            return score, J * in_tolerances[:, None], np.concatenate([rotation, position], axis=1) * in_tolerances

        # The answer kept per start: its latest configuration within the tolerances (the pull only brings it nearer
        # q_nominal), else its least wrong one; a step at a limit can undo what the one before it reached.
        kept, kept_score = q.copy(), np.full(len(q), np.inf)
        active = np.arange(len(q))
        scores = np.full((GAUSS_NEWTON_STEPS + 1, len(q)), np.inf)  # each start's score, per step
        for step in range(GAUSS_NEWTON_STEPS + 1):
            score, J, error = scored(active, q[active])
            scores[step, active] = score
            keep = (score <= 1.0) | (score < kept_score[active])
            kept[active[keep]], kept_score[active[keep]] = q[active[keep]], score[keep]
            if step == GAUSS_NEWTON_STEPS:
                break
            pull = (q_nominal - q[active]) * moving
            JT = np.swapaxes(J, 1, 2)
            pull -= (JT @ np.linalg.solve(J @ JT + 1e-6 * np.eye(6), (J @ pull[..., None])))[..., 0]
            # Done: converged and no nearer to q_nominal along the arm's self-motion; or no longer converging.
            done = (score <= CONVERGED_SHARE) & (np.abs(pull).max(axis=1) < NULL_SPACE_SETTLED_RAD)
            if step >= STALL_STEPS:
                done |= (score > CONVERGED_SHARE) & (score > STALL_SHARE * scores[step - STALL_STEPS, active])
            active, J, pull, error = active[~done], J[~done], pull[~done], error[~done]
            if not len(active):
                break
            towards = NOMINAL_PULL * NOMINAL_PULL_DECAY**step * (q_nominal - q[active]) * moving
            q[active] = bounded_step(
                q[active] + NULL_SPACE_GAIN * pull + towards,
                error,
                J,
                lower[active],
                upper[active],
                GAUSS_NEWTON_STEP_RAD,
            )
        return [kept[k] if kept_score[k] <= 1.0 else None for k in range(len(q))]

    def solve_held(
        self,
        X_WG_left: RigidTransform,
        X_E1E2: RigidTransform,
        q_near: np.ndarray,
        position_tolerance: float,
        angle_tolerance: float,
        start: np.ndarray | None = None,
        closure_tolerances: tuple[float, float] = (0.0005, 0.005),
        min_distance: float | None = None,
    ) -> IkResult:
        """Both arms holding one object: the left grasp frame at X_WG_left (within the tolerances, m and
        rad) and the right one at X_E1E2 from it (within closure_tolerances, m and rad), nearest to q_near,
        solved from `start` (default q_near); with min_distance (m), Drake's geometry that far apart at least."""
        world, plant = self.world, self.world.plant
        left, right = world.grasp_frames["left"], world.grasp_frames["right"]
        ik = InverseKinematics(plant, world.plant_context, with_joint_limits=True)
        q, prog = ik.q(), ik.prog()
        tol = np.full(3, position_tolerance)
        p = X_WG_left.translation()
        ik.AddPositionConstraint(left, [0, 0, 0], plant.world_frame(), p - tol, p + tol)
        ik.AddOrientationConstraint(left, RotationMatrix(), plant.world_frame(), X_WG_left.rotation(), angle_tolerance)
        closure = np.full(3, closure_tolerances[0])
        p_E1E2 = X_E1E2.translation()
        ik.AddPositionConstraint(right, [0, 0, 0], left, p_E1E2 - closure, p_E1E2 + closure)
        ik.AddOrientationConstraint(right, RotationMatrix(), left, X_E1E2.rotation(), closure_tolerances[1])
        if min_distance is not None:
            ik.AddMinimumDistanceLowerBoundConstraint(min_distance)
        initial = world.full_positions(q_near if start is None else start)
        fixed = np.setdiff1d(np.arange(plant.num_positions()), world.arm_indices)
        prog.AddBoundingBoxConstraint(initial[fixed], initial[fixed], q[fixed])
        prog.AddQuadraticErrorCost(np.eye(len(world.arm_indices)), q_near, q[world.arm_indices])
        prog.SetInitialGuess(q, initial)
        result = Solve(prog)
        if result.is_success():
            return IkResult(True, result.GetSolution(q)[world.arm_indices], "solved")
        return IkResult(False, q_near, f"both hands cannot hold the object there ({result.get_solution_result()})")

    def _solve_once(
        self, targets, start, q_nominal, position_tolerance, angle_tolerance, min_distance, limit_margin=0.0,
        torso=False, major_iterations=None,
    ) -> IkResult:  # fmt: skip
        """One SNOPT solve (at most `major_iterations` major iterations if given); the joints of an arm without a
        target, and the torso unless `torso`, stay at `start`."""
        world, plant = self.world, self.world.plant
        ik = InverseKinematics(plant, world.plant_context, with_joint_limits=True)
        q = ik.q()
        prog = ik.prog()
        for side, X in targets.items():
            frame = world.grasp_frames[side]
            tol = np.full(3, position_tolerance)
            ik.AddPositionConstraint(
                frame, [0, 0, 0], plant.world_frame(), X.translation() - tol, X.translation() + tol
            )
            ik.AddOrientationConstraint(frame, RotationMatrix(), plant.world_frame(), X.rotation(), angle_tolerance)
        if min_distance is not None:
            ik.AddMinimumDistanceLowerBoundConstraint(min_distance)
        # A measured start may lie a hair beyond a limit (the PD holds it there): held joints must be feasible.
        start = np.clip(start, world.lower, world.upper)
        fixed_q = world.full_positions(start)
        arm = world.arm_indices
        free = np.concatenate(
            [
                arm[:7] if "left" in targets else [],
                arm[7:14] if "right" in targets else [],
                arm[world.torso :] if torso and world.torso is not None else [],
            ]
        )
        fixed = np.setdiff1d(np.arange(plant.num_positions()), free.astype(int))
        prog.AddBoundingBoxConstraint(fixed_q[fixed], fixed_q[fixed], q[fixed])
        if limit_margin > 0:
            prog.AddBoundingBoxConstraint(world.lower + limit_margin, world.upper - limit_margin, q[arm])
        prog.AddQuadraticErrorCost(np.eye(len(arm)), q_nominal, q[arm])
        prog.SetInitialGuess(q, world.full_positions(start))
        options = SolverOptions()
        if major_iterations is not None:
            options.SetOption(SnoptSolver.id(), "Major iterations limit", major_iterations)
        result = Solve(prog, None, options)
        q_arms = result.GetSolution(q)[arm]
        return IkResult(result.is_success(), q_arms, str(result.get_solution_result()))
