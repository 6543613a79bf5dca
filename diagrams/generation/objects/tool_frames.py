"""The true tool frame of a generated instance, from its tool parts (PartRole.TOOL) by its category's rule.

Every generated can, in every family, has a straight spout (a frustum, perhaps a rose on its end): its outflow axis is
the tool parts' principal direction, pointing away from the rest of the can, and its tip the centre of their far end
face. Every generated drill has its chuck along x_O: the bit's axis is x_O, its tip BIT_LENGTH_M beyond the centre of
the chuck's front face.
"""

import numpy as np

from systems.perception.parts import PartRole
from systems.shape_space.tool_frame import BIT_LENGTH_M, ToolFrame

# m: the vertices this near the tool parts' farthest along the axis make up their end face
END_FACE_BAND_M = 0.003


def tool_of(category: str, parts: list) -> ToolFrame | None:
    """The tool frame in O of an instance of `category` made of `parts` (instance.Part: .role, .mesh in O); None for
    a category without one (or an instance without tool parts)."""
    tool = [part.mesh.vertices for part in parts if part.role == PartRole.TOOL]
    rest = [part.mesh.vertices for part in parts if part.role != PartRole.TOOL]
    if not tool or not rest or category not in ("watering_can", "drill"):
        return None
    tool = np.vstack(tool)
    if category == "drill":
        axis = np.array([1.0, 0.0, 0.0])
    else:
        centred = tool - tool.mean(axis=0)
        axis = np.linalg.eigh(centred.T @ centred)[1][:, -1]
        if axis @ (tool.mean(axis=0) - np.vstack(rest).mean(axis=0)) < 0:
            axis = -axis
    along = tool @ axis
    face = tool[along >= along.max() - END_FACE_BAND_M].mean(axis=0)
    return ToolFrame(face + (BIT_LENGTH_M * axis if category == "drill" else 0.0), axis)
