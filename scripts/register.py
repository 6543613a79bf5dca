"""Registers one observed point cloud to a category's shape space and writes the result.

python scripts/register.py --space models/shape_space_watering_can.npz --cloud can.ply --json out.json
python scripts/register.py --space my_space.npz --cloud scan.pcd --initial-xyz-yaw 0.7 0 0.76 0.1 --any-orientation
python scripts/register.py --space models/shape_space_drill.npz --cloud view.ply --viewpoint 0.2 0 1.6  # a single view

The cloud is in your world frame, in metres (a cloud in millimetres is rejected, saying so).
Without --initial-xyz-yaw the search starts at the cloud's lowest-centre point with yaw 0
(and the yaw hypotheses of the registrar).
Writes the refined pose X_WO, the latent vector, the warped grasp poses (as 4 x 4
matrices) and, with --reconstruction FILE.ply, the whole inferred shape. Give --viewpoint
(the camera's position) for a single view: the model's unseen side then stays out of the
fit, and each grasp is re-placed on the points seen about it.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import open3d as o3d
from pydrake.math import RigidTransform, RotationMatrix

from diagrams.cli import write_json
from systems.perception.shape_registrar import scale_prior
from systems.shape_space.registration import Registrar
from systems.shape_space.space import ShapeSpace
from systems.shape_space.units import check_metres


def read_cloud(path: Path) -> np.ndarray:
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such cloud file")
    if path.suffix.lower() not in (".ply", ".pcd", ".xyz", ".pts"):
        raise ValueError(f"{path}: unsupported cloud format (use .ply, .pcd, .xyz or .pts)")
    points = np.asarray(o3d.io.read_point_cloud(str(path)).points)
    if len(points) == 0:
        raise ValueError(f"{path}: the cloud is empty or could not be read")
    check_metres(points, str(path))
    return points


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--space", type=Path, required=True, help="shape space (.npz) from build_shape_space.py")
    parser.add_argument("--cloud", type=Path, required=True, help="observed points (.ply, .pcd, .xyz, .pts)")
    parser.add_argument("--initial-xyz-yaw", type=float, nargs=4, metavar=("X", "Y", "Z", "YAW"))
    parser.add_argument(
        "--viewpoint",
        type=float,
        nargs=3,
        metavar=("X", "Y", "Z"),
        help="where the cloud was seen from (the camera's position, m, in the cloud's frame): only the model's "
        "points visible from there are matched; without it, all are",
    )
    parser.add_argument("--any-orientation", action="store_true", help="not upright: search the full 3D rotation")
    parser.add_argument("--json", type=Path, help="write the result here")
    parser.add_argument("--reconstruction", type=Path, help="write the inferred full shape here (.ply)")
    args = parser.parse_args(argv)
    try:
        space = ShapeSpace.load(args.space)
        points = read_cloud(args.cloud)
        finite = points[np.all(np.isfinite(points), axis=1)]
        if args.initial_xyz_yaw:
            x, y, z, yaw = args.initial_xyz_yaw
        else:
            (x, y), z, yaw = np.median(finite[:, :2], axis=0), np.min(finite[:, 2]) if len(finite) else 0.0, 0.0
        X_WO_initial = RigidTransform(RotationMatrix.MakeZRotation(yaw), [x, y, z])
        start = time.perf_counter()
        registrar = Registrar(space, upright=not args.any_orientation, scale_prior=scale_prior(space.category))
        result = registrar.register(points, X_WO_initial, args.viewpoint)
        seconds = time.perf_counter() - start
    except (FileNotFoundError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    report = {
        "category": space.category,
        "X_WO": result.X_WO.GetAsMatrix4().tolist(),
        "latent": result.latent.tolist(),
        "scale": result.scale.tolist(),
        "poor_fit": result.poor_fit,
        "grasp_poses_W": {name: X.GetAsMatrix4().tolist() for name, X in result.grasp_poses_W.items()},
        "fit_error_m": result.fit_error_m,
        "registration_s": seconds,
        "tool_W": result.tool_W.entries() if result.tool_W else None,
    }
    print(f"registered to {space.category} in {seconds:.2f} s, mean fit error {1000 * result.fit_error_m:.1f} mm")
    print(f"X_WO translation {np.round(result.X_WO.translation(), 4).tolist()}")
    if result.tool_W:
        print(f"tool tip {np.round(result.tool_W.tip, 4).tolist()}, axis {np.round(result.tool_W.axis, 3).tolist()}")
    if result.poor_fit:
        print(f"warning: {result.poor_fit}: its grasps cannot be trusted")
    if args.reconstruction:
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(result.reconstructed_W))
        o3d.io.write_point_cloud(str(args.reconstruction), cloud)
        print(f"wrote {args.reconstruction}")
    if args.json:
        write_json(args.json, report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
