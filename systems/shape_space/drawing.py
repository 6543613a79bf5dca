"""A figure of a shape space: its mean shape and first components, with the control poses' origins."""

from pathlib import Path

import numpy as np


def draw_space(space, path: Path, components: int = 3, spread: float = 2.0):
    """A figure of the space: the mean shape and each of the first components at -spread, +spread standard
    deviations, seen from the front (x_O right, z_O up) and from above, with the grasp frames' origins."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = min(components, space.latent_size)
    rows = [("mean", np.zeros(space.latent_size))]
    for k in range(shown):
        for sign in (-1, 1):
            latent = np.zeros(space.latent_size)
            latent[k] = sign * spread * np.sqrt(space.pca.variances[k])
            rows.append((f"component {k + 1}: {sign * spread:+.0f} sd", latent))
    size = (2.2 * len(rows), 4.6)
    figure, axes = plt.subplots(2, len(rows), figsize=size, squeeze=False, sharex="row", sharey="row")
    for column, (title, latent) in enumerate(rows):
        surface = space.reconstruct(latent)
        grasps = np.array([X.translation() for X in space.control_poses_at(latent).values()])
        for row, (u, v) in enumerate(((0, 2), (0, 1))):
            ax = axes[row, column]
            ax.scatter(surface[:, u], surface[:, v], s=0.2, c="0.4")
            ax.scatter(grasps[:, u], grasps[:, v], s=12, c=["tab:blue", "tab:blue", "tab:red", "tab:red"])
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
        axes[0, column].set_title(title, fontsize=8)
    axes[0, 0].set_ylabel("front (x, z)")
    axes[1, 0].set_ylabel("above (x, y)")
    title = f"{space.category}: mean and first components; control poses left blue, right red (outer: pre-grasps)"
    figure.suptitle(title, fontsize=9)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)
