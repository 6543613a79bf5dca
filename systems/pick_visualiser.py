"""Draws what the pick's plans were made from in meshcat: the camera's object points, the reconstructed
shape, and each plan's grasp-frame paths."""

from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat, Rgba
from pydrake.systems.framework import LeafSystem

from systems.messages import PerceptionResult, PickStatus, PlanResult
from systems.perception.pose_estimator import to_point_cloud

SEEN = Rgba(0.1, 0.4, 1.0, 1.0)
RECONSTRUCTED = Rgba(1.0, 0.6, 0.0, 1.0)
GRASP_PATH = Rgba(0.1, 0.8, 0.2, 1.0)


class PickVisualiser(LeafSystem):
    """Publishes perception's result once it has been read, and every successful plan's grasp paths.

    .. pydrake_system::

        name: PickVisualiser
        input_ports:
        - status
        - perception
        - plan
        output_ports: []

    ``status`` (PickStatus: perception is drawn once ``perceived``), ``perception`` (PerceptionResult),
    ``plan`` (PlanResult). It changes nothing in the simulation (publish events only, at multiples of the
    supervisor's period); what it has drawn is the viewer's own bookkeeping.
    """

    def __init__(self, meshcat: Meshcat, period_s: float = 0.05):
        super().__init__()
        self.meshcat = meshcat
        self.status_port = self.DeclareAbstractInputPort("status", AbstractValue.Make(PickStatus()))
        self.perception_port = self.DeclareAbstractInputPort("perception", AbstractValue.Make(PerceptionResult()))
        self.plan_port = self.DeclareAbstractInputPort("plan", AbstractValue.Make(PlanResult()))
        self._drawn_perception, self._drawn_plans = False, set()
        self.DeclarePeriodicPublishEvent(period_s, 0.0, self._publish)
        self.DeclareForcedPublishEvent(self._publish)

    def _publish(self, context):
        if not self._drawn_perception and self.status_port.Eval(context).perceived:
            self._drawn_perception = True
            self.draw_perception(self.perception_port.Eval(context))
        plan = self.plan_port.Eval(context)
        if plan.success and plan.id not in self._drawn_plans:
            self._drawn_plans.add(plan.id)
            for side, path_W in plan.grasp_paths_W.items():
                self.meshcat.SetLine(f"perception/grasp_path_{plan.id}_{side}", path_W.T, 3.0, GRASP_PATH)

    def draw_perception(self, result: PerceptionResult):
        """The camera's object points and the reconstructed shape (the ground truth's surface) in W."""
        for path, points_W, rgba in (
            ("perception/camera_points", result.points_W, SEEN),
            ("perception/reconstruction", result.reconstruction_W, RECONSTRUCTED),
        ):
            if points_W is not None and len(points_W):
                self.meshcat.SetObject(path, to_point_cloud(points_W), point_size=0.006, rgba=rgba)
