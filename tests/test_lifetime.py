"""A released diagram is freed: its Python leaves' state and its plant (diagrams/lifetime.py)."""

import gc
import weakref

from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from diagrams.lifetime import release


class _Payload:
    """Stands for a leaf's heavy state (a network, a planner)."""


class _Leaf(LeafSystem):
    def __init__(self, plant):
        super().__init__()
        self.DeclareVectorInputPort("u", 1)
        self.DeclareVectorOutputPort("y", 1, self._calc)
        self.plant = plant
        self.payload = _Payload()

    def _calc(self, context, output):
        output.SetAtIndex(0, 2.0 * self.get_input_port().Eval(context)[0])


def _simulated_diagram():
    """A nested diagram with Python leaves and a plant, simulated for 0.1 s; returns weak references to a leaf's
    payload and to the plant, and the diagram."""
    inner = DiagramBuilder()
    leaf = inner.AddSystem(_Leaf(None))
    inner.ExportInput(leaf.get_input_port(), "u")
    inner.ExportOutput(leaf.get_output_port(), "y")
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, 0.001)
    plant.Finalize()
    nested = builder.AddSystem(inner.Build())
    outer_leaf = builder.AddSystem(_Leaf(plant))
    builder.Connect(nested.get_output_port(), outer_leaf.get_input_port())
    builder.ExportInput(nested.get_input_port(), "u")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.get_input_port().FixValue(simulator.get_mutable_context(), [1.5])
    simulator.AdvanceTo(0.1)
    output = outer_leaf.get_output_port().Eval(outer_leaf.GetMyContextFromRoot(simulator.get_context()))
    assert output[0] == 6.0
    return weakref.ref(leaf.payload), weakref.ref(outer_leaf.payload), weakref.ref(plant), diagram


def test_a_released_diagram_is_freed():
    *watched, diagram = _simulated_diagram()
    release(diagram)
    del diagram
    gc.collect()
    assert [ref() is None for ref in watched] == [True, True, True]


def test_without_release_pydrake_keeps_it():
    # The reason release exists (drake issue #22515). Should a pydrake release free such diagrams by itself, this
    # fails: then release is no longer needed.
    *watched, diagram = _simulated_diagram()
    del diagram
    gc.collect()
    assert all(ref() is not None for ref in watched)
