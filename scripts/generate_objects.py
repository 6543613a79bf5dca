"""Generates object instances (meshes, convex collision pieces, SDF, ground-truth grasps).

Examples:
  python scripts/generate_objects.py                       # the fixed train/test instances
  python scripts/generate_objects.py --category drill --extra 5 --out /tmp/drills
"""

import argparse
import time
from pathlib import Path

from diagrams.generation.objects import catalog


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--category",
        choices=sorted(catalog.CATEGORIES),
        action="append",
        help="category to generate (repeatable; default: all)",
    )
    parser.add_argument(
        "--extra", type=int, default=0, help="instead of the fixed instances, generate this many extra_<i> instances"
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output root (default: sdf/objects); instances go to <out>/<category>/<name>",
    )
    args = parser.parse_args()
    for category in args.category or sorted(catalog.CATEGORIES):
        names = [f"extra_{i}" for i in range(args.extra)] if args.extra else catalog.instance_names(category)
        for name in names:
            start = time.perf_counter()
            instance = catalog.generate(category, name)
            directory = (args.out / category / name) if args.out else catalog.instance_directory(category, name)
            instance.write(directory)
            print(f"{category}/{name}: {directory} ({time.perf_counter() - start:.2f} s)")


if __name__ == "__main__":
    main()
