"""Batched kinematics and the sphere model against Drake's own kinematics and geometry."""

import numpy as np
import pytest
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import FrameIndex, JacobianWrtVariable, MultibodyForces
from pydrake.systems.framework import DiagramBuilder

from diagrams.scenario import planned_joints
from diagrams.station import AddCentauro
from systems.planning.dynamics import gravity_torques, joint_torques
from systems.planning.kinematics import EndEffectors
from systems.planning.sphere_model import SphereGroup
from systems.planning.world import centauro_kinematics


@pytest.fixture(scope="module")
def robot(scenario):
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
    _, hands = AddCentauro(plant, scene_graph, scenario)
    plant.Finalize()
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    # The planned joints: both arms and the torso yaw, which turns them both.
    kinematics, spheres = centauro_kinematics(plant, scene_graph, plant_context, planned_joints(scenario), hands)
    joints = [plant.GetJointByName(n) for n in planned_joints(scenario)]
    return plant, scene_graph, plant_context, kinematics, spheres, joints


def random_configurations(joints, count, seed=0):
    lower = np.array([j.position_lower_limits()[0] for j in joints])
    upper = np.array([j.position_upper_limits()[0] for j in joints])
    return np.random.default_rng(seed).uniform(lower, upper, size=(count, len(joints)))


def test_batched_kinematics_equals_drake(robot):
    plant, _, plant_context, kinematics, _, joints = robot
    q_batch = random_configurations(joints, 20)
    poses = kinematics.body_poses(q_batch)
    default = plant.GetPositions(plant_context).copy()
    for q, batch_poses in zip(q_batch, poses, strict=True):
        for joint, value in zip(joints, q, strict=True):
            joint.set_angle(plant_context, value)
        for link, X in zip(kinematics.links, batch_poses, strict=True):
            X_drake = plant.EvalBodyPoseInWorld(plant_context, plant.get_body(link.body_index)).GetAsMatrix4()
            np.testing.assert_allclose(X, X_drake, atol=1e-10)
    plant.SetPositions(plant_context, default)


def test_grasp_frame_jacobians_equal_drake(robot):
    """The batched poses and geometric Jacobians of both hands' grasp frames (rows angular then translational
    velocity in W, per planned joint) are Drake's, at random configurations."""
    plant, _, plant_context, kinematics, _, joints = robot
    frames = [
        frame
        for frame in map(plant.get_frame, map(FrameIndex, range(plant.num_frames())))
        if frame.name() == "grasp_frame"
    ]
    assert len(frames) == 2  # each hand's
    end_effectors = EndEffectors(kinematics, frames)
    q_batch = random_configurations(joints, 10, seed=3)
    poses, jacobians = end_effectors.jacobians(q_batch)
    columns = [joint.velocity_start() for joint in joints]
    default = plant.GetPositions(plant_context).copy()
    for b, q in enumerate(q_batch):
        for joint, value in zip(joints, q, strict=True):
            joint.set_angle(plant_context, value)
        for frame, X, J in zip(frames, poses, jacobians, strict=True):
            np.testing.assert_allclose(X[b], frame.CalcPoseInWorld(plant_context).GetAsMatrix4(), atol=1e-10)
            J_drake = plant.CalcJacobianSpatialVelocity(
                plant_context, JacobianWrtVariable.kV, frame, [0, 0, 0], plant.world_frame(), plant.world_frame()
            )
            np.testing.assert_allclose(J[b], J_drake[:, columns], atol=1e-10)
    plant.SetPositions(plant_context, default)


def test_spheres_cover_every_collision_geometry(robot):
    plant, scene_graph, plant_context, kinematics, spheres, joints = robot
    q = random_configurations(joints, 1, seed=3)[0]
    for joint, value in zip(joints, q, strict=True):
        joint.set_angle(plant_context, value)
    centres = spheres.centres_W(kinematics.body_poses(q))[0]
    inspector = scene_graph.model_inspector()
    # Sample points on each body's collision geometry's surface via its pose; each must lie in some sphere.
    for link in kinematics.links:
        body = plant.get_body(link.body_index)
        X_WB = plant.EvalBodyPoseInWorld(plant_context, body).GetAsMatrix4()
        mine = spheres.body == kinematics.position_of_body[link.body_index]
        for geometry in plant.GetCollisionGeometriesForBody(body):
            X_BG = inspector.GetPoseInFrame(geometry).GetAsMatrix4()
            for corner in _extreme_points(inspector.GetShape(geometry)):
                p = (X_WB @ X_BG @ np.append(corner, 1.0))[:3]
                inside = np.linalg.norm(centres[mine] - p, axis=1) <= spheres.radius[mine] + 1e-9
                assert inside.any(), f"{body.name()}: {corner} not covered"
    assert set(np.unique(spheres.group)) == set(SphereGroup)


def _extreme_points(shape):
    """Points on a primitive's boundary that a cover must contain (box corners, capsule tips)."""
    from pydrake.geometry import Box, Capsule, Sphere

    if isinstance(shape, Box):
        half = np.array([shape.width(), shape.depth(), shape.height()]) / 2
        return [half * (2 * np.array(signs) - 1) for signs in np.ndindex(2, 2, 2)]
    if isinstance(shape, Capsule):
        tip = shape.length() / 2 + shape.radius()
        return [np.array([0, 0, tip]), np.array([0, 0, -tip]), np.array([shape.radius(), 0, 0])]
    if isinstance(shape, Sphere):
        return [np.array([shape.radius(), 0, 0])]
    return []


def test_batched_gravity_torques_equal_drake(robot):
    plant, _, plant_context, kinematics, _, joints = robot
    q_batch = random_configurations(joints, 10, seed=5)
    torques = gravity_torques(kinematics, q_batch)
    default = plant.GetPositions(plant_context).copy()
    for q, tau in zip(q_batch, torques, strict=True):
        for joint, value in zip(joints, q, strict=True):
            joint.set_angle(plant_context, value)
        tau_drake = plant.CalcGravityGeneralizedForces(plant_context)
        np.testing.assert_allclose(tau, [tau_drake[j.velocity_start()] for j in joints], atol=1e-9)
    plant.SetPositions(plant_context, default)


def test_batched_inverse_dynamics_equal_drake(robot):
    """joint_torques against Drake's CalcInverseDynamics (gravity and joint damping as applied forces), with every
    joint but the arms' still."""
    plant, _, plant_context, kinematics, _, joints = robot
    rng = np.random.default_rng(5)
    q = random_configurations(joints, 5, seed=5)
    qd, qdd = rng.normal(size=q.shape), rng.normal(size=q.shape)
    torques = joint_torques(kinematics, kinematics.body_poses(q), qd, qdd)
    default_q, default_v = plant.GetPositions(plant_context).copy(), plant.GetVelocities(plant_context).copy()
    indices = [joint.velocity_start() for joint in joints]
    for k in range(len(q)):
        for joint, value in zip(joints, q[k], strict=True):
            joint.set_angle(plant_context, value)
        v, vd = np.zeros(plant.num_velocities()), np.zeros(plant.num_velocities())
        v[indices], vd[indices] = qd[k], qdd[k]
        plant.SetVelocities(plant_context, v)
        forces = MultibodyForces(plant)
        plant.CalcForceElementsContribution(plant_context, forces)
        expected = plant.CalcInverseDynamics(plant_context, vd, forces)[indices]
        np.testing.assert_allclose(torques[k], expected, atol=1e-9)
    plant.SetPositions(plant_context, default_q)
    plant.SetVelocities(plant_context, default_v)
