"""The RGB-D sensor model alone: its statistics match its parameters, and it is seeded."""

import dataclasses

import numpy as np
import pytest
from pydrake.systems.sensors import CameraInfo, ImageDepth32F, ImageRgba8U

from systems.perception.rgbd_noise import (
    PRESETS,
    RgbdNoise,
    RgbdNoiseParameters,
    noise_parameters,
    noisy_color,
    noisy_depth,
)

INTRINSICS = CameraInfo(640, 480, np.radians(50.0))
BRIGHT = np.full((480, 640, 4), 200, np.uint8)


def flat(depth: float) -> np.ndarray:
    return np.full((480, 640), depth, np.float32)


@pytest.mark.parametrize("depth", [1.0, 2.0])
def test_axial_noise_grows_with_depth_squared(depth):
    p = RgbdNoiseParameters(axial_sigma_m=0.0005, axial_sigma_per_m2=0.0015)
    noisy = noisy_depth(flat(depth), BRIGHT, INTRINSICS, p, np.random.default_rng(0))
    expected = 0.0005 + 0.0015 * depth**2
    assert np.std(noisy - depth) == pytest.approx(expected, rel=0.02)
    assert abs(np.mean(noisy - depth)) < 1e-4


def test_the_random_dropout_share_is_the_parameter():
    p = RgbdNoiseParameters(dropout_share=0.03)
    noisy = noisy_depth(flat(1.2), BRIGHT, INTRINSICS, p, np.random.default_rng(1))
    assert np.mean(noisy == 0) == pytest.approx(0.03, abs=0.002)
    assert np.all((noisy == 0) | (noisy == np.float32(1.2)))


def test_flying_pixels_lie_between_the_surfaces_only_at_depth_edges():
    depth = flat(1.0)
    depth[:, 320:] = 1.5  # a 50 cm step between columns 319 and 320
    p = RgbdNoiseParameters(flying_pixel_share=0.5)
    noisy = noisy_depth(depth, BRIGHT, INTRINSICS, p, np.random.default_rng(2))
    between = (noisy > 1.0 + 1e-6) & (noisy < 1.5 - 1e-6)
    columns = np.unique(np.nonzero(between)[1])
    np.testing.assert_array_equal(columns, [319, 320])
    assert np.mean(between[:, 319:321]) == pytest.approx(0.5, abs=0.05)


def test_flying_pixels_survive_at_a_curved_silhouette_seen_at_a_grazing_angle():
    """A ball 10 cm in radius, 1 m away, before a wall at 1.5 m: its rim is seen at a grazing angle (no return
    there), but the pixels that see both the rim and the wall fly between them, as a time-of-flight sensor's do
    (a grazing-angle test on the noisy depth took them all for steep surfaces and hid them)."""
    v, u = np.indices((480, 640))
    x = (u - INTRINSICS.center_x()) / INTRINSICS.focal_x()
    y = (v - INTRINSICS.center_y()) / INTRINSICS.focal_y()
    # The ray (x, y, 1) t meets the sphere |p - (0, 0, 1)| = 0.1 where t^2 (1 + r^2) - 2 t + 0.99 = 0.
    r2 = x**2 + y**2
    disc = 1.0 - 0.99 * (1.0 + r2)
    ball = np.where(disc >= 0, (1.0 - np.sqrt(np.maximum(disc, 0))) / (1.0 + r2), np.inf)
    depth = np.minimum(ball, 1.5).astype(np.float32)
    p = RgbdNoiseParameters(flying_pixel_share=0.5, grazing_angle_deg=75.0)
    noisy = noisy_depth(depth, BRIGHT, INTRINSICS, p, np.random.default_rng(5))
    between = (noisy > 1.0) & (noisy < 1.45)
    rim = np.isfinite(ball) & ~np.isfinite(np.pad(ball, 1, constant_values=np.inf)[2:, 1:-1] + ball)
    assert np.count_nonzero(between) > 0.3 * np.count_nonzero(rim)
    assert np.all(noisy[np.abs(ball - 0.9) < 0.005] > 0)  # the ball's front faces the camera


def test_edge_dropouts_and_dark_surfaces():
    depth = flat(1.0)
    depth[:, 320:] = 1.5
    rgb = BRIGHT.copy()
    rgb[:100] = 5  # a black band across the top
    p = RgbdNoiseParameters(edge_dropout_share=1.0, dark_intensity=0.05, dark_dropout_share=1.0)
    noisy = noisy_depth(depth, rgb, INTRINSICS, p, np.random.default_rng(3))
    assert np.all(noisy[:100] == 0) and np.all(noisy[100:, 319:321] == 0)
    assert np.all(noisy[100:, :319] > 0) and np.all(noisy[100:, 321:] > 0)


def test_a_surface_seen_at_a_grazing_angle_returns_nothing():
    """The plane Z = 1 + 5 X (normal 79 deg off the optical axis): seen along the axis at 79 deg from its
    rays, it returns nothing; far to the left, where the rays meet it at under 60 deg, everything."""
    v, u = np.indices((480, 640))
    x = (u - INTRINSICS.center_x()) / INTRINSICS.focal_x()
    steep = np.where(x < 0.15, 1.0 / (1.0 - 5.0 * np.minimum(x, 0.15)), np.inf).astype(np.float32)
    p = RgbdNoiseParameters(grazing_angle_deg=75.0)
    noisy = noisy_depth(steep, BRIGHT, INTRINSICS, p, np.random.default_rng(4))
    along_the_axis = (np.abs(x) < 0.02) & (np.abs(v - 240) < 20)
    assert np.mean(noisy[along_the_axis] == 0) > 0.95
    assert np.all(noisy[x < -0.35] > 0)
    facing = noisy_depth(flat(1.0), BRIGHT, INTRINSICS, p, np.random.default_rng(4))
    assert np.all(facing > 0)


def test_colour_gain_and_noise():
    p = RgbdNoiseParameters(color_gain_range=(0.85, 1.15), color_sigma=4 / 255)
    noisy = noisy_color(np.full((480, 640, 4), 128, np.uint8), p, np.random.default_rng(5)).astype(float)
    assert np.all(noisy[..., 3] == 128)
    for channel in range(3):
        assert 0.85 * 128 - 1 < noisy[..., channel].mean() < 1.15 * 128 + 1
        assert np.std(noisy[..., channel]) == pytest.approx(4.0, abs=0.3)


def test_the_system_is_seeded_by_the_scenario_and_the_image_time():
    system = RgbdNoise(INTRINSICS, PRESETS["kinect_v2"], seed=7)
    context = system.CreateDefaultContext()
    color, depth = ImageRgba8U(640, 480), ImageDepth32F(640, 480)
    color.mutable_data[:] = 120
    depth.mutable_data[:] = 1.3
    system.GetInputPort("color_image").FixValue(context, color)
    system.GetInputPort("depth_image").FixValue(context, depth)

    def images(time):
        context.SetTime(time)
        return [np.array(system.GetOutputPort(n).Eval(context).data) for n in ("color_image", "depth_image")]

    first, again, later = images(0.5), images(0.5), images(0.6)
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(first[1], later[1])
    other_seed = RgbdNoise(INTRINSICS, PRESETS["kinect_v2"], seed=8)
    other_context = other_seed.CreateDefaultContext()
    other_seed.GetInputPort("color_image").FixValue(other_context, color)
    other_seed.GetInputPort("depth_image").FixValue(other_context, depth)
    other_context.SetTime(0.5)
    assert not np.array_equal(np.array(other_seed.GetOutputPort("depth_image").Eval(other_context).data), first[1])


def test_bad_parameters_are_named():
    with pytest.raises(ValueError, match="unknown rgbd noise preset 'kinect'"):
        noise_parameters("kinect")
    with pytest.raises(ValueError, match=r"unknown rgbd noise parameter\(s\) \['axial_sigma'\]"):
        noise_parameters("kinect_v2", {"axial_sigma": 0.001})
    with pytest.raises(ValueError, match="dropout_share = 3.0 is not a share"):
        noise_parameters("kinect_v2", {"dropout_share": 3.0})
    with pytest.raises(ValueError, match="metres are expected"):
        noise_parameters("kinect_v2", {"axial_sigma_m": 0.5})  # 0.5 mm written as 0.5
    with pytest.raises(ValueError, match="finite"):
        dataclasses.replace(PRESETS["perfect"], axial_sigma_per_m2=float("nan"))
    assert noise_parameters("realsense_d435", {"dropout_share": 0.0}).dropout_share == 0.0
