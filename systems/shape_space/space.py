"""A category's latent shape space (Rodriguez & Behnke 2018; paper §IV-A).

Offline: a canonical instance's surface points Y (in O) are deformed by CPD onto each
training instance, giving displacement fields V_i = T_i - Y (3 M numbers). Each PCA-EM
sample is V_i followed by how the instance's grasp frames sit against the canonical
ones (the moves of a small star of points about each grasp frame, scaled by
`grasp_weight`): a latent vector z then decodes the field V(z), the shape Y + V(z),
and the grasp frames together. A field carries a grasp frame poorly (the frames lie
off the surface, where CPD's correspondences slide along handles); a training
instance's true frames, learnt beside its field, do not.
"""

import functools
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation
from tqdm import tqdm

from systems.shape_space.cpd import FieldInterpolator, deformable_cpd, rigid_cpd, thinned
from systems.shape_space.pca_em import PcaModel, pca_em
from systems.shape_space.propagation import propagated_poses
from systems.shape_space.tool_frame import ToolFrame

# The control poses: the pre-grasp and grasp frame of each hand.
POSE_NAMES = ("left_pregrasp", "left_grasp", "right_pregrasp", "right_grasp")
GRASP_NAMES = ("left_grasp", "right_grasp")
FRAME_PROBE = 0.1  # m: radius of the star of points that stands for a grasp frame in the latent space
# m: radius of the star of landmarks that ties the canonical grasp frames to an annotated
# instance's while its field is built.
LANDMARK_PROBE = 0.02
# m: kernel width that carries the field from the canonical points onto the dense surface. Narrower
# than the fields' own beta, whose smoothing blurs thin parts (drill handles).
SURFACE_WARP_WIDTH = 0.02
# The default spread (standard deviation of the log) of the stretches that scaled copies of a few models get, per axis
# of C, and the seed they are drawn from (build_shape_space(scaled_copies=..., copy_spread=...)).
SCALED_COPY_SIGMA = 0.1
SCALED_COPY_SEED = 0
# The tool's surface (ShapeSpace.tool_at): the canonical surface within TOOL_RADIUS (m) of the last TOOL_REACH (m) of
# the tool's axis up to its tip; its far end, the points within TOOL_END_BAND (m) of the farthest along the axis.
TOOL_RADIUS = 0.03
TOOL_REACH = 0.12
TOOL_END_BAND = 0.005
MIN_TOOL_POINTS = 10
# Where every annotated model's tool axis lies within this of the canonical one's in the category frame (deg), the
# axis is the category's own and does not turn with the fitted surface (ShapeSpace.tool_turns).
TOOL_AXIS_SAME_DEG = 1.0


@dataclass
class ShapeSpace:
    category: str
    canonical_name: str
    canonical_points: np.ndarray  # M x 3, in the canonical O frame, metres
    pca: PcaModel  # over [flattened M x 3 displacement field, grasp_weight * flattened grasp stars' moves]
    beta: float  # width of the fields' Gaussian kernel, metres
    control_poses: dict[str, RigidTransform]  # canonical X_OG per POSE_NAMES entry
    instance_names: list[str]
    # A denser sampling of the canonical surface (K x 3, in O), warped for reconstructions.
    canonical_surface: np.ndarray
    grasp_weight: float  # how the grasp stars' moves are scaled in the PCA samples
    # Control poses carried from the canonical model onto instances that had none ({name: {pose: X_CG}}, in the
    # canonical frame C), while the space was built; not saved.
    propagated: dict = dataclass_field(default_factory=dict)
    tool: ToolFrame | None = None  # the canonical tool frame, in O; None: the category has none
    # Whether the tool's axis turns as the fitted tool surface turns (tool_at). False where the annotated models'
    # axes all agreed in O (tool_axes_agree: a drill's bit along its housing); True where they differ (a can's
    # spout) or only the canonical model's was given.
    tool_turns: bool = True

    @property
    def latent_size(self) -> int:
        return len(self.pca.variances)

    @property
    def field_size(self) -> int:
        return self.canonical_points.size

    def field_basis(self) -> tuple[np.ndarray, np.ndarray]:
        """The field at z = 0 (M x 3) and what each latent component adds to it (q x M x 3)."""
        M, n = len(self.canonical_points), self.field_size
        return self.pca.mean[:n].reshape(M, 3), self.pca.components[:, :n].reshape(-1, M, 3)

    def field(self, latent: np.ndarray) -> np.ndarray:
        """Displacements (M x 3) of the canonical points at latent vector `latent`."""
        return self.pca.decode(latent)[0, : self.field_size].reshape(-1, 3)

    def shape(self, latent: np.ndarray) -> np.ndarray:
        """The deformed canonical points (M x 3, in O) at `latent`."""
        return self.canonical_points + self.field(latent)

    def reconstruct(self, latent: np.ndarray) -> np.ndarray:
        """The whole inferred surface (K x 3, in O): the dense canonical surface carried by the field."""
        at_zero, per_component = self._surface_warp
        return at_zero + np.tensordot(np.ravel(latent), per_component, axes=1)

    @functools.cached_property
    def _surface_warp(self) -> tuple[np.ndarray, np.ndarray]:
        """reconstruct() is affine in the latent vector: the surface at z = 0 (K x 3), and what each
        latent component adds to it (q x K x 3). Computed once, not per registration."""
        mean, components = self.field_basis()
        M, K = len(self.canonical_points), len(self.canonical_surface)
        fields = np.concatenate([mean[None], components])  # (1 + q) x M x 3
        interpolate = FieldInterpolator(self.canonical_points, SURFACE_WARP_WIDTH)
        moved = interpolate(fields.transpose(1, 0, 2).reshape(M, -1), self.canonical_surface)
        moved = moved.reshape(K, -1, 3).transpose(1, 0, 2)  # (1 + q) x K x 3
        return self.canonical_surface + moved[0], moved[1:]

    def tool_at(self, latent: np.ndarray) -> ToolFrame | None:
        """The tool frame at `latent`, in O (None where the space has none), from the tool's surface there: the
        canonical surface within TOOL_RADIUS of the last TOOL_REACH of the tool's axis (the spout's end and rose, a
        drill's chuck) is carried by the field, the axis turned as that surface turned (its best rigid fit), and the
        tip put as far beyond the surface's far end, along the axis, as the canonical tip lies beyond its own. Where the
        axis does not turn (tool_turns False), it stays the canonical one from the end's centre (the end face as the
        surface lies): the warp of a short tool's surface turns it by a few degrees that no annotated model had (a
        drill's chuck: 1.9 deg median on extra_201-208 turned, 0.4 deg kept, kinect_v2 views)."""
        if self.tool is None:
            return None
        reference = self.canonical_surface[self._tool_points]
        at_zero, per_component = self._tool_warp
        moved = at_zero + np.tensordot(np.ravel(latent), per_component, axes=1)
        turn, _ = Rotation.align_vectors(moved - moved.mean(axis=0), reference - reference.mean(axis=0))
        turned = turn.apply(self.tool.axis)  # the fitted surface's own axis: its end face lies across it
        along = moved @ turned
        end = moved[along >= along.max() - TOOL_END_BAND].mean(axis=0)
        axis = turned if self.tool_turns else self.tool.axis
        return ToolFrame(end + (along.max() - end @ turned + self.tool_beyond) * axis, axis)

    @functools.cached_property
    def _tool_warp(self) -> tuple[np.ndarray, np.ndarray]:
        """The tool's surface as reconstruct() carries it: at z = 0, and what each latent component adds."""
        at_zero, per_component = self._surface_warp
        return at_zero[self._tool_points], per_component[:, self._tool_points]

    @functools.cached_property
    def _tool_points(self) -> np.ndarray:
        """Which canonical surface points (K bools) make up the tool's surface (tool_at)."""
        return tool_surface(self.canonical_surface, self.tool)

    @functools.cached_property
    def tool_beyond(self) -> float:
        """How far (m) the canonical tip lies beyond its tool surface's far end, along the axis (a drill's bit)."""
        surface = self.canonical_surface[self._tool_points]
        return float(self.tool.tip @ self.tool.axis - np.max(surface @ self.tool.axis))

    def control_poses_at(self, latent: np.ndarray) -> dict[str, RigidTransform]:
        """All control poses at `latent`, in O.

        Each grasp frame is the rigid fit to its decoded star; each pre-grasp keeps its canonical pose
        relative to its grasp.
        """
        decoded = self.pca.decode(latent)[0, self.field_size :] / self.grasp_weight
        moves = decoded.reshape(len(GRASP_NAMES), -1, 3)
        poses = {}
        for name, move in zip(GRASP_NAMES, moves, strict=True):
            X_OG = self.control_poses[name]
            X_GP = X_OG.InvertAndCompose(self.control_poses[name.replace("grasp", "pregrasp")])
            poses[name] = fit_frame(grasp_landmarks(X_OG, FRAME_PROBE) + move)
            poses[name.replace("grasp", "pregrasp")] = poses[name] @ X_GP
        return {name: poses[name] for name in POSE_NAMES}

    def save(self, path: Path):
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(
            path,
            category=self.category,
            canonical_name=self.canonical_name,
            canonical_points=self.canonical_points.astype(np.float32),
            mean=self.pca.mean.astype(np.float32),
            components=self.pca.components.astype(np.float32),
            variances=self.pca.variances,
            noise_variance=self.pca.noise_variance,
            beta=self.beta,
            control_poses=np.stack([self.control_poses[n].GetAsMatrix4() for n in POSE_NAMES]),
            instance_names=np.array(self.instance_names),
            canonical_surface=self.canonical_surface.astype(np.float32),
            grasp_weight=self.grasp_weight,
            **({"tool_tip": self.tool.tip, "tool_axis": self.tool.axis} if self.tool else {}),
            tool_turns=self.tool_turns,
        )

    @staticmethod
    def load(path: Path) -> "ShapeSpace":
        """Raises FileNotFoundError naming the script that builds the file, ValueError if it is not a space."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no shape space; run scripts/build_shape_space.py")
        try:
            with np.load(path) as data:
                pca = PcaModel(
                    data["mean"].astype(float),
                    data["components"].astype(float),
                    data["variances"],
                    float(data["noise_variance"]),
                )
                return ShapeSpace(
                    str(data["category"]),
                    str(data["canonical_name"]),
                    data["canonical_points"].astype(float),
                    pca,
                    float(data["beta"]),
                    {n: RigidTransform(m) for n, m in zip(POSE_NAMES, data["control_poses"], strict=True)},
                    [str(n) for n in data["instance_names"]],
                    data["canonical_surface"].astype(float),
                    float(data["grasp_weight"]),
                    tool=ToolFrame(data["tool_tip"], data["tool_axis"]) if "tool_tip" in data else None,
                    tool_turns=bool(data["tool_turns"]) if "tool_turns" in data else True,
                )
        except (KeyError, ValueError, OSError) as error:
            raise ValueError(
                f"{path} is not a shape space file of this version ({error}); "
                "rebuild it with scripts/build_shape_space.py"
            ) from None


def tool_surface(points: np.ndarray, tool: ToolFrame) -> np.ndarray:
    """Which of a model's surface points (N x 3, in its frame) make up its tool's surface (N bools): those within
    TOOL_RADIUS of the last TOOL_REACH of the tool's axis up to its tip.

    Raises:
        ValueError: fewer than MIN_TOOL_POINTS of them (the tool frame lies off the model).
    """
    offset = points - tool.tip
    along = np.clip(offset @ -tool.axis, 0.0, TOOL_REACH)
    near = np.linalg.norm(offset + along[:, None] * tool.axis, axis=1) < TOOL_RADIUS
    if np.count_nonzero(near) < MIN_TOOL_POINTS:
        raise ValueError(
            f"the tool frame (tip {np.round(tool.tip, 3).tolist()} m) lies off the model: {np.count_nonzero(near)} of "
            f"its surface points within {100 * TOOL_RADIUS:.0f} cm of the last {100 * TOOL_REACH:.0f} cm of its axis "
            f"(at least {MIN_TOOL_POINTS})"
        )
    return near


def chamfer(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric Chamfer distance: the mean of both directions' mean nearest-point distances (m)."""
    return 0.5 * float(cKDTree(b).query(a)[0].mean() + cKDTree(a).query(b)[0].mean())


def choose_canonical(clouds: dict[str, np.ndarray]) -> str:
    """The medoid: the instance with the smallest summed Chamfer distance to all others."""
    names = list(clouds)
    cost = {a: sum(chamfer(clouds[a], clouds[b]) for b in names if b != a) for a in names}
    return min(cost, key=cost.get)


def grasp_landmarks(X_OG: RigidTransform, radius: float = LANDMARK_PROBE) -> np.ndarray:
    """A grasp frame as 7 points (in O): its origin and +-radius along each of its axes."""
    return X_OG.multiply(_star(radius).T).T


def _star(radius: float) -> np.ndarray:
    return radius * np.vstack([np.zeros(3), np.eye(3), -np.eye(3)])


def fit_frame(star: np.ndarray) -> RigidTransform:
    """The frame (X_OG) whose grasp_landmarks best fit (Kabsch) a moved star of 7 points."""
    reference = _star(1.0)  # centred, like any star: its origin is its mean
    turn, _ = Rotation.align_vectors(star - star.mean(axis=0), reference)
    return RigidTransform(RotationMatrix(turn.as_matrix()), star.mean(axis=0))


def build_shape_space(
    category: str,
    clouds: dict[str, np.ndarray],
    control_poses: dict[str, dict[str, RigidTransform]],
    components: int = 8,
    canonical_points: int = 800,
    beta: float = 0.05,
    lam: float = 1.0,
    canonical: str | None = None,
    align: str = "none",
    landmarks: bool = True,
    propagate: bool = True,
    target_points: int = 2000,
    grasp_weight: float = 10.0,
    initial_sigma: float = 0.02,
    scaled_copies: int = 0,
    copy_spread: float = SCALED_COPY_SIGMA,
    tools: dict[str, ToolFrame] | None = None,
) -> ShapeSpace:
    """Builds the space from surface clouds (each in its own O frame) of a category's instances.

    Args:
        clouds: instance name -> N x 3 surface points. The canonical one's, all of them, is the
            surface that reconstructions warp: give it dense.
        control_poses: instance name -> {POSE_NAMES entry: X_OG}; the canonical instance's are the
            space's. Where another instance has them too, they are its grasp frames in the space, and
            its field must carry the canonical grasp frames onto them (landmarks in CPD): the handles
            then correspond, which CPD's nearest surfaces alone often get wrong. Elsewhere the
            instance's field carries the canonical frames.
        components: latent size (clipped to the number of instances - 1).
        canonical_points: how many of the canonical cloud's points carry the field.
        beta, lam: the CPD fields' kernel width (m) and smoothness weight.
        canonical: the canonical instance's name; default: the medoid (needs its control poses).
        align: how each cloud is moved onto the canonical one before its field is built (ALIGNMENTS):
            "none" where the clouds share an upright frame (generated instances, most scans and exports);
            "vertical" where each has its own heading and origin but z is up: turned about z and shifted in x, y,
            its bottom onto the canonical's (both stand on a table); "rigid" where even that differs.
        landmarks: let the other instances' control poses, where given, guide their fields and be
            their grasp frames.
        propagate: (with landmarks) where an instance has no control poses, carry the canonical ones onto it
            (propagation.propagated_poses) and use those as if given; else its field carries them.
        target_points: at most this many points of each other cloud are CPD's target.
        grasp_weight: scale of the grasp stars' moves (m) against the fields' (m) in the PCA samples;
            > 1 spends the latent components on what moves the grasps (docs/history/registration_parameters.md).
        initial_sigma: the CPD mixture's starting width (m). The clouds share the O frame (or are aligned
            first), so the fields start local: from the clouds' whole spread, CPD slides the points along
            the surface and the latent components learn that noise (docs/history/registration_parameters.md).
        scaled_copies: beside each instance, this many copies of it stretched along C's axes (scaled_copy), each
            a sample of its own: a few models then still span the proportions a category varies in.
        copy_spread: the standard deviation of the log of each copy's stretch per axis (drawn from a fixed seed:
            the same draws scaled).
        tools: instance name -> its tool frame in its O (the canonical one's is the space's; none: no tool frame).
    """
    if len(clouds) < 2:
        raise ValueError(f"a shape space needs at least 2 instances, got {len(clouds)}")
    if scaled_copies < 0:
        raise ValueError(f"scaled_copies must be 0 or more, got {scaled_copies}")
    if scaled_copies and not copy_spread > 0:
        raise ValueError(f"copy_spread must be positive, got {copy_spread}")
    if canonical is None:
        with_poses = {n: thinned(c, target_points) for n, c in clouds.items() if n in control_poses}
        if not with_poses:
            raise ValueError("no instance has control poses: give them for at least the canonical model")
        canonical = choose_canonical(with_poses)
    surface = clouds[canonical]
    source = thinned(surface, canonical_points)
    canonical_grasps = control_poses[canonical]
    canonical_stars = _stars(canonical_grasps, FRAME_PROBE)
    options = {"beta": beta, "lam": lam, "w": 0.05, "max_iterations": 150, "initial_sigma2": initial_sigma**2}
    total = len(clouds) * (1 + scaled_copies) - 1  # every model and copy but the canonical itself
    bar = tqdm(total=total, unit="model", desc=f"{category}: CPD to each", dynamic_ncols=True)

    def sample_of(name: str, target: np.ndarray, grasps_C: dict | None, fit) -> np.ndarray:
        """A PCA sample: the field (fit) from the canonical points onto target (C), and the grasp stars' moves."""
        if grasps_C is None:  # the field carries the canonical frames
            result = fit()
            stars = result.warp(canonical_stars)
        else:  # the frames guide the field (handle onto handle) and are learnt beside it
            result = fit(landmarks=(_stars(canonical_grasps, LANDMARK_PROBE), _stars(grasps_C, LANDMARK_PROBE)))
            stars = _stars(grasps_C, FRAME_PROBE)
        chamfer_mm = 1000 * chamfer(result.transformed, target)
        bar.set_postfix_str(f"{name}: {result.iterations} iterations, Chamfer {chamfer_mm:.1f} mm")
        bar.update()
        return np.concatenate([(result.transformed - source).ravel(), grasp_weight * (stars - canonical_stars).ravel()])

    samples, propagated, tool_axes = [], {}, []  # tool_axes: the other annotated models' tool axes, in C
    rng = np.random.default_rng(SCALED_COPY_SEED)
    foot = np.array([*surface[:, :2].mean(axis=0), surface[:, 2].min()])  # the copies' fixed point, in C
    for name, cloud in clouds.items():
        if name == canonical:
            samples.append(np.zeros(source.size + canonical_stars.size))
            cloud_C, given = surface, canonical_grasps
        else:
            X_CF = alignment(thinned(cloud, target_points), source, align)  # the model's frame F in the canonical's C
            cloud_C = X_CF.multiply(cloud.T).T  # all of it: the propagation's ICP fits onto it
            given = {n: X_CF @ X_FG for n, X_FG in control_poses[name].items()} if name in control_poses else None
            if name in (tools or {}):
                tool_axes.append(X_CF.rotation().multiply(tools[name].axis))
        versions = [] if name == canonical else [(name, cloud_C, given)]
        for k in range(scaled_copies):
            scale = np.exp(rng.normal(0.0, copy_spread, 3))
            versions.append((f"{name} stretched {k + 1}", *scaled_copy(cloud_C, given, scale, foot)))
        for version, points_C, grasps_C in versions:
            target = thinned(points_C, target_points)
            fit = functools.partial(deformable_cpd, source, target, **options)
            if not landmarks:
                grasps_C = None
            elif grasps_C is None and propagate:  # carried from the canonical, each copy on its own
                grasps_C = propagated_poses(surface, canonical_grasps, fit(), points_C)
                if version == name:
                    propagated[name] = grasps_C
            samples.append(sample_of(version, target, grasps_C, fit))
    bar.close()
    pca = pca_em(np.array(samples), min(components, len(samples) - 1))
    tool = (tools or {}).get(canonical)
    if tool is not None:
        tool_surface(surface, tool)  # (a tool frame off the canonical model: said now, not at every registration)
    return ShapeSpace(
        category,
        canonical,
        source,
        pca,
        beta,
        canonical_grasps,
        list(clouds),
        surface,
        grasp_weight,
        propagated,
        tool,
        tool_turns=tool is None or not tool_axes_agree(tool.axis, tool_axes),
    )


def tool_axes_agree(canonical: np.ndarray, others: list[np.ndarray]) -> bool:
    """Whether the other annotated models' tool axes (unit, in the category frame) all lie within TOOL_AXIS_SAME_DEG
    of the canonical one's; none given says nothing about how the category's vary (False)."""
    if not others:
        return False
    return bool(np.all(np.asarray(others) @ canonical >= np.cos(np.radians(TOOL_AXIS_SAME_DEG))))


def scaled_poses(
    poses_O: dict[str, RigidTransform], scale: np.ndarray, about: np.ndarray | None = None
) -> dict[str, RigidTransform]:
    """Control poses (X_OG, O) of a shape scaled by `scale` (3,) along O's axes about the point `about` (3, O):
    each grasp frame's origin scaled, its axes kept; each pre-grasp keeps its pose relative to its grasp. About O's
    origin by default."""
    about = np.zeros(3) if about is None else about
    out = {}
    for name in GRASP_NAMES:
        X_OG = poses_O[name]
        X_GP = X_OG.InvertAndCompose(poses_O[name.replace("grasp", "pregrasp")])
        out[name] = RigidTransform(X_OG.rotation(), about + scale * (X_OG.translation() - about))
        out[name.replace("grasp", "pregrasp")] = out[name] @ X_GP
    return {name: out[name] for name in poses_O}


def scaled_copy(
    points_C: np.ndarray, poses_C: dict[str, RigidTransform] | None, scale: np.ndarray, foot: np.ndarray
) -> tuple[np.ndarray, dict[str, RigidTransform] | None]:
    """A model (N x 3, in C) stretched by `scale` (3,) along C's axes about `foot` (3, in C: under the canonical
    model's centroid, on the table), and its control poses with it where given (scaled_poses, as the registrar's
    scale treats them)."""
    stretched = foot + scale * (points_C - foot)
    return stretched, None if poses_C is None else scaled_poses(poses_C, scale, foot)


ALIGNMENTS = ("none", "vertical", "rigid")
VERTICAL_STARTS = 8  # headings tried by the "vertical" alignment, evenly spaced


def alignment(cloud: np.ndarray, canonical: np.ndarray, how: str) -> RigidTransform:
    """The rigid move X_CF that takes `cloud` (in its frame F) onto `canonical` (in C), by `how` (ALIGNMENTS)."""
    if how == "none":
        return RigidTransform()
    if how == "rigid":
        result = rigid_cpd(cloud, canonical, w=0.05)
        return RigidTransform(RotationMatrix(result.R), result.t)
    if how != "vertical":
        raise ValueError(f"unknown alignment {how!r}; one of {ALIGNMENTS}")
    best, X_best = None, None
    lift = np.percentile(canonical[:, 2], 1) - np.percentile(cloud[:, 2], 1)  # bottom onto bottom
    for heading in 2 * np.pi * np.arange(VERTICAL_STARTS) / VERTICAL_STARTS:
        X_start = RigidTransform(RotationMatrix.MakeZRotation(heading), [0.0, 0.0, lift])
        result = rigid_cpd(X_start.multiply(cloud.T).T, canonical, w=0.05, upright=True)
        if best is None or result.sigma2 < best.sigma2:
            best, X_best = result, RigidTransform(RotationMatrix(result.R), result.t) @ X_start
    return X_best


def _stars(poses: dict[str, RigidTransform], radius: float) -> np.ndarray:
    """Both grasp frames' grasp_landmarks, stacked (14 x 3)."""
    return np.vstack([grasp_landmarks(poses[n], radius) for n in GRASP_NAMES])
