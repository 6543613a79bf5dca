"""What the pick supervisor checks, what it waits on and how long before it names the cause and stops, and how a
failure is recorded (fail: the stage and the reason).

- The hands after closing: each must hold something, its measured opening neither closed to nothing
  (below MIN_GRASPED_WIDTH) nor still open (within NOT_CLOSED_MARGIN of OPEN_WIDTH).
- A camera frame (perception's or a look's): at most CAMERA_WAIT_S after asking. Perception latches only a fresh
  image (systems/perception/camera_latch.py), so while the camera's images have stopped, the frame does not come.
- A move: until the trajectory source has played the plan to its end (its Playback, which pauses while the robot's
  status is stale). A pause longer than STATUS_LOST_S (the scenario's hardware.status_lost_s) ends the pick with
  the arms holding.
"""

import logging
import math

from systems.messages import OPEN_WIDTH, SIDES, Mode, PickStatus, Playback, Stage

MIN_GRASPED_WIDTH = 0.004  # m
NOT_CLOSED_MARGIN = 0.01  # m
CAMERA_WAIT_S = 10.0  # s: the camera's images may stop this long before the pick stops
STATUS_LOST_S = 5.0  # s: the robot's status may stop this long during a move before the pick stops


def camera_silence(t: float, asked_s: float, what: str) -> str:
    """Why the pick stops waiting for a camera frame asked for at asked_s (context s), or "" while it may wait."""
    if t - asked_s <= CAMERA_WAIT_S:
        return ""
    return f"no fresh camera image for {CAMERA_WAIT_S:.0f} s after asking for {what}: the camera's images stopped"


def played_s(playback: Playback | None, plan_id: int, t: float) -> float:
    """The trajectory time the source has played plan plan_id to (s); without a playback input, context time t."""
    if playback is None:
        return t
    return playback.time_s if playback.plan_id == plan_id else -math.inf


def status_silence(playback: Playback | None, move: str, lost_after_s: float | None = None) -> str:
    """Why the pick stops waiting for a move whose playing has paused longer than lost_after_s (None: STATUS_LOST_S;
    the robot's status stopped), or ""."""
    lost_after_s = STATUS_LOST_S if lost_after_s is None else lost_after_s
    if playback is None or playback.paused_for_s <= lost_after_s:
        return ""
    return f"the robot's status stopped for {lost_after_s:.0f} s during the {move}: the arms hold where they are"


def not_holding(widths: tuple[float, ...], when: str = "") -> str:
    """Why the hands, measured open by `widths` (m, one per side), do not both hold something, or "" if they do."""
    for side, width in zip(SIDES, widths, strict=True):
        if width < MIN_GRASPED_WIDTH:
            return f"{when}the {side} hand closed on nothing (opening {width * 1000:.1f} mm)"
        if width > OPEN_WIDTH - NOT_CLOSED_MARGIN:
            return f"{when}the {side} hand did not close (opening {width * 1000:.1f} mm)"
    return ""


def fail(status: PickStatus, stage: Stage, message: str):
    """Ends the pick in `status`: failed at `stage` for `message`, the attempt's failure recorded."""
    logging.warning("pick stopped at %s: %s", stage, message)
    status.mode, status.failed_stage, status.message = Mode.FAILED, stage, stage_message(stage, message)
    status.attempt_failures = (*status.attempt_failures, (str(stage), status.message))


def stage_message(stage: Stage, message: str) -> str:
    """A failure's message, led by its stage."""
    return message if message.startswith(stage) else f"{stage}: {message}"
