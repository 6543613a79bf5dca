"""The generated instances as a shape space's training data (scripts/build_shape_space.py without --folder): each
one's surface points and its true control poses, in its object frame O."""

from diagrams.generation.objects import catalog
from diagrams.generation.objects.library import generated_instance_directory, load_info
from systems.shape_space.folder import sample_mesh


def generated_instances(category: str, extra: int, wide: int = 0):
    """Clouds, true control poses and true tool frames (where the category has them) of the training instances,
    `extra` more of their family (extra_0..) and `wide` of the generator's wider family (wide_0..)."""
    names = [n for n in catalog.instance_names(category) if n.startswith("train")]
    names += [f"extra_{i}" for i in range(extra)] + [f"wide_{i}" for i in range(wide)]
    clouds, poses, tools = {}, {}, {}
    for name in names:
        directory = generated_instance_directory(category, name)
        clouds[name] = sample_mesh(directory / "visual.obj")
        info = load_info(directory / "info.yaml")
        poses[name] = info.control_poses()
        if (tool := info.tool_frame()) is not None:
            tools[name] = tool
    return clouds, poses, tools
