"""A realistic RGB-D sensor: what a real depth camera does to the renderer's perfect images.

Depth (metres, 0 where the sensor returns nothing, as real drivers do):
  * lateral jitter: each pixel reports the depth of a neighbour offset by N(0, lateral_sigma_px) pixels;
  * axial noise: N(0, sigma(z)), sigma(z) = axial_sigma_m + axial_sigma_per_m2 * z^2;
  * flying pixels: at depth edges (a step over edge_jump_m to a 4-neighbour), flying_pixel_share of the
    pixels take a depth uniformly between the two surfaces (time-of-flight pixels that see both);
  * dropouts: depth missing where the surface is seen at a grazing angle (beyond grazing_angle_deg from
    the ray; flying pixels aside), on dark surfaces (colour intensity below dark_intensity,
    dark_dropout_share of them), at edge_dropout_share of the edge pixels (stereo occlusion shadows), and
    at random (dropout_share).
Colour: a per-channel exposure gain uniform in color_gain_range, then N(0, color_sigma) per pixel (0-1 scale).

Presets and their sources (`PRESETS`; every parameter can be overridden):
  * kinect_v2 (time of flight): axial noise 0.5 mm + 1.5 mm/m^2 z^2, after Fankhauser et al., "Kinect v2 for
    mobile robot navigation: evaluation and modeling", ICAR 2015 (1-2 mm at 1-2 m, growing with the angle);
    flying pixels at depth edges and dropouts at grazing angles, after Sarbolandi, Lefloch and Kolb, "Kinect
    range sensing: structured-light versus time-of-flight Kinect", CVIU 2015.
  * realsense_d435 (active stereo): RMS depth error z^2 * subpixel / (focal_px * baseline) with subpixel 0.08,
    baseline 50 mm and a 640 px focal length, 2.5 mm/m^2, after Grunnet-Jepsen et al., "Tuning depth cameras
    for best performance" (Intel RealSense white paper, 2019); few flying pixels, missing depth in the
    occlusion shadows at edges.

Every draw comes from a generator seeded by (seed, the image's time in microseconds): the same scenario seed
and the same frame give the same noise.
"""

import dataclasses
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import CameraInfo, ImageDepth32F, ImageRgba8U


@dataclass(frozen=True)
class RgbdNoiseParameters:
    axial_sigma_m: float = 0.0
    axial_sigma_per_m2: float = 0.0  # m of sigma per m^2 of depth
    lateral_sigma_px: float = 0.0
    edge_jump_m: float = 0.02
    flying_pixel_share: float = 0.0
    edge_dropout_share: float = 0.0
    grazing_angle_deg: float = 90.0
    dark_intensity: float = 0.0  # 0-1
    dark_dropout_share: float = 0.0
    dropout_share: float = 0.0
    color_gain_range: tuple[float, float] = (1.0, 1.0)
    color_sigma: float = 0.0  # 0-1 scale

    def __post_init__(self):
        shares = ("flying_pixel_share", "edge_dropout_share", "dark_dropout_share", "dropout_share")
        for name in shares:
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"rgbd noise: {name} = {getattr(self, name)} is not a share in [0, 1]")
        for name in ("axial_sigma_m", "axial_sigma_per_m2", "lateral_sigma_px", "edge_jump_m", "color_sigma"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"rgbd noise: {name} = {value} must be finite and >= 0")
        if self.axial_sigma_m > 0.05:
            raise ValueError(f"rgbd noise: axial_sigma_m = {self.axial_sigma_m} m; metres are expected (5 cm at most)")
        low, high = self.color_gain_range
        if not 0 < low <= high:
            raise ValueError(f"rgbd noise: color_gain_range {self.color_gain_range} must be 0 < low <= high")


PRESETS = {
    "perfect": RgbdNoiseParameters(),  # the renderer's images as they are
    "kinect_v2": RgbdNoiseParameters(
        axial_sigma_m=0.0005,
        axial_sigma_per_m2=0.0015,
        lateral_sigma_px=0.5,
        flying_pixel_share=0.5,
        grazing_angle_deg=75.0,
        dark_intensity=0.08,
        dark_dropout_share=0.5,
        dropout_share=0.03,
        color_gain_range=(0.85, 1.15),
        color_sigma=4 / 255,
    ),
    "realsense_d435": RgbdNoiseParameters(
        axial_sigma_m=0.0005,
        axial_sigma_per_m2=0.0025,
        lateral_sigma_px=0.5,
        flying_pixel_share=0.05,
        edge_dropout_share=0.5,
        grazing_angle_deg=70.0,
        dark_intensity=0.05,
        dark_dropout_share=0.3,
        dropout_share=0.01,
        color_gain_range=(0.85, 1.15),
        color_sigma=3 / 255,
    ),
}


def noise_parameters(preset: str, overrides: dict[str, float] | None = None) -> RgbdNoiseParameters:
    """A preset's parameters with some replaced. Raises ValueError naming an unknown preset or parameter."""
    if preset not in PRESETS:
        raise ValueError(f"unknown rgbd noise preset {preset!r}; known: {', '.join(PRESETS)}")
    fields = {f.name for f in dataclasses.fields(RgbdNoiseParameters)}
    unknown = set(overrides or {}) - fields
    if unknown:
        raise ValueError(f"unknown rgbd noise parameter(s) {sorted(unknown)}; known: {sorted(fields)}")
    return dataclasses.replace(PRESETS[preset], **(overrides or {}))


def sensor_model(preset: str, overrides: dict[str, float] | None = None) -> RgbdNoiseParameters | None:
    """noise_parameters, or None for the "perfect" preset: the renderer's images stay as they are."""
    return None if preset == "perfect" else noise_parameters(preset, overrides)


def depth_edges(depth: np.ndarray, jump: float) -> tuple[np.ndarray, np.ndarray]:
    """Pixels whose depth steps by more than `jump` (m) to a 4-neighbour, and that neighbour's depth there
    (the farthest such one; NaN elsewhere)."""
    padded = np.pad(depth, 1, mode="edge")
    other = np.full(depth.shape, np.nan)
    with np.errstate(invalid="ignore"):  # inf - inf between two pixels that return nothing: no edge
        for dv, du in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            neighbour = padded[1 + dv : 1 + dv + depth.shape[0], 1 + du : 1 + du + depth.shape[1]]
            step = np.abs(neighbour - depth) > jump
            farther = step & ~(np.abs(other - depth) >= np.abs(neighbour - depth))
            other = np.where(farther, neighbour, other)
    return np.isfinite(other), other


def grazing(depth: np.ndarray, intrinsics: CameraInfo, max_angle_deg: float) -> np.ndarray:
    """Pixels whose surface (normal from the back-projected neighbours) is seen more than max_angle_deg off
    its ray."""
    if max_angle_deg >= 90.0:
        return np.zeros(depth.shape, bool)
    height, width = depth.shape
    # The ray through each pixel, (x, y, 1), and the back-projected point z (x, y, 1), per coordinate (float32:
    # a camera frame's worth at a time).
    x = ((np.arange(width) - intrinsics.center_x()) / intrinsics.focal_x()).astype(np.float32)[None, :]
    y = ((np.arange(height) - intrinsics.center_y()) / intrinsics.focal_y()).astype(np.float32)[:, None]
    z = depth.astype(np.float32)
    du = [np.gradient(c, axis=1) for c in (x * z, y * z, z)]
    dv = [np.gradient(c, axis=0) for c in (x * z, y * z, z)]
    normal = (du[1] * dv[2] - du[2] * dv[1], du[2] * dv[0] - du[0] * dv[2], du[0] * dv[1] - du[1] * dv[0])
    along_ray = normal[0] * x + normal[1] * y + normal[2]
    with np.errstate(invalid="ignore"):
        cosine = np.abs(along_ray) / (np.sqrt(sum(n**2 for n in normal)) * np.sqrt(x**2 + y**2 + 1) + 1e-12)
    return cosine < np.cos(np.radians(max_angle_deg))


def noisy_depth(
    depth: np.ndarray, rgb: np.ndarray, intrinsics: CameraInfo, p: RgbdNoiseParameters, rng: np.random.Generator
) -> np.ndarray:
    """H x W depth (m; inf or 0: nothing) as the sensor reports it; 0 where it reports nothing."""
    z = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0).astype(float)
    height, width = z.shape
    if p.lateral_sigma_px > 0:
        v, u = np.indices(z.shape)
        dv, du = rng.normal(0.0, p.lateral_sigma_px, size=(2, height, width))
        z = z[np.clip(np.rint(v + dv), 0, height - 1).astype(int), np.clip(np.rint(u + du), 0, width - 1).astype(int)]
    measured = z > 0
    # A surface seen at a grazing angle returns too little light; a flying pixel is no surface, but a mixture of
    # two (and a silhouette's rim, where flying pixels arise, is always seen at a grazing angle).
    too_grazing = grazing(np.where(measured, z, np.nan), intrinsics, p.grazing_angle_deg)
    edge, other = depth_edges(np.where(measured, z, np.inf), p.edge_jump_m)
    edge &= measured
    flying = edge & (rng.random(z.shape) < p.flying_pixel_share) & np.isfinite(other)
    mix = rng.random(z.shape)
    z = np.where(flying, z + mix * (np.nan_to_num(other, posinf=0.0) - z), z)
    sigma = p.axial_sigma_m + p.axial_sigma_per_m2 * z**2
    z = z + rng.normal(0.0, 1.0, size=z.shape) * sigma
    missing = ~measured | (too_grazing & ~flying)
    missing |= edge & ~flying & (rng.random(z.shape) < p.edge_dropout_share)
    if p.dark_dropout_share > 0:
        dark = rgb[..., :3].mean(axis=-1) / 255.0 < p.dark_intensity
        missing |= dark & (rng.random(z.shape) < p.dark_dropout_share)
    missing |= rng.random(z.shape) < p.dropout_share
    return np.where(missing, 0.0, z).astype(np.float32)


def noisy_color(rgba: np.ndarray, p: RgbdNoiseParameters, rng: np.random.Generator) -> np.ndarray:
    """H x W x 4 uint8 colour after the exposure gain and pixel noise (alpha kept)."""
    gain = rng.uniform(*p.color_gain_range, size=3)
    rgb = rgba[..., :3] / 255.0 * gain + rng.normal(0.0, p.color_sigma, size=rgba[..., :3].shape)
    out = rgba.copy()
    out[..., :3] = np.clip(np.rint(rgb * 255.0), 0, 255).astype(np.uint8)
    return out


class RgbdNoise(LeafSystem):
    """The renderer's colour and depth images as a real RGB-D sensor reports them.

    .. pydrake_system::

        name: RgbdNoise
        input_ports:
        - color_image
        - depth_image
        output_ports:
        - color_image
        - depth_image

    ``color_image`` (ImageRgba8U); ``depth_image`` (ImageDepth32F, m; 0 where the sensor returns nothing).
    The noise of each image is drawn from (seed, context time): outputs depend on the inputs and time only.
    """

    def __init__(self, intrinsics: CameraInfo, parameters: RgbdNoiseParameters, seed: int):
        super().__init__()
        self.intrinsics, self.parameters, self.seed = intrinsics, parameters, seed
        self.DeclareAbstractInputPort("color_image", AbstractValue.Make(ImageRgba8U()))
        self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F()))
        tickets = {self.time_ticket(), self.all_input_ports_ticket()}
        self.DeclareAbstractOutputPort(
            "color_image", lambda: AbstractValue.Make(ImageRgba8U()), self._calc_color, tickets
        )
        self.DeclareAbstractOutputPort(
            "depth_image", lambda: AbstractValue.Make(ImageDepth32F()), self._calc_depth, tickets
        )

    def _rng(self, context, stream: int) -> np.random.Generator:
        return np.random.default_rng([self.seed, stream, int(round(context.get_time() * 1e6))])

    def _calc_color(self, context, output):
        image = self.GetInputPort("color_image").Eval(context)
        noisy = noisy_color(np.asarray(image.data), self.parameters, self._rng(context, 0))
        result = ImageRgba8U(image.width(), image.height())
        result.mutable_data[:] = noisy
        output.set_value(result)

    def _calc_depth(self, context, output):
        image = self.GetInputPort("depth_image").Eval(context)
        rgb = np.asarray(self.GetInputPort("color_image").Eval(context).data)
        depth = noisy_depth(
            np.asarray(image.data)[..., 0], rgb, self.intrinsics, self.parameters, self._rng(context, 1)
        )
        result = ImageDepth32F(image.width(), image.height())
        result.mutable_data[:] = depth[..., None]
        output.set_value(result)
