"""A RefineNet-style semantic segmentation network in plain torch (paper §III; Lin et al. 2017).

Encoder: a strided stem and four ResNet basic blocks (1/4 ... 1/32 resolution).
Decoder: RefineNet multi-path refinement. Starting from the coarsest map, each
RefineBlock passes the finer encoder map through residual conv units, fuses it
with the upsampled coarser result, and applies chained residual pooling; a light
last fusion with the stem's 1/2-resolution map sharpens the object boundaries.
A linear (1x1) classifier gives per-pixel class scores, and the pixel-wise softmax
(or its argmax) the classes. Everything runs on the CPU.
"""

import copy
import functools
import warnings
from pathlib import Path

import cv2
import numpy as np
import torch
from torch import nn
from torch.nn import functional as F
from torch.nn.utils.fusion import fuse_conv_bn_eval

# Network input size (width, height); camera images are resized to it.
INPUT_SIZE = (320, 240)
MISSING_WEIGHTS = "{}: no segmenter weights; run scripts/train_segmenter.py"


class ResidualBlock(nn.Module):
    """ResNet basic block: two 3x3 convolutions with a (projected) shortcut."""

    def __init__(self, in_channels: int, out_channels: int, stride: int):
        super().__init__()
        self.conv1 = nn.Conv2d(in_channels, out_channels, 3, stride, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(out_channels)
        self.conv2 = nn.Conv2d(out_channels, out_channels, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(out_channels)
        self.shortcut = nn.Sequential(
            nn.Conv2d(in_channels, out_channels, 1, stride, bias=False), nn.BatchNorm2d(out_channels)
        )

    def forward(self, x):
        y = F.relu(self.bn1(self.conv1(x)))
        return F.relu(self.bn2(self.conv2(y)) + self.shortcut(x))


class ResidualConvUnit(nn.Module):
    """RefineNet RCU: x + conv(relu(conv(relu(x))))."""

    def __init__(self, channels: int):
        super().__init__()
        self.conv1 = nn.Conv2d(channels, channels, 3, 1, 1)
        self.conv2 = nn.Conv2d(channels, channels, 3, 1, 1)

    def forward(self, x):
        return x + self.conv2(F.relu(self.conv1(F.relu(x))))


class ChainedResidualPooling(nn.Module):
    """RefineNet CRP: a chain of 5x5 max-pool + conv stages, each added to the output."""

    def __init__(self, channels: int, stages: int = 2):
        super().__init__()
        self.convs = nn.ModuleList(nn.Conv2d(channels, channels, 3, 1, 1, bias=False) for _ in range(stages))

    def forward(self, x):
        x = F.relu(x)
        out, path = x, x
        for conv in self.convs:
            # (the 5 x 5 max pool as 1 x 5 then 5 x 1: the same maxima in less time on the CPU)
            path = conv(F.max_pool2d(F.max_pool2d(path, (1, 5), 1, (0, 2)), (5, 1), 1, (2, 0)))
            out = out + path
        return out


class RefineBlock(nn.Module):
    """Fuses a finer encoder map with the refined coarser map (or refines the coarsest alone)."""

    def __init__(self, channels: int, has_coarser: bool):
        super().__init__()
        self.adapt = ResidualConvUnit(channels)
        self.fuse_fine = nn.Conv2d(channels, channels, 3, 1, 1)
        self.fuse_coarse = nn.Conv2d(channels, channels, 3, 1, 1) if has_coarser else None
        self.pool = ChainedResidualPooling(channels)
        self.out = ResidualConvUnit(channels)

    def forward(self, fine, coarser=None):
        x = self.fuse_fine(self.adapt(fine))
        if coarser is not None:
            x = x + F.interpolate(self.fuse_coarse(coarser), size=x.shape[-2:], mode="bilinear", align_corners=False)
        return self.out(self.pool(x))


class RefineNetLite(nn.Module):
    """Four ResNet blocks, four RefineBlocks, a fusion with the stem, a 1x1 classifier."""

    def __init__(self, num_classes: int, widths=(24, 32, 48, 64), channels: int = 32, stem_channels: int = 16):
        super().__init__()
        self.num_classes = num_classes
        self.stem = nn.Sequential(
            nn.Conv2d(3, stem_channels, 3, 2, 1, bias=False), nn.BatchNorm2d(stem_channels), nn.ReLU()
        )
        ins = (stem_channels, *widths[:-1])
        self.encoder = nn.ModuleList(ResidualBlock(i, o, 2) for i, o in zip(ins, widths, strict=True))
        self.reduce = nn.ModuleList(nn.Conv2d(w, channels, 1) for w in widths)
        self.refine = nn.ModuleList(RefineBlock(channels, has_coarser=i < 3) for i in range(4))
        self.fine_from_refined = nn.Conv2d(channels, stem_channels, 1)
        self.fine_from_stem = nn.Conv2d(stem_channels, stem_channels, 1)
        self.fine = ResidualConvUnit(stem_channels)
        self.classifier = nn.Conv2d(stem_channels, num_classes, 1)

    def forward(self, image):
        """image: N x 3 x H x W in [-0.5, 0.5] -> class scores N x C x H x W."""
        stem = self.stem(image)
        x, features = stem, []
        for block in self.encoder:
            x = block(x)
            features.append(x)
        refined = None
        for i in reversed(range(4)):
            refined = self.refine[i](self.reduce[i](features[i]), refined)
        up = F.interpolate(self.fine_from_refined(refined), size=stem.shape[-2:], mode="bilinear", align_corners=False)
        scores = self.classifier(self.fine(up + self.fine_from_stem(stem)))
        # (upsampled in float32 and the plain layout: bfloat16 or channels-last take twice the time here)
        return F.interpolate(scores.float().contiguous(), size=image.shape[-2:], mode="bilinear", align_corners=False)


def for_inference(model: RefineNetLite) -> RefineNetLite:
    """A copy of the model (in eval mode) for inference alone: each batch norm folded into the convolution before
    it (torch's fuse_conv_bn_eval), the same scores within float rounding in less time. Not for training."""
    fused = copy.deepcopy(model).eval()
    fused.stem[0], fused.stem[1] = fuse_conv_bn_eval(fused.stem[0], fused.stem[1]), nn.Identity()
    for block in fused.encoder:
        block.conv1, block.bn1 = fuse_conv_bn_eval(block.conv1, block.bn1), nn.Identity()
        block.conv2, block.bn2 = fuse_conv_bn_eval(block.conv2, block.bn2), nn.Identity()
        block.shortcut[0], block.shortcut[1] = fuse_conv_bn_eval(block.shortcut[0], block.shortcut[1]), nn.Identity()
    return fused


# TorchScript's executor profiles a module's first calls and optimises it after them: until then a call takes two to
# three times as long (2026-12-06: the part network's first two calls 27-29 ms, then 10-11 ms).
WARM_UP_CALLS = 3


def frozen(model: nn.Module, example: torch.Tensor) -> nn.Module:
    """The inference model traced on an example input and frozen (TorchScript): the same scores within float rounding,
    without Python's call between each module, which on these 2 cores is a fifth to a quarter of a frame's time
    (2026-12-06: the part network 11.7 -> 9.4 ms in bfloat16, the segmenter 37 -> 28 ms). The example's batch size,
    dtype and layout are those it is then called with; it is run WARM_UP_CALLS times here, so that a pick's first
    frame meets the optimised module.

    torch 2.13 (pinned in pyproject.toml) marks TorchScript deprecated in favour of torch.compile, which takes 53 s
    to compile the part network on this VM, in every process; its warning is not repeated here.
    """
    with torch.no_grad(), warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r".*torch\.jit.* is deprecated", category=DeprecationWarning)
        traced = torch.jit.freeze(torch.jit.trace(model.eval(), example))
        for _ in range(WARM_UP_CALLS):
            traced(example)
    return traced


def load_for_inference(path, dtype: torch.dtype, input_hw: tuple[int, int]) -> tuple[nn.Module, dict]:
    """The network saved at `path` for inference, and its metadata (a copy): folded (for_inference), channels-last
    in `dtype`, frozen for 1 x 3 x H x W inputs (input_hw = (H, W)). Built once per process for each file (its path
    and modification time), dtype and input size: a diagram built again, as each pick of a campaign builds one, takes
    the same frozen network (tracing and warming it up takes 0.5-1 s).

    Raises:
        FileNotFoundError: no such file (the message says how to make it).
    """
    path = Path(path).resolve()
    try:
        modified_ns = path.stat().st_mtime_ns
    except FileNotFoundError:
        raise FileNotFoundError(MISSING_WEIGHTS.format(path)) from None
    model, metadata = _frozen_network(path, modified_ns, dtype, tuple(input_hw))
    return model, copy.deepcopy(metadata)


@functools.lru_cache(maxsize=8)
def _frozen_network(path: Path, mtime_ns: int, dtype: torch.dtype, input_hw: tuple[int, int]):
    model, metadata = load(path)
    model = for_inference(model).to(dtype, memory_format=torch.channels_last)
    example = torch.zeros((1, 3, *input_hw), dtype=dtype).contiguous(memory_format=torch.channels_last)
    return frozen(model, example), metadata


def with_classes(model: RefineNetLite, num_classes: int) -> RefineNetLite:
    """A copy of the model with its classifier widened to num_classes: the known classes keep their weights, each
    new one starts as a copy of the background's with a lower bias (it must be learnt before it wins a pixel)."""
    if num_classes < model.num_classes:
        raise ValueError(f"cannot narrow a {model.num_classes}-class segmenter to {num_classes} classes")
    widened = copy.deepcopy(model)
    old = model.classifier
    widened.classifier = nn.Conv2d(old.in_channels, num_classes, 1)
    with torch.no_grad():
        widened.classifier.weight[: model.num_classes] = old.weight
        widened.classifier.bias[: model.num_classes] = old.bias
        widened.classifier.weight[model.num_classes :] = old.weight[0]
        widened.classifier.bias[model.num_classes :] = old.bias[0] - 1.0
    widened.num_classes = num_classes
    return widened


def with_new_classifier(model: RefineNetLite, num_classes: int, seed: int) -> RefineNetLite:
    """A copy of the model with a fresh classifier of num_classes (seeded): its encoder and decoder as a start for
    another per-pixel task (the part network starts from the segmenter)."""
    torch.manual_seed(seed)
    copied = copy.deepcopy(model)
    copied.classifier = nn.Conv2d(model.classifier.in_channels, num_classes, 1)
    copied.num_classes = num_classes
    return copied


def resize_to_input(rgb: np.ndarray) -> np.ndarray:
    """A camera-resolution colour image (H x W x 3 or 4, uint8) at the network's INPUT_SIZE, RGB."""
    return cv2.resize(rgb[:, :, :3], INPUT_SIZE, interpolation=cv2.INTER_AREA)


def to_input(rgb: np.ndarray) -> torch.Tensor:
    """H x W x 3 uint8 images (or a batch N x H x W x 3) -> network input in [-0.5, 0.5]."""
    x = torch.from_numpy(np.ascontiguousarray(rgb)).float().div_(255.0).sub_(0.5)
    return x.permute(0, 3, 1, 2) if x.dim() == 4 else x.permute(2, 0, 1).unsqueeze(0)


def save(model: RefineNetLite, path, metadata: dict):
    torch.save({"state_dict": model.state_dict(), "num_classes": model.num_classes, "metadata": metadata}, path)


def load(path) -> tuple[RefineNetLite, dict]:
    """Loads weights saved by `save`; the model is in eval mode.

    Raises:
        FileNotFoundError: no such file (the message says how to make it).
    """
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise FileNotFoundError(MISSING_WEIGHTS.format(path)) from None
    model = RefineNetLite(checkpoint["num_classes"])
    model.load_state_dict(checkpoint["state_dict"])
    model.eval()
    return model, checkpoint["metadata"]
