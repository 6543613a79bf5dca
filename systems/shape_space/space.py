"""A category's latent shape space (Rodriguez & Behnke 2018; paper §IV-A).

Offline: a canonical instance's surface points Y (in O) are deformed by CPD onto each
training instance; the displacement fields V_i = T_i - Y (flattened, 3 M numbers) go
through PCA-EM. A latent vector z gives the field V(z) = mean + z C, the shape
Y + V(z), and, interpolated off the points, the warp of any other point, such as the
canonical instance's grasp control poses.
"""

import functools
import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from systems.shape_space.cpd import FieldInterpolator, deformable_cpd, rigid_cpd
from systems.shape_space.pca_em import PcaModel, pca_em

# The control poses: the pre-grasp and grasp frame of each hand.
POSE_NAMES = ("left_pregrasp", "left_grasp", "right_pregrasp", "right_grasp")
FRAME_PROBE = 0.1  # m: radius of the star of points whose motion turns a control pose
# m: radius of the star of landmarks that ties the canonical grasp frames to an annotated
# instance's while its field is built.
LANDMARK_PROBE = 0.02


@dataclass
class ShapeSpace:
    category: str
    canonical_name: str
    canonical_points: np.ndarray  # M x 3, in the canonical O frame, metres
    pca: PcaModel  # over flattened M x 3 displacement fields
    beta: float  # width of the fields' Gaussian kernel, metres
    control_poses: dict[str, RigidTransform]  # canonical X_OG per POSE_NAMES entry
    instance_names: list[str]
    # A denser sampling of the canonical surface (K x 3, in O), warped for reconstructions.
    canonical_surface: np.ndarray

    @property
    def latent_size(self) -> int:
        return len(self.pca.variances)

    def field(self, latent: np.ndarray) -> np.ndarray:
        """Displacements (M x 3) of the canonical points at latent vector `latent`."""
        return self.pca.decode(latent)[0].reshape(-1, 3)

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
        M, K = len(self.canonical_points), len(self.canonical_surface)
        fields = np.vstack([self.pca.mean, self.pca.components]).reshape(-1, M, 3)  # (1 + q) x M x 3
        moved = self._interpolator(fields.transpose(1, 0, 2).reshape(M, -1), self.canonical_surface)
        moved = moved.reshape(K, -1, 3).transpose(1, 0, 2)  # (1 + q) x K x 3
        return self.canonical_surface + moved[0], moved[1:]

    def warp_points(self, latent: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Any points (K x 3, in the canonical O) carried by the field at `latent`."""
        points = np.atleast_2d(points)
        return points + self._interpolator(self.field(latent), points)

    @functools.cached_property
    def _interpolator(self) -> FieldInterpolator:
        return FieldInterpolator(self.canonical_points, self.beta)

    def warp_pose(self, latent: np.ndarray, X_OG: RigidTransform) -> RigidTransform:
        """A control pose carried by the field: its origin moves with the field, and it turns by the
        rotation that best fits (Kabsch) how the field moves a small star of points around it."""
        star = grasp_landmarks(X_OG, FRAME_PROBE)
        moved = self.warp_points(latent, star)
        turn, _ = Rotation.align_vectors(moved - moved.mean(axis=0), star - star.mean(axis=0))
        return RigidTransform(RotationMatrix(turn.as_matrix()) @ X_OG.rotation(), moved[0])

    def control_poses_at(self, latent: np.ndarray) -> dict[str, RigidTransform]:
        """All control poses at `latent`, in O.

        Each grasp is warped by the field; each pre-grasp keeps its canonical pose relative to its
        grasp (it lies off the surface, where the field fades out and says little).
        """
        poses = {}
        for side in ("left", "right"):
            X_OG = self.control_poses[f"{side}_grasp"]
            X_GP = X_OG.InvertAndCompose(self.control_poses[f"{side}_pregrasp"])
            poses[f"{side}_grasp"] = self.warp_pose(latent, X_OG)
            poses[f"{side}_pregrasp"] = poses[f"{side}_grasp"] @ X_GP
        return poses

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
                )
        except (KeyError, ValueError, OSError) as error:
            raise ValueError(f"{path} is not a shape space file ({error})") from None


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
    star = radius * np.vstack([np.zeros(3), np.eye(3), -np.eye(3)])
    return X_OG.multiply(star.T).T


def build_shape_space(
    category: str,
    clouds: dict[str, np.ndarray],
    control_poses: dict[str, dict[str, RigidTransform]],
    components: int = 8,
    canonical_points: int = 800,
    beta: float = 0.05,
    lam: float = 1.0,
    canonical: str | None = None,
    align: bool = False,
    landmarks: bool = True,
) -> ShapeSpace:
    """Builds the space from surface clouds (each in its own O frame) of a category's instances.

    Args:
        clouds: instance name -> N x 3 surface points.
        control_poses: instance name -> {POSE_NAMES entry: X_OG}; the canonical instance's are the
            space's. Where another instance has them too, its field must carry the canonical grasp
            frames onto its own (landmarks in CPD): the handles then correspond, which CPD's nearest
            surfaces alone often get wrong.
        components: latent size (clipped to the number of instances - 1).
        canonical_points: how many of the canonical cloud's points carry the field.
        beta, lam: the CPD fields' kernel width (m) and smoothness weight.
        canonical: the canonical instance's name; default: the medoid (needs its control poses).
        align: the clouds' frames differ (a user's folder): align each rigidly to the canonical first.
            Generated instances share the category's O frame and need no alignment.
        landmarks: let the other instances' control poses, where given, guide their fields.
    """
    if len(clouds) < 2:
        raise ValueError(f"a shape space needs at least 2 instances, got {len(clouds)}")
    if canonical is None:
        with_poses = {n: c for n, c in clouds.items() if n in control_poses}
        if not with_poses:
            raise ValueError("no instance has control poses: give them for at least the canonical model")
        canonical = choose_canonical(with_poses)
    surface = clouds[canonical]
    source = surface[np.linspace(0, len(surface) - 1, min(canonical_points, len(surface))).astype(int)]
    fields = []
    for name, cloud in clouds.items():
        if name == canonical:
            fields.append(np.zeros(source.size))
            continue
        guide = None
        if landmarks and name in control_poses:
            targets = np.vstack([grasp_landmarks(control_poses[name][f"{side}_grasp"]) for side in ("left", "right")])
            sources = np.vstack(
                [grasp_landmarks(control_poses[canonical][f"{side}_grasp"]) for side in ("left", "right")]
            )
            guide = (sources, targets)
        if align:
            rigid = rigid_cpd(cloud, source, w=0.05)
            aligned = rigid.transformed
            if guide is not None:
                guide = (guide[0], rigid.s * guide[1] @ rigid.R.T + rigid.t)
        else:
            aligned = cloud
        result = deformable_cpd(source, aligned, beta=beta, lam=lam, w=0.05, max_iterations=150, landmarks=guide)
        logging.info(
            "%s: CPD %d iterations, Chamfer after %.4f m", name, result.iterations, chamfer(result.transformed, aligned)
        )
        fields.append((result.transformed - source).ravel())
    pca = pca_em(np.array(fields), min(components, len(clouds) - 1))
    return ShapeSpace(category, canonical, source, pca, beta, control_poses[canonical], list(clouds), surface)
