"""The held-out shop family (scripts/make_shop_held_out.py): the designs the issue names, written as a user's files
whose sidecars carry the true grasps and each face's part role."""

import numpy as np
import pytest
import trimesh

from diagrams.generation.objects import shop_held_out
from diagrams.generation.objects.hand_clearance import hands_fit
from diagrams.generation.objects.library import load_info
from systems.perception.parts import PartRole


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    root = tmp_path_factory.mktemp("shop_held_out")
    return {category: shop_held_out.write(category, root / category) for category in shop_held_out.DESIGNS}


@pytest.fixture(scope="module")
def designs():
    return {category: shop_held_out.instances(category) for category in shop_held_out.DESIGNS}


def _axes(instance, side):
    R = instance.grasps[side].grasp.GetDeterministicValue().rotation().matrix()
    return R[:, 0], R[:, 2]


def test_the_family_has_the_designs_the_issue_names(designs):
    cans, drills = designs["watering_can"], designs["drill"]
    assert len(cans) >= 6 and len(drills) >= 6
    across = [c for c in cans if abs(_axes(c, "left")[0][1]) > 0.99]
    assert len(across) >= 2, "top handles across the body"
    loops = [c for c in cans if {p.name for p in c.parts} >= {"loop_top", "loop_rear"}]
    assert len(loops) == 1
    assert min(c.visual_mesh().extents[0] for c in cans) <= 0.2, "a small can, at most 20 cm long"
    side_angles = []
    for drill in drills:
        x, _ = _axes(drill, "left")
        if abs(x[2]) > 0.05:  # a sloping side handle: its angle from the vertical
            side_angles.append(np.degrees(np.arccos(abs(x[2]))))
    assert any(30.0 <= a <= 60.0 for a in side_angles), side_angles
    names = [d.name for d in drills]
    assert any("d_grip" in n or "hammer" in n for n in names) and any("top" in n or "carry" in n for n in names)


@pytest.mark.slow
def test_every_design_stands_its_hands_fit_and_its_grasps_lie_in_their_handles(designs):
    for instance in designs["watering_can"] + designs["drill"]:
        assert hands_fit(instance), instance.name
        for side, role in (("left", PartRole.LEFT_HANDLE), ("right", PartRole.RIGHT_HANDLE)):
            point = instance.grasps[side].grasp.GetDeterministicValue().translation()[None, :]
            depth = max(trimesh.proximity.signed_distance(p.mesh, point)[0] for p in instance.parts if p.role == role)
            assert depth > 0.008, f"{instance.name}: its {side} grasp is not inside its handle"


@pytest.mark.slow
def test_the_files_read_back_as_written_watertight_with_a_role_for_every_face(written, designs):
    for category, paths in written.items():
        assert [p.stem for p in paths] == [d.name for d in designs[category]]
        for path, instance in zip(paths, designs[category], strict=True):
            mesh = trimesh.load(path, force="mesh")
            assert mesh.is_watertight and mesh.bounds[0][2] == pytest.approx(0.0, abs=1e-6), path.name
            with np.load(path.with_suffix(".parts.npz")) as parts:
                roles, centres = parts["face_roles"], parts["face_centres"]
            assert len(roles) == len(mesh.faces)
            np.testing.assert_allclose(mesh.triangles_center, centres, atol=1e-6)
            assert set(np.unique(roles)) == {PartRole.BODY, PartRole.LEFT_HANDLE, PartRole.RIGHT_HANDLE, PartRole.TOOL}
            info = load_info(path.with_suffix(".info.yaml"))
            for side in ("left", "right"):
                np.testing.assert_allclose(
                    info.grasps[side].grasp.GetDeterministicValue().GetAsMatrix4(),
                    instance.grasps[side].grasp.GetDeterministicValue().GetAsMatrix4(),
                    atol=1e-9,
                )
