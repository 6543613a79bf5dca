"""The perception benchmark on held-out scenes with the unseen test instances (scripts/benchmark_perception.py).

Each scene is a new random background with one test can or drill at a random pose,
seen from the chest camera's nominal pose (the whole object in view), its colour and depth as the
RGB-D sensor model reports them (kinect_v2 by default; perfect: the renderer's images). The Segmenter and
PoseEstimator systems run as they do in the pick diagram (FixValue / Eval).
"""

import dataclasses
import logging
import platform
import time
from pathlib import Path

import cv2
import numpy as np
import torch
from pydrake.common.value import AbstractValue

from diagrams.generation.synthetic_scenes import CLASSES, SyntheticScene
from diagrams.perception import MakePoseEstimator
from diagrams.scenario import load_scenario
from systems.perception.images import to_depth_image, to_rgba_image
from systems.perception.rgbd_noise import noisy_color, noisy_depth, sensor_model
from systems.perception.segmenter import Segmenter
from systems.perception.segmenter_training import intersection_over_union

OBJECT_REGION = ((0.6, 0.85), (-0.2, 0.2))  # m, in W: where the robot picks from
MIN_OBJECT_PIXELS = 1500


def yaw_of(X) -> float:
    """The yaw of a pose's x axis about z (rad)."""
    R = X.rotation().matrix()
    return float(np.arctan2(R[1, 0], R[0, 0]))


def wrap(angle: float) -> float:
    """The angle in [-pi, pi) (rad)."""
    return float((angle + np.pi) % (2 * np.pi) - np.pi)


def render_held_out_frame(scene: SyntheticScene):
    """A frame with exactly one object wholly in view (re-placed until it is)."""
    for _ in range(20):
        frame = scene.render(object_region=OBJECT_REGION, count=1)
        object_pixels = frame.labels > 0
        on_border = object_pixels[[0, -1]].any() or object_pixels[:, [0, -1]].any()
        if np.count_nonzero(object_pixels) >= MIN_OBJECT_PIXELS and not on_border:
            return frame
    raise RuntimeError("could not place an object wholly in view in 20 tries")


def draw_result(frame, segmentation, estimate, intrinsics, scale: float = 0.5) -> np.ndarray:
    """The colour image with the predicted mask tinted and the estimated object frame drawn (x red, y green)."""
    image = frame.rgb.copy()
    if segmentation.found:
        image[segmentation.mask] = (0.5 * image[segmentation.mask] + [0, 0, 127]).astype(np.uint8)
    if estimate.found:
        X_CW = frame.X_WC.inverse()
        axes = estimate.X_WO.multiply(np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]]).T)
        p = X_CW.multiply(axes)
        uv = np.column_stack(
            [
                intrinsics.focal_x() * p[0] / p[2] + intrinsics.center_x(),
                intrinsics.focal_y() * p[1] / p[2] + intrinsics.center_y(),
            ]
        ).astype(int)
        for end, color in ((1, (255, 0, 0)), (2, (0, 255, 0))):
            cv2.line(image, tuple(uv[0]), tuple(uv[end]), color, 3)
    return cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)


def run(scenes: int, seed: int, weights: Path, sensor_name: str | None, flip: bool, figure_tiles: int = 0):
    """The benchmark's results over `scenes` held-out scenes of the stream `seed` (sensor_name: an RGB-D sensor
    model preset, None or perfect for the renderer's images; flip: the segmenter's test-time flip), and up to
    `figure_tiles` drawn results of the first scenes."""
    scenario = load_scenario()
    rng = np.random.default_rng(seed)

    sensor = sensor_model(sensor_name)
    intrinsics = scenario.camera.MakeCameras()[1].core().intrinsics()
    segmenter = Segmenter(weights, flip=flip)
    pose_estimator = MakePoseEstimator(scenario)
    predicted, predicted_dominant, truth, rows, tiles = [], [], [], [], []
    for i in range(scenes):
        scene = SyntheticScene(scenario, rng, split="test", cameras=1, camera_jitter=False)
        frame = render_held_out_frame(scene)
        category, instance, X_WO_true = frame.objects[0]
        if sensor is not None:  # (a stream of its own: the scenes are those of a run without it)
            noise = np.random.default_rng([seed, i])
            depth = noisy_depth(frame.depth, frame.rgb, intrinsics, sensor, noise)
            frame = dataclasses.replace(frame, rgb=noisy_color(frame.rgb, sensor, noise), depth=depth)

        seg_context = segmenter.CreateDefaultContext()
        segmenter.GetInputPort("color_image").FixValue(seg_context, to_rgba_image(frame.rgb))
        start = time.perf_counter()
        segmentation = segmenter.GetOutputPort("segmentation").Eval(seg_context)
        segmentation_s = time.perf_counter() - start
        labels = segmenter.GetOutputPort("labels").Eval(seg_context)

        pose_context = pose_estimator.CreateDefaultContext()
        pose_estimator.GetInputPort("segmentation").FixValue(pose_context, AbstractValue.Make(segmentation))
        pose_estimator.GetInputPort("depth_image").FixValue(pose_context, to_depth_image(frame.depth))
        pose_estimator.GetInputPort("camera_pose").FixValue(pose_context, AbstractValue.Make(frame.X_WC))
        start = time.perf_counter()
        estimate = pose_estimator.GetOutputPort("estimate").Eval(pose_context)
        pose_s = time.perf_counter() - start

        predicted.append(labels)
        dominant = np.zeros_like(labels)
        if segmentation.found:
            dominant[segmentation.mask] = CLASSES.index(segmentation.category)
        predicted_dominant.append(dominant)
        truth.append(frame.labels)
        if len(tiles) < figure_tiles:
            tiles.append(draw_result(frame, segmentation, estimate, pose_estimator.intrinsics))
        row = {
            "category": category,
            "instance": instance,
            "found": estimate.found,
            "category_correct": estimate.category == category,
            "segmentation_s": segmentation_s,
            "pose_s": pose_s,
        }
        if estimate.found and estimate.category == category:
            row["translation_error_m"] = float(np.linalg.norm(estimate.X_WO.translation() - X_WO_true.translation()))
            row["yaw_error_rad"] = abs(wrap(yaw_of(estimate.X_WO) - yaw_of(X_WO_true)))
        rows.append(row)
        logging.info(
            "%3d %-12s %-7s %s seg %.3f s pose %.4f s  dt %s  dyaw %s",
            i,
            category,
            instance,
            "ok  " if row["category_correct"] else "MISS",
            segmentation_s,
            pose_s,
            f"{row.get('translation_error_m', float('nan')):.3f} m",
            f"{np.degrees(row.get('yaw_error_rad', float('nan'))):5.1f} deg",
        )

    iou = intersection_over_union(np.stack(predicted), np.stack(truth), len(CLASSES))
    # The dominant object's mask: what the pose estimator consumes.
    iou_dominant = intersection_over_union(np.stack(predicted_dominant), np.stack(truth), len(CLASSES))
    localised = [r for r in rows if "translation_error_m" in r]
    results = {
        "scenes": scenes,
        "seed": seed,
        "sensor": sensor_name,
        "iou": dict(zip(CLASSES, iou.tolist(), strict=True)),
        "iou_mean": float(np.nanmean(iou[1:])),  # network labels, over the object classes
        "iou_dominant": dict(zip(CLASSES, iou_dominant.tolist(), strict=True)),
        "iou_dominant_mean": float(np.nanmean(iou_dominant[1:])),
        "category_accuracy": float(np.mean([r["category_correct"] for r in rows])),
        "segmentation_s_median": float(np.median([r["segmentation_s"] for r in rows])),
        "pose_s_median": float(np.median([r["pose_s"] for r in rows])),
        "translation_error_m_median": float(np.median([r["translation_error_m"] for r in localised])),
        "translation_error_m_p90": float(np.percentile([r["translation_error_m"] for r in localised], 90)),
        "yaw_error_rad_median": float(np.median([r["yaw_error_rad"] for r in localised])),
        "yaw_error_rad_p90": float(np.percentile([r["yaw_error_rad"] for r in localised], 90)),
        "torch_threads": torch.get_num_threads(),
        "machine": platform.processor() or platform.machine(),
        "frames": rows,
    }
    return results, tiles


def print_table(results: dict) -> None:
    """The summary beside its targets."""
    print()
    print(f"{'metric':32s} {'value':>10s}  target")
    for key, value, target in (
        ("iou_mean (can, drill)", results["iou_mean"], ">= 0.9"),
        ("iou_dominant_mean (after post.)", results["iou_dominant_mean"], ""),
        ("iou watering_can", results["iou"]["watering_can"], ""),
        ("iou drill", results["iou"]["drill"], ""),
        ("category accuracy", results["category_accuracy"], ""),
        ("segmentation_s_median", results["segmentation_s_median"], "<= 0.15 s"),
        ("pose_s_median", results["pose_s_median"], "<= 0.02 s"),
        ("translation_error_m_median", results["translation_error_m_median"], "<= 0.02 m"),
        ("yaw_error_deg_median", np.degrees(results["yaw_error_rad_median"]), "<= 15 deg"),
        ("yaw_error_deg_p90", np.degrees(results["yaw_error_rad_p90"]), ""),
    ):
        print(f"{key:32s} {value:10.4f}  {target}")


def write_mosaic(path: Path, tiles: list[np.ndarray]) -> None:
    """The drawn results in rows of three (.png)."""
    rows_of_tiles = [np.hstack(tiles[i : i + 3]) for i in range(0, len(tiles) - len(tiles) % 3 or 1, 3)]
    cv2.imwrite(str(path), cv2.cvtColor(np.vstack(rows_of_tiles), cv2.COLOR_RGB2BGR))
    print(f"wrote {path}")
