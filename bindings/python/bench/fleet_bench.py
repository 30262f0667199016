"""The fleet benchmark: a simulated fleet through the batch, serially and on
a local Ray cluster, with a worker killed mid-batch, and the tyre alerts.

    target/python-venv/bin/python bindings/python/bench/fleet_bench.py [--vehicles 5 --drives 6 --duration 600 --workers 2]

Prints: drives per hour per core (calibrate + diagnose) and per hour of
driving; whether the Ray rows equal the serial rows with one worker
killed; the storage a drive-hour takes (drive folder and MCAP); the tyre
report (each leak's alert against the drive where it passed the size the
drives can show, alerts on cars without a leak, wear trends against the
truth).
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

from wheelcal import fleet, simfleet, tyres

ROOT = Path(__file__).resolve().parents[3]


def size_of(path: Path) -> int:
    if path.is_file():
        return path.stat().st_size
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def tyre_report(rows: pd.DataFrame, truth: pd.DataFrame) -> None:
    rows = rows.copy()
    rows["drive"] = [p.rsplit("/", 1)[-1] for p in rows["drive"]]
    alerts = tyres.step_alerts(rows)
    steps = tyres.step_table(rows).merge(truth[["drive", "index", "leak_mm", "leak_wheel"]], on="drive")
    leaking = sorted(truth.loc[truth["leak_wheel"].fillna("") != "", "vehicle"].unique())
    print("\n## tyres")
    for a in alerts:
        print("ALERT", a.message())
    for car in leaking:
        s = steps[steps["vehicle"] == car]
        shows = s[(2 * math.pi * s["leak_mm"] / 1000) > tyres.ALERT_Z * s["sigma_m"]]
        first_shown = int(shows["index"].iloc[0]) if len(shows) else None
        start = int(s.loc[s["leak_mm"] > 0, "index"].iloc[0])
        a = next((a for a in alerts if a.vehicle == car), None)
        alerted = int(s.loc[s["drive"] == a.first_drive, "index"].iloc[0]) if a else None
        size_mm = 2 * math.pi * float(s.loc[s["index"] == alerted, "leak_mm"].iloc[0]) if a else float("nan")
        wheel = s["leak_wheel"].iloc[-1]
        said = "no alert" if a is None else ("the wheel named right" if a.wheel == wheel else "THE WRONG WHEEL")
        print(
            f"leak {car} ({wheel.upper()}): starts drive {start}, passes 5 sigma of the test at drive "
            f"{first_shown}, alerted at drive {alerted} ({said}); "
            f"latency {alerted - first_shown if a and first_shown is not None else 'n/a'} drives; "
            f"leak at the alert {size_mm:.3f} mm of circumference; z of each leak drive: "
            + ", ".join(f"{z:.1f}" for z in s.loc[s["leak_mm"] > 0, "z"])
        )
    false = [a for a in alerts if a.vehicle not in leaking]
    print(f"alerts on cars without a leak: {len(false)} (of {rows['vehicle'].nunique() - len(leaking)} cars)")
    shown = {d for a in alerts for d in a.drives}
    trends = tyres.wear_trends(rows, exclude=shown)
    t0 = truth.groupby("vehicle").first()
    within2 = 0
    for _, r in trends.iterrows():
        true = -2 * math.pi * t0.loc[r["vehicle"], f"wear_rate_{r['wheel']}_mm_per_1000km"] / 1000
        z = (r["slope_m_per_1000km"] - true) / r["sigma_slope_m_per_1000km"]
        within2 += abs(z) <= 2
        print(
            f"wear {r['vehicle']} {r['wheel']}: {1000 * r['slope_m_per_1000km']:+.3f} +- {1000 * r['sigma_slope_m_per_1000km']:.3f} "
            f"mm/1000 km, truth {1000 * true:+.3f} ({z:+.2f} sigma, {r['drives']} drives)"
        )
    print(f"wear trends within 2 sigma of the truth: {within2} of {len(trends)}")


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--vehicles", type=int, default=5)
    p.add_argument("--drives", type=int, default=6)
    p.add_argument("--duration", type=float, default=600.0)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--leak", default="1,3")
    p.add_argument("--leak-mm-per-drive", type=float, default=0.06)
    p.add_argument("--leak-start", type=int, default=None)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--work", type=Path, default=ROOT / "target" / "fleet-bench")
    p.add_argument("--no-ray", action="store_true")
    p.add_argument("--no-diagnosis", action="store_true", help="calibrate only")
    a = p.parse_args()
    shutil.rmtree(a.work, ignore_errors=True)
    a.work.mkdir(parents=True)
    plan = simfleet.FleetPlan(
        vehicles=a.vehicles,
        drives=a.drives,
        leak=tuple(int(x) for x in a.leak.split(",") if x),
        duration_s=a.duration,
        seed=a.seed,
        leak_mm_per_drive=a.leak_mm_per_drive,
        leak_start=a.leak_start,
    )
    t = time.perf_counter()
    manifest = simfleet.simulate_fleet(plan, a.work / "drives", ROOT / "target" / "release" / "sensor-bridge")
    print(f"simulated {a.vehicles * a.drives} drives of {a.duration:.0f} s in {time.perf_counter() - t:.1f} s")
    truth = pd.read_csv(a.work / "drives" / "truth.csv")
    n = len(truth)
    hours = n * a.duration / 3600

    t = time.perf_counter()
    serial = fleet.run(manifest, a.work / "serial.parquet", serial=True, with_diagnosis=not a.no_diagnosis)
    ts = time.perf_counter() - t
    what = "calibrate" if a.no_diagnosis else "calibrate + diagnose"
    print(f"\n## serial (1 core, {what}): {n} drives in {ts:.1f} s: {n / ts * 3600:.0f} drives/hour/core; "
          f"{hours / ts * 3600:.1f} hours of driving per hour per core ({ts / n:.2f} s per {a.duration:.0f} s drive)")

    if not a.no_ray:
        marker = a.work / "killed-once"
        t = time.perf_counter()
        done = subprocess.run(
            [sys.executable, "-m", "wheelcal.fleet", str(manifest), "--out", str(a.work / "ray.parquet"),
             "--num-cpus", str(a.workers), "--crash-once", f"{n // 2}={marker}"]
            + (["--no-diagnosis"] if a.no_diagnosis else []),
            capture_output=True, text=True,
        )
        tr = time.perf_counter() - t
        if done.returncode != 0:
            print(done.stderr[-2000:])
            return 1
        ray_rows = pd.read_parquet(a.work / "ray.parquet")
        equal = ray_rows.equals(serial)
        print(f"## ray ({a.workers} workers, the worker of drive {n // 2} killed once: {marker.exists()}): {n} drives in "
              f"{tr:.1f} s wall (with Ray's start-up) = {n / tr * 3600 / a.workers:.0f} drives/hour/core; "
              f"rows equal the serial run's: {equal}; rows {len(ray_rows)} of {n}; "
              f"part files {len(list((a.work / 'ray.parquet.parts').iterdir()))}")

    one = a.work / "drives" / truth["drive"].iloc[0]
    mcap = a.work / "one.mcap"
    subprocess.run([str(ROOT / "target/release/sensor-bridge"), "convert", "--no-foxglove", str(one), str(mcap)],
                   check=True, capture_output=True)
    per_hour = 3600 / a.duration
    print(f"\n## storage per drive-hour: folder {size_of(one) * per_hour / 1e6:.0f} MB, "
          f"MCAP {size_of(mcap) * per_hour / 1e6:.0f} MB; result row {size_of(a.work / 'serial.parquet') / n / 1e3:.1f} kB "
          "(merged Parquet / drives)")
    tyre_report(serial, truth)
    return 0


if __name__ == "__main__":
    sys.exit(main())
