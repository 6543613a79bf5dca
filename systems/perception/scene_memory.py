"""The scene the planner avoids, remembered where the robot's own arms hide it.

A frame taken with the arms over the table (the clear's look from where the hands backed off, before the move home)
does not see what stands under them: SceneCloud leaves the robot out, and nothing counts as hidden behind it. The
move home planned in that frame alone swept an arm through a drill the frame before had seen (clear report table 0,
2026-12-05: the drill knocked over, 91 degrees). The memory keeps, of the scene it held for the frame before, the
points the new frame cannot see because the robot stands in front of them: the depth measured in their pixel is
OCCLUSION_MARGIN_M nearer than they are, and the surface measured there lies on the robot (its sphere model, grown
by SceneCloud's SELF_MARGIN_M). Everything else the new frame decides: what it sees through is gone, what it sees is
there. So a frame with the arms out of view (every pick's frame at home) forgets what came before, and the object
to pick is never remembered into its own way (points within TARGET_MARGIN_M of its reconstruction are left out).

Frames: W the world, C the depth camera (z along the optical axis); metres.
"""

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import EventStatus, LeafSystem
from pydrake.systems.sensors import CameraInfo, ImageDepth32F
from scipy.spatial import cKDTree

from systems.parallel import THREADS
from systems.perception.depth_view import DepthView
from systems.perception.scene_cloud import SELF_MARGIN_M, TARGET_MARGIN_M
from systems.planning.sphere_model import on_the_robot

OCCLUSION_MARGIN_M = 0.02  # m: a pixel's measured depth this much nearer than a point hides it (sensor noise below)


def hidden_by_robot(
    points_W: np.ndarray, depth: np.ndarray, intrinsics: CameraInfo, X_WC: RigidTransform, robot_spheres_W: np.ndarray
) -> np.ndarray:
    """Which of the points (N x 3 in W) the frame (depth: H x W, m; X_WC: the depth camera's pose) cannot see because
    the robot stands in front of them (N bools): the depth measured in their pixel is OCCLUSION_MARGIN_M nearer, and
    the surface measured there lies within SELF_MARGIN_M of the robot's spheres (S x 4: centre in W, radius)."""
    points_W = np.asarray(points_W, float).reshape(-1, 3)
    if not len(points_W) or not len(robot_spheres_W):
        return np.zeros(len(points_W), bool)
    focal, centre = (intrinsics.focal_x(), intrinsics.focal_y()), (intrinsics.center_x(), intrinsics.center_y())
    seen = DepthView(depth, X_WC, focal, centre).look_up(points_W)
    nearer = np.flatnonzero(np.nan_to_num(seen.measured, nan=np.inf) < seen.depth - OCCLUSION_MARGIN_M)
    if not len(nearer):
        return np.zeros(len(points_W), bool)
    # The surface measured in the point's pixel: on the point's ray from the camera, at the measured depth.
    camera_W = X_WC.translation()
    scale = (seen.measured[nearer] / seen.depth[nearer])[:, None]
    surface_W = camera_W + scale * (points_W[nearer] - camera_W)
    hidden = np.zeros(len(points_W), bool)
    hidden[nearer[on_the_robot(surface_W, robot_spheres_W, SELF_MARGIN_M)]] = True
    return hidden


def remembered_scene(
    scene_W: np.ndarray,
    before_W: np.ndarray,
    depth: np.ndarray,
    intrinsics: CameraInfo,
    X_WC: RigidTransform,
    robot_spheres_W: np.ndarray,
    object_cloud_W: np.ndarray | None = None,
) -> np.ndarray:
    """The scene of this frame (scene_W, N x 3 in W) and, of the scene remembered for the frame before (before_W,
    M x 3), the points the robot hides in this one (hidden_by_robot), but for those within TARGET_MARGIN_M of the
    object's reconstruction (object_cloud_W, K x 3, or None)."""
    kept = before_W[hidden_by_robot(before_W, depth, intrinsics, X_WC, robot_spheres_W)] if len(before_W) else before_W
    if len(kept) and object_cloud_W is not None and len(object_cloud_W):
        kept = kept[cKDTree(object_cloud_W).query(kept, workers=THREADS)[0] > TARGET_MARGIN_M]
    return np.vstack([scene_W, kept]) if len(kept) else scene_W


@dataclass
class _Remembered:
    frame_id: float = 0.0  # the latched frame this scene is of (0: none yet)
    scene_W: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


class SceneMemory(LeafSystem):
    """The scene of the latched frame, with what the robot hides in it remembered from the frame before
    (remembered_scene).

    .. pydrake_system::

        name: SceneMemory
        input_ports:
        - scene_cloud_W
        - depth_image
        - camera_pose
        - robot_spheres_W
        - object_cloud_W
        - frame_id
        - trigger
        output_ports:
        - scene_cloud_W

    ``scene_cloud_W`` (N x 3 in W, m): SceneCloud's, of the latched frame; ``depth_image``, ``camera_pose`` (the
    camera body's X_WB), ``robot_spheres_W`` (S x 4) and ``object_cloud_W`` (K x 3) of the same frame;
    ``frame_id`` (1): the latched frame's id; ``trigger`` (1): the frame asked for (the latch's). Output: the
    remembered scene (N' x 3 in W).

    The state holds the output for one frame. It is written only at the latch's own update times, as the latch takes
    a new frame (trigger above frame_id): a write at another time would make Drake write back every state, the
    latch's included, and perception would compute its frame again. The output is computed from the state and the
    inputs, so it is the same whether or not that write has happened yet.

    Args:
        intrinsics, X_BC: the depth camera's intrinsics and its pose in the camera body.
        period_s, offset_s: the latch's (CameraLatch).
    """

    def __init__(self, intrinsics: CameraInfo, X_BC: RigidTransform, period_s: float = 0.01, offset_s: float = 0.0):
        super().__init__()
        self.intrinsics, self.X_BC = intrinsics, X_BC
        self.DeclareAbstractInputPort("scene_cloud_W", AbstractValue.Make(np.zeros((0, 3))))
        self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F()))
        self.DeclareAbstractInputPort("camera_pose", AbstractValue.Make(RigidTransform()))
        self.DeclareAbstractInputPort("robot_spheres_W", AbstractValue.Make(np.zeros((0, 4))))
        self.DeclareAbstractInputPort("object_cloud_W", AbstractValue.Make(np.zeros((0, 3))))
        self.DeclareVectorInputPort("frame_id", 1)
        self.DeclareVectorInputPort("trigger", 1)
        self._state = self.DeclareAbstractState(AbstractValue.Make(_Remembered()))
        self.DeclareAbstractOutputPort(
            "scene_cloud_W",
            lambda: AbstractValue.Make(np.zeros((0, 3))),
            self._calc,
            {self.all_input_ports_ticket(), self.abstract_state_ticket(self._state)},
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, offset_s, self._update)

    def _calc(self, context, output):
        remembered = context.get_abstract_state(self._state).get_value()
        frame_id = float(self.GetInputPort("frame_id").Eval(context)[0])
        scene_W = self.GetInputPort("scene_cloud_W").Eval(context)
        image = self.GetInputPort("depth_image").Eval(context)
        if frame_id == remembered.frame_id:  # (the latch still waits for the frame after the one remembered)
            output.set_value(remembered.scene_W)
            return
        if image.width() == 0:  # no frame yet
            output.set_value(scene_W)
            return
        X_WC = self.GetInputPort("camera_pose").Eval(context) @ self.X_BC
        output.set_value(
            remembered_scene(
                scene_W,
                remembered.scene_W,
                np.asarray(image.data)[:, :, 0],
                self.intrinsics,
                X_WC,
                self.GetInputPort("robot_spheres_W").Eval(context),
                self.GetInputPort("object_cloud_W").Eval(context),
            )
        )

    def _update(self, context, state) -> EventStatus:
        """As the latch takes a new frame, the scene of the frame it held is kept (the next frame's memory)."""
        remembered = context.get_abstract_state(self._state).get_value()
        frame_id = float(self.GetInputPort("frame_id").Eval(context)[0])
        asked = float(self.GetInputPort("trigger").Eval(context)[0])
        if asked <= frame_id or frame_id == remembered.frame_id or frame_id <= 0:
            return EventStatus.DidNothing()
        scene_W = self.GetOutputPort("scene_cloud_W").Eval(context)
        state.get_mutable_abstract_state(self._state).set_value(_Remembered(frame_id, np.array(scene_W)))
        return EventStatus.Succeeded()
