"""Gravity compensation feed-forward for the simulated arms."""

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import BasicVector, LeafSystem


class SimulationDiverged(RuntimeError):
    """The simulated plant's state is no longer finite (a contact blew up): nothing after it can be trusted."""


class GravityCompensation(LeafSystem):
    """Outputs the actuator torques that cancel gravity on one model instance.

    The plant's PD actuators add this as feed-forward, so a position-controlled arm
    does not sag. Bodies welded to the arm (the hands) are included; free bodies
    (a grasped object) are not: the PD loop takes up the payload.

    .. pydrake_system::

        name: GravityCompensation
        input_ports:
        - state
        output_ports:
        - actuation

    Args:
        plant: the station's finalized plant (used for its model only).
        model_instance: the instance whose actuators receive the torques.
    """

    def __init__(self, plant: MultibodyPlant, model_instance: ModelInstanceIndex):
        super().__init__()
        self._plant = plant
        self._plant_context = plant.CreateDefaultContext()
        self._model_instance = model_instance
        # Each arm actuator drives one revolute joint: its torque acts on that joint's dof.
        actuators = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices(model_instance)]
        self._dof_of_actuator = np.array([a.joint().velocity_start() for a in actuators])
        self.state_input = self.DeclareVectorInputPort("state", plant.num_multibody_states())
        self.actuation_output = self.DeclareVectorOutputPort("actuation", len(actuators), self._calc_actuation)

    def _calc_actuation(self, context, output: BasicVector):
        x = self.state_input.Eval(context)
        if not np.all(np.isfinite(x)):  # (Drake's own check would end the process: SystemExit)
            raise SimulationDiverged(
                f"the simulated plant's state is not finite at t = {context.get_time():.3f} s (the simulation diverged)"
            )
        self._plant.SetPositionsAndVelocities(self._plant_context, x)
        tau_g = self._plant.CalcGravityGeneralizedForces(self._plant_context)
        output.SetFromVector(-tau_g[self._dof_of_actuator])
