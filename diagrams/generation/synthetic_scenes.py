"""Randomised synthetic scenes for training and testing the segmenter (paper §III).

A *scene* is one Drake diagram: Centauro, a table, walls, floor, lights and
clutter with random sizes and colours, several chest-camera poses, and every
object instance of the requested split (recoloured at random) as a free body.
A *frame* re-places the objects, the clutter and the arms, picks a camera and
renders colour and label images; the unused objects wait below the floor.

Class ids of the label images: 0 background, then CLASSES' order.
"""

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from pathlib import Path

import numpy as np
from pydrake.geometry import (
    Box,
    Cylinder,
    LightParameter,
    MakeRenderEngineVtk,
    Mesh,
    RenderEngineVtkParams,
    Rgba,
    Sphere,
)
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import SpatialInertia
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import RgbdSensor

from diagrams.generation.centauro_description import joint_names
from diagrams.generation.objects import catalog
from diagrams.generation.objects.bowl import bowl_file
from diagrams.generation.objects.library import generated_instance_directory
from diagrams.scenario import Scenario
from diagrams.station import AddCentauro, make_parser
from systems import categories

# The segmenter's classes: background, then the generated categories (a taught one widens it: add_category.py).
CLASSES = ("background", *categories.GENERATED)
PARKED = RigidTransform([0.0, 0.0, -10.0])  # where unused bodies wait, out of every view
CROWDED_OBJECTS = 3  # at most this many objects in a frame of a crowded scene
# The wider family's members the segmenter learns from (split "wide"; the wider shape space is built from
# wide_0..39), and those it is validated on (the wider shape space's validation range too).
WIDE_TRAINING = tuple(f"wide_{i}" for i in range(16))
WIDE_VALIDATION = tuple(f"wide_{i}" for i in range(100, 108))
# The shop family's (handles in every form) members the part network learns from, and those it is validated on.
SHOP_TRAINING = tuple(f"shop_{i}" for i in range(40))
SHOP_VALIDATION = tuple(f"shop_{i}" for i in range(100, 120))
# Split "parts": every family's training members, for the part network.
PART_TRAINING = tuple(f"train_{i}" for i in range(8)) + WIDE_TRAINING + SHOP_TRAINING
PART_VALIDATION = tuple(f"test_{i}" for i in range(3)) + WIDE_VALIDATION + SHOP_VALIDATION


class ClutterShape(IntEnum):
    """A clutter body's shape, drawn by its value (the bowl in crowded scenes only)."""

    BOX = 0
    CYLINDER = 1
    SPHERE = 2
    BOWL = 3


@dataclass
class Frame:
    rgb: np.ndarray  # H x W x 3 uint8
    labels: np.ndarray  # H x W uint8 class ids
    depth: np.ndarray  # H x W float32, metres (inf where nothing)
    X_WC: RigidTransform  # the colour camera's pose
    # Ground truth of each placed object: (category, instance name, X_WO).
    objects: list[tuple[str, str, RigidTransform]]
    # Each placed object's pixels (H x W bool each, in `objects`' order): what of it the camera sees.
    object_masks: list[np.ndarray] = field(default_factory=list)


def category_models(category: str, split: str, instances: Sequence[str] | None = None) -> list[tuple[str, Path]]:
    """(name, model file) of the category's instances of a split ("train", "test", "wide": WIDE_TRAINING, or
    "parts": PART_TRAINING), or
    the named generated instances; a taught category's training models whatever the split (it has no other)."""
    if category not in catalog.CATEGORIES:
        folder = categories.category_directory(category) / "training"
        models = [(path.stem, path) for path in sorted(folder.glob("*.sdf"))]
        if not models:
            raise FileNotFoundError(f"{folder} holds no models: teach {category!r} again with scripts/add_category.py")
        return models
    if instances:
        names = instances
    elif split == "wide":
        names = WIDE_TRAINING
    elif split == "parts":
        names = PART_TRAINING
    else:
        names = [n for n in catalog.instance_names(category) if n.startswith(split)]
    return [(name, generated_instance_directory(category, name) / "model.sdf") for name in names]


def recoloured_sdf(model_file: Path, rgb, model_name: str) -> str:
    """The model's SDF text with absolute mesh paths, a new diffuse colour and no collision geometry."""
    text = model_file.read_text()
    text = re.sub(r"<collision.*?</collision>", "", text, flags=re.S)
    text = re.sub(
        r"<uri>([^:<]+)</uri>", lambda m: f"<uri>file://{(model_file.parent / m.group(1)).resolve()}</uri>", text
    )
    text = re.sub(r"<diffuse>[^<]*</diffuse>", "<diffuse>{:.3f} {:.3f} {:.3f} 1</diffuse>".format(*rgb), text)
    return re.sub(r'<model name="[^"]*"', f'<model name="{model_name}"', text, count=1)


def random_color(rng, saturated=False) -> np.ndarray:
    """An RGB colour; `saturated` draws mostly from the vivid colours real tools and cans come in."""
    if saturated:
        # Not colorsys' HSV map: this wheel gives saturated colours for two thirds of the draws,
        # dark ones for a sixth and pale ones for a sixth. The shipped segmenter was trained on it,
        # so it stays (changing it changes every training and validation frame).
        hue = rng.uniform(0, 6)
        rgb = np.clip(np.abs((hue - np.array([3, 2, 4])) % 6 - 3) - 1, 0, 1)
        return np.clip(rgb * rng.uniform(0.5, 1.0) + rng.uniform(0.0, 0.3), 0.0, 1.0)
    return rng.uniform(0.05, 0.95, size=3)


def rgba(rgb) -> np.ndarray:
    return np.append(rgb, 1.0)


class SyntheticScene:
    """One randomised background with every instance of a split ready to be placed."""

    def __init__(
        self,
        scenario: Scenario,
        rng: np.random.Generator,
        split: str = "train",
        cameras: int = 3,
        classes=CLASSES,
        camera_jitter: bool = True,
        instances: Sequence[str] | None = None,
        models: dict[str, list[tuple[str, Path]]] | None = None,
        crowded: bool = False,
    ):
        """Args:
        scenario: robot, camera and nominal table placement.
        rng: the source of every random draw.
        split: whose instances ("train", "test" or "wide"; a taught category has its training models only).
        cameras: how many camera poses to choose from per frame.
        classes: the label images' class names by id, background first: the categories placed.
        camera_jitter: perturb the cameras about the chest mount (else all sit at the nominal pose).
        instances: these instances of each category instead of the split's (any generated name, e.g. extra_101).
        models: {category: [(name, SDF file)]}: these models of the categories named instead (a user's files).
        crowded: a cluttered table: up to CROWDED_OBJECTS objects, more clutter (bowls too), half of it next to
            the objects (in front of them, behind them, touching them in the image).
        """
        self.rng = rng
        self.classes = tuple(classes)
        self.crowded = crowded
        builder = DiagramBuilder()
        self.plant, self.scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
        plant = self.plant
        self.robot, _ = AddCentauro(plant, self.scene_graph, scenario)
        self.ready_pose = np.array(scenario.initial_arm_positions)
        self.table_height = rng.uniform(0.7, 0.8)
        self.table_x = scenario.table_xyz[0] + rng.uniform(-0.05, 0.05)
        self._add_static_background()
        clutter = plant.AddModelInstance("clutter")
        count = rng.integers(*((3, 10) if crowded else (2, 7)))
        self.clutter = [self._add_clutter_body(clutter, i) for i in range(count)]
        # Every instance of the split, freshly coloured.
        self.objects = []  # (category, instance, body)
        parser = make_parser(plant)
        for category in self.classes[1:]:
            chosen = models[category] if models and category in models else category_models(category, split, instances)
            for name, model_file in chosen:
                color = random_color(rng, saturated=rng.uniform() < 0.8)
                text = recoloured_sdf(model_file, color, f"{category}_{name}")
                (instance,) = parser.AddModelsFromString(text, "sdf")
                body = plant.get_body(plant.GetBodyIndices(instance)[0])
                self.objects.append((category, name, body))
        plant.Finalize()

        params = RenderEngineVtkParams(default_clear_color=random_color(rng), lights=self._random_lights())
        self.scene_graph.AddRenderer("vtk", MakeRenderEngineVtk(params))
        X_WC_nominal = self._nominal_camera_pose(scenario)
        color_camera, depth_camera = scenario.camera.MakeCameras()
        self.sensors = []
        for _ in range(cameras):
            jitter = RigidTransform(RollPitchYaw(rng.uniform(-0.12, 0.12, size=3)), rng.uniform(-0.06, 0.06, size=3))
            X_WC = X_WC_nominal @ jitter if camera_jitter else X_WC_nominal
            sensor = builder.AddSystem(RgbdSensor(self.scene_graph.world_frame_id(), X_WC, color_camera, depth_camera))
            builder.Connect(self.scene_graph.get_query_output_port(), sensor.query_object_input_port())
            self.sensors.append((sensor, X_WC))
        self.diagram = builder.Build()
        self.context = self.diagram.CreateDefaultContext()
        self.plant_context = plant.GetMyMutableContextFromRoot(self.context)
        self.class_of_label = self._label_classes()

    def _nominal_camera_pose(self, scenario) -> RigidTransform:
        mount = self.plant.GetFrameByName("camera_mount")
        X_WM = mount.CalcPoseInWorld(self.plant.CreateDefaultContext())
        return X_WM @ scenario.camera.X_PB.GetDeterministicValue()

    def _add_static_background(self):
        rng, plant = self.rng, self.plant
        world = plant.world_body()
        depth, width, thickness = rng.uniform(0.7, 0.9), rng.uniform(1.0, 1.6), 0.04
        top = RigidTransform([self.table_x, rng.uniform(-0.05, 0.05), self.table_height - thickness / 2])
        plant.RegisterVisualGeometry(world, top, Box(depth, width, thickness), "table_top", rgba(random_color(rng)))
        self.table_extent = (top.translation()[:2], np.array([depth, width]) / 2)
        leg_color = rgba(random_color(rng))
        for sx in (-1, 1):
            for sy in (-1, 1):
                leg = top.translation() + [sx * (depth / 2 - 0.04), sy * (width / 2 - 0.04), -self.table_height / 2]
                plant.RegisterVisualGeometry(
                    world, RigidTransform(leg), Box(0.05, 0.05, self.table_height - 0.04), f"leg{sx}{sy}", leg_color
                )
        plant.RegisterVisualGeometry(
            world, RigidTransform([0, 0, -0.05]), Box(10, 10, 0.1), "floor", rgba(random_color(rng))
        )
        wall_x = self.table_x + rng.uniform(0.8, 2.5)
        plant.RegisterVisualGeometry(
            world, RigidTransform([wall_x, 0, 1.5]), Box(0.1, 8, 3), "front_wall", rgba(random_color(rng))
        )
        for side in (-1, 1):
            plant.RegisterVisualGeometry(
                world,
                RigidTransform([1.0, side * rng.uniform(1.2, 2.5), 1.5]),
                Box(6, 0.1, 3),
                f"side_wall{side}",
                rgba(random_color(rng)),
            )

    def _add_clutter_body(self, model_instance, index):
        rng, plant = self.rng, self.plant
        body = plant.AddRigidBody(
            f"clutter_{index}", model_instance, SpatialInertia.SolidBoxWithMass(0.1, 0.1, 0.1, 0.1)
        )
        kind = ClutterShape(rng.integers(len(ClutterShape) if self.crowded else ClutterShape.BOWL))
        size = rng.uniform(0.03, 0.12, size=3)
        pose = RigidTransform([0, 0, size[2] / 2])
        if kind == ClutterShape.BOX:
            shape = Box(*size)
        elif kind == ClutterShape.CYLINDER:
            shape = Cylinder(size[0] / 2, size[2])
        elif kind == ClutterShape.SPHERE:
            shape, pose = Sphere(size[0] / 2), RigidTransform([0, 0, size[0] / 2])
        else:  # a bowl, 10-18 cm across
            shape, pose = Mesh(str(bowl_file(round(size[0] + 0.07, 2), round(size[2] / 2 + 0.03, 2)))), RigidTransform()
        plant.RegisterVisualGeometry(body, pose, shape, "visual", rgba(random_color(rng, rng.uniform() < 0.5)))
        return body

    def _random_lights(self) -> list[LightParameter]:
        rng = self.rng
        lights = []
        for _ in range(rng.integers(1, 4)):
            direction = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), -rng.uniform(0.3, 1.0)])
            tint = 1.0 - rng.uniform(0.0, 0.25, size=3)
            lights.append(
                LightParameter(
                    type="directional",
                    color=Rgba(*tint, 1.0),
                    direction=direction / np.linalg.norm(direction),
                    frame="world",
                    intensity=rng.uniform(0.4, 1.1),
                )
            )
        # A headlight keeps the objects' camera-facing sides from going black.
        lights.append(LightParameter(type="directional", frame="camera", intensity=rng.uniform(0.2, 0.6)))
        return lights

    def _label_classes(self) -> dict[int, int]:
        """Render label (the plant's body index) -> class id."""
        return {int(body.index()): self.classes.index(category) for category, _, body in self.objects}

    def _place_on_table(self, body, xy, yaw):
        X = RigidTransform(RotationMatrix.MakeZRotation(yaw), [xy[0], xy[1], self.table_height])
        self.plant.SetFreeBodyPose(self.plant_context, body, X)
        return X

    def render(
        self,
        max_objects: int = 2,
        object_region=((0.55, 0.95), (-0.3, 0.3)),
        count: int | None = None,
        placement: tuple[str, str, float, np.ndarray] | None = None,
    ) -> Frame:
        """Re-places everything at random and renders one frame from a random camera.

        Args:
            max_objects: at most this many objects (none in 10 % of the frames); CROWDED_OBJECTS when crowded.
            object_region: ((x_min, x_max), (y_min, y_max)) of the objects' origins in W, m.
            count: exactly this many objects instead.
            placement: (category, instance, yaw, xy): exactly this object at this pose on the table.
        """
        rng, plant = self.rng, self.plant
        for body in [b for *_, b in self.objects] + self.clutter:
            plant.SetFreeBodyPose(self.plant_context, body, PARKED)
        if self.crowded:
            max_objects = CROWDED_OBJECTS
        if count is None:
            count = rng.choice(max_objects + 1, p=[0.1] + [0.9 / max_objects] * max_objects)
        placed, occupied, placed_bodies = [], [], []
        if placement is not None:
            category, name, yaw, xy = placement
            (body,) = [b for c, n, b in self.objects if (c, n) == (category, name)]
            placed.append((category, name, self._place_on_table(body, xy, yaw)))
            placed_bodies.append(body)
            occupied.append(np.asarray(xy))
            count = 1
        for index in rng.permutation(len(self.objects)):
            if len(placed) == count:
                break
            xy = np.array([rng.uniform(*object_region[0]), rng.uniform(*object_region[1])])
            if any(np.linalg.norm(xy - other) < (0.22 if self.crowded else 0.35) for other in occupied):
                continue
            category, name, body = self.objects[index]
            placed.append((category, name, self._place_on_table(body, xy, rng.uniform(-np.pi, np.pi))))
            placed_bodies.append(body)
            occupied.append(xy)
        centre, half = self.table_extent
        objects = list(occupied)
        for body in self.clutter:
            if self.crowded and objects and rng.uniform() < 0.5:  # next to an object
                angle = rng.uniform(-np.pi, np.pi)
                beside = rng.uniform(0.07, 0.2) * np.array([np.cos(angle), np.sin(angle)])
                xy = objects[rng.integers(len(objects))] + beside
                self._place_on_table(body, xy, rng.uniform(-np.pi, np.pi))
                continue
            xy = centre + rng.uniform(-0.9, 0.9, size=2) * half
            if any(np.linalg.norm(xy - other) < 0.2 for other in occupied):
                continue
            self._place_on_table(body, xy, rng.uniform(-np.pi, np.pi))
            occupied.append(xy)
        self._random_arms()
        sensor, X_WC = self.sensors[rng.integers(len(self.sensors))]
        sensor_context = sensor.GetMyContextFromRoot(self.context)
        rgb = np.array(sensor.color_image_output_port().Eval(sensor_context).data)[:, :, :3]
        label_image = np.array(sensor.label_image_output_port().Eval(sensor_context).data)[:, :, 0]
        depth = np.array(sensor.depth_image_32F_output_port().Eval(sensor_context).data)[:, :, 0]
        labels = np.zeros(label_image.shape, np.uint8)
        for label, class_id in self.class_of_label.items():
            labels[label_image == label] = class_id
        masks = [label_image == int(body.index()) for body in placed_bodies]
        return Frame(rgb, labels, depth, X_WC, placed, masks)

    def _random_arms(self):
        """Arms near the ready pose (the hands in view, as during a pick)."""
        joints = [self.plant.GetJointByName(n, self.robot) for n in joint_names(1) + joint_names(2)]
        for joint, ready in zip(joints, self.ready_pose, strict=True):
            q = ready + self.rng.uniform(-0.2, 0.2)
            joint.set_angle(
                self.plant_context, np.clip(q, joint.position_lower_limits()[0], joint.position_upper_limits()[0])
            )
