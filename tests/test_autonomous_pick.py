"""The shape registrar system alone, and the autonomous pick (no ground truth until judging) end to end."""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform

from diagrams.autonomous_pick import perceive, run_autonomous_pick
from diagrams.objects.library import resolve_object
from diagrams.scenario import replace_object
from diagrams.station import object_pose_on_table
from systems.pose_estimator import ObjectEstimate
from systems.shape_registrar import ShapeRegistrar
from systems.shape_space.space import POSE_NAMES


def test_shape_registrar_system_alone(scenario):
    registrar = ShapeRegistrar()
    context = registrar.CreateDefaultContext()
    X_WO = RigidTransform([0.73, 0.0, 0.76])
    space = registrar.registrars["drill"].space
    observed = X_WO.multiply(space.reconstruct(np.zeros(space.latent_size)).T).T[::3]
    registrar.GetInputPort("estimate").FixValue(
        context, AbstractValue.Make(ObjectEstimate(True, "drill", X_WO, observed))
    )
    grasps = registrar.GetOutputPort("grasp_poses").Eval(context)
    assert grasps.found and set(grasps.poses_W) == set(POSE_NAMES)
    refined = registrar.GetOutputPort("X_WO").Eval(context)
    assert np.linalg.norm(refined.translation() - X_WO.translation()) < 0.01
    assert len(registrar.GetOutputPort("reconstructed_cloud_W").Eval(context)) > 1000

    registrar.GetInputPort("estimate").FixValue(context, AbstractValue.Make(ObjectEstimate(False, message="empty")))
    nothing = registrar.GetOutputPort("grasp_poses").Eval(context)
    assert not nothing.found and "nothing to register" in nothing.message
    assert len(registrar.GetOutputPort("reconstructed_cloud_W").Eval(context)) == 0


def test_perception_chain_localises_an_unseen_drill(scenario):
    drill = replace_object(scenario, category="drill", instance="test_1")
    perceived = perceive(drill)
    truth = object_pose_on_table(drill, resolve_object(drill.object))
    assert perceived.category == "drill"
    assert np.linalg.norm(perceived.X_WO.translation() - truth.translation()) < 0.03


def test_autonomous_pick_of_an_unseen_drill(scenario):
    outcome, _ = run_autonomous_pick(replace_object(scenario, category="drill", instance="test_1", yaw=0.25))
    assert outcome.success, outcome.message
