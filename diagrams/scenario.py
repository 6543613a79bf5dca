"""The Scenario: everything a run needs, loaded from YAML with Drake's typed loader.

Files live beside this module (`default.yaml`, ...). A `--scenario_text` overlay
on the command line is merged on top of the file, field by field.
"""

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed
from pydrake.lcm import DrakeLcmParams
from pydrake.multibody.plant import MultibodyPlantConfig
from pydrake.systems.analysis import SimulatorConfig
from pydrake.systems.sensors import CameraConfig
from pydrake.visualization import VisualizationConfig

from diagrams.generation.centauro_description import robot_joint_names
from systems.perception.rgbd_noise import noise_parameters
from systems.shape_space.units import MESH_UNITS, MESH_UP_AXES

SCENARIO_DIR = Path(__file__).resolve().parent
DEFAULT_SCENARIO = SCENARIO_DIR / "default.yaml"


@dataclass
class ObjectConfig:
    """Which object lies on the table, and where."""

    # False: an empty table (what a pick does when it sees nothing).
    present: bool = True
    # Category: "watering_can", "drill", or one taught by scripts/add_category.py.
    category: str = "watering_can"
    # A generated instance: train_<i>, test_<i> (the fixed seeded ones), extra_<seed> or wide_<seed>.
    instance: str = "test_0"
    # A user's own model instead of a generated instance: .sdf, .urdf, or a mesh: .obj, .ply, .stl, .glb
    # (then `mass`, `scale`, `units` and `up` apply). Relative paths are relative to the working
    # directory. Empty: use `instance`.
    file: str = ""
    # Mass of an .obj model, kg.
    mass: float = 1.0
    # Uniform scale of a mesh model, applied before its units are read.
    scale: float = 1.0
    # A mesh model's units: "auto" (read from its size), "m", "cm", "mm" or "in".
    units: str = "auto"
    # A mesh model's up axis: "auto" (the face it stands on), "z" or "y" (then turned z up, x kept).
    up: str = "auto"
    # Object frame origin in the table_top frame, metres.
    xy: list[float] = field(default_factory=lambda: [-0.12, 0.0])
    # Rotation about the world z axis relative to the category's presentation
    # pose (can: spout to the robot's left; drill: chuck away), rad. The paper
    # evaluated -0.25, 0 and +0.25.
    yaw: float = 0.0


@dataclass
class ClutterObjectConfig:
    """Another object on the table, not the one to pick (a cluttered table). It exists in the simulation only:
    the pick knows it as the camera sees it (diagrams/generation/clutter_scenes.py draws whole tables)."""

    # "box", "cylinder", "bowl", "pot" (a plant pot), or a category ("watering_can", "drill"): then the generated
    # `instance`.
    kind: str = "box"
    # For a category: a generated instance (train_<i>, test_<i>, extra_<seed>, wide_<seed>).
    instance: str = ""
    # A box's extent along x, y, z; a cylinder's, bowl's or pot's diameter, (unused), height; m. Not for a category.
    size: list[float] = field(default_factory=lambda: [0.08, 0.08, 0.1])
    # Its colour, RGB in [0, 1]; not for a category (its model's own).
    color: list[float] = field(default_factory=lambda: [0.6, 0.6, 0.6])
    # Its origin (the centre of its base) in the table_top frame, m.
    xy: list[float] = field(default_factory=lambda: [-0.12, 0.25])
    # Rotation about the world z axis, rad (for a category, from its presentation pose).
    yaw: float = 0.0
    # Mass of a box, cylinder, bowl or pot, kg.
    mass: float = 0.3


@dataclass
class ArmControllerConfig:
    """Joint PD gains of the simulated arms (the plant's own PD actuators)."""

    # Proportional gain per joint 1..7, N m/rad.
    kp: list[float] = field(default_factory=lambda: [1500, 1500, 1000, 1000, 400, 400, 150])
    # Derivative gain per joint 1..7, N m s/rad.
    kd: list[float] = field(default_factory=lambda: [80, 80, 50, 50, 15, 15, 5])


@dataclass
class RobotConfig:
    """Which of the robot's joints are planned."""

    # "free": the torso yaw is planned with the arms (15 joints: the left arm, the right arm, the torso);
    # "locked": the torso stands straight and only the arms move (14 joints, the model of the first rounds).
    torso: str = "free"
    # PD gains of the torso yaw joint (N m/rad, N m s/rad): it carries the whole upper body.
    torso_kp: float = 3000.0
    torso_kd: float = 300.0


@dataclass
class HandControllerConfig:
    """PD gains of each finger's prismatic joint; the joint's effort limit caps the squeeze."""

    # N/m.
    kp: float = 4000.0
    # N s/m.
    kd: float = 40.0


@dataclass
class HardwareConfig:
    """The LCM backend (diagrams/hardware_station.py, scripts/robot_driver.py): channels and safety."""

    # Arm joint commands (lcmt_iiwa_command, 14 joints: left arm then right) and status (lcmt_iiwa_status).
    arm_command_channel: str = "CENTAURO_COMMAND"
    arm_status_channel: str = "CENTAURO_STATUS"
    # Hand opening commands and status (lcmt_schunk_wsg_command / _status, mm).
    left_hand_command_channel: str = "LEFT_HAND_COMMAND"
    left_hand_status_channel: str = "LEFT_HAND_STATUS"
    right_hand_command_channel: str = "RIGHT_HAND_COMMAND"
    right_hand_status_channel: str = "RIGHT_HAND_STATUS"
    # The chest camera's colour and depth images (lcmt_image_array, zlib-compressed).
    camera_channel: str = "CAMERA0_IMAGES"
    # Period of commands and status messages, s.
    control_period_s: float = 0.005
    # Period of camera messages from the driver, s.
    camera_period_s: float = 0.1
    # How long to wait for the robot's first status (and images) before giving up, s.
    status_timeout_s: float = 10.0
    # A status older than this trips the watchdog: the arms hold where they were, and go on once it is back, s.
    watchdog_s: float = 0.25
    # A status away longer than this (a move paused as long) stops the pick, the arms holding for good, s.
    status_lost_s: float = 5.0


@dataclass
class PlaceConfig:
    """Where the place task (task: place) sets the object down, upright."""

    # The object frame's target origin in the table_top frame, like object.xy, m.
    xy: list[float] = field(default_factory=lambda: [-0.12, -0.15])
    # Target rotation about the world z axis relative to the category's presentation pose, like object.yaw, rad.
    yaw: float = 0.0
    # Look at the held object (the object tracker) before the carry and before the set-down; false: place from
    # the first look alone, as if the object did not move in the hands.
    looks: bool = True


@dataclass
class ClearConfig:
    """The clear task's drop zone (task: clear): every familiar object on the table is taken there, one after
    another, and set down upright where it touches nothing already there (systems/planning/drop_zone.py)."""

    # The zone's centre in the table_top frame, m: at the table's right side, where the arms set objects down
    # (docs/clear.md).
    zone_xy: list[float] = field(default_factory=lambda: [-0.14, -0.38])
    # Its extent along x and y, m.
    zone_size: list[float] = field(default_factory=lambda: [0.48, 0.40])
    # The most objects the robot takes on (cleared or given up), however many it sees.
    max_objects: int = 6
    # Where the arms go between objects, j_arm1_1..7 then j_arm2_1..7, rad ([]: back to the start). The right arm
    # stands raised, its hand over 32 cm above the zone: at the start it hangs 15 cm above the zone's near rows, the
    # part every object is carried to, and what stands there would be in its way home (docs/clear.md).
    home_arm_positions: list[float] = field(
        default_factory=lambda: [0.9, 0.2, 0.5, -2.2, 0.0, 0.5, 0.0] + [0.5, -0.2, -0.5, -2.4, 0.0, 0.5, 0.0]
    )


@dataclass
class AimConfig:
    """The aim task's board (task: aim): a vertical board standing on the table, facing the robot, with a target
    disc of a colour of its own (systems/perception/board_target.py's TARGET_RGB) marked on its face."""

    # The centre of the bottom edge of its face (the side towards the robot) in the table_top frame, m. The arms
    # reach a board 20 cm in from the table's far edge, not one at an edge (docs/use.md).
    board_xyz: list[float] = field(default_factory=lambda: [0.2, 0.0, 0.0])
    # The target's centre on the face: along the board from its centre (y in W) and above the table, m; []: drawn
    # from random_seed within AIM_TARGET_RANGE (where the arms reach it: docs/use.md).
    target_yz: list[float] = field(default_factory=list)


@dataclass
class PourConfig:
    """The pour task's container (task: pour): a bowl or plant pot standing on the table (it may be moved: a free
    body), into which the can is poured (diagrams/pour_container.py draws what is not given)."""

    # Its base's centre in the table_top frame, m; []: drawn from random_seed beside the can, to its left.
    target_xy: list[float] = field(default_factory=list)
    # "bowl" or "pot"; "": drawn from random_seed.
    target_category: str = ""
    # Its rim's outer diameter and its height, m; []: drawn from random_seed within the category's sizes.
    size: list[float] = field(default_factory=list)
    # The pour: the can's outflow this far below the horizontal, deg. The arms holding a can by its two handles
    # reach 15 deg down in most placements, 20 in two thirds, 40 in none (docs/use.md).
    tilt_deg: float = 15.0


@dataclass
class BoxObstacleConfig:
    """A box fixed on the table (e.g. between the object and the place target), known to the planner as the
    table is. It must not touch the object where it rests or where it is placed: see the layouts
    place_over_box_<category>.yaml."""

    present: bool = False
    # Centre of its base in the table_top frame, m.
    xy: list[float] = field(default_factory=lambda: [-0.12, -0.075])
    # Size along x, y, z, m.
    size: list[float] = field(default_factory=lambda: [0.16, 0.03, 0.08])


@dataclass
class PlanningConfig:
    """How the pick's planner stage runs."""

    # In simulation, context seconds from a plan request to its trajectory (the robot holds meanwhile).
    # A fixed time, never the wall time planning took: the same seed plans and moves the same on a busy
    # or an idle machine. STOMP is then limited by iterations only.
    latency_s: float = 0.3
    # On the hardware backend the plan starts as soon as it exists; STOMP gives up after this, s.
    hardware_time_limit_s: float = 2.0


@dataclass
class FaultConfig:
    """Faults injected to test the pick's checks and retries (simulation, and the spawned LCM driver's restart)."""

    # Each registered grasp pose moved by this in its own grasp frame G (x along the handle, z the approach
    # axis), m, on the first `grasp_offset_attempts` attempts: a hand that closes on nothing. In a clear, on the
    # object taken on `grasp_offset_object`-th (0: the first) alone.
    grasp_offset_G: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])
    grasp_offset_attempts: int = 1
    grasp_offset_object: int = 0
    # The object moved by this on the table (x, y in W, m) at context time nudge_at_s: pushed while the arms
    # reach for it.
    nudge_xy: list[float] = field(default_factory=lambda: [0.0, 0.0])
    nudge_at_s: float = 1.0
    # Both hands open this long into the first carry (the first attempt, the first object), s: the object drops;
    # negative: no drop.
    drop_in_carry_after_s: float = -1.0
    # The robot's status stops for status_gap_s this long into the first carry (the first attempt, the first
    # object), s; negative: no gap. The arms hold, and go on once it is back. With pick.py --spawn-driver, the
    # driver's process is frozen that long (its status and images stop).
    status_gap_in_carry_after_s: float = -1.0
    status_gap_s: float = 2.0
    # The camera's images stop for camera_gap_s from this context time, s; negative: no gap. Perception waits.
    camera_gap_at_s: float = -1.0
    camera_gap_s: float = 5.0
    # The robot driver process killed (SIGKILL) once this many objects have been taken on, and started again from
    # the world it last wrote (LCM with pick.py --spawn-driver only; 0: never). The pick waits for its status.
    driver_restart_after_objects: int = 0


@dataclass
class CameraNoiseConfig:
    """The RGB-D sensor model between the camera and everything that reads it (systems/perception/rgbd_noise.py)."""

    # "perfect" (the renderer's images as they are), "kinect_v2" or "realsense_d435".
    preset: str = "perfect"
    # The preset's parameters replaced, e.g. {dropout_share: 0.05, axial_sigma_per_m2: 0.002}.
    overrides: dict[str, float] = field(default_factory=dict)


@dataclass
class Scenario:
    """A complete simulation scenario."""

    # Seed for every random draw of a run (yaw noise, sensor noise, ...).
    random_seed: int = 0
    # The object on the table.
    object: ObjectConfig = field(default_factory=ObjectConfig)
    # What the pick does once both hands hold the object: "lift" (lift and hold it, the paper's task),
    # "place" (lift, carry it to `place`, set it down upright, open the hands, retreat) or "aim" (a drill: aim its
    # bit at the target on the `aim` board, hold, back off, set it down where it stood), "pour" (a can: pour into the
    # `pour` container, bring it upright, set it down where it stood) or "clear" (every familiar
    # object on the table, nearest first, into the `clear` drop zone).
    task: str = "lift"
    place: PlaceConfig = field(default_factory=PlaceConfig)
    aim: AimConfig = field(default_factory=AimConfig)
    pour: PourConfig = field(default_factory=PourConfig)
    clear: ClearConfig = field(default_factory=ClearConfig)
    # A box on the table, known to the planner.
    obstacle: BoxObstacleConfig = field(default_factory=BoxObstacleConfig)
    # Other objects on the table, unknown to the planner (it sees them through the camera).
    clutter: list[ClutterObjectConfig] = field(default_factory=list)
    # Misalignment experiment (paper §V-B, which used 0.2): the yaw of the estimated pose handed to
    # the shape registration is turned by an offset uniform in +-this, drawn from random_seed, rad.
    registration_yaw_noise: float = 0.0
    # Attempts at the task, the first included: a failed check (a hand closed on nothing, the object lost in
    # the lift) opens the hands, backs off and starts again from a new camera frame.
    max_attempts: int = 3
    # Before the approach, look at the object again (the object tracker) and, where it moved since it was seen,
    # reach for it where it is now.
    look_before_approach: bool = True
    # Where the shape-space fit is poor, build each hand's grasp on the handle the camera sees (the part network's
    # parts, a tube fitted to each; the fit their prior: systems/shape_space/part_grasps.py); false: a poor fit
    # is refused, as before part perception.
    part_grasps: bool = True
    # The category the user names for the object to pick (pick.py --object): perception registers the object to
    # it and reports what the segmenter's network made of it; "": the network's classes decide.
    requested_category: str = ""
    # Faults injected for tests (simulation only).
    faults: FaultConfig = field(default_factory=FaultConfig)
    # Height of the robot's pelvis frame above the floor, metres.
    pelvis_height: float = 1.0
    # Table base frame position in the world (the floor under its centre), metres.
    table_xyz: list[float] = field(default_factory=lambda: [0.85, 0.0, 0.0])
    # Initial joint positions j_arm1_1..7 then j_arm2_1..7, rad: the "ready" pose, elbows bent,
    # hands 0.22 m above the table top beside the object, the right arm the mirror of the left (a free
    # torso starts straight, at 0).
    initial_arm_positions: list[float] = field(
        default_factory=lambda: [0.9, 0.2, 0.5, -2.2, 0.0, 0.5, 0.0] + [0.9, -0.2, -0.5, -2.2, 0.0, 0.5, 0.0]
    )
    # Initial hand opening width, metres (0 closed, 0.12 fully open).
    initial_hand_width: float = 0.1
    planning: PlanningConfig = field(default_factory=PlanningConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    arm_controller: ArmControllerConfig = field(default_factory=ArmControllerConfig)
    hand_controller: HandControllerConfig = field(default_factory=HandControllerConfig)
    # Multibody plant: discrete SAP at 1 ms.
    plant_config: MultibodyPlantConfig = field(
        default_factory=lambda: MultibodyPlantConfig(time_step=0.001, discrete_contact_approximation="sap")
    )
    simulator_config: SimulatorConfig = field(
        default_factory=lambda: SimulatorConfig(target_realtime_rate=0.0, publish_every_time_step=False)
    )
    # The chest RGB-D camera; X_PB is relative to the robot's camera_mount frame.
    camera: CameraConfig = field(
        default_factory=lambda: CameraConfig(
            name="camera0",
            width=640,
            height=480,
            fps=10.0,
            center_x=None,
            center_y=None,
            focal=CameraConfig.FovDegrees(y=50.0),
            clipping_far=4.0,
            z_far=4.0,
            renderer_name="vtk",
            renderer_class="RenderEngineVtk",
            label=True,
            depth=True,
        )
    )
    # What a real sensor does to the camera's images (noise drawn from random_seed and the image's time).
    camera_noise: CameraNoiseConfig = field(default_factory=CameraNoiseConfig)
    # Meshcat drawing options.
    visualization: VisualizationConfig = field(default_factory=VisualizationConfig)
    # LCM for the hardware backend; simulations never touch the network.
    lcm: DrakeLcmParams = field(default_factory=lambda: DrakeLcmParams(lcm_url="memq://null"))
    hardware: HardwareConfig = field(default_factory=HardwareConfig)

    def __reduce__(self):  # for worker processes and Ray: Drake's config structs do not pickle, their YAML does
        return _scenario_from_yaml, (yaml_dump_typed(self),)


def _scenario_from_yaml(text: str) -> Scenario:
    return yaml_load_typed(schema=Scenario, data=text)


def load_scenario(filename: str | Path | None = None, scenario_text: str = "") -> Scenario:
    """Loads a Scenario from a YAML file, then overlays `scenario_text` (YAML) on it.

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: the YAML does not match the Scenario schema, with the reason.
    """
    path = Path(filename) if filename else DEFAULT_SCENARIO
    if not path.is_file():
        raise FileNotFoundError(f"scenario file not found: {path}")
    scenario = overlay_scenario(Scenario(), path.read_text(), str(path))
    return overlay_scenario(scenario, scenario_text, "--scenario_text")


def overlay_scenario(scenario: Scenario, text: str, source: str) -> Scenario:
    """`scenario` with the fields the YAML `text` names replaced, validated.

    Raises:
        ValueError: the YAML does not match the Scenario schema or a field is out of range, naming `source`.
    """
    if text.strip():
        try:
            scenario = yaml_load_typed(data=text, defaults=scenario)
        except Exception as error:  # Drake raises RuntimeError; yaml raises its own.
            raise ValueError(f"invalid scenario in {source}: {error}") from error
    validate(scenario)
    return scenario


def place_over_box_scenario(category: str) -> Path:
    """The place-with-a-box layout of a category: object, target and a box between them on the table (the
    carry goes over it), chosen where both arms reach every test instance at every evaluated yaw.

    Raises:
        FileNotFoundError: the category has no such layout.
    """
    path = SCENARIO_DIR / f"place_over_box_{category}.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"no place-over-a-box layout for {category} ({path})")
    return path


def validate(scenario: Scenario) -> None:
    """Checks what the schema cannot express; raises ValueError naming the field.

    Every number must be finite (a NaN yaw would otherwise abort deep inside Drake), and lie where
    the robot, table and object make sense.
    """
    _check_finite("", scenario)
    obj = scenario.object
    if len(scenario.initial_arm_positions) != 14:
        raise ValueError(f"initial_arm_positions must have 14 entries, got {len(scenario.initial_arm_positions)}")
    if len(obj.xy) != 2:
        raise ValueError(f"object.xy must have 2 entries, got {obj.xy}")
    if len(scenario.table_xyz) != 3:
        raise ValueError(f"table_xyz must have 3 entries, got {scenario.table_xyz}")
    for name in ("kp", "kd"):
        if len(getattr(scenario.arm_controller, name)) != 7:
            raise ValueError(f"arm_controller.{name} must have 7 entries (joints 1..7)")
    if not 0 <= scenario.registration_yaw_noise <= math.pi:
        raise ValueError(f"registration_yaw_noise must lie in [0, pi] rad, got {scenario.registration_yaw_noise}")
    if not abs(obj.yaw) <= 2 * math.pi:
        raise ValueError(f"object.yaw must lie in [-2 pi, 2 pi] rad, got {obj.yaw}")
    if not all(abs(v) <= MAX_TABLE_OFFSET_M for v in obj.xy):
        raise ValueError(f"object.xy must lie within {MAX_TABLE_OFFSET_M} m of the table's centre, got {obj.xy}")
    if not 0 < obj.mass <= MAX_OBJECT_MASS_KG:
        raise ValueError(f"object.mass must lie in (0, {MAX_OBJECT_MASS_KG}] kg, got {obj.mass}")
    if not 1 <= scenario.max_attempts <= MAX_ATTEMPTS:
        raise ValueError(f"max_attempts must lie in [1, {MAX_ATTEMPTS}], got {scenario.max_attempts}")
    faults = scenario.faults
    if len(faults.grasp_offset_G) != 3 or not all(abs(v) <= MAX_GRASP_OFFSET_M for v in faults.grasp_offset_G):
        raise ValueError(f"faults.grasp_offset_G must be 3 entries of at most {MAX_GRASP_OFFSET_M} m (x, y, z in G)")
    if len(faults.nudge_xy) != 2 or not all(abs(v) <= MAX_GRASP_OFFSET_M for v in faults.nudge_xy):
        raise ValueError(f"faults.nudge_xy must be 2 entries of at most {MAX_GRASP_OFFSET_M} m")
    if faults.drop_in_carry_after_s > 30:
        raise ValueError(f"faults.drop_in_carry_after_s must be at most 30 s (negative: none), got "
                         f"{faults.drop_in_carry_after_s}")  # fmt: skip
    for name in ("status_gap_s", "camera_gap_s"):
        if not 0 < getattr(faults, name) <= MAX_GAP_S:
            raise ValueError(f"faults.{name} must be in (0, {MAX_GAP_S}] s, got {getattr(faults, name)}")
    if faults.grasp_offset_attempts < 0:
        raise ValueError(f"faults.grasp_offset_attempts must be >= 0, got {faults.grasp_offset_attempts}")
    if (restart := faults.driver_restart_after_objects) < 0:
        raise ValueError(f"faults.driver_restart_after_objects must be >= 0 (0: never), got {restart}")
    if faults.grasp_offset_object < 0:
        raise ValueError(f"faults.grasp_offset_object must be >= 0 (the first: 0), got {faults.grasp_offset_object}")
    if scenario.robot.torso not in TORSO_MODES:
        raise ValueError(f"robot.torso must be one of {TORSO_MODES}, got {scenario.robot.torso!r}")
    if scenario.task not in TASKS:
        raise ValueError(f"task must be one of {TASKS}, got {scenario.task!r}")
    if len(scenario.place.xy) != 2 or not all(abs(v) <= MAX_TABLE_OFFSET_M for v in scenario.place.xy):
        raise ValueError(f"place.xy must be 2 entries within {MAX_TABLE_OFFSET_M} m of the table's centre")
    if not abs(scenario.place.yaw) <= 2 * math.pi:
        raise ValueError(f"place.yaw must lie in [-2 pi, 2 pi] rad, got {scenario.place.yaw}")
    _validate_aim(scenario)
    _validate_pour(scenario.pour)
    _validate_clear(scenario.clear)
    box = scenario.obstacle
    if len(box.xy) != 2 or len(box.size) != 3 or not all(0 < v <= 1.0 for v in box.size):
        raise ValueError(f"obstacle: xy must have 2 entries and size 3 in (0, 1] m, got {box.xy}, {box.size}")
    for index, other in enumerate(scenario.clutter):
        _validate_clutter(f"clutter[{index}]", other)
    if obj.scale <= 0:
        raise ValueError(f"object.scale must be positive, got {obj.scale}")
    if obj.units not in MESH_UNITS or obj.up not in MESH_UP_AXES:
        raise ValueError(f"object.units must be one of {MESH_UNITS} and object.up one of {MESH_UP_AXES}")
    if not 0 <= scenario.planning.latency_s <= 10:
        raise ValueError(f"planning.latency_s must lie in [0, 10] s, got {scenario.planning.latency_s}")
    try:
        noise_parameters(scenario.camera_noise.preset, scenario.camera_noise.overrides)
    except ValueError as error:
        raise ValueError(f"camera_noise: {error}") from None
    if scenario.planning.hardware_time_limit_s <= 0:
        raise ValueError(
            f"planning.hardware_time_limit_s must be positive, got {scenario.planning.hardware_time_limit_s}"
        )


def _validate_aim(scenario: Scenario) -> None:
    aim = scenario.aim
    if len(aim.board_xyz) != 3 or not all(abs(v) <= MAX_TABLE_OFFSET_M for v in aim.board_xyz):
        raise ValueError(f"aim.board_xyz must be 3 entries within {MAX_TABLE_OFFSET_M} m of the table top's centre")
    if aim.target_yz and (len(aim.target_yz) != 2 or abs(aim.target_yz[0]) > BOARD_SIZE_M[0] / 2
                          or not 0 < aim.target_yz[1] < BOARD_SIZE_M[1]):  # fmt: skip
        raise ValueError(
            f"aim.target_yz must be [] (drawn) or 2 entries on the board's face: along it within "
            f"{BOARD_SIZE_M[0] / 2} m of its centre, and (0, {BOARD_SIZE_M[1]}) m above the table; got {aim.target_yz}"
        )


def _validate_pour(pour: PourConfig) -> None:
    if pour.target_xy and (len(pour.target_xy) != 2 or not all(abs(v) <= MAX_TABLE_OFFSET_M for v in pour.target_xy)):
        raise ValueError(f"pour.target_xy must be [] (drawn) or 2 entries within {MAX_TABLE_OFFSET_M} m of the "
                         f"table top's centre, got {pour.target_xy}")  # fmt: skip
    if pour.target_category not in ("", *POUR_CONTAINERS):
        raise ValueError(f"pour.target_category must be '' (drawn) or one of {POUR_CONTAINERS}, got "
                         f"{pour.target_category!r}")  # fmt: skip
    if pour.size and (len(pour.size) != 2 or not all(0.05 <= v <= 0.5 for v in pour.size)):
        raise ValueError(f"pour.size must be [] (drawn) or [diameter, height] in [0.05, 0.5] m, got {pour.size}")
    if not 0.0 <= pour.tilt_deg <= 80.0:
        raise ValueError(f"pour.tilt_deg must lie in [0, 80] deg (the outflow below the horizontal), got "
                         f"{pour.tilt_deg}")  # fmt: skip


def _validate_clear(clear: ClearConfig) -> None:
    if len(clear.zone_xy) != 2 or not all(abs(v) <= MAX_TABLE_OFFSET_M for v in clear.zone_xy):
        raise ValueError(f"clear.zone_xy must be 2 entries within {MAX_TABLE_OFFSET_M} m of the table's centre")
    if len(clear.zone_size) != 2 or not all(0.1 <= v <= 1.2 for v in clear.zone_size):
        raise ValueError(f"clear.zone_size must be 2 entries in [0.1, 1.2] m (x, y), got {clear.zone_size}")
    if not 1 <= clear.max_objects <= 20:
        raise ValueError(f"clear.max_objects must lie in [1, 20], got {clear.max_objects}")
    if len(clear.home_arm_positions) not in (0, 14):
        raise ValueError(f"clear.home_arm_positions must have 14 entries (or none: the start), got "
                         f"{len(clear.home_arm_positions)}")  # fmt: skip


def clutter_name(other: ClutterObjectConfig) -> str:
    """A clutter object's name for reports: its shape, or its category and instance."""
    return f"{other.kind}/{other.instance}" if other.instance else other.kind


def _validate_clutter(name: str, other: ClutterObjectConfig) -> None:
    if other.kind not in CLUTTER_SHAPES and not other.instance:
        raise ValueError(f"{name}.kind must be one of {CLUTTER_SHAPES}, or a category with an instance: {other.kind!r}")
    if len(other.xy) != 2 or not all(abs(v) <= MAX_TABLE_OFFSET_M for v in other.xy):
        raise ValueError(f"{name}.xy must be 2 entries within {MAX_TABLE_OFFSET_M} m of the table's centre")
    if other.kind in CLUTTER_SHAPES and (len(other.size) != 3 or not all(0 < v <= 0.5 for v in other.size)):
        raise ValueError(f"{name}.size must be 3 entries in (0, 0.5] m, got {other.size}")
    if len(other.color) != 3 or not all(0 <= v <= 1 for v in other.color):
        raise ValueError(f"{name}.color must be 3 entries in [0, 1], got {other.color}")
    if not 0 < other.mass <= MAX_OBJECT_MASS_KG:
        raise ValueError(f"{name}.mass must lie in (0, {MAX_OBJECT_MASS_KG}] kg, got {other.mass}")


TASKS = ("lift", "place", "aim", "pour", "clear")
TABLE_HEIGHT = 0.76  # m: the table_top frame above the table's base (sdf/scene/table.sdf)
TABLE_HALF_SIZE = (0.4, 0.6)  # m: the table top's half depth (x) and half width (y) about its frame (the same file)
POUR_CONTAINERS = ("bowl", "pot")  # what the pour task pours into
# The aim task's board: width (along y), height and thickness, m.
BOARD_SIZE_M = (0.5, 0.4, 0.02)
CLUTTER_SHAPES = ("box", "cylinder", "bowl", "pot")
TORSO_MODES = ("free", "locked")
# Bounds of the scenario's physical fields.
MAX_TABLE_OFFSET_M = 1.0
MAX_ATTEMPTS = 10
MAX_GRASP_OFFSET_M = 0.2  # m: an injected grasp offset larger than this is a unit mistake
MAX_GAP_S = 60.0  # s: an injected link gap longer than this outlasts any pick
MAX_OBJECT_MASS_KG = 20.0


def _check_finite(path: str, value) -> None:
    """Raises ValueError naming the first NaN or infinite number in a (nested) scenario field."""
    if isinstance(value, bool) or value is None:
        return
    if isinstance(value, float | int):
        if not math.isfinite(value):
            raise ValueError(f"{path} must be finite, got {value}")
    elif isinstance(value, list | tuple):
        for index, item in enumerate(value):
            _check_finite(f"{path}[{index}]", item)
    elif isinstance(value, dict):
        for key, item in value.items():
            _check_finite(f"{path}.{key}", item)
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for item in dataclasses.fields(value):
            _check_finite(f"{path}.{item.name}" if path else item.name, getattr(value, item.name))


def torso_free(scenario: Scenario) -> bool:
    """Whether the torso yaw is a planned joint (else it is welded straight)."""
    return scenario.robot.torso == "free"


def planned_joints(scenario: Scenario) -> list[str]:
    """The robot's planned joints in the order of every configuration vector (14 or 15)."""
    return robot_joint_names(torso_free(scenario))


def initial_positions(scenario: Scenario) -> np.ndarray:
    """The planned joints' initial positions (rad): the arms' ready pose, and the torso straight if free."""
    return np.array(list(scenario.initial_arm_positions) + [0.0] * torso_free(scenario))


def replace_object(scenario: Scenario, **changes) -> Scenario:
    """A copy of the scenario with object fields changed."""
    return dataclasses.replace(scenario, object=dataclasses.replace(scenario.object, **changes))
