"""Draws a use task's tool tip path, as the simulator measured it (the plant's object and its true tool frame), over
its target: a pour's spout tip over the container's opening, an aim's bit tip at the board's target.

Left: seen from above, the robot at the bottom (W's x up the page, its y to the left); the hold in colour.
Right: the tip's height over the run, the hold shaded, the target's height (the rim, the board's target) dashed.

python scripts/pick.py --task pour --json pour.json
python scripts/draw_use.py pour.json --out docs/use_pour.png
python scripts/draw_use.py evaluation.json --record 3 --out pour3.png    # one record of evaluate.py's --json
"""

import argparse
import json
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("outcome", type=Path, help="pick.py's --json of a pour or an aim, or evaluate.py's --json")
    parser.add_argument("--record", type=int, default=0, help="which record of evaluate.py's --json")
    parser.add_argument("--out", default="use.png", help="the figure (.png)")
    args = parser.parse_args()
    outcome = json.loads(args.outcome.read_text())
    if "records" in outcome:
        outcome = outcome["records"][args.record]
    use = outcome.get("use") or {}
    if not use.get("tip_path_W"):
        raise SystemExit(f"{args.outcome}: no tool tip path in it (pick.py --task pour|aim --json writes one)")
    path = np.array(use["tip_path_W"])
    t, tip = path[:, 0], path[:, 1:]
    hold = np.zeros(len(t), bool)
    if use.get("hold_t_s"):
        hold = (t >= use["hold_t_s"][0] - 1e-6) & (t <= use["hold_t_s"][1] + 1e-6)

    figure, (above, height) = plt.subplots(1, 2, figsize=(11, 5), gridspec_kw={"width_ratios": [1, 1.3]})
    above.plot(tip[:, 1], tip[:, 0], color="0.6", lw=1, label="the tip over the run")
    above.plot(tip[hold, 1], tip[hold, 0], ".", color="tab:blue", ms=4, label="during the hold")
    above.plot(tip[0, 1], tip[0, 0], "o", color="0.3", ms=5, label="where it started")
    if use["task"] == "pour":
        centre, radius = np.array(use["opening_centre_W"]), use["opening_radius_m"]
        for r, style in ((radius, "-"), (radius - 0.01, ":")):
            above.add_patch(plt.Circle(centre[1::-1], r, fill=False, ec="tab:brown", ls=style, lw=1.5))
        above.plot([], [], "-", color="tab:brown", label="the opening (dotted: 1 cm inside, the judge's limit)")
        target_z, target_label = centre[2], "the rim"
        figures = (
            f"spout tip {100 * use.get('tip_from_centre_m', np.nan):.1f} cm from the centre, outflow "
            f"{-np.degrees(use.get('outflow_elevation_rad', np.nan)):.1f} deg down (asked "
            f"{np.degrees(use['tilt_asked_rad']):.0f})"
        )
    else:
        target, normal = np.array(use["target_W"]), np.array(use["normal_W"])
        along = np.cross([0.0, 0.0, 1.0], normal)[:2] * 0.15  # the board's face, seen from above
        face = np.array([target[:2] - along, target[:2] + along])
        above.plot(face[:, 1], face[:, 0], "-", color="tab:brown", lw=3, label="the board's face")
        above.plot(target[1], target[0], "x", color="tab:red", ms=9, mew=2, label="the target")
        target_z, target_label = target[2], "the target"
        figures = (
            f"bit {np.degrees(use.get('axis_error_rad', np.nan)):.1f} deg off the normal, tip "
            f"{1000 * use.get('tip_to_target_m', np.nan):.1f} mm from the target"
        )
    above.set_aspect("equal", adjustable="datalim")
    above.invert_xaxis()
    above.set_xlabel("y in W (m): to the robot's left")
    above.set_ylabel("x in W (m): away from the robot")
    above.legend(fontsize=7, loc="best")

    height.plot(t, tip[:, 2], color="0.3", lw=1.2)
    if hold.any():
        height.axvspan(t[hold][0], t[hold][-1], color="tab:blue", alpha=0.15, label="the hold")
    height.axhline(target_z, ls="--", color="tab:brown", label=target_label)
    height.set_xlabel("simulated time (s)")
    height.set_ylabel("tip height in W (m)")
    height.legend(fontsize=8)
    verdict = "poured" if use["task"] == "pour" else "aimed"
    figure.suptitle(
        f"{use['task']}: {verdict if use.get(verdict) else 'not ' + verdict}; {figures}\n"
        f"{outcome.get('message', '')[:150]}",
        fontsize=9,
    )
    figure.tight_layout()
    figure.savefig(args.out, dpi=90)
    print(f"wrote {args.out}: {outcome.get('message', '')}")


if __name__ == "__main__":
    main()
