"""Draws a cleared table from above: where each familiar object stood and where it ended (its true footprint, from
the simulator), the drop zone, and the order the robot took them in.

python scripts/pick.py --task clear --scene clutter --clutter-index 3 --json clear.json
python scripts/draw_clear.py clear.json --out docs/clear.png
python scripts/draw_clear.py report.jsonl --record 4 --out table4.png     # one table of an evaluation's records
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
    parser.add_argument("outcome", type=Path, help="pick.py's --json of a clear, or an evaluation's records (.jsonl)")
    parser.add_argument("--record", type=int, default=0, help="which record of a .jsonl file")
    parser.add_argument("--out", default="clear.png", help="the figure (.png)")
    args = parser.parse_args()
    text = args.outcome.read_text()
    outcome = json.loads(text.splitlines()[args.record]) if args.outcome.suffix == ".jsonl" else json.loads(text)
    clear = outcome.get("clear") or {}
    if "zone" not in clear or "objects" not in clear:
        raise SystemExit(f"{args.outcome}: no judged clear in it (pick.py --task clear --json writes one)")

    figure, axes = plt.subplots(figsize=(7, 7))
    # Seen from above with the robot at the bottom: W's x up the page, its y to the left (drawn as (y, x)).
    centre, size = np.array(clear["zone"]["centre_W"])[::-1], np.array(clear["zone"]["size"])[::-1]
    low = centre - 0.5 * size
    axes.add_patch(plt.Rectangle(low, *size, fill=True, color="0.92", zorder=0))
    axes.add_patch(plt.Rectangle(low, *size, fill=False, ec="0.3", lw=1.5, zorder=1))
    axes.text(*(centre + [0.0, 0.5 * size[1] - 0.02]), "drop zone", fontsize=9, color="0.3", ha="center")
    order = _order(clear)
    for k, judged in enumerate(clear["objects"]):
        start, end = (np.array(judged[key])[:, ::-1] for key in ("start_footprint_W", "end_footprint_W"))
        colour = "tab:green" if judged["cleared"] else "tab:red"
        axes.fill(*start.T, fc="none", ec="0.5", ls="--", lw=1)
        axes.fill(*end.T, fc=colour, alpha=0.35, ec=colour, lw=1.5)
        a, b = start.mean(axis=0), end.mean(axis=0)
        if np.linalg.norm(b - a) > 0.02:
            axes.annotate("", b, a, arrowprops={"arrowstyle": "->", "color": colour, "lw": 1.5})
        label = f"{order[k]}. " if order.get(k) else ""
        axes.text(*a, f"{label}{judged['category']}", fontsize=8, ha="center", va="center")
    axes.set_aspect("equal")
    axes.invert_xaxis()
    axes.set_xlabel("y in W (m): to the robot's left")
    axes.set_ylabel("x in W (m): away from the robot")
    cleared = clear.get("objects_cleared", 0)
    axes.set_title(
        f"{cleared} of {clear.get('familiar_objects', 0)} familiar objects cleared (green), distractors moved "
        f"{100 * clear.get('others_moved_m_max', 0.0):.1f} cm at most\ndashed: where they stood; numbers: the order "
        "they were taken on",
        fontsize=9,
    )
    figure.tight_layout()
    figure.savefig(args.out, dpi=90)
    print(f"wrote {args.out}: {outcome.get('message', '')}")


def _order(clear: dict) -> dict[int, int]:
    """Which judged object (index) was the robot's k-th taken on (1-based): the one whose start lies nearest where the
    supervisor saw it."""
    order = {}
    starts = np.array([judged["start_xy_W"] for judged in clear["objects"]])
    for rank, taken in enumerate(clear.get("taken_on", []), start=1):
        nearest = int(np.argmin(np.linalg.norm(starts - np.array(taken["seen_xy_W"]), axis=1)))
        order.setdefault(nearest, rank)
    return order


if __name__ == "__main__":
    main()
