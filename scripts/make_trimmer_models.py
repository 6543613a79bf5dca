"""Writes a folder of hedge trimmers as a user would bring them: plain meshes, one annotated.

python scripts/make_trimmer_models.py --out my_trimmers     # my_trimmers/train/*.obj + poses.yaml, test/*.obj
python scripts/make_trimmer_models.py --out my_trimmers --test 3 --seed 7

A second family to teach (after make_pot_models.py's pots), designed to be judged on, never tuned on: the
pipeline reaches it only through the user paths (`scripts/add_category.py --folder my_trimmers/train --poses
my_trimmers/train/poses.yaml --name trimmer`, then `--object-file my_trimmers/test/trimmer_test_0.obj`).

Each trimmer lies across the robot (its length along y_O): a flat motor body, a blade reaching out to the
robot's left (+y_O), an arched front handle over the body near the blade and a closed rear handle (a rounded
loop) behind the body, to the robot's right. Unlike a pot it is not half-turn symmetric. The left hand takes the
front arch's top from above and from the blade's side (its bar along x_O), the right hand the rear loop's upper
grip from above and from the robot's side (its bar along y_O). The object frame O has its origin at the centre
of the body's bottom face, z up. Only the first training trimmer's control poses go into poses.yaml (the
canonical model); every test trimmer gets `<name>.info.yaml` beside it (its true grasps and mass) for judging,
never for the pick.
"""

import argparse
from pathlib import Path

from diagrams.generation.objects.trimmer import CATEGORY, build, sample_parameters
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
