"""The perception benchmark on cluttered tables (scripts/benchmark_perception.py --scene clutter).

Each table is a seeded cluttered table (diagrams/generation/clutter_scenes.py, the report range: unseen instances),
seen by the station's chest camera through the sensor model once the objects have settled. The Segmenter (told the
category, with the depth image) and the PoseEstimator run as in the pick diagram. Judged on the simulator's ground
truth: the chosen region's IoU with the target's true mask, whether the network's class of it is the category, and
the estimated pose's translation error. Empty tables: the same tables with no object of either category (only the
boxes, cylinders and bowls): a detection is an object the pick's perception (segmenter with the category named,
pose estimator, shape registrar) hands on grasps for, with either category named; the instances the network
labelled as objects are counted too.
"""

import dataclasses
import logging
import time
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue

from diagrams.evaluation import PAPER_CATEGORIES
from diagrams.generation.clutter_scenes import clutter_scene
from diagrams.perception import MakePoseEstimator, MakeSegmenter
from diagrams.scenario import CLUTTER_SHAPES, Scenario, clutter_name
from diagrams.station import settled_frame
from systems.messages import GraspPoses, ObjectEstimate, Segmentation
from systems.perception.images import to_depth_image, to_rgba_image
from systems.perception.shape_registrar import ShapeRegistrar


def _to_images(frame):
    return to_rgba_image(frame.rgb), to_depth_image(frame.depth)


@dataclass
class _Perceived:
    """One frame's segmentation and pose estimate, as the pick's perception makes them."""

    segmentation: Segmentation
    estimate: ObjectEstimate
    segmentation_s: float  # the segmentation's wall time, s


def _perceive(segmenter, pose_estimator, rgb, depth, X_WB) -> _Perceived:
    """The segmentation and pose estimate of one frame (X_WB: the camera body's pose in W)."""
    context = segmenter.CreateDefaultContext()
    segmenter.GetInputPort("color_image").FixValue(context, rgb)
    segmenter.GetInputPort("depth_image").FixValue(context, depth)
    segmenter.GetInputPort("camera_pose").FixValue(context, AbstractValue.Make(X_WB))
    start = time.perf_counter()
    segmentation = segmenter.GetOutputPort("segmentation").Eval(context)
    segmentation_s = time.perf_counter() - start
    pose_context = pose_estimator.CreateDefaultContext()
    pose_estimator.GetInputPort("segmentation").FixValue(pose_context, AbstractValue.Make(segmentation))
    pose_estimator.GetInputPort("depth_image").FixValue(pose_context, depth)
    pose_estimator.GetInputPort("camera_pose").FixValue(pose_context, AbstractValue.Make(X_WB))
    return _Perceived(segmentation, pose_estimator.GetOutputPort("estimate").Eval(pose_context), segmentation_s)


def _perceived_grasps(segmenter, pose_estimator, registrar, rgb, depth, X_WB) -> GraspPoses:
    """What the pick's perception hands on for one frame (segmenter -> pose estimator -> shape registrar), not found
    with the reason where a stage found nothing or the fit is poor."""
    estimate = _perceive(segmenter, pose_estimator, rgb, depth, X_WB).estimate
    context = registrar.CreateDefaultContext()
    registrar.GetInputPort("estimate").FixValue(context, AbstractValue.Make(estimate))
    return registrar.GetOutputPort("grasp_poses").Eval(context)


def run(base: Scenario, weights, tables: int, empty_tables: int, split: str = "report") -> dict:
    """The benchmark's rows and summary (see the module docstring)."""
    pose_estimator = MakePoseEstimator(base)
    rows, empty_rows = [], []
    for category in PAPER_CATEGORIES:
        segmenter = MakeSegmenter(base, weights, category)
        for k in range(tables):
            scenario = clutter_scene(base, category, k, split)
            frame = settled_frame(scenario)
            rgb, depth = _to_images(frame)
            perceived = _perceive(segmenter, pose_estimator, rgb, depth, frame.X_WB)
            segmentation, estimate = perceived.segmentation, perceived.estimate
            truth = frame.labels == frame.object_label
            union = np.count_nonzero(truth | segmentation.mask)
            iou = np.count_nonzero(truth & segmentation.mask) / union if union else 0.0
            row = {
                "category": category,
                "table": k,
                "instance": scenario.object.instance,
                "clutter": [clutter_name(other) for other in scenario.clutter],
                "found": segmentation.found,
                "iou": float(iou),
                "category_correct": segmentation.network_category == category,
                "segmentation_s": perceived.segmentation_s,
                "message": segmentation.message,
            }
            if estimate.found:
                error = estimate.X_WO.translation() - frame.X_WO.translation()
                row["translation_error_m"] = float(np.linalg.norm(error))
            rows.append(row)
            logging.info(
                "%-12s %2d IoU %.3f %s  dt %s  %s",
                category,
                k,
                iou,
                "ok  " if row["category_correct"] else "MISS",
                f"{row.get('translation_error_m', float('nan')):.3f} m",
                segmentation.message,
            )
    segmenter = MakeSegmenter(base, weights, category="")  # (no category: the network's instances alone)
    registrar = ShapeRegistrar(list(PAPER_CATEGORIES))
    named = {category: MakeSegmenter(base, weights, category) for category in PAPER_CATEGORIES}
    for k in range(empty_tables):
        table = clutter_scene(base, PAPER_CATEGORIES[k % 2], k, split)
        shapes = [other for other in table.clutter if other.kind in CLUTTER_SHAPES]
        table = dataclasses.replace(table, object=dataclasses.replace(table.object, present=False), clutter=shapes)
        frame = settled_frame(table)
        labels = segmenter.segment(frame.rgb)
        instances = segmenter.instances_of(labels, frame.depth, frame.X_WB)
        rgb, depth = _to_images(frame)
        grasped = {c: _perceived_grasps(named[c], pose_estimator, registrar, rgb, depth, frame.X_WB) for c in named}
        detections = [c for c, grasps in grasped.items() if grasps.found]
        empty_rows.append({"table": k, "clutter": [clutter_name(o) for o in shapes], "instances": len(instances),
                           "largest_px": max((i.pixel_count for i in instances), default=0),
                           "detections": detections,
                           "registration": {c: grasps.message for c, grasps in grasped.items()}})  # fmt: skip
        logging.info(
            "empty %2d: %d instance(s), grasps for %s %s", k, len(instances), detections or "none",
            [clutter_name(o) for o in shapes],
        )  # fmt: skip
    summary = {}
    for category in PAPER_CATEGORIES:
        mine = [r for r in rows if r["category"] == category]
        located = [r["translation_error_m"] for r in mine if "translation_error_m" in r]
        summary[category] = {
            "tables": len(mine),
            "target_iou_median": float(np.median([r["iou"] for r in mine])),
            "target_iou_mean": float(np.mean([r["iou"] for r in mine])),
            "category_accuracy": float(np.mean([r["category_correct"] for r in mine])),
            "translation_error_m_median": float(np.median(located)) if located else float("nan"),
        }
    return {
        "split": split,
        "tables_per_category": tables,
        "target_iou_mean": float(np.mean([r["iou"] for r in rows])),
        "target_iou_median": float(np.median([r["iou"] for r in rows])),
        "category_accuracy": float(np.mean([r["category_correct"] for r in rows])),
        "translation_error_m_median": float(
            np.median([r["translation_error_m"] for r in rows if "translation_error_m" in r])
        ),
        "segmentation_s_median": float(np.median([r["segmentation_s"] for r in rows])),
        "empty_tables": empty_tables,
        "empty_tables_without_detection": sum(not r["detections"] for r in empty_rows),
        "empty_tables_without_instance": sum(r["instances"] == 0 for r in empty_rows),
        "per_category": summary,
        "tables": rows,
        "empty": empty_rows,
    }


def print_table(results: dict) -> None:
    """The summary beside its targets, per category, and the empty tables."""
    print(f"\n{'cluttered tables (' + results['split'] + ' range)':40s} {'value':>8s}  target")
    for key, value, target in (
        ("target IoU, mean", results["target_iou_mean"], ">= 0.85"),
        ("target IoU, median", results["target_iou_median"], ""),
        ("category accuracy", results["category_accuracy"], ">= 0.95"),
        ("pose translation error, median (m)", results["translation_error_m_median"], "<= 0.02"),
        ("segmentation time, median (s)", results["segmentation_s_median"], ""),
    ):
        print(f"{key:40s} {value:8.3f}  {target}")
    for category, row in results["per_category"].items():
        print(
            f"  {category:12s} IoU mean {row['target_iou_mean']:.3f} median {row['target_iou_median']:.3f}, "
            f"category {row['category_accuracy']:.2f}, "
            f"translation median {100 * row['translation_error_m_median']:.1f} cm"
        )
    empty = results["empty_tables"]
    print(f"empty tables (distractors only) without a detection: {results['empty_tables_without_detection']}/{empty}"
          f"  target >= {int(np.ceil(0.95 * empty))}/{empty}")  # fmt: skip
    print(
        f"  (without an instance the network labelled an object: {results['empty_tables_without_instance']}/{empty};"
        " a detection is an object perception hands grasps on for, either category named)"
    )
