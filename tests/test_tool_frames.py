"""Tool frames: the generators' (the spout's end, the chuck's axis), the shape spaces' (carried to a novel instance
and placed on the tool seen), and the user's (a poses file's `tool`)."""

import numpy as np
import pytest
import trimesh
import yaml
from pydrake.math import RigidTransform, RotationMatrix

from diagrams.generation.objects import catalog, shop_held_out, unfamiliar
from diagrams.generation.objects.library import load_info
from diagrams.generation.objects.watering_can import spout_axis
from systems.perception.depth_view import DepthView
from systems.perception.shape_registrar import shape_space_file
from systems.shape_space import folder as folder_tools
from systems.shape_space.folder import pose_entries
from systems.shape_space.registration import Registrar
from systems.shape_space.space import ShapeSpace, tool_axes_agree
from systems.shape_space.tool_frame import BIT_LENGTH_M, ToolFrame
from systems.shape_space.tool_placement import returned_points, tool_centred_on_seen, tool_end_in_image
from systems.shape_space.visibility import visible_from


def test_a_tool_frame_moves_scales_and_measures_its_errors():
    tool = ToolFrame([0.2, 0.0, 0.2], [2.0, 0.0, 0.0])  # the axis is made unit
    np.testing.assert_allclose(tool.axis, [1.0, 0.0, 0.0])
    X = RigidTransform(RotationMatrix.MakeZRotation(np.pi / 2), [1.0, 0.0, 0.0])
    moved = tool.moved(X)
    np.testing.assert_allclose(moved.tip, [1.0, 0.2, 0.2], atol=1e-12)
    np.testing.assert_allclose(moved.axis, [0.0, 1.0, 0.0], atol=1e-12)
    stretched = ToolFrame([0.1, 0.0, 0.1], [1.0, 0.0, 1.0]).scaled(np.array([2.0, 1.0, 1.0]))
    np.testing.assert_allclose(stretched.tip, [0.2, 0.0, 0.1])
    np.testing.assert_allclose(stretched.axis, np.array([2.0, 0.0, 1.0]) / np.sqrt(5))
    tip, angle = ToolFrame([0.2, 0.003, 0.2], [1.0, 0.0, 0.0]).errors(moved.moved(X.inverse()))
    assert tip == pytest.approx(0.003) and angle == pytest.approx(0.0, abs=1e-7)
    for bad in ([np.nan, 0, 0], [0, 0]):
        with pytest.raises(ValueError, match="tool frame"):
            ToolFrame(bad, [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="non-zero axis"):
        ToolFrame([0, 0, 0], [0, 0, 0])


@pytest.mark.parametrize("name", ["test_0", "wide_3", "extra_101"])
def test_a_generated_cans_tool_frame_is_its_spouts_end(name):
    """The tip is the centre of the rose's end face, the axis the spout's (both known to its generator)."""
    instance = catalog.generate("watering_can", name)
    spout = spout_axis(instance.parameters)
    tool = instance.tool_frame()
    np.testing.assert_allclose(tool.axis, spout.direction, atol=1e-9)
    np.testing.assert_allclose(tool.tip, spout.end + 0.025 * spout.direction, atol=1e-9)


@pytest.mark.parametrize("name", ["test_0", "wide_3", "shop_5"])
def test_a_generated_drills_tool_frame_is_a_bit_along_its_chuck(name):
    """The axis is the chuck's (x_O); the tip a bit's length beyond the chuck's front face, on its axis."""
    instance = catalog.generate("drill", name)
    tool = instance.tool_frame()
    chuck = next(part.mesh for part in instance.parts if part.name == "chuck")
    np.testing.assert_allclose(tool.axis, [1.0, 0.0, 0.0])
    assert tool.tip[0] == pytest.approx(chuck.bounds[1][0] + BIT_LENGTH_M, abs=1e-9)
    np.testing.assert_allclose(tool.tip[1:], chuck.bounds.mean(axis=0)[1:], atol=1e-3)


def test_every_held_out_design_knows_its_tool_frame_and_writes_it():
    """The hand-made designs too (the shop family's and the unfamiliar one's): the can's tip on its mesh's surface,
    pointing out of it; the drill's a bit's length off it, along x_O."""
    designs = [*shop_held_out.instances("watering_can"), *shop_held_out.instances("drill")]
    designs += [*unfamiliar.instances("watering_can", "held_out"), *unfamiliar.instances("drill", "held_out")]
    for instance in designs:
        tool = instance.tool_frame()
        assert tool is not None, instance.name
        assert instance.info().tool_frame().errors(tool) == (0.0, 0.0)
        mesh = instance.visual_mesh()
        distance = abs(trimesh.proximity.signed_distance(mesh, [tool.tip])[0])
        if instance.category == "drill":
            assert distance == pytest.approx(BIT_LENGTH_M, abs=2e-3), instance.name
        else:
            assert distance < 1e-3 and not mesh.contains([tool.tip + 0.01 * tool.axis])[0], instance.name


def test_a_generated_instances_info_file_holds_its_tool_frame():
    info = load_info(catalog.instance_directory("drill", "test_0") / "info.yaml")
    expected = catalog.generate("drill", "test_0").tool_frame()
    assert info.tool_frame().errors(expected) == pytest.approx((0.0, 0.0), abs=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize(("category", "instance"), [("watering_can", "test_0"), ("drill", "test_2")])
def test_registration_carries_the_tool_frame_to_an_unseen_instance(category, instance):
    """Seen from one side, an unseen can's spout tip within 1 cm and its axis within 3 deg (5.9 mm, 0.7 deg); an
    unseen drill's bit tip within 1 cm, its axis within 3 deg (6.9 mm, 1.6 deg)."""
    registrar = Registrar(ShapeSpace.load(shape_space_file(category)))
    directory = catalog.instance_directory(category, instance)
    mesh = trimesh.load(directory / "visual.obj", force="mesh")
    X_WO = RigidTransform(RotationMatrix.MakeZRotation(0.2), [0.7, 0.0, 0.76])
    surface_W = X_WO.multiply(trimesh.sample.sample_surface_even(mesh, 6000, seed=2)[0].T).T
    camera = np.array([0.1, 0.0, 1.6])
    result = registrar.register(surface_W[visible_from(surface_W, camera)], X_WO, camera)
    truth = load_info(directory / "info.yaml").tool_frame().moved(X_WO)
    tip, angle = result.tool_W.errors(truth)
    assert tip < 0.01 and angle < np.radians(3), (tip, np.degrees(angle))


def test_a_tool_axis_turns_with_the_fitted_shape_only_where_the_annotated_models_axes_differ(tmp_path):
    """The shipped drill spaces learnt from 48 and 88 bits along x_O: the axis stays, whatever the latent; the cans'
    spouts differ, so theirs turns. A file from before the flag turns (as it did)."""
    assert tool_axes_agree(np.array([1.0, 0, 0]), [np.array([1.0, 0, 0]), np.array([np.cos(0.01), np.sin(0.01), 0])])
    assert not tool_axes_agree(np.array([1.0, 0, 0]), [np.array([np.cos(0.03), 0, np.sin(0.03)])])  # 1.7 deg
    assert not tool_axes_agree(np.array([1.0, 0, 0]), [])  # the canonical's alone says nothing
    drill, can = (ShapeSpace.load(shape_space_file(c)) for c in ("drill", "watering_can"))
    assert not drill.tool_turns and can.tool_turns
    turned = []
    for space in (drill, can):
        latents = np.random.default_rng(0).normal(size=(5, space.latent_size)) * 2 * np.sqrt(space.pca.variances)
        axes = np.array([space.tool_at(z).axis for z in latents])
        turned.append(np.degrees(np.arccos(np.clip(axes @ space.tool.axis, -1, 1))).max())
    assert turned[0] == pytest.approx(0.0, abs=1e-6) and turned[1] > 1.0, turned
    drill.save(tmp_path / "drill.npz")
    assert not ShapeSpace.load(tmp_path / "drill.npz").tool_turns
    with np.load(tmp_path / "drill.npz") as data:
        np.savez(tmp_path / "old.npz", **{k: data[k] for k in data.files if k != "tool_turns"})
    assert ShapeSpace.load(tmp_path / "old.npz").tool_turns


def test_a_poses_file_gives_the_canonical_models_tool_frame_in_its_files_frame_and_units(tmp_path):
    """In millimetres with y up, as the models: read in metres, z up; a malformed one is a clear error."""
    can = catalog.generate("watering_can", "train_0")
    X_FM = RigidTransform(RotationMatrix.MakeXRotation(-np.pi / 2), np.zeros(3))  # y up: z_M is y_F
    for name in ("a", "b"):
        mesh = catalog.generate("watering_can", f"train_{name == 'b':d}").visual_mesh()
        mesh.apply_transform(1000.0 * X_FM.GetAsMatrix4())
        mesh.export(tmp_path / f"{name}.obj")
    in_file = {n: X_FM @ X for n, X in can.info().control_poses().items()}
    in_file = {n: RigidTransform(X.rotation(), 1000.0 * X.translation()) for n, X in in_file.items()}
    tool_F = can.tool_frame().moved(X_FM)
    spec = {"canonical": "a.obj", "poses": pose_entries(in_file)}
    spec["tool"] = {"tip": (1000.0 * tool_F.tip).tolist(), "axis": tool_F.axis.tolist()}
    (tmp_path / "poses.yaml").write_text(yaml.safe_dump(spec))
    models = folder_tools.folder_instances(tmp_path, tmp_path / "poses.yaml")
    assert models.reading.up == "y" and models.tool.errors(can.tool_frame()) == pytest.approx((0, 0), abs=1e-9)
    spec["tool"] = {"tip": [1.0, 2.0]}
    (tmp_path / "poses.yaml").write_text(yaml.safe_dump(spec))
    with pytest.raises(SystemExit, match="tool needs a tip"):
        folder_tools.folder_instances(tmp_path, tmp_path / "poses.yaml")
    spec["tool"] = {"tip": (1000.0 * tool_F.tip).tolist(), "axis": tool_F.axis.tolist()}
    spec["tool"]["tip"][0] += 300.0  # 30 cm off the spout: a tool frame off the model, said at once
    (tmp_path / "poses.yaml").write_text(yaml.safe_dump(spec))
    with pytest.raises(SystemExit, match="poses.yaml: the tool frame .* lies off the model"):
        folder_tools.folder_instances(tmp_path, tmp_path / "poses.yaml")


def _chuck(radius=0.018, length=0.05, points=20000, end_radius=None):
    """A capped cylinder (a chuck) along +x from the origin to x = length, or a frustum narrowing to end_radius:
    surface points (N x 3), unit normals."""
    end_radius = radius if end_radius is None else end_radius
    rng = np.random.default_rng(3)
    side = rng.uniform(0.0, 2 * np.pi, points)
    x = rng.uniform(0.0, length, points)
    r_x = radius + (end_radius - radius) * x / length
    wall = np.column_stack([x, r_x * np.cos(side), r_x * np.sin(side)])
    slope = (radius - end_radius) / length
    wall_normals = np.column_stack([np.full(points, slope), np.cos(side), np.sin(side)])
    r, t = end_radius * np.sqrt(rng.uniform(0, 1, points // 4)), rng.uniform(0, 2 * np.pi, points // 4)
    cap = np.column_stack([np.full(len(r), length), r * np.cos(t), r * np.sin(t)])
    wall_normals /= np.linalg.norm(wall_normals, axis=1, keepdims=True)
    normals = np.vstack([wall_normals, np.tile([1.0, 0, 0], (len(r), 1))])
    return np.vstack([wall, cap]), normals


def _view_of(surface):
    """The mask (DepthView) of `surface` (N x 3) in a camera behind and above it, looking along +x 0.6 rad down."""
    forward = np.array([np.cos(0.6), 0.0, -np.sin(0.6)])
    right = np.array([0.0, -1.0, 0.0])
    X_WC = RigidTransform(RotationMatrix(np.column_stack([right, np.cross(forward, right), forward])), [-0.8, 0, 0.6])
    focal, centre, shape = (580.0, 580.0), (320.0, 240.0), (480, 640)
    p = X_WC.inverse().multiply(surface.T).T
    uv = np.round(np.array(focal) * p[:, :2] / p[:, 2:3] + centre).astype(int)
    assert p[:, 2].min() > 0 and uv.min() >= 0 and uv[:, 0].max() < shape[1] and uv[:, 1].max() < shape[0]
    mask = np.zeros(shape, bool)
    mask[uv[:, 1], uv[:, 0]] = True
    return DepthView(np.ones(shape), X_WC, focal, centre, mask)


def test_the_tool_end_is_read_where_the_mask_ends_and_its_middle_across():
    """A chuck pointing away from a camera behind and above it: a frame 9 mm short and 6 mm aside is moved back onto
    the chuck its mask shows, within 2 mm."""
    surface, _ = _chuck()
    view = _view_of(surface)
    truth = ToolFrame(np.array([0.05 + BIT_LENGTH_M, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]))
    off = np.array([-0.009, 0.006, 0.0])  # short along the axis, aside
    placed = tool_end_in_image(ToolFrame(truth.tip + off, truth.axis), BIT_LENGTH_M, surface + off, view)
    tip, _ = placed.errors(truth)
    assert tip < 0.002, 1000 * (placed.tip - truth.tip)
    no_mask = DepthView(view.depth, view.X_WC, view.focal, view.centre)
    assert tool_end_in_image(truth, BIT_LENGTH_M, surface, no_mask) is truth


def test_a_tapering_tools_end_is_read_with_its_end_as_wide_as_the_seen_tube():
    """A chuck narrowing from 22 to 12 mm radius: its surface's median width over its last stretch is wider than its
    end, and the tip read from the mask's end with it lands millimetres short; with the seen tube's end radius
    (tool_centred_on_seen's) it lands within 1 mm, from 6 mm short or 6 mm beyond."""
    surface, _ = _chuck(radius=0.022, end_radius=0.012)
    view = _view_of(surface)
    truth = ToolFrame(np.array([0.05 + BIT_LENGTH_M, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]))
    median_width = tool_end_in_image(truth, BIT_LENGTH_M, surface, view)
    assert truth.tip[0] - median_width.tip[0] > 0.002
    for along in (-0.006, 0.006):
        off = np.array([along, 0.0, 0.0])
        placed = tool_end_in_image(ToolFrame(truth.tip + off, truth.axis), BIT_LENGTH_M, surface + off, view, 0.012)
        assert abs(placed.tip[0] - truth.tip[0]) < 0.001, 1000 * (placed.tip - truth.tip)


def test_the_points_a_depth_sensor_returns_face_its_ray_within_the_grazing_limit():
    surface, normals = _chuck(points=4000)
    camera = np.array([-0.8, 0.0, 0.6])
    returned = returned_points(surface, surface, camera)
    rays = surface - camera
    facing = np.abs(np.einsum("ni,ni->n", normals, rays)) / np.linalg.norm(rays, axis=1)
    kept = {tuple(point) for point in returned}
    inside = np.array([tuple(point) in kept for point in surface])
    clear = np.abs(facing - np.cos(np.radians(75.0))) > 0.05  # (away from the limit: the estimated normals' noise)
    agree = inside[clear] == (facing[clear] >= np.cos(np.radians(75.0)))
    assert agree.mean() > 0.97  # (about the cap's rim a normal from the nearest points mixes the wall's and the cap's)
    assert 0.2 < inside.mean() < 0.9


def test_a_known_axis_is_moved_onto_the_centre_of_the_seen_tools_cross_sections():
    """A chuck's near half as a depth camera above and in front returns it (1 mm noise, a few flying pixels behind
    its outline): a frame 5 mm above and 4 mm beside its axis comes back within 1 mm of it, along the axis where it
    was; with too few points seen, or points that are no tube's, it stays."""
    surface, normals = _chuck(points=6000)
    camera = np.array([-0.6, 0.2, 0.5])
    rays = camera - surface
    seen = surface[np.einsum("ni,ni->n", normals, rays) > 0.25 * np.linalg.norm(rays, axis=1)]
    rng = np.random.default_rng(5)
    seen = seen + rng.normal(0.0, 0.001, seen.shape)
    edge = seen[rng.choice(len(seen), 40, replace=False)]
    seen = np.vstack([seen, edge - 0.03 * (camera - edge) / np.linalg.norm(camera - edge, axis=1, keepdims=True)])
    truth = ToolFrame(np.array([0.05 + BIT_LENGTH_M, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]))
    off = np.array([0.003, -0.004, 0.005])
    tube = tool_centred_on_seen(ToolFrame(truth.tip + off, truth.axis), BIT_LENGTH_M, seen)
    placed = tube.tool_W
    assert np.abs(placed.tip[1:] - truth.tip[1:]).max() < 0.001, 1000 * (placed.tip - truth.tip)
    assert placed.tip[0] == pytest.approx(truth.tip[0] + off[0]) and np.allclose(placed.axis, truth.axis)
    assert tube.end_radius == pytest.approx(0.018, abs=0.0015)  # the chuck's radius
    plane = np.column_stack([rng.uniform(0.0, 0.05, 500), rng.uniform(-0.03, 0.03, 500), np.zeros(500)])
    for too_little in (seen[:20], plane):  # too few points; points that are no tube's
        tube = tool_centred_on_seen(truth, BIT_LENGTH_M, too_little)
        assert tube.tool_W is truth and tube.end_radius is None
