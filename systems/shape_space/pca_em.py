"""PCA by expectation-maximisation (Roweis, 1998; Tipping & Bishop's probabilistic PCA).

Used over the flattened CPD deformation fields of a category's training instances
(one row each): the fields are long (3 M numbers) and few, so EM on the
samples costs O(n d q) per iteration and never forms the d x d covariance.
"""

from dataclasses import dataclass

import numpy as np


@dataclass
class PcaModel:
    mean: np.ndarray  # d
    components: np.ndarray  # q x d, orthonormal rows, by decreasing variance
    variances: np.ndarray  # q, the data's variance along each component
    noise_variance: float  # per dimension, of what the components leave unexplained

    def encode(self, samples: np.ndarray) -> np.ndarray:
        """Latent coordinates (n x q) of samples (n x d)."""
        return (np.atleast_2d(samples) - self.mean) @ self.components.T

    def decode(self, latent: np.ndarray) -> np.ndarray:
        """Samples (n x d) at latent coordinates (n x q)."""
        return self.mean + np.atleast_2d(latent) @ self.components


def pca_em(
    samples: np.ndarray, components: int, iterations: int = 500, tolerance: float = 1e-9, seed: int = 0
) -> PcaModel:
    """Fits `components` principal components of `samples` (n x d) by EM.

    Raises:
        ValueError: fewer than 2 samples, non-finite values, or more components than the
            centred data can have (n - 1).
    """
    Y = np.asarray(samples, dtype=float)
    if Y.ndim != 2 or len(Y) < 2:
        raise ValueError(f"PCA needs an n x d array with n >= 2, got shape {Y.shape}")
    if not np.all(np.isfinite(Y)):
        raise ValueError("PCA samples contain NaN or infinite values")
    n, d = Y.shape
    if not 1 <= components <= min(n - 1, d):
        raise ValueError(f"{components} components requested; {n} samples of dimension {d} allow 1..{min(n - 1, d)}")
    mean = Y.mean(axis=0)
    Yc = Y - mean
    C = np.random.default_rng(seed).standard_normal((d, components))
    for _ in range(iterations):
        # E-step: latent coordinates of each sample; M-step: the subspace that best explains them.
        X = np.linalg.solve(C.T @ C, C.T @ Yc.T)
        C_next = np.linalg.solve(X @ X.T, X @ Yc).T  # Yc^T X^T (X X^T)^-1; X X^T is symmetric
        change = np.linalg.norm(C_next - C) / max(np.linalg.norm(C), 1e-300)
        C = C_next
        if change < tolerance:
            break
    # EM finds the subspace; an SVD inside it gives the ordered orthonormal axes.
    basis, _ = np.linalg.qr(C)
    projected = Yc @ basis
    _, singular, Vt = np.linalg.svd(projected, full_matrices=False)
    axes = Vt @ basis.T
    variances = singular**2 / (n - 1)
    residual = np.sum(Yc**2) / (n - 1) - variances.sum()
    noise = max(residual, 0.0) / max(d - components, 1)
    return PcaModel(mean, axes, variances, noise)
