"""Where the repository's files live, independent of the working directory, and the user's cache.

A module below both systems/ and diagrams/: the cores take their file locations from here.
"""

import os
from pathlib import Path

import numpy as np

REPO_ROOT = Path(__file__).resolve().parent.parent
SDF_DIR = REPO_ROOT / "sdf"
MODELS_DIR = REPO_ROOT / "models"
PACKAGE_XML = SDF_DIR / "package.xml"
PACKAGE_NAME = "dualarm"


def cache_dir() -> Path:
    """The user's cache for derived data (generated objects, IK seed tables, templates)."""
    root = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(root) / "dualarm"


def save_npz_atomically(path: Path, **arrays: np.ndarray) -> None:
    """np.savez_compressed to `path` through a temporary file: a concurrent reader sees the whole file or none."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_suffix(f".{os.getpid()}.tmp.npz")
    np.savez_compressed(partial, **arrays)
    os.replace(partial, path)
