"""Writes sdf/centauro/centauro.sdf from the kinematics in diagrams/generation/centauro_description.py."""

import argparse
from pathlib import Path

from diagrams.generation.centauro_description import centauro_sdf
from diagrams.paths import SDF_DIR


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=SDF_DIR / "centauro" / "centauro.sdf")
    args = parser.parse_args()
    args.out.write_text(centauro_sdf())
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
