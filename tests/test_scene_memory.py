"""The scene memory: what the robot's arms hide in a frame is remembered from the frame before; everything else the
new frame decides."""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.sensors import CameraInfo, ImageDepth32F

from systems.perception.scene_memory import SceneMemory, hidden_by_robot, remembered_scene

INTRINSICS = CameraInfo(64, 48, np.pi / 3)
X_WC = RigidTransform()  # the camera at W's origin, looking along +z
FLOOR_M = 1.0  # the depth everywhere but where the sphere stands
SPHERE = np.array([[0.0, 0.0, 0.5, 0.05]])  # a robot sphere on the optical axis, 0.5 m away, 5 cm radius


def _depth_with_sphere() -> np.ndarray:
    """The depth image of a floor at FLOOR_M with the robot's sphere in front of it (its near surface)."""
    depth = np.full((48, 64), FLOOR_M, np.float32)
    v, u = np.mgrid[0:48, 0:64]
    x = (u - INTRINSICS.center_x()) / INTRINSICS.focal_x()
    y = (v - INTRINSICS.center_y()) / INTRINSICS.focal_y()
    on_sphere = x**2 + y**2 < (0.05 / 0.5) ** 2
    depth[on_sphere] = 0.45
    return depth


def test_points_behind_the_robot_are_hidden_by_it_and_those_behind_the_floor_or_before_it_are_not():
    points = np.array([
        [0.0, 0.0, 0.9],  # behind the sphere: hidden by the robot
        [0.2, 0.0, 0.9],  # in front of the floor, off the sphere's pixels: seen through (it is gone)
        [0.2, 0.0, 1.2],  # behind the floor: hidden, but not by the robot
        [0.0, 0.0, 0.3],  # in front of the sphere: the frame would see it
        [5.0, 0.0, 0.9],  # outside the image
    ])  # fmt: skip
    hidden = hidden_by_robot(points, _depth_with_sphere(), INTRINSICS, X_WC, SPHERE)
    assert hidden.tolist() == [True, False, False, False, False]
    assert not hidden_by_robot(points, _depth_with_sphere(), INTRINSICS, X_WC, np.zeros((0, 4))).any()


def test_the_remembered_scene_adds_what_the_robot_hides_but_not_near_the_object():
    now = np.array([[0.1, 0.1, 1.0]])
    before = np.array([[0.0, 0.0, 0.9], [0.01, 0.0, 0.9], [0.2, 0.0, 0.9]])
    scene = remembered_scene(now, before, _depth_with_sphere(), INTRINSICS, X_WC, SPHERE)
    assert np.array_equal(scene, np.vstack([now, before[:2]]))
    near_object = np.array([[0.0, 0.0, 0.92]])  # the object to pick stands there now: its space is its own
    scene = remembered_scene(now, before, _depth_with_sphere(), INTRINSICS, X_WC, SPHERE, near_object)
    assert np.array_equal(scene, now)


def _image(depth: np.ndarray) -> ImageDepth32F:
    image = ImageDepth32F(depth.shape[1], depth.shape[0])
    image.mutable_data[:, :, 0] = depth
    return image


def test_the_memory_keeps_the_frame_before_as_the_latch_takes_the_next_and_hands_on_what_the_arms_hide():
    dut = SceneMemory(INTRINSICS, RigidTransform(), period_s=0.01)
    context = dut.CreateDefaultContext()
    first = np.array([[0.0, 0.0, 0.9], [0.2, 0.0, 0.9]])  # the frame at home: the arms out of view
    inputs = {
        "scene_cloud_W": first,
        "depth_image": _image(np.full((48, 64), FLOOR_M, np.float32)),
        "camera_pose": X_WC,
        "robot_spheres_W": np.zeros((0, 4)),
        "object_cloud_W": np.zeros((0, 3)),
    }
    for port, value in inputs.items():
        dut.GetInputPort(port).FixValue(context, AbstractValue.Make(value))
    dut.GetInputPort("frame_id").FixValue(context, [1.0])
    dut.GetInputPort("trigger").FixValue(context, [1.0])
    simulator = Simulator(dut, context)
    simulator.AdvanceTo(0.05)
    assert np.array_equal(dut.GetOutputPort("scene_cloud_W").Eval(context), first)  # nothing remembered yet
    assert context.get_abstract_state(0).get_value().frame_id == 0.0  # (no new frame asked for: nothing written)
    dut.GetInputPort("trigger").FixValue(context, [2.0])  # the next frame asked for: the first is kept
    simulator.AdvanceTo(0.1)
    assert context.get_abstract_state(0).get_value().frame_id == 1.0
    # The second frame: the arms over the table hide the first point; the second is seen through.
    second = np.array([[0.3, 0.3, 1.0]])
    dut.GetInputPort("scene_cloud_W").FixValue(context, AbstractValue.Make(second))
    dut.GetInputPort("depth_image").FixValue(context, AbstractValue.Make(_image(_depth_with_sphere())))
    dut.GetInputPort("robot_spheres_W").FixValue(context, AbstractValue.Make(SPHERE))
    dut.GetInputPort("frame_id").FixValue(context, [2.0])
    assert np.array_equal(dut.GetOutputPort("scene_cloud_W").Eval(context), np.vstack([second, first[:1]]))
