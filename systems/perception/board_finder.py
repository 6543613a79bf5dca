"""The board finder: the aim task's board and target in one camera frame (systems/perception/board_target.py).

Frames: W the world, B the camera body (camera_pose is X_WB), C the depth sensor (X_BC, its mounting).
"""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import CameraInfo, ImageDepth32F, ImageRgba8U

from systems.messages import BoardSeen
from systems.perception.board_target import board_of, board_points, target_pixels
from systems.perception.depth_cleaning import flying_pixels
from systems.perception.pose_estimator import depth_to_points


class BoardFinder(LeafSystem):
    """Finds the board's plane and its target's centre in a latched RGB-D frame.

    .. pydrake_system::

        name: BoardFinder
        input_ports:
        - color_image
        - depth_image
        - camera_pose
        output_ports:
        - board

    ``color_image`` (ImageRgba8U) and ``depth_image`` (ImageDepth32F, m) of the same view; ``camera_pose``
    (RigidTransform X_WB). ``board`` (BoardSeen): the board's outward normal and the target's centre in W, or why
    they were not found (an empty frame: "no frame yet").
    """

    def __init__(self, intrinsics: CameraInfo, X_BC: RigidTransform):
        super().__init__()
        self.intrinsics, self.X_BC = intrinsics, X_BC
        self.DeclareAbstractInputPort("color_image", AbstractValue.Make(ImageRgba8U()))
        self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F()))
        self.DeclareAbstractInputPort("camera_pose", AbstractValue.Make(RigidTransform()))
        self.DeclareAbstractOutputPort("board", lambda: AbstractValue.Make(BoardSeen()), self._calc_board)

    def _calc_board(self, context, output):
        rgb = self.get_input_port(0).Eval(context).data
        depth = self.get_input_port(1).Eval(context).data[..., 0]
        if rgb.size == 0 or depth.size == 0:
            output.set_value(BoardSeen(False, message="the board: no frame yet"))
            return
        X_WC = self.get_input_port(2).Eval(context) @ self.X_BC
        output.set_value(find_board(rgb, depth, self.intrinsics, X_WC))


def find_board(rgb: np.ndarray, depth: np.ndarray, intrinsics: CameraInfo, X_WC: RigidTransform) -> BoardSeen:
    """The board and its target in one frame (H x W x 3+ uint8 colour, H x W depth in m, the same view; X_WC the
    depth sensor's pose)."""
    valid = ~flying_pixels(depth)
    target_mask = target_pixels(rgb) & valid
    to_W = X_WC.GetAsMatrix34()
    target_W = _in_world(depth_to_points(depth, target_mask, intrinsics), to_W)
    seen_W = _in_world(depth_to_points(depth, valid, intrinsics), to_W)
    try:
        board = board_of(board_points(seen_W, target_W), target_W, X_WC.translation())
    except ValueError as error:
        return BoardSeen(False, message=str(error))
    return BoardSeen(True, board.normal_W, board.target_W, "board found")


def _in_world(points_C: np.ndarray, X_WC: np.ndarray) -> np.ndarray:
    return points_C @ X_WC[:, :3].T + X_WC[:, 3]
