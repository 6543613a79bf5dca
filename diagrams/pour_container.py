"""The pour task's container on the table: a bowl or a plant pot (scenario.pour), added to the station as the last of
the other objects on the table (table_clutter), a free body the judge watches.

What the scenario leaves out is drawn from its random_seed: the kind, the size within CONTAINER_SIZES, and where it
stands: beside the can, to its left (+y_W), a gap of CONTAINER_GAP_M from the can's footprint, a little towards the
robot (CONTAINER_BACK_M). The can pours with its outflow to the robot's left (systems/planning/pour_goals.py,
POUR_HEADING_W, 60 deg left of straight ahead): there the arms reach the steepest tilts (docs/use.md).

Frames: W the world (z up); the container's base frame K: origin at the centre of its base on the table top, z up.
"""

import numpy as np

from diagrams.generation.objects.bowl import WALL_M
from diagrams.scenario import TABLE_HEIGHT, ClutterObjectConfig, Scenario
from systems.perception.container_opening import Opening

# Drawn sizes (rim's outer diameter, height), m: a cereal or salad bowl, a herb pot.
CONTAINER_SIZES = {"bowl": ((0.14, 0.20), (0.045, 0.065)), "pot": ((0.12, 0.15), (0.06, 0.08))}
CONTAINER_GAP_M = (0.03, 0.06)  # m: from the can's footprint (to its left) to the container's rim
CONTAINER_BACK_M = (0.0, 0.08)  # m: the container's centre this much nearer the robot (-x_W) than the can's origin
CONTAINER_MASS_KG = 0.4
CONTAINER_RGB = {"bowl": [0.92, 0.9, 0.84], "pot": [0.72, 0.36, 0.22]}  # porcelain, terracotta


def pour_container(scenario: Scenario) -> ClutterObjectConfig | None:
    """The pour task's container as an object on the table (None: not a pour)."""
    if scenario.task != "pour":
        return None
    pour = scenario.pour
    rng = np.random.default_rng([scenario.random_seed, 81])
    kinds = list(CONTAINER_SIZES)
    kind = pour.target_category or kinds[int(rng.integers(len(kinds)))]
    diameters, heights = CONTAINER_SIZES[kind]
    drawn = [rng.uniform(*diameters), rng.uniform(*heights)]
    diameter, height = pour.size or drawn
    gap, back = rng.uniform(*CONTAINER_GAP_M), rng.uniform(*CONTAINER_BACK_M)
    if pour.target_xy:
        xy = list(pour.target_xy)
    else:
        x, y = scenario.object.xy
        xy = [x - back, y + _left_of_object(scenario) + gap + diameter / 2]
    return ClutterObjectConfig(
        kind=kind, size=[diameter, diameter, height], color=CONTAINER_RGB[kind], xy=xy, mass=CONTAINER_MASS_KG
    )


def table_clutter(scenario: Scenario) -> list[ClutterObjectConfig]:
    """The other objects on the table: scenario.clutter, and a pour's container last."""
    container = pour_container(scenario)
    return [*scenario.clutter, *([container] if container is not None else [])]


def true_opening(scenario: Scenario) -> Opening:
    """Ground truth: the pour container's opening where it stands (its rim's inner radius, centre at the rim's
    height), in W.

    Raises:
        ValueError: the scenario is no pour.
    """
    container = pour_container(scenario)
    if container is None:
        raise ValueError(f"a {scenario.task} task has no container to pour into")
    diameter, _, height = container.size
    centre = np.array(scenario.table_xyz) + [*container.xy, TABLE_HEIGHT + height]
    return Opening(centre, diameter / 2 - WALL_M, 0)


def _left_of_object(scenario: Scenario) -> float:
    """How far the object's footprint reaches to the left (+y_W) of its origin where it stands, m."""
    from diagrams.generation.objects.library import resolve_object
    from diagrams.planning_scene import object_surface_W
    from diagrams.station import object_pose_on_table

    if not scenario.object.present:
        return 0.0
    model = resolve_object(scenario.object)
    X_WO = object_pose_on_table(scenario, model)
    points, _ = object_surface_W(model, X_WO, 2000)
    return float(points[:, 1].max() - X_WO.translation()[1])
