"""Writes the held-out shop family as a user would bring it: OBJ meshes of cans and drills with the handles people's
own have, never tuned on (diagrams/generation/objects/shop_held_out.py says what each design is).

python scripts/make_shop_held_out.py --out shop_held_out    # shop_held_out/<category>/<name>.obj and sidecars

Beside each OBJ: `<name>.info.yaml` (its true grasps and mass, for judging; the pick never reads it) and
`<name>.parts.npz` (each face's part role, for judging a part segmentation).
"""

import argparse
from pathlib import Path

from diagrams.generation.objects import shop_held_out


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True, help="folder to write <category>/*.obj into")
    args = parser.parse_args()
    for category in shop_held_out.DESIGNS:
        for path in shop_held_out.write(category, args.out / category):
            print(f"wrote {path}")


if __name__ == "__main__":
    main()
