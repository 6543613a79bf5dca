"""What the use tasks' judges share (aim_judge.py, pour_judge.py): the place task's judge with no target (the object
must end where it stood), the object's true tool frame on the plant, and the tool tip's path over the whole run,
recorded in the outcome's `use` for a figure (scripts/draw_use.py)."""

import numpy as np
from pydrake.multibody.plant import MultibodyPlant

from diagrams.pick_simulation import PlaceJudge
from systems.messages import Mode
from systems.shape_space.tool_frame import ToolFrame

TIP_PATH_EVERY_S = 0.25  # s: the tool tip's path is recorded this often (a 90 s pick: some 360 points)


class ToolJudge(PlaceJudge):
    """PlaceJudge with no target, watching the object's true tool frame (tool_O: its model's, in O).

    Attributes:
        tip_path: (t s, x, y, z m in W) of the true tool tip, every TIP_PATH_EVERY_S of the run.
        hold_t: the first and last time (s) the pick was in hold_mode (the use's hold), or [].
    """

    def __init__(self, plant: MultibodyPlant, context, mode_of, tool_O: ToolFrame, hold_mode: Mode):
        super().__init__(plant, context, None, mode_of)
        self.tool_O, self.hold_mode = tool_O, hold_mode
        self.tip_path: list[list[float]] = []
        self.hold_t: list[float] = []

    def tool_W(self) -> ToolFrame:
        """The true tool frame in W now."""
        return self.tool_O.moved(self.body.EvalPoseInWorld(self.plant_context))

    def sample(self, t: float) -> float:
        z = super().sample(t)
        if self.body is not None and (not self.tip_path or t >= self.tip_path[-1][0] + TIP_PATH_EVERY_S - 1e-9):
            self.tip_path.append([round(float(t), 3), *np.round(self.tool_W().tip, 4).tolist()])
        if self.mode_of(self.context) == self.hold_mode:
            self.hold_t = [self.hold_t[0] if self.hold_t else float(t), float(t)]
        return z

    def judged_use(self, outcome, use: dict, checks: dict[str, bool], done: str):
        """PlaceJudge.judged_use with the tip's path in use["tip_path_W"] and the hold's times in use["hold_t_s"]."""
        return super().judged_use(outcome, use | {"tip_path_W": self.tip_path, "hold_t_s": self.hold_t}, checks, done)
