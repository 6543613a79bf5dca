"""The aim task's board in the station: a vertical board welded on the table, facing the robot, with a target disc
marked on its face (scenario.aim).

Frames: W the world (z up); the board's face F: origin at the centre of the face's bottom edge, on the table top,
x_F its outward normal (towards the robot: -x_W), z_F up.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, Cylinder
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant

from diagrams.scenario import BOARD_SIZE_M, TABLE_HEIGHT, Scenario
from systems.perception.board_target import TARGET_RGB

BOARD_INSTANCE = "board"
BOARD_RGBA = (0.86, 0.86, 0.82, 1.0)
TARGET_RADIUS_M = 0.025
TARGET_PROUD_M = 0.0005  # m: the disc (seen, not touched) lies this far in front of the face
# The drawn targets: along the board from its centre (y) and above the table (z), m: where the arms reach them
# holding a drill (benchmark_use_reach.py --task aim --inset 0.2: 27 of 27 at 25 and 30 cm up, 17 of 27 at 20 cm).
AIM_TARGET_RANGE = ((-0.1, 0.1), (0.25, 0.30))


@dataclass(frozen=True)
class BoardPlacement:
    """Where the board and its target stand, in W."""

    X_WF: RigidTransform  # the face frame F (module docstring)
    target_W: np.ndarray  # (3,) the target's centre, on the face, m

    @property
    def normal_W(self) -> np.ndarray:
        """The face's outward normal (towards the robot), unit."""
        return self.X_WF.rotation().matrix()[:, 0].copy()


def board_placement(scenario: Scenario) -> BoardPlacement:
    """The scenario's board and target; a target not given is drawn from random_seed within AIM_TARGET_RANGE."""
    aim = scenario.aim
    X_WF = RigidTransform(
        RotationMatrix.MakeZRotation(np.pi), np.array(scenario.table_xyz) + aim.board_xyz + [0.0, 0.0, TABLE_HEIGHT]
    )
    if aim.target_yz:
        along, up = aim.target_yz
    else:
        rng = np.random.default_rng([scenario.random_seed, 80])
        along, up = (rng.uniform(*bounds) for bounds in AIM_TARGET_RANGE)
    # Along the board: +y_W is -y_F (F faces the robot).
    return BoardPlacement(X_WF, X_WF.multiply([0.0, -along, up]))


def board_box(scenario: Scenario) -> tuple[RigidTransform, np.ndarray]:
    """The board as a box (X_WB of its centre, its size along B's axes, m): as the planning benchmark's boxes."""
    X_WF = board_placement(scenario).X_WF
    width, height, thickness = BOARD_SIZE_M
    return X_WF @ RigidTransform([-thickness / 2, 0.0, height / 2]), np.array([thickness, width, height])


def AddBoard(plant: MultibodyPlant, scenario: Scenario):
    """The board (a body of its own model instance BOARD_INSTANCE, welded) and its target disc (seen only)."""
    placement = board_placement(scenario)
    X_WB, size = board_box(scenario)
    instance = plant.AddModelInstance(BOARD_INSTANCE)
    body = plant.AddRigidBody(BOARD_INSTANCE, instance)
    plant.WeldFrames(plant.world_frame(), body.body_frame(), placement.X_WF)
    X_FB = placement.X_WF.InvertAndCompose(X_WB)
    plant.RegisterVisualGeometry(body, X_FB, Box(*size), "board_visual", np.array(BOARD_RGBA))
    plant.RegisterCollisionGeometry(body, X_FB, Box(*size), "board_collision", CoulombFriction(0.6, 0.5))
    target_F = placement.X_WF.inverse().multiply(placement.target_W)
    X_FT = RigidTransform(RotationMatrix.MakeYRotation(np.pi / 2), target_F + [TARGET_PROUD_M / 2, 0.0, 0.0])
    disc = Cylinder(TARGET_RADIUS_M, TARGET_PROUD_M)
    plant.RegisterVisualGeometry(body, X_FT, disc, "board_target_visual", np.append(TARGET_RGB, 1.0))
    return instance
