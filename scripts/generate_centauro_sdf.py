"""Writes sdf/centauro/centauro.sdf (the torso on its yaw joint) and centauro_torso_locked.sdf (the torso
welded) from the kinematics in diagrams/generation/centauro_description.py."""

import argparse
from pathlib import Path

from diagrams.generation.centauro_description import centauro_sdf, sdf_name
from diagrams.paths import SDF_DIR


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out-dir", type=Path, default=SDF_DIR / "centauro")
    args = parser.parse_args()
    for torso in (True, False):
        path = args.out_dir / sdf_name(torso)
        path.write_text(centauro_sdf(torso))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
