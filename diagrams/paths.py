"""Where the repository's model files live, independent of the working directory."""

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
SDF_DIR = REPO_ROOT / "sdf"
MODELS_DIR = REPO_ROOT / "models"
PACKAGE_XML = SDF_DIR / "package.xml"
PACKAGE_NAME = "dualarm"
