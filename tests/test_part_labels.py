"""Functional parts: the roles of generated parts, the part labels of a rendered frame, the shop family's handles
and grasps, and the fixed instances' shapes kept as they were."""

import functools
import hashlib

import numpy as np
import pytest
import trimesh
from pydrake.math import RigidTransform

from diagrams.generation.objects import catalog, watering_can
from diagrams.generation.objects.hand_clearance import hands_fit
from diagrams.generation.objects.watering_can_shop import TOP_SHAPES
from diagrams.generation.part_labels import (
    face_role_surface,
    face_roles,
    on_handles,
    part_image,
    part_surface,
    true_part_surface,
)
from diagrams.generation.synthetic_scenes import SyntheticScene
from diagrams.scenario import ObjectConfig
from systems.perception.parts import PartRole, part_name

LEFT, RIGHT, TOOL, BODY = PartRole.LEFT_HANDLE, PartRole.RIGHT_HANDLE, PartRole.TOOL, PartRole.BODY


def test_every_part_of_a_generated_can_and_drill_has_its_role():
    can = {part.name: part.role for part in catalog.generate("watering_can", "train_0").parts}
    assert can == {"body": BODY, "spout": TOOL, "rose": TOOL, "top_handle": LEFT, "rear_handle": RIGHT}
    drill = {part.name: part.role for part in catalog.generate("drill", "wide_3").parts}
    expected = {"battery": BODY, "grip": RIGHT, "housing": BODY, "chuck": TOOL, "side_handle": LEFT, "knob": LEFT}
    assert drill == expected
    assert part_name("drill", RIGHT) == "pistol grip" and part_name("watering_can", LEFT) == "top handle"
    assert part_name("watering_can", TOOL) == "spout" and part_name("pot", RIGHT) == "right handle"


def _pixel(X_CW: RigidTransform, camera_info, p_W) -> tuple[int, int]:
    x, y, z = X_CW.multiply(np.asarray(p_W, dtype=float))
    return round(camera_info.focal_y() * y / z + camera_info.center_y()), round(
        camera_info.focal_x() * x / z + camera_info.center_x()
    )


@pytest.fixture(scope="module")
def can_frame(scenario):
    """A rendered frame of train_0's can turned 0.4 rad from its presentation, and what the part image needs."""
    name = "train_0"
    scene = SyntheticScene(
        scenario,
        np.random.default_rng(3),
        classes=("background", "watering_can"),
        instances=(name,),
        cameras=1,
        camera_jitter=False,
    )
    frame = scene.render(placement=("watering_can", name, 0.4, np.array([0.75, 0.05])))
    (_, _, X_WO), depth_camera = frame.objects[0], scenario.camera.MakeCameras()[1].core()
    X_WC = frame.X_WC @ depth_camera.sensor_pose_in_camera_body()
    return {
        "instance": catalog.generate("watering_can", name),
        "X_WO": X_WO,
        "X_WC": X_WC,
        "camera_info": depth_camera.intrinsics(),
        "depth": frame.depth,
        "mask": frame.labels == 1,
    }


def test_part_image_of_a_rendered_can_puts_each_role_where_its_part_is(can_frame):
    f = can_frame
    instance = f["instance"]
    image = part_image(part_surface(instance.parts), f["X_WO"], f["depth"], f["mask"], f["camera_info"], f["X_WC"])
    assert image.dtype == np.uint8 and np.array_equal(image > 0, f["mask"])
    assert {PartRole(r) for r in np.unique(image[f["mask"]])} == {BODY, LEFT, RIGHT, TOOL}
    X_CW = f["X_WC"].inverse()
    spout = watering_can.spout_axis(instance.parameters)
    points_O = {
        LEFT: instance.grasps["left"].grasp.GetDeterministicValue().translation(),
        RIGHT: instance.grasps["right"].grasp.GetDeterministicValue().translation(),
        TOOL: spout.end + 0.02 * spout.direction,  # on the rose
    }
    for role, p_O in points_O.items():
        row, col = _pixel(X_CW, f["camera_info"], f["X_WO"].multiply(p_O))
        around = image[row - 2 : row + 3, col - 2 : col + 3]
        assert np.count_nonzero(around == role) >= 20, f"{role.name} around its point: {around}"


def test_a_mesh_with_face_roles_labels_a_frame_as_its_parts_do(can_frame):
    """The held-out OBJ files carry per-face roles of their union mesh: they give the parts' labels."""
    f = can_frame
    surface = part_surface(f["instance"].parts)
    mesh = f["instance"].visual_mesh()
    from_faces = face_role_surface(mesh, face_roles(mesh, surface))
    args = (f["X_WO"], f["depth"], f["mask"], f["camera_info"], f["X_WC"])
    by_parts, by_faces = part_image(surface, *args), part_image(from_faces, *args)
    assert np.count_nonzero(by_parts != by_faces) <= 0.01 * np.count_nonzero(f["mask"])


@functools.cache
def _shop_instance(category: str, seed: int):
    return catalog.generate(category, f"shop_{seed}")


def _shop(category: str, wanted) -> list:
    """The shop instances among shop_0..9 whose parameters `wanted` takes."""
    return [instance for k in range(10) if wanted((instance := _shop_instance(category, k)).parameters)]


@pytest.mark.slow
def test_a_shop_can_with_its_top_handle_across_the_body_is_grasped_along_y_from_above():
    across = _shop("watering_can", lambda p: p["top_across"] and TOP_SHAPES[int(p["top_shape"])] != "loop")
    assert len(across) >= 2
    for instance in across:
        X_OG = instance.grasps["left"].grasp.GetDeterministicValue()
        R = X_OG.rotation().matrix()
        assert abs(R[:, 0] @ [0.0, 1.0, 0.0]) > 0.999, "x_G runs along the handle, across the body"
        assert R[:, 2] @ [0.0, 0.0, -1.0] > 0.999, "the hand comes from above"
        top = next(part for part in instance.parts if part.role == LEFT)
        depth = trimesh.proximity.signed_distance(top.mesh, X_OG.translation()[None, :])[0]
        assert depth == pytest.approx(instance.parameters["tube_radius"], abs=2e-3), "on the handle's centre line"


@pytest.mark.slow
@pytest.mark.parametrize("category", sorted(catalog.CATEGORIES))
def test_every_shop_grasp_lies_in_its_hands_part_and_the_hands_fit(category):
    for k in range(6):
        instance = _shop_instance(category, k)
        assert hands_fit(instance), instance.name
        for side, role in (("left", LEFT), ("right", RIGHT)):
            point = instance.grasps[side].grasp.GetDeterministicValue().translation()[None, :]
            parts = [part for part in instance.parts if part.role == role]
            depth = max(trimesh.proximity.signed_distance(part.mesh, point)[0] for part in parts)
            assert depth > 0.008, f"{instance.name}: the {side} grasp is not inside its handle"


def test_a_shop_can_with_one_loop_handle_gives_its_top_stretch_to_the_left_hand_and_its_rear_to_the_right():
    (loop, *_) = _shop("watering_can", lambda p: TOP_SHAPES[int(p["top_shape"])] == "loop")
    roles = {part.name: part.role for part in loop.parts}
    assert roles["loop_top"] == LEFT and roles["loop_rear"] == RIGHT
    top = next(part.mesh for part in loop.parts if part.name == "loop_top")
    rear = next(part.mesh for part in loop.parts if part.name == "loop_rear")
    # The rear stretch runs down behind the body; the top one along the top, above the lid.
    assert rear.bounds[0][0] < top.bounds[0][0] + 0.05 and rear.bounds[0][2] < top.bounds[0][2]
    assert loop.visual_mesh().is_watertight


def _shape_digest(category: str, name: str) -> str:
    """A digest of an instance's parts (names, roles, densities, vertices to the micrometre, in a sorted order)
    and its ground truth to the nanometre: what a change of shape or grasp changes."""
    instance = catalog.generate(category, name)
    digest = hashlib.sha256()
    for part in instance.parts:
        vertices = np.round(part.mesh.vertices, 6) + 0.0  # + 0.0: no negative zeros
        digest.update(f"{part.name}:{int(part.role)}:{part.density}:{len(part.collision)}".encode())
        digest.update(np.ascontiguousarray(vertices[np.lexsort(vertices.T[::-1])]).tobytes())
    info = instance.info()
    values = [info.mass, *info.com, *sorted(info.parameters.items())]
    for pose in info.control_poses().values():
        values.extend(pose.GetAsMatrix4().ravel())
    digest.update(repr([v if isinstance(v, tuple) else f"{v:.9f}" for v in values]).encode())
    return digest.hexdigest()[:16]


# Digests of instances as the generators made them before the shop family came: their files (visual.obj,
# collision pieces, info.yaml) hashed the same as those 2aa0962 wrote.
SHAPE_DIGESTS = {
    ("watering_can", "train_0"): "9af493a2587ed956",
    ("watering_can", "wide_100"): "42ba344ecdb96d11",
    ("drill", "test_1"): "1b7ae40caae24eca",
    ("drill", "wide_0"): "d0515e16e480ea44",
}


@pytest.mark.parametrize("key", sorted(SHAPE_DIGESTS), ids=lambda key: "/".join(key))
def test_every_existing_instance_keeps_its_shape(key):
    assert _shape_digest(*key) == SHAPE_DIGESTS[key]


def test_a_grasp_is_judged_on_its_own_handle_and_off_it_a_few_centimetres_away():
    config = ObjectConfig(category="watering_can", instance="shop_3")
    surface = true_part_surface(config)
    instance = catalog.generate("watering_can", "shop_3")
    grasps_O = {s: instance.grasps[s].grasp.GetDeterministicValue().translation() for s in ("left", "right")}
    assert on_handles(surface, grasps_O) == {"left": True, "right": True}
    swapped = {"left": grasps_O["right"], "right": grasps_O["left"]}  # each on the other hand's handle
    assert on_handles(surface, swapped) == {"left": False, "right": False}
    beside = {"left": grasps_O["left"] + [0.0, 0.0, 0.06], "right": grasps_O["right"]}  # 6 cm above the top handle
    assert on_handles(surface, beside) == {"left": False, "right": True}
    assert true_part_surface(ObjectConfig(category="watering_can", file="my_can.sdf")) is None  # parts unknown
