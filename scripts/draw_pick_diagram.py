"""Draws the pick diagram (Drake's GenerateGraphviz): its stages and their ports, one level deep.

python scripts/draw_pick_diagram.py --dot docs/pick_diagram.dot --png docs/pick_diagram.png   # PNG needs graphviz's dot
"""

import argparse
import shutil
import subprocess
from pathlib import Path

from diagrams.autonomous_pick import MakePickDiagram
from diagrams.scenario import load_scenario


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dot", type=Path, required=True, help="the Graphviz source to write")
    parser.add_argument("--png", type=Path, help="also render it (needs graphviz: apt-get install graphviz)")
    parser.add_argument("--oracle", action="store_true", help="the ground-truth pick instead")
    args = parser.parse_args()
    diagram = MakePickDiagram(load_scenario(), perception="ground_truth" if args.oracle else "camera")
    args.dot.write_text(diagram.GetGraphvizString(max_depth=1))
    print(f"wrote {args.dot}")
    if args.png:
        if shutil.which("dot") is None:
            raise SystemExit("no 'dot' here to render the PNG: apt-get install graphviz")
        subprocess.run(["dot", "-Tpng", "-Gdpi=70", str(args.dot), "-o", str(args.png)], check=True)
        print(f"wrote {args.png}")


if __name__ == "__main__":
    main()
