"""Drake images from numpy arrays: what a camera's ports carry, for feeding a perception stage frames rendered or
recorded elsewhere (FixValue on its color_image and depth_image inputs)."""

import numpy as np
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U


def to_rgba_image(rgb: np.ndarray) -> ImageRgba8U:
    """An H x W x 3 uint8 colour array as an opaque RGBA image."""
    image = ImageRgba8U(rgb.shape[1], rgb.shape[0])
    image.mutable_data[:, :, :3] = rgb
    image.mutable_data[:, :, 3] = 255
    return image


def to_depth_image(depth: np.ndarray) -> ImageDepth32F:
    """An H x W float32 depth array (m) as a depth image."""
    image = ImageDepth32F(depth.shape[1], depth.shape[0])
    image.mutable_data[:, :, 0] = depth
    return image
