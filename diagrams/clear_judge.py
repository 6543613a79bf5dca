"""Judges the clear task on the simulator's ground truth: where every object on the table ended.

A familiar object (the scenario's object and every clutter object that is a category's instance) is cleared when it
ends resting in the drop zone (its true footprint's centre inside the zone, x and y), upright (within
CLEAR_TILT_RAD), let go, and apart from every other familiar object (their true footprints, the convex outlines of
their meshes seen from above, do not meet: a conservative test, a handle's outline is wider than the handle). A
distractor (a box, cylinder or bowl) may move at most DISTRACTOR_LIMIT_M over the whole run. The clear succeeds when
every familiar object is cleared and no distractor moved more.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant

from diagrams.generation.clutter_scenes import instance_outline
from diagrams.pick_simulation import SETTLED_S, LiftJudge, PickOutcome, hands_touching
from diagrams.scenario import ObjectConfig, Scenario
from diagrams.station import CLUTTER_INSTANCE, OBJECT_INSTANCE
from systems.planning.drop_zone import DropZone, footprint_at
from systems.planning.outlines import outlines_apart

CLEAR_TILT_RAD = np.radians(5.0)
DISTRACTOR_LIMIT_M = 0.02


@dataclass
class _Familiar:
    """A familiar object on the plant: its name, category, body and true footprint in its frame (M x 2, m)."""

    name: str
    category: str
    body: object
    outline_O: np.ndarray
    start_W: RigidTransform | None = None


class ClearJudge(LiftJudge):
    """The clear task's judge (module docstring); its figures go to the outcome's `clear`."""

    def __init__(self, plant: MultibodyPlant, context, scenario: Scenario, zone: DropZone, mode_of=None):
        """mode_of(context): the pick's mode, recorded where a distractor first moved too far (None: not recorded)."""
        super().__init__(plant, context)
        self.zone, self.context, self.mode_of = zone, context, mode_of
        self.first_moved = {}  # distractor index -> (t s, the pick's mode) when it first moved too far
        self.familiar = [_familiar(plant, name, config) for name, config in familiar_objects(scenario)]
        self.distractors = [index for index, other in enumerate(scenario.clutter) if not other.instance]

    def sample(self, t: float) -> float:
        z = super().sample(t)
        for familiar in self.familiar:
            if familiar.start_W is None and t >= SETTLED_S:
                familiar.start_W = familiar.body.EvalPoseInWorld(self.plant_context)
        for index in self.distractors:
            if index not in self.first_moved and self.others_moved[index] > DISTRACTOR_LIMIT_M:
                mode = str(self.mode_of(self.context)) if self.mode_of is not None else ""
                self.first_moved[index] = (t, mode)
        return z

    def outcome(self) -> PickOutcome:
        outcome = super().outcome()
        ends = [f.body.EvalPoseInWorld(self.plant_context) for f in self.familiar]
        footprints = [footprint_at(f.outline_O, X) for f, X in zip(self.familiar, ends, strict=True)]
        records = []
        for k, (familiar, X_WO, footprint) in enumerate(zip(self.familiar, ends, footprints, strict=True)):
            tilt = float(np.arccos(np.clip(X_WO.rotation().matrix()[2, 2], -1.0, 1.0)))  # (from the vertical)
            in_zone = bool(self.zone.contains(footprint.mean(axis=0)))
            apart = bool(all(outlines_apart(footprint, other, 0.0) for j, other in enumerate(footprints) if j != k))
            held = bool(hands_touching(self.plant, self.plant_context, familiar.body))
            start = familiar.start_W.translation() if familiar.start_W is not None else np.full(3, np.nan)
            started = footprint if familiar.start_W is None else footprint_at(familiar.outline_O, familiar.start_W)
            records.append({
                "name": familiar.name, "category": familiar.category,
                "start_xy_W": [float(v) for v in start[:2]], "end_xy_W": [float(v) for v in X_WO.translation()[:2]],
                "in_zone": in_zone, "tilt_rad": tilt, "apart": apart, "let_go": not held,
                "cleared": bool(in_zone and tilt <= CLEAR_TILT_RAD and apart and not held),
                "start_footprint_W": np.round(started, 4).tolist(),
                "end_footprint_W": np.round(footprint, 4).tolist(),
            })  # fmt: skip
        moved = max((outcome.others_moved_m[i] for i in self.distractors), default=0.0)
        cleared = sum(r["cleared"] for r in records)
        outcome.clear = {
            "objects": records, "familiar_objects": len(records), "objects_cleared": cleared,
            "objects_cleared_share": cleared / len(records) if records else 1.0, "others_moved_m_max": float(moved),
            "zone": {"centre_W": list(map(float, self.zone.centre_W)), "size": list(map(float, self.zone.size))},
            "others_first_moved": [{"clutter_index": i, "t_s": t, "mode": mode}
                                   for i, (t, mode) in sorted(self.first_moved.items())],
        }  # fmt: skip
        outcome.success = cleared == len(records) and moved <= DISTRACTOR_LIMIT_M
        problems = [f"{r['name']} ({r['category']}) not cleared" for r in records if not r["cleared"]]
        if moved > DISTRACTOR_LIMIT_M:
            problems.append(f"a distractor moved {100 * moved:.1f} cm")
        outcome.message = f"cleared {cleared} of {len(records)} familiar objects" + (
            f": {'; '.join(problems)}" if problems else ""
        )
        return outcome


def familiar_objects(scenario: Scenario) -> list[tuple[str, ObjectConfig]]:
    """The familiar objects on a table to clear, as (model instance name, config): the scenario's object, where
    present, and every clutter object that is a category's instance."""
    familiar = [(OBJECT_INSTANCE, scenario.object)] if scenario.object.present else []
    for index, other in enumerate(scenario.clutter):
        if other.instance:
            config = ObjectConfig(category=other.kind, instance=other.instance)
            familiar.append((CLUTTER_INSTANCE.format(index), config))
    return familiar


def _familiar(plant: MultibodyPlant, model_name: str, config: ObjectConfig) -> _Familiar:
    body = plant.get_body(plant.GetBodyIndices(plant.GetModelInstanceByName(model_name))[0])
    if not config.instance:
        raise ValueError("the clear task is judged on generated instances: a user's mesh has no known footprint")
    outline_O, _ = instance_outline(config.category, config.instance, (0.0, 0.0), 0.0)
    return _Familiar(model_name, config.category, body, outline_O)
