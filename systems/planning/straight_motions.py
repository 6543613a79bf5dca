"""Straight motions: each hand's grasp frame along a straight line to its goal, its orientation kept (the approach
to a grasp, the retreat from it), and tracking a nearby pose of both hands on the arms' branch."""

import logging

import numpy as np
from pydrake.math import RigidTransform

from systems.planning.hand_constraints import MAX_STEP, bounded_step, rotation_error
from systems.planning.ik import DualArmIk
from systems.planning.world import SIDES, PlanningWorld

APPROACH_STEPS = 3
MAX_STRAIGHT_STEP = 0.6  # rad: the most a joint may turn between two keyframes of a straight motion
# Tracking a straight motion's next keyframe: at most this many Gauss-Newton steps, to within these position (m)
# and orientation (rad, about sin of the angle) errors per hand.
TRACK_ITERATIONS = 40
TRACK_TOLERANCES = (0.001, 0.005)


class PlanningError(RuntimeError):
    """No motion: names the phase that failed and why."""


class WouldTouch(PlanningError):
    """A straight motion refused because a step of it would touch the robot itself or the fixed scene."""


class StraightMotions:
    """Plans straight motions of both hands in a PlanningWorld, by tracking and, where that stalls, the IK."""

    def __init__(self, world: PlanningWorld, ik: DualArmIk):
        self.world, self.ik = world, ik

    def straight(
        self,
        q_start: np.ndarray,
        targets_W: dict[str, RigidTransform],
        steps: int = APPROACH_STEPS,
        min_steps: int | None = None,
    ):
        """Keyframes moving each hand's origin along a straight line to its target, its orientation kept as
        at q_start (the IK branch kept: no half turns, no restarts).

        The whole line is tracked with the arms alone first, the torso held (a turning torso sweeps both hands
        along arcs between keyframes). Where that stalls, each keyframe is tracked from the one before with the
        torso too, and where that stalls, SNOPT solves it from there (then from the nearest seeds), as long as the
        arms stay on their branch (a jump would leave the line between keyframes).

        min_steps: where a later step fails, the keyframes of the steps before it are the move, as long as there
        are at least this many (a back-off goes as far as the arms reach); None: the whole line or nothing.

        A step also fails where the arms, moving to it, would touch the robot itself or the fixed scene by Drake's
        exact geometry (the contacts where the robot stands at q_start may stay, no deeper; the contacts a grasp
        makes do not count: a hand with a welded object, the two hands' fingers at an object's close handles):
        tracking keeps the hands on their lines, not the forearms off the torso.

        Raises:
            PlanningError: naming the step whose IK failed (WouldTouch: that would touch).
        """
        keyframes, failure = self._tracked_line(q_start, targets_W, steps)
        error = PlanningError
        standing = self.world.penetrations(q_start, grasp_contacts=False)
        for step in range(1, len(keyframes)):
            if not self.world.segment_is_free(
                keyframes[step - 1], keyframes[step], tolerated=standing, grasp_contacts=False
            ):
                failure, error = f"step {step} of {steps}: the arms would touch the robot or the table", WouldTouch
                keyframes = keyframes[:step]
                break
        if failure is not None:
            if min_steps is None or len(keyframes) - 1 < min_steps:
                raise error(failure)
            logging.warning("straight move: %s; ending after step %d", failure, len(keyframes) - 1)
        return np.stack(keyframes)

    def _tracked_line(
        self, q_start: np.ndarray, targets_W: dict[str, RigidTransform], steps: int
    ) -> tuple[list[np.ndarray], str | None]:
        """straight()'s keyframes from q_start, each hand's origin moved along its line, before the collision
        check: as far as tracking and the IK reach (and why they stopped short, or None)."""
        start_poses = self.world.grasp_frame_poses(q_start)
        line = [
            {
                side: RigidTransform(
                    start_poses[side].rotation(),
                    (1 - step / steps) * start_poses[side].translation() + step / steps * targets_W[side].translation(),
                )
                for side in SIDES
            }
            for step in range(1, steps + 1)
        ]
        keyframes, q = [np.asarray(q_start, float)], np.asarray(q_start, float)
        if self.world.torso is not None:
            for targets in line:
                if (q := self.track(q, targets, with_torso=False)) is None:
                    break
                keyframes.append(q)
            else:
                return keyframes, None
            keyframes, q = [np.asarray(q_start, float)], np.asarray(q_start, float)
        for step, targets in enumerate(line, start=1):
            if (tracked := self.track(q, targets)) is not None:
                keyframes.append(tracked)
                q = tracked
                continue
            torso = [q[self.world.torso]] if self.world.torso is not None else None  # where it stands: no jump
            result = self.ik.solve(targets, q, min_distance=None, allow_half_turn=False, restarts=4, torso_yaws=torso)
            failure = None
            if not result.success:
                failure = f"step {step} of {steps}: IK failed ({result.message})"
            elif np.abs(result.q - q).max() > MAX_STRAIGHT_STEP:
                failure = f"step {step} of {steps}: the arms would change their IK branch"
            if failure is not None:
                return keyframes, failure
            keyframes.append(result.q)
            q = result.q
        return keyframes, None

    def track(self, q: np.ndarray, targets_W: dict[str, RigidTransform], with_torso: bool = True) -> np.ndarray | None:
        """The planned joints moved from q until both grasp frames are at targets_W (within TRACK_TOLERANCES), by
        damped Gauss-Newton steps of every joint at once (the torso held unless with_torso) within the limits,
        each joint at most MAX_STEP a step: a nearby target is reached on q's branch. None where the steps stall
        (a limit, a singularity, too far)."""
        world = self.world
        q = np.atleast_2d(np.asarray(q, float)).copy()
        for _ in range(TRACK_ITERATIONS):
            poses, jacobians = world.end_effectors.jacobians(q)
            errors, rows = [], []
            for X, J, side in zip(poses, jacobians, SIDES, strict=True):
                R = targets_W[side].rotation().matrix()
                errors += [X[:, :3, 3] - targets_W[side].translation(), rotation_error(R, X[:, :3, :3])]
                rows += [J[:, 3:], R.T @ J[:, :3]]
            error = np.concatenate(errors, axis=1)[0]
            if all(np.abs(error[i : i + 3]).max() < TRACK_TOLERANCES[(i // 3) % 2] for i in range(0, 12, 3)):
                return q[0]
            jacobian = np.concatenate(rows, axis=1)
            if world.torso is not None and not with_torso:
                jacobian[:, :, world.torso] = 0.0  # a joint without effect on the error is not moved
            q = bounded_step(q, error[None], jacobian, world.lower, world.upper, MAX_STEP)
        return None
