"""The segmenter system: colour image in, per-pixel classes and the dominant object's mask out."""

import logging
import time
from pathlib import Path

import cv2
import numpy as np
import torch
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import CameraInfo, ImageDepth32F, ImageRgba8U
from torch.nn import functional as F

from systems.messages import LeftOut, Segmentation
from systems.parallel import parallel_map
from systems.paths import MODELS_DIR
from systems.perception import segmentation_network
from systems.perception.instances import Instance, TableView, foot_hidden, named_object, next_object, object_instances
from systems.perception.object_completion import completed_mask
from systems.perception.part_segmenter import PartSegmenter
from systems.perception.pose_estimator import depth_to_points

DEFAULT_WEIGHTS = MODELS_DIR / "segmenter.pt"
# The network also on the mirror image, its scores summed (see Segmenter.segment).
TEST_TIME_FLIP = True


def check_category(category: str, classes) -> None:
    """Raises ValueError unless category is one of the object classes (classes[1:]; 0 is the background)."""
    if category not in classes[1:]:
        raise ValueError(f"the segmenter knows no category {category!r} (it knows {', '.join(classes[1:])})")


def dominant_object(labels: np.ndarray, classes, min_pixels: int) -> Segmentation:
    """The largest connected region of one object class (outer contour, filled): the object when the user named
    no category.

    Args:
        labels: H x W class ids (0 = background).
        classes: class names by id.
        min_pixels: smaller regions are noise; with none larger, nothing is found.
    """
    best = Segmentation(False, mask=np.zeros(labels.shape, bool))
    kernel = np.ones((3, 3), np.uint8)
    for class_id, name in enumerate(classes):
        if class_id == 0:
            continue
        pixels = cv2.morphologyEx((labels == class_id).astype(np.uint8), cv2.MORPH_OPEN, kernel)
        contours, _ = cv2.findContours(pixels, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        for contour in contours:
            region = np.zeros(labels.shape, np.uint8)
            cv2.drawContours(region, [contour], -1, 1, thickness=cv2.FILLED)
            mask = (region & pixels).astype(bool)  # keep holes, e.g. inside a handle loop
            count = int(np.count_nonzero(mask))
            if count > best.pixel_count:
                best = Segmentation(True, name, mask, count)
    if best.pixel_count < min_pixels:
        return Segmentation(
            False,
            mask=np.zeros(labels.shape, bool),
            message=f"no object in view: the largest object region has {best.pixel_count} px (< {min_pixels})",
        )
    best.message = f"{best.category}: {best.pixel_count} px"
    return best


class Segmenter(LeafSystem):
    """RefineNet-style semantic segmentation of the colour image.

    .. pydrake_system::

        name: Segmenter
        input_ports:
        - color_image
        - depth_image (optional)
        - camera_pose (optional)
        - left_out (optional)
        output_ports:
        - labels
        - segmentation

    Inputs ``color_image`` (ImageRgba8U from the camera) and, optionally, ``depth_image`` (ImageDepth32F, m, the
    same view) and ``camera_pose`` (RigidTransform X_WB of the camera body, as the PoseEstimator's). Outputs
    ``labels`` (H x W uint8 class ids at the camera's resolution: 0 background, then ``classes``) and
    ``segmentation`` (a Segmentation of the object to pick, with its parts where there is a part network; its
    compute_s counts the networks too).
    Without a named category that is the dominant object, the largest region of one class (dominant_object).
    With one, it is the nearest object the network labelled that category, objects cut apart in 3D where the depth
    image and the intrinsics are given (systems/perception/instances.py: a cluttered table), and where the camera's
    pose and the table top are given too, an object's upper part that self-occlusion cut off joins it, and so do
    the object's parts the network left unlabelled, found in 3D (systems/perception/object_completion.py; only of
    an object the network labelled that category).

    Args:
        weights: the network's (its classes come with it).
        min_pixels: smaller object regions are noise.
        category: the category the user named ("": the network's classes decide): the nearest object labelled so,
            or, with none, the largest object taken as that category; the network's own class is reported
            (instances.named_object).
        intrinsics: the depth camera's: with them and a depth image, objects are cut apart in 3D
            (instances.object_instances); without, each connected region of object pixels is one.
        X_BC: the depth sensor in the camera body (with camera_pose: the depth camera's pose).
        table_top_z: the table top's height in W, m: with it and a camera_pose, a floating cluster joins the
            standing object below it (instances.TableView).
        flip: also run the network on the mirror image and sum the two score maps (test-time flip: twice the
            network's time).
        part_segmenter: with it, the object's pixels are labelled with their functional parts too
            (Segmentation.parts; part_segmenter.py).
        first_near_W: the clear task's: the object is the nearest to this point (x, y in W, m; the drop zone's
            centre) of every category's, leaving out those in ``left_out`` (LeftOut: the drop zone, objects given up;
            instances.next_object). Needs the depth image, the intrinsics and the camera's pose.

    Raises:
        ValueError: the weights' network knows no such category.
    """

    def __init__(
        self,
        weights: Path = DEFAULT_WEIGHTS,
        min_pixels: int = 400,
        category: str = "",
        intrinsics: CameraInfo | None = None,
        flip: bool = TEST_TIME_FLIP,
        X_BC: RigidTransform | None = None,
        table_top_z: float | None = None,
        part_segmenter: PartSegmenter | None = None,
        first_near_W: tuple[float, float] | None = None,
    ):
        super().__init__()
        self.part_segmenter = part_segmenter
        # Folded, channels-last (the CPU's convolutions take about a third of the time) and frozen (a quarter less)
        input_hw = segmentation_network.INPUT_SIZE[::-1]
        self.model, metadata = segmentation_network.load_for_inference(weights, torch.float32, input_hw)
        self.classes = tuple(metadata["classes"])
        self.min_pixels, self.category, self.intrinsics, self.flip = min_pixels, category, intrinsics, flip
        self.X_BC, self.table_top_z = X_BC or RigidTransform(), table_top_z
        if category:
            check_category(category, self.classes)
        if first_near_W is not None and (category or intrinsics is None or table_top_z is None):
            raise ValueError("the clear task's segmenter chooses among every category and needs the depth camera")
        self.first_near_W = first_near_W
        # One inference now: the network comes warmed up, but each of the pool's threads' first call into torch
        # takes longer (2026-12-06: a first segmentation 40 ms without this, then 28 ms)
        self.segment(np.zeros((*segmentation_network.INPUT_SIZE[::-1], 3), np.uint8))
        self.color_image_port = self.DeclareAbstractInputPort("color_image", AbstractValue.Make(ImageRgba8U()))
        self.depth_image_port = self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F()))
        self.camera_pose_port = self.DeclareAbstractInputPort("camera_pose", AbstractValue.Make(RigidTransform()))
        self.left_out_port = self.DeclareAbstractInputPort("left_out", AbstractValue.Make(LeftOut()))
        # Computed from the image alone (not from time): an image that does not change is segmented once.
        inputs = {self.all_input_ports_ticket()}
        self.labels_port = self.DeclareAbstractOutputPort(
            "labels", lambda: AbstractValue.Make(np.zeros((0, 0), np.uint8)), self._calc_labels, inputs
        )
        self.DeclareAbstractOutputPort(
            "segmentation",
            lambda: AbstractValue.Make(Segmentation(False)),
            self._calc_mask,
            inputs,
        )

    def segment(self, rgb: np.ndarray) -> np.ndarray:
        """H x W x 3 uint8 -> H x W uint8 class ids.

        The network runs at INPUT_SIZE on the image (and with `flip` its mirror image: the two score maps are
        summed), and the scores are upsampled to the camera's size.
        """
        if rgb.ndim != 3 or rgb.shape[2] < 3 or rgb.size == 0:
            raise ValueError(f"expected an H x W x 3 colour image, got shape {rgb.shape}")
        x = segmentation_network.to_input(segmentation_network.resize_to_input(rgb))
        if self.flip:  # the image and its mirror image on the cores at once (each as it would run alone)
            scores, mirrored = parallel_map(self._scores, [x, x.flip(-1)])
            scores = scores + mirrored.flip(-1)
        else:
            scores = self._scores(x)
        scores = F.interpolate(scores, size=rgb.shape[:2], mode="bilinear", align_corners=False)
        # (numpy's argmax over the class axis: torch's takes 25 ms at 512 x 424 on one thread)
        return scores[0].numpy().argmax(axis=0).astype(np.uint8)

    def _scores(self, x: torch.Tensor) -> torch.Tensor:
        """The network's class scores (1 x C x h x w, no gradient) for one input image (1 x 3 x h x w)."""
        with torch.no_grad():  # (in the calling thread: torch's gradient mode is per thread)
            return self.model(x.contiguous(memory_format=torch.channels_last))

    def table_view(self, X_WB: RigidTransform | None) -> TableView | None:
        """The table top as the depth camera sees it from the camera body's pose X_WB (None without a table top or
        a pose)."""
        if self.table_top_z is None or X_WB is None:
            return None
        return TableView(X_WB @ self.X_BC, self.table_top_z)

    def _complete(
        self, segmentation: Segmentation, labels: np.ndarray, depth: np.ndarray, table: TableView, instances: list
    ):
        """Adds the object's parts the network left unlabelled, found in 3D (object_completion), to its mask; never
        the pixels of the other instances found."""
        others = np.zeros(labels.shape, bool)
        for instance in instances:
            if not (instance.mask & segmentation.mask).any():
                others |= instance.mask
        mask = completed_mask(segmentation.mask, labels, depth, self.intrinsics, table, others)
        added = int(np.count_nonzero(mask & ~segmentation.mask))
        if added:
            segmentation.mask, segmentation.pixel_count = mask, segmentation.pixel_count + added
            segmentation.message += f", {added} px more of it in 3D"

    def _calc_labels(self, context, output):
        image = self.color_image_port.Eval(context)
        output.set_value(self.segment(np.asarray(image.data)))

    def _calc_mask(self, context, output):
        started = time.perf_counter()
        labels = self.labels_port.Eval(context)
        depth, X_WB = None, None
        if self.depth_image_port.HasValue(context):
            depth = np.asarray(self.depth_image_port.Eval(context).data)[:, :, 0]
        if self.camera_pose_port.HasValue(context):
            X_WB = self.camera_pose_port.Eval(context)
        left_out = self.left_out_port.Eval(context) if self.left_out_port.HasValue(context) else LeftOut()
        segmentation = self.object_of(labels, depth, X_WB, left_out)
        # The parts of an object the network took for another category than the one named would be that other
        # category's parts given this one's roles: the named category's shape alone must explain it.
        agreed = segmentation.network_category in ("", segmentation.category)
        if segmentation.found and self.part_segmenter is not None and agreed:
            rgb = np.asarray(self.color_image_port.Eval(context).data)
            segmentation.parts = self.part_segmenter.parts_of(rgb, segmentation.mask)
        if segmentation.network_category and segmentation.network_category != segmentation.category:
            logging.warning("segmentation: %s", segmentation.message)
        segmentation.compute_s = time.perf_counter() - started
        output.set_value(segmentation)

    def instances_of(
        self, labels: np.ndarray, depth: np.ndarray | None = None, X_WB: RigidTransform | None = None
    ) -> list[Instance]:
        """The object instances in a labelled image, cut apart in 3D where the depth image and the camera body's pose
        X_WB are given (instances.object_instances), before any is completed."""
        return object_instances(labels, depth, self.classes, self.min_pixels, self.intrinsics, self.table_view(X_WB))

    def object_of(
        self,
        labels: np.ndarray,
        depth: np.ndarray | None = None,
        X_WB: RigidTransform | None = None,
        left_out: LeftOut | None = None,
    ) -> Segmentation:
        """The object to pick in a labelled image (H x W class ids), as the class docstring says, from the depth
        image (H x W, m) and the camera body's pose X_WB where given; the clear task's leaves out `left_out`."""
        if not self.category and self.first_near_W is None:
            return dominant_object(labels, self.classes, self.min_pixels)
        if depth is not None and depth.shape != labels.shape:
            raise ValueError(f"depth image {depth.shape} and colour image {labels.shape} differ in size")
        table = self.table_view(X_WB)
        instances = self.instances_of(labels, depth, X_WB)
        if self.first_near_W is not None:
            if depth is None or table is None:
                raise ValueError("the clear task's segmenter needs the depth image and the camera's pose")
            points = [table.X_WC.multiply(depth_to_points(depth, i.mask, self.intrinsics).T).T for i in instances]
            left_out = left_out or LeftOut()
            hidden = [foot_hidden(i.mask, depth) for i in instances]
            segmentation = next_object(
                instances, self.classes, points, left_out, self.first_near_W, labels.shape, self.table_top_z, hidden
            )
        else:
            segmentation = named_object(instances, self.classes, self.category, labels.shape)
        # (An object the network took for another category, taken as named, is a guess: on a table of other things
        # it is a mislabelled patch of one of them, and completing it would make that thing the object.)
        recognised = segmentation.found and segmentation.network_category == segmentation.category
        if recognised and depth is not None and self.intrinsics is not None and table is not None:
            self._complete(segmentation, labels, depth, table, instances)
        return segmentation
