"""Judges the pour task on the simulator's ground truth: the plant's can and container, not the plan.

During the hold (the pick's mode POUR_HOLD) every sample measures the true tool frame (the can's pose on the plant
and its model's true tool frame: the spout's tip and outflow) against the container's true opening: the tip's
horizontal distance from the opening's centre, its height above the rim, and the outflow's angle below the
horizontal. Poured: for the worst sample, the tip within the opening's radius less POUR_INSIDE_M of its centre and
above the rim, the outflow at least the scenario's tilt down, held POUR_HELD_S at least; the container moved less
than CONTAINER_MOVED_M over the whole run. Then the can must end set down where it stood before the pick, upright, as
the place task's judge says (ToolJudge: PlaceJudge with no target).
"""

import numpy as np
from pydrake.multibody.plant import MultibodyPlant

from diagrams.pick_simulation import SAMPLE_S, PickOutcome
from diagrams.tool_judge import ToolJudge
from systems.messages import Mode
from systems.perception.container_opening import Opening
from systems.planning.pour_goals import outflow_elevation
from systems.shape_space.tool_frame import ToolFrame

POUR_INSIDE_M = 0.01  # m: the tip at least this far inside the opening's rim, horizontally
CONTAINER_MOVED_M = 0.005  # m: the container may be moved less than this
POUR_HELD_S = 1.5  # s of the 2 s hold sampled (the samples fall every SAMPLE_S)


class PourJudge(ToolJudge):
    """The pour task's judge (module docstring); its figures go to the outcome's `use`."""

    def __init__(
        self, plant: MultibodyPlant, context, mode_of, opening: Opening, tool_O: ToolFrame, tilt_below_rad: float
    ):
        super().__init__(plant, context, mode_of, tool_O, Mode.POUR_HOLD)
        self.opening, self.tilt_below_rad = opening, tilt_below_rad
        self.pours: list[tuple[float, float, float]] = []  # (tip from the centre m, above the rim m, outflow rad)

    def sample(self, t: float) -> float:
        z = super().sample(t)
        if self.body is not None and self.mode_of(self.context) == Mode.POUR_HOLD:
            X_WO = self.body.EvalPoseInWorld(self.plant_context)
            tip = self.tool_O.moved(X_WO).tip  # (the pose read once: the outflow below needs it too)
            offset = tip - self.opening.centre_W
            self.pours.append(
                (float(np.linalg.norm(offset[:2])), float(offset[2]), outflow_elevation(X_WO, self.tool_O))
            )
        return z

    def outcome(self) -> PickOutcome:
        outcome = super().outcome()
        pours = np.array(self.pours).reshape(-1, 3)
        held_s = len(pours) * SAMPLE_S
        moved = outcome.others_moved_m[-1] if outcome.others_moved_m else float("nan")
        use = {"task": "pour", "held_s": held_s, "container_moved_m": moved,
               "tilt_asked_rad": self.tilt_below_rad, "opening_radius_m": self.opening.radius,
               "opening_centre_W": np.round(self.opening.centre_W, 4).tolist()}  # fmt: skip
        checks = {"never poured": len(pours) > 0}
        if len(pours):
            off, low, outflow = float(pours[:, 0].max()), float(pours[:, 1].min()), float(pours[:, 2].max())
            use |= {"tip_from_centre_m": off, "tip_above_rim_m": low, "outflow_elevation_rad": outflow}
            inside = self.opening.radius - POUR_INSIDE_M
            checks |= {
                f"held {held_s:.2f} s": held_s >= POUR_HELD_S - 1e-9,
                f"spout tip {100 * off:.1f} cm from the opening's centre (at most {100 * inside:.1f})": off <= inside,
                f"spout tip {100 * low:.1f} cm above the rim": low > 0.0,
                f"outflow {np.degrees(-outflow):.1f} deg below the horizontal (at least "
                f"{np.degrees(self.tilt_below_rad):.0f})": -outflow >= self.tilt_below_rad - 1e-9,
            }
        checks[f"the container moved {1000 * moved:.1f} mm"] = moved < CONTAINER_MOVED_M
        return self.judged_use(outcome, use, checks, "poured")
