"""The end of a diagram's life in a process that builds many (evaluate.py's workers, the endurance benchmark).

pydrake (1.51) ties the lifetimes of a diagram's systems, its builders and their ports together by reference cycles
(each object's `_pydrake_internal_ref_cycle_peers` set), meant for Python's garbage collector. A LeafSystem written
in Python never becomes garbage: the C++ side holds its callbacks (bound methods) out of the collector's sight, and
the cycles then keep its whole diagram alive, plant, scene graph, renderer, networks and planners included
(drake issue #22515). Measured on the clear's report tables (kinect_v2): every table left about 42 MB of heap in use
behind it, 36 MB without simulating; after `release`, 1.5 MB (the emptied leaves' C++ shells).
"""

from pydrake.systems.framework import Diagram, System

PEERS = "_pydrake_internal_ref_cycle_peers"  # pydrake's attribute holding an object's cycle peers


def release(diagram: Diagram) -> None:
    """Unlinks the diagram's systems, their ports and the builders from one another, and empties the systems written
    in Python (their state: networks, planners, images), so that all of it is freed once the caller drops the diagram
    and whatever else it holds of it (simulator, contexts, systems).

    Call it last: afterwards neither the diagram nor anything taken from it may be used (a system may already be
    gone, and touching it crashes the process)."""
    for system in _systems(diagram):
        ports = [system.get_input_port(i) for i in range(system.num_input_ports())]
        ports += [system.get_output_port(i) for i in range(system.num_output_ports())]
        for linked in (system, *ports):
            linked.__dict__.pop(PEERS, None)
        if type(system).__module__.partition(".")[0] != "pydrake":
            system.__dict__.clear()


def _systems(diagram: Diagram) -> list[System]:
    """The diagram and every system inside it, nested diagrams' included, outermost first."""
    found = [diagram]
    for system in diagram.GetSystems():
        found += _systems(system) if isinstance(system, Diagram) else [system]
    return found
