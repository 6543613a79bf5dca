"""LCM messages received as raw bytes and decoded with checks, so that bad input is rejected, not fatal.

Drake's C++ LCM deserialisation aborts the whole process on a malformed message, and
its converters trust sizes and values; a robot's bus must survive a garbage packet.
Subscribers therefore keep the raw bytes (RawMessage as the "LCM type" of
LcmSubscriberSystem), and each decode_* below turns them into numbers or raises
MalformedMessage with the reason. Units: SI (m, rad, s, N m); WSG messages are in mm.
"""

import itertools
import zlib

import numpy as np
from drake import (
    lcmt_iiwa_command,
    lcmt_iiwa_status,
    lcmt_image,
    lcmt_image_array,
    lcmt_schunk_wsg_command,
    lcmt_schunk_wsg_status,
)


class MalformedMessage(ValueError):
    """A message that cannot be decoded, has the wrong sizes, or holds non-finite numbers."""


class RawMessage:
    """Duck-typed LCM type for LcmSubscriberSystem.Make: keeps the bytes, numbered as they are taken in."""

    _sequence = itertools.count(1)

    def __init__(self, data: bytes = b"", sequence: int = 0):
        self.data, self.sequence = data, sequence  # sequence 0: nothing received yet

    @classmethod
    def decode(cls, data) -> "RawMessage":
        return cls(bytes(data), next(cls._sequence))

    def encode(self) -> bytes:
        return self.data


def _decode(lcm_type, raw: RawMessage):
    try:
        return lcm_type.decode(raw.data)
    except Exception as error:  # lcm raises ValueError (fingerprint) or struct.error (truncated)
        raise MalformedMessage(f"not a valid {lcm_type.__name__}: {error}") from error


def _finite(name: str, values, size: int) -> np.ndarray:
    array = np.asarray(values, dtype=float)
    if array.shape != (size,):
        raise MalformedMessage(f"{name} has {array.size} entries, expected {size}")
    if not np.all(np.isfinite(array)):
        raise MalformedMessage(f"{name} holds NaN or inf")
    return array


def decode_arm_status(raw: RawMessage, joints: int) -> tuple[int, np.ndarray]:
    """(utime, [position_commanded, position_measured, velocity_estimated, torque_commanded]) concatenated."""
    message = _decode(lcmt_iiwa_status, raw)
    if message.num_joints != joints:
        raise MalformedMessage(f"status for {message.num_joints} joints, expected {joints}")
    fields = (
        "joint_position_commanded",
        "joint_position_measured",
        "joint_velocity_estimated",
        "joint_torque_commanded",
    )
    return message.utime, np.concatenate([_finite(name, getattr(message, name), joints) for name in fields])


def decode_arm_command(raw: RawMessage, joints: int) -> tuple[int, np.ndarray]:
    """(utime, joint positions in rad)."""
    message = _decode(lcmt_iiwa_command, raw)
    if message.num_joints != joints:
        raise MalformedMessage(f"command for {message.num_joints} joints, expected {joints}")
    return message.utime, _finite("joint_position", message.joint_position, joints)


def decode_hand_status(raw: RawMessage) -> tuple[int, np.ndarray]:
    """(utime, [opening width m, opening rate m/s])."""
    message = _decode(lcmt_schunk_wsg_status, raw)
    values = _finite("hand status", [message.actual_position_mm, message.actual_speed_mm_per_s], 2)
    return message.utime, values / 1000.0


def decode_hand_command(raw: RawMessage) -> tuple[int, np.ndarray]:
    """(utime, [opening width m])."""
    message = _decode(lcmt_schunk_wsg_command, raw)
    return message.utime, _finite("hand command", [message.target_position_mm], 1) / 1000.0


_PIXELS = {
    (lcmt_image.PIXEL_FORMAT_RGBA, lcmt_image.CHANNEL_TYPE_UINT8): (np.uint8, 4),
    (lcmt_image.PIXEL_FORMAT_DEPTH, lcmt_image.CHANNEL_TYPE_FLOAT32): (np.float32, 1),
}


def decode_images(raw: RawMessage) -> tuple[int, dict[str, np.ndarray]]:
    """(utime, {"color": H x W x 4 uint8, "depth": H x W x 1 float32 metres}) from an lcmt_image_array."""
    message = _decode(lcmt_image_array, raw)
    images = {}
    for image in message.images:
        kind = _PIXELS.get((image.pixel_format, image.channel_type))
        if kind is None:
            continue  # e.g. a label image: not used
        dtype, channels = kind
        data = image.data
        if image.compression_method == lcmt_image.COMPRESSION_METHOD_ZLIB:
            try:
                data = zlib.decompress(data)
            except zlib.error as error:
                raise MalformedMessage(f"image {image.header.frame_name!r}: {error}") from error
        elif image.compression_method != lcmt_image.COMPRESSION_METHOD_NOT_COMPRESSED:
            raise MalformedMessage(f"image compression {image.compression_method} is not supported")
        expected = image.height * image.width * channels * np.dtype(dtype).itemsize
        if image.width <= 0 or image.height <= 0 or len(data) != expected:
            size = f"{image.width} x {image.height}"
            raise MalformedMessage(f"image of {size} has {len(data)} bytes, expected {expected}")
        name = "color" if channels == 4 else "depth"
        images[name] = np.frombuffer(data, dtype).reshape(image.height, image.width, channels).copy()
    if set(images) != {"color", "depth"}:
        raise MalformedMessage(f"an image array needs one RGBA and one depth image, found {sorted(images) or 'none'}")
    if images["color"].shape[:2] != images["depth"].shape[:2]:
        raise MalformedMessage("the colour and depth images differ in size")
    return message.header.utime, images
