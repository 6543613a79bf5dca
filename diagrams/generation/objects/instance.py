"""An object instance: its parts, mass properties, ground-truth grasp frames, and files.

Frames:
  O: object frame. Origin at the centre of the face the object rests on, z up,
     x along the category's functional axis (can: spout; drill: chuck).
  G: a hand's grasp frame. z is the approach direction (out of the palm), x runs
     along the grasped handle, y is the axis the fingers close along. The hands
     are symmetric, so G rotated by pi about its z axis is an equivalent grasp.
"""

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh
from pydrake.common.schema import Transform
from pydrake.common.yaml import yaml_dump_typed
from pydrake.math import RigidTransform, RotationMatrix

from diagrams.generation.objects import geometry
from diagrams.generation.objects.tool_frames import tool_of
from systems.perception.parts import PartRole
from systems.shape_space.tool_frame import ToolFrame

# How far the pre-grasp pose backs off from the grasp along -z_G, in metres.
PREGRASP_DISTANCE = 0.10


@dataclass
class Part:
    """One watertight piece of an object, with its convex collision pieces."""

    name: str
    mesh: trimesh.Trimesh
    collision: list[trimesh.Trimesh]
    # Relative density: lets a drill's battery be heavier than its housing.
    density: float = 1.0
    # What the part is for: which hand holds it, the tool, or the body.
    role: PartRole = PartRole.BODY


@dataclass
class Handle:
    """A hand's handle: its parts, and where on it and along which axis the hand holds it (in O)."""

    parts: list[Part]
    # The grasp point, m.
    point: np.ndarray
    # The handle's axis at the point (any length).
    axis: np.ndarray


# Spacing of a handle's centre line (m): even, so that a tube's rings and collision pieces follow its bends.
HANDLE_PATH_SPACING = 0.004


def tube_part(name: str, path: np.ndarray, radius: float, role: PartRole) -> Part:
    """A handle: a tube of `radius` (m) along `path` (n x 3, m, in O), resampled evenly, with short convex
    collision pieces."""
    path = geometry.resampled(path, HANDLE_PATH_SPACING)
    return Part(name, geometry.tube(path, radius), geometry.short_tube_pieces(path, radius), role=role)


@dataclass
class HandGrasp:
    """Pre-grasp and grasp poses of one hand's grasp frame G in the object frame O."""

    # X_OP: the grasp frame backed off along -z_G by PREGRASP_DISTANCE.
    pregrasp: Transform = field(default_factory=Transform)
    # X_OG: where the hand's grasp frame must be when the fingers close.
    grasp: Transform = field(default_factory=Transform)


@dataclass
class ToolInfo:
    """A tool frame as info.yaml holds it (systems/shape_space/tool_frame.py); empty lists: none."""

    # m, in O: the spout's tip (where the water leaves), the tip of a drill's bit.
    tip: list[float] = field(default_factory=list)
    # Unit, in O: the outflow direction, the bit's axis out of the chuck.
    axis: list[float] = field(default_factory=list)


@dataclass
class ObjectInfo:
    """What the generator knows about an instance; stored as info.yaml beside its SDF."""

    # Category name, e.g. "watering_can" or "drill".
    category: str = ""
    # Instance name within the category, e.g. "test_0".
    name: str = ""
    # Total mass in kg.
    mass: float = 0.0
    # Centre of mass in O, metres.
    com: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    # Shape parameters the instance was generated from (metres, radians).
    parameters: dict[str, float] = field(default_factory=dict)
    # Ground-truth grasps keyed by hand: "left" and "right".
    grasps: dict[str, HandGrasp] = field(default_factory=dict)
    # The ground-truth tool frame (empty where the category has none).
    tool: ToolInfo = field(default_factory=ToolInfo)

    def control_poses(self) -> dict[str, RigidTransform]:
        """X_OG by control pose name, "<side>_pregrasp" and "<side>_grasp" (as in a shape space)."""
        return {
            f"{side}_{kind}": getattr(grasp, kind).GetDeterministicValue()
            for side, grasp in self.grasps.items()
            for kind in ("pregrasp", "grasp")
        }

    def tool_frame(self) -> ToolFrame | None:
        """The tool frame in O, None where the info has none."""
        return ToolFrame(self.tool.tip, self.tool.axis) if self.tool.tip else None


# A handle grasp's approach leans at least this far from the handle's axis (rad): closer to parallel, no hand comes
# from that side, and handle_grasp says so.
MIN_APPROACH_TO_AXIS = np.radians(15.0)


def make_grasp(point, approach, handle_axis) -> HandGrasp:
    """Builds a HandGrasp from the grasp point, approach direction and handle axis (all in O): z_G the approach as
    given, x_G the handle axis made perpendicular to it."""
    z = np.asarray(approach, dtype=float)
    z /= np.linalg.norm(z)
    x = np.asarray(handle_axis, dtype=float)
    x = x - z * np.dot(x, z)
    x /= np.linalg.norm(x)
    return _hand_grasp(point, x, z)


def handle_grasp(point, handle_axis, approach) -> HandGrasp:
    """A grasp on a handle whatever its direction (all in O): x_G along the handle's axis at `point`, z_G the
    category's approach direction for the hand made perpendicular to x_G (Gram-Schmidt), the fingers closing
    across the handle along y_G.

    Raises:
        ValueError: the approach runs within MIN_APPROACH_TO_AXIS of the handle's axis (its perpendicular part
            is then mostly noise: a generator's ranges keep its handles clear of that).
    """
    x = np.asarray(handle_axis, dtype=float)
    x /= np.linalg.norm(x)
    z = np.asarray(approach, dtype=float)
    z /= np.linalg.norm(z)
    z = z - x * np.dot(z, x)
    if np.linalg.norm(z) < np.sin(MIN_APPROACH_TO_AXIS):
        raise ValueError(f"the approach {approach} runs along the handle's axis {handle_axis}: no grasp from there")
    z /= np.linalg.norm(z)
    return _hand_grasp(point, x, z)


def _hand_grasp(point, x: np.ndarray, z: np.ndarray) -> HandGrasp:
    """The grasp at `point` with axes x_G, z_G (unit, perpendicular), and its pre-grasp backed off along -z_G."""
    y = np.cross(z, x)
    R_OG = RotationMatrix(np.column_stack([x, y, z]))
    X_OG = RigidTransform(R_OG, np.asarray(point, dtype=float))
    X_OP = X_OG @ RigidTransform([0.0, 0.0, -PREGRASP_DISTANCE])
    return HandGrasp(pregrasp=Transform(X_OP), grasp=Transform(X_OG))


@dataclass
class ObjectInstance:
    """A generated instance: parts, target mass and grasps."""

    category: str
    name: str
    parameters: dict[str, float]
    parts: list[Part]
    mass: float
    grasps: dict[str, HandGrasp]

    def visual_mesh(self) -> trimesh.Trimesh:
        """The watertight union of all parts, in O."""
        return trimesh.boolean.union([p.mesh for p in self.parts], engine="manifold")

    def mass_properties(self) -> tuple[np.ndarray, np.ndarray]:
        """Centre of mass (3,) and rotational inertia about it (3, 3), in O, SI units."""
        masses = np.array([p.mesh.volume * p.density for p in self.parts])
        scale = self.mass / masses.sum()
        com = sum(m * p.mesh.center_mass for m, p in zip(masses, self.parts, strict=True))
        com = com / masses.sum()
        inertia = np.zeros((3, 3))
        for part in self.parts:
            # trimesh's moment_inertia is about the part's own centre of mass for unit density.
            part_mass = part.mesh.volume * part.density * scale
            I_part = part.mesh.moment_inertia * part.density * scale
            d = part.mesh.center_mass - com
            inertia += I_part + part_mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
        return com, inertia

    def info(self) -> ObjectInfo:
        com, _ = self.mass_properties()
        return ObjectInfo(
            category=self.category,
            name=self.name,
            mass=float(self.mass),
            com=[float(c) for c in com],
            parameters={k: float(v) for k, v in self.parameters.items()},
            grasps=self.grasps,
            tool=ToolInfo(**tool.entries()) if (tool := self.tool_frame()) else ToolInfo(),
        )

    def tool_frame(self) -> ToolFrame | None:
        """The true tool frame in O (tool_frames.tool_of: from the tool parts), None where the category has none."""
        return tool_of(self.category, self.parts)

    def write(self, directory: Path) -> Path:
        """Writes visual.obj, collision_*.obj, model.sdf and info.yaml; returns the SDF path."""
        directory.mkdir(parents=True, exist_ok=True)
        for stale in directory.glob("collision_*.obj"):
            stale.unlink()
        export_obj(self.visual_mesh(), directory / "visual.obj")
        pieces = [piece for part in self.parts for piece in part.collision]
        for i, piece in enumerate(pieces):
            export_obj(piece, directory / f"collision_{i:02d}.obj")
        com, inertia = self.mass_properties()
        sdf = object_sdf(
            model_name=f"{self.category}_{self.name}",
            visual_uri="visual.obj",
            collision_uris=[f"collision_{i:02d}.obj" for i in range(len(pieces))],
            mass=self.mass,
            com=com,
            inertia=inertia,
            color=COLORS.get(self.category, (0.6, 0.6, 0.6)),
        )
        path = directory / "model.sdf"
        path.write_text(sdf)
        (directory / "info.yaml").write_text(yaml_dump_typed(self.info()))
        return path


COLORS = {"watering_can": (0.15, 0.55, 0.25), "drill": (0.85, 0.45, 0.1)}


def export_obj(mesh: trimesh.Trimesh, path: Path) -> None:
    """Writes an OBJ with vertex normals (Drake's renderer needs them)."""
    text = trimesh.exchange.obj.export_obj(mesh, include_normals=True, include_texture=False)
    path.write_text(text)


def object_sdf(model_name, visual_uri, collision_uris, mass, com, inertia, color, scale=1.0) -> str:
    """SDF text for a single free rigid body with convex collision pieces.

    Args:
        model_name: SDF model name.
        visual_uri: mesh file for the visual, relative to the SDF.
        collision_uris: convex mesh files for collision, relative to the SDF.
        mass: kg. com: centre of mass in the body frame (m). inertia: 3x3 about com (kg m^2).
        color: RGB in [0, 1].
        scale: uniform mesh scale.
    """
    r, g, b = color
    collisions = "\n".join(
        f"""      <collision name="collision_{i:02d}">
        <geometry><mesh><uri>{uri}</uri><scale>{scale} {scale} {scale}</scale><drake:declare_convex/></mesh></geometry>
        <drake:proximity_properties>
          <drake:mu_dynamic>1.0</drake:mu_dynamic>
          <drake:mu_static>1.0</drake:mu_static>
        </drake:proximity_properties>
      </collision>"""
        for i, uri in enumerate(collision_uris)
    )
    J = inertia
    return f"""<?xml version="1.0"?>
<!-- Generated by scripts/generate_objects.py; do not edit by hand. -->
<sdf version="1.9" xmlns:drake="http://drake.mit.edu">
  <model name="{model_name}">
    <link name="base_link">
      <inertial>
        <pose>{com[0]:.6f} {com[1]:.6f} {com[2]:.6f} 0 0 0</pose>
        <mass>{mass:.6f}</mass>
        <inertia>
          <ixx>{J[0, 0]:.8f}</ixx><ixy>{J[0, 1]:.8f}</ixy><ixz>{J[0, 2]:.8f}</ixz>
          <iyy>{J[1, 1]:.8f}</iyy><iyz>{J[1, 2]:.8f}</iyz><izz>{J[2, 2]:.8f}</izz>
        </inertia>
      </inertial>
      <visual name="visual">
        <geometry><mesh><uri>{visual_uri}</uri><scale>{scale} {scale} {scale}</scale></mesh></geometry>
        <material><diffuse>{r} {g} {b} 1</diffuse></material>
      </visual>
{collisions}
    </link>
  </model>
</sdf>
"""
