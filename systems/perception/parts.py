"""Functional parts of an object: the role each object pixel (and each part of a generated model) plays.

A part image holds one `PartRole` per pixel. The roles are the same for every category (the hand each handle
belongs to, the tool, the rest); what a role is called depends on the category (`part_name`).
"""

from systems.messages import PartRole

__all__ = ["PartRole", "part_name"]


# What each role is called on an object of the category (a taught category's roles go by the generic names).
PART_NAMES = {
    "watering_can": {
        PartRole.BODY: "body",
        PartRole.LEFT_HANDLE: "top handle",
        PartRole.RIGHT_HANDLE: "rear handle",
        PartRole.TOOL: "spout",
    },
    "drill": {
        PartRole.BODY: "body",
        PartRole.LEFT_HANDLE: "side handle",
        PartRole.RIGHT_HANDLE: "pistol grip",
        PartRole.TOOL: "chuck",
    },
}
GENERIC_PART_NAMES = {
    PartRole.NONE: "none",
    PartRole.BODY: "body",
    PartRole.LEFT_HANDLE: "left handle",
    PartRole.RIGHT_HANDLE: "right handle",
    PartRole.TOOL: "tool",
}


def part_name(category: str, role: PartRole) -> str:
    """What the role's part is called on an object of `category` (e.g. drill, RIGHT_HANDLE: "pistol grip")."""
    return PART_NAMES.get(category, {}).get(PartRole(role), GENERIC_PART_NAMES[PartRole(role)])
