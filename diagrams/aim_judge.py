"""Judges the aim task on the simulator's ground truth: the plant's drill, not the plan.

During the hold (the pick's mode AIM_HOLD) every sample measures the true tool frame (the drill's pose on the plant
and its model's true tool frame) against the board's face F: the bit's axis against the face's inward normal, the
tip's distance from the target across the normal, and its distance off the face along it. Aimed: the worst sample
within AIM_AXIS_TOLERANCE_RAD, AIM_TARGET_TOLERANCE_M and AIM_OFF_SURFACE_M, held AIM_HELD_S at least, and nothing
touched the board over the whole run. Then the drill must end set down where it stood before the pick, as the place
task's judge says (PlaceJudge with no target).
"""

import numpy as np
from pydrake.multibody.plant import MultibodyPlant

from diagrams.aim_board import BOARD_INSTANCE, BoardPlacement
from diagrams.pick_simulation import SAMPLE_S, PickOutcome
from diagrams.tool_judge import ToolJudge
from systems.messages import Mode
from systems.shape_space.tool_frame import ToolFrame

AIM_AXIS_TOLERANCE_RAD = np.radians(3.0)
AIM_TARGET_TOLERANCE_M = 0.01
AIM_OFF_SURFACE_M = (0.002, 0.010)  # m: the tip's distance off the face, at least and at most
AIM_HELD_S = 1.5  # s of the 2 s hold sampled (the samples fall every SAMPLE_S)


class AimJudge(ToolJudge):
    """The aim task's judge (module docstring); its figures go to the outcome's `use`."""

    def __init__(self, plant: MultibodyPlant, context, mode_of, board: BoardPlacement, tool_O: ToolFrame):
        super().__init__(plant, context, mode_of, tool_O, Mode.AIM_HOLD)
        self.board = board
        self.board_bodies = set(plant.GetBodyIndices(plant.GetModelInstanceByName(BOARD_INSTANCE)))
        self.aims: list[tuple[float, float, float]] = []  # (axis rad, across m, off m) per hold sample
        self.touched = False

    def sample(self, t: float) -> float:
        z = super().sample(t)
        if self.body is None:
            return z
        if self.mode_of(self.context) == Mode.AIM_HOLD:
            tool = self.tool_W()
            normal = self.board.normal_W
            axis = float(np.arccos(np.clip(tool.axis @ -normal, -1.0, 1.0)))
            offset = tool.tip - self.board.target_W  # (the target lies on the face; the disc on it is seen only)
            off = float(offset @ normal)
            across = float(np.linalg.norm(offset - off * normal))
            self.aims.append((axis, across, off))
        self.touched = self.touched or self._board_touched()
        return z

    def _board_touched(self) -> bool:
        results = self.plant.get_contact_results_output_port().Eval(self.plant_context)
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)
            if {info.bodyA_index(), info.bodyB_index()} & self.board_bodies:
                return True
        return False

    def outcome(self) -> PickOutcome:
        outcome = super().outcome()
        aims = np.array(self.aims).reshape(-1, 3)
        held_s = len(aims) * SAMPLE_S
        use = {"task": "aim", "held_s": held_s, "board_touched": self.touched,
               "target_W": np.round(self.board.target_W, 4).tolist(),
               "normal_W": np.round(self.board.normal_W, 4).tolist()}  # fmt: skip
        checks = {"never aimed": len(aims) > 0}
        if len(aims):
            axis, across = float(aims[:, 0].max()), float(aims[:, 1].max())
            nearest, farthest = float(aims[:, 2].min()), float(aims[:, 2].max())
            use |= {"axis_error_rad": axis, "tip_to_target_m": across, "tip_off_surface_m": [nearest, farthest]}
            low, high = AIM_OFF_SURFACE_M
            checks |= {
                f"held {held_s:.2f} s": held_s >= AIM_HELD_S - 1e-9,
                f"bit axis {np.degrees(axis):.1f} deg off the normal": axis <= AIM_AXIS_TOLERANCE_RAD,
                f"tip {1000 * across:.1f} mm from the target": across <= AIM_TARGET_TOLERANCE_M,
                f"tip {1000 * nearest:.1f}-{1000 * farthest:.1f} mm off the face": low <= nearest and farthest <= high,
            }
        checks["the board touched"] = not self.touched
        return self.judged_use(outcome, use, checks, "aimed")
