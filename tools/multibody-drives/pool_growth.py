#!/usr/bin/env python3
"""Speed growth on one car, pooled over drives (issue 37, item 4).

    pool_growth.py OUT_DIR [--calibrator PATH] [--noise-seeds 4]

One drive cannot show a speed growth of typical size (its information
limit is 4-5x typical on these drives: the circumferences' scale, which
every drive must fit, takes most of it). It is a car effect, so drives of
one car add up. This writes, for the BMW (vehicle 2) on routes 1 and 4,
NOISE_SEEDS drives with `speed_radius_growth` planted (k_v 2.5e-6) and the
same drives without it (the same noise seeds: paired), runs
`calibrator diagnose` on each set together, and prints the pooled speed
growth of each beside the k_v the wheels really show
(`score.effective_speed_growth`: the multibody tyres have one of their own).
The physics of each route is cached in OUT_DIR/.mb-cache (about 5 minutes
a route the first time; `make_drives.py suite` leaves its cache there too).
"""

import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from score import DEFAULT_CAL, effective_speed_growth  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out_dir")
    ap.add_argument("--calibrator", default=os.path.normpath(DEFAULT_CAL))
    ap.add_argument("--noise-seeds", type=int, default=4)
    a = ap.parse_args()
    os.makedirs(a.out_dir, exist_ok=True)
    sets = {"planted": [], "none": []}
    for i in range(1, a.noise_seeds + 1):
        for route in (1, 4):
            noise = 2000 + 10 * route + i
            for name, tag, extra in (("planted", "g", ["--effect", "speed_radius_growth"]), ("none", "0", [])):
                d = os.path.join(a.out_dir, f"{tag}-r{route}-n{i}")
                if not os.path.isdir(d):
                    subprocess.run(["nice", "-n", "10", sys.executable, os.path.join(HERE, "make_drives.py"),
                                    "drive", d, "--vehicle", "2", "--seed", str(route),
                                    "--noise-seed", str(noise), "--cache", os.path.join(a.out_dir, ".mb-cache"),
                                    *extra], check=True, capture_output=True)
                sets[name].append(d)
    print("| drives | planted k_v | pooled k_v ± sigma | z (Bonferroni's critical) | verdict | shows from | the wheels' own k_v, mean over the drives | per-drive limits, median |")
    print("|---|---|---|---|---|---|---|---|")
    for name, drives in sets.items():
        out = os.path.join(a.out_dir, f"pooled-{name}.json")
        subprocess.run(["nice", "-n", "10", a.calibrator, "diagnose", *drives, "--json", out, "--no-progress"],
                       check=True, capture_output=True)
        j = json.load(open(out))
        car = j["car"]
        e = next(x for x in car["effects"] if x["effect"] == "speed_radius_growth")
        # What decides and what the CLI prints: the fit with every other car
        # effect of its source free.
        shown = {**e, **{k: v for k, v in (e.get("joint") or {}).items() if v is not None}}
        eff = [effective_speed_growth(d)["k_v"] for d in drives]
        singles = []
        for d in j["drives"]:
            lim = next(x for x in d["information_limit"]["effects"] if x["effect"] == "speed_radius_growth")
            singles.append(lim["joint"]["smallest"])
        singles.sort()
        print(f"| {len(drives)} ({name}) | {2.5e-6 if name == 'planted' else 0.0:.1e} | "
              f"{shown['estimate']:.2e} ± {shown['sigma']:.1e} | {shown['wald_z']:+.1f} ({car['z_critical']:.1f}) | "
              f"{e['verdict']} | {shown['smallest']:.2e} | {sum(eff) / len(eff):.2e} | {singles[len(singles) // 2]:.2e} |")


if __name__ == "__main__":
    main()
