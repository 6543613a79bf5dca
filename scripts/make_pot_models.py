"""Writes a folder of two-handled cooking pots as a user would bring them: plain meshes, one annotated.

python scripts/make_pot_models.py --out my_pots             # my_pots/train/*.obj + poses.yaml, my_pots/test/*.obj
python scripts/make_pot_models.py --out my_pots --train 3 --test 1 --seed 7

The robot's pipeline never sees this script: the pots reach it only through the user paths
(`scripts/add_category.py --folder my_pots/train --poses my_pots/train/poses.yaml --name pot`, then
`--object-file my_pots/test/pot_test_0.obj`). It stands in for a user's CAD files.

Each pot: a lidded body (cylinder or slightly tapered), a knob on the lid, and two loop handles on the
wall rising above the rim, leaning outwards, one at +y and one at -y. The object frame O has its origin at
the centre of the bottom face, z up; the pots are half-turn symmetric about z. The left hand takes the
+y handle's apex from above and outside, the right hand the -y one. Only the first training pot's
control poses go into poses.yaml (the canonical model); every test pot gets `<name>.info.yaml`
beside it (its true grasps and mass) for judging, never for the pick.
"""

import argparse
from pathlib import Path

from diagrams.generation.objects.pot import CATEGORY, build, sample_parameters
from diagrams.generation.objects.user_folder import write_folder


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, required=True, help="folder to write train/ and test/ into")
    parser.add_argument("--train", type=int, default=8, help="training models (the first one annotated)")
    parser.add_argument("--test", type=int, default=3, help="test models, with their true grasps beside them")
    parser.add_argument("--seed", type=int, default=2018)
    args = parser.parse_args()
    write_folder(args.out, CATEGORY, sample_parameters, build, args.train, args.test, args.seed)


if __name__ == "__main__":
    main()
