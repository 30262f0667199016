#!/usr/bin/env python3
"""Dead-reckon a drive's rear wheels against its truth with a load transfer
k_z (and a relative track error) applied, reading a_y either from the
wheels' own yaw rate or from the gyro, and print the position RMS over
42 s blocks, each started from the truth's pose, not aligned.

    dr_check.py DRIVE --ay wheels|gyro --k-z K [--track-rel R] [K ...]

A dev check of how the two readings of a_y behave
(docs/notebook/2026-11-29-lateral-acceleration-source.md); no side-slip
or longitudinal slip is applied. Needs numpy. About a minute per value
of K on a 9-minute drive.
"""

import argparse
import os
import tomllib

import numpy as np

BLOCK_S = 42.0
SMOOTH_S = 0.5


def load(drive):
    tr = np.genfromtxt(os.path.join(drive, "truth.csv"), delimiter=",", names=True)
    wh = np.genfromtxt(os.path.join(drive, "wheels.csv"), delimiter=",", names=True)
    imu = np.genfromtxt(os.path.join(drive, "imu.csv"), delimiter=",", names=True)
    truth = tomllib.load(open(os.path.join(drive, "truth.toml"), "rb"))
    veh = tomllib.load(open(os.path.join(drive, "vehicle.toml"), "rb"))
    c, n = truth["circumference_m"], veh["ticks_per_rev"]
    wt = wh["t_s"]
    dt = np.diff(wt)
    d = {
        "t": veh["track_width_m"],
        "dt": dt,
        "dl": np.diff(wh["rl_ticks"]) / n * c["rl"],
        "dr": np.diff(wh["rr_ticks"]) / n * c["rr"],
        "x": np.interp(wt, tr["t_s"], tr["x_m"]),
        "y": np.interp(wt, tr["t_s"], tr["y_m"]),
        "yaw": np.interp(wt, tr["t_s"], np.unwrap(tr["yaw_rad"])),
        "gz": np.interp(wt[1:] - dt / 2, imu["t_s"], imu["gz_rad_s"]),
    }
    half = int(round(SMOOTH_S / 2 / np.median(dt)))
    ker = np.ones(2 * half + 1) / (2 * half + 1)
    d["v"] = np.convolve(0.5 * (d["dl"] + d["dr"]), ker, "same") / dt
    d["w_wheels"] = np.convolve((d["dr"] - d["dl"]) / d["t"], ker, "same") / dt
    d["w_gyro"] = np.convolve(d["gz"], ker, "same")
    return d


def rms(d, ay, k_z, track_rel):
    steps = int(round(BLOCK_S / np.median(d["dt"])))
    blocks = []
    for s in range(0, len(d["dt"]) - steps, steps):
        x, y, p = d["x"][s], d["y"][s], d["yaw"][s]
        err = []
        for i in range(s, s + steps):
            left = d["dl"][i] * (1 + k_z * ay[i])
            right = d["dr"][i] * (1 - k_z * ay[i])
            dp = (right - left) / (d["t"] * (1 + track_rel))
            ds = 0.5 * (left + right)
            x += ds * np.cos(p + dp / 2)
            y += ds * np.sin(p + dp / 2)
            p += dp
            if i % 10 == 0:
                err.append(np.hypot(x - d["x"][i + 1], y - d["y"][i + 1]))
        blocks.append(np.sqrt(np.mean(np.square(err))))
    return float(np.sqrt(np.mean(np.square(blocks))))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("drive")
    ap.add_argument("--ay", choices=["wheels", "gyro"], required=True)
    ap.add_argument("--k-z", type=float, nargs="+", required=True)
    ap.add_argument("--track-rel", type=float, default=0.0)
    a = ap.parse_args()
    d = load(a.drive)
    ay = d["v"] * (d["w_wheels"] if a.ay == "wheels" else d["w_gyro"])
    for k in a.k_z:
        print(f"a_y from the {a.ay}, k_z {k:.3g}, track {100 * a.track_rel:+.2f} %: "
              f"position RMS over {BLOCK_S:.0f} s blocks {rms(d, ay, k, a.track_rel):.2f} m")


if __name__ == "__main__":
    main()
