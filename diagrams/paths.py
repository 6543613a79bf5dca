"""Where the repository's model files live (defined in systems/paths.py, below both packages)."""

from systems.paths import MODELS_DIR, PACKAGE_NAME, PACKAGE_XML, REPO_ROOT, SDF_DIR

__all__ = ["MODELS_DIR", "PACKAGE_NAME", "PACKAGE_XML", "REPO_ROOT", "SDF_DIR"]
