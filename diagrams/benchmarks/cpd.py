"""Our deformable CPD beside the reference implementation, pycpd (scripts/benchmark_registration.py --cpd-sizes):
the same problem, parameters and number of iterations, their times and errors."""

import logging
import time

import numpy as np
import pycpd

from systems.perception.shape_registrar import shape_space_file
from systems.shape_space.cpd import deformable_cpd
from systems.shape_space.space import ShapeSpace


def smooth_warp(points: np.ndarray) -> np.ndarray:
    """The points (m) moved by a smooth field (at most 4 cm along any axis): what both implementations recover."""
    return points + 0.02 * np.column_stack(
        [np.sin(8 * points[:, 1]), np.cos(7 * points[:, 0]) - 1, np.sin(6 * points[:, 2])]
    )


def cpd_comparison(sizes, beta: float = 0.1, lam: float = 2.0, iterations: int = 50):
    """Both implementations, the same problem, parameters and number of iterations."""
    space = ShapeSpace.load(shape_space_file("watering_can"))
    mesh_points = space.canonical_points
    rows = []
    for size in sizes:
        rng = np.random.default_rng(size)
        source = mesh_points[rng.choice(len(mesh_points), size, replace=len(mesh_points) < size)]
        source = source + rng.normal(0, 1e-3, source.shape)
        truth = smooth_warp(source)
        target = truth[rng.permutation(size)]
        start = time.perf_counter()
        ours = deformable_cpd(source, target, beta=beta, lam=lam, max_iterations=iterations, tolerance=0.0)
        ours_s = time.perf_counter() - start
        reference = pycpd.DeformableRegistration(
            X=target, Y=source, beta=beta, alpha=lam, max_iterations=iterations, tolerance=0.0
        )
        start = time.perf_counter()
        reference_points, _ = reference.register()
        reference_s = time.perf_counter() - start
        row = {
            "points": size,
            "iterations": iterations,
            "ours_s": ours_s,
            "pycpd_s": reference_s,
            "speedup": reference_s / ours_s,
            "ours_error_m": float(np.linalg.norm(ours.transformed - truth, axis=1).mean()),
            "pycpd_error_m": float(np.linalg.norm(reference_points - truth, axis=1).mean()),
        }
        rows.append(row)
        logging.info("CPD %d points: ours %.2f s, pycpd %.2f s (%.1fx)", size, ours_s, reference_s, row["speedup"])
    return rows


def print_comparison(rows: list[dict]) -> None:
    """The comparison's table: per size, both times, the speedup and both errors."""
    header = ("CPD points", "ours s", "pycpd s", "speedup", "ours err mm", "pycpd err mm")
    print("\n" + " ".join(f"{h:>12s}" for h in header))
    for r in rows:
        print(
            f"{r['points']:12d} {r['ours_s']:12.3f} {r['pycpd_s']:12.3f} {r['speedup']:12.1f} "
            f"{1000 * r['ours_error_m']:12.2f} {1000 * r['pycpd_error_m']:12.2f}"
        )
