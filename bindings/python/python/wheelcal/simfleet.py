"""A simulated fleet: several cars over weeks, each drive written by the
project's simulator (``sensor-bridge simulate``) with the tyres' state of
that day, and the manifest of the drives.

Each car's rear tyres wear slowly and steadily with the odometer (a rate
per wheel, the two within about 10 % of each other); each drive adds a
temperature and load change of the rolling radius common to both tyres;
on the cars given a leak, one rear tyre's rolling radius falls further
from a chosen drive on, by a growing amount per drive. The simulator's
knob is the tread lost per wheel (``--wear RL,RR,FL,FR`` in mm of radius):
wear, the common change and the leak all enter through it, so the truth
of every drive is its ``truth.toml`` circumferences, and the truth of the
fleet is in ``truth.csv`` beside the manifest.

    python -m wheelcal.simfleet OUT_DIR --vehicles 5 --drives 6 [--leak 1,3] [--sensor-bridge PATH]
"""

from __future__ import annotations

import argparse
import datetime as dt
import math
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

VEHICLES = ("compact", "saloon", "van")


@dataclass
class FleetPlan:
    """What to simulate."""

    vehicles: int = 5
    drives: int = 6
    #: Indices of the cars with a slow leak.
    leak: tuple[int, ...] = (1, 3)
    #: Rear-left or rear-right leaking, per leaking car (alternating).
    duration_s: float = 300.0
    scenario: str = "mixed"
    seed: int = 1
    #: Tread wear, mm of radius per 1000 km (the left wheel's; the right within 10 %).
    wear_mm_per_1000km: float = 0.12
    #: 1-sigma of the per-drive temperature/load change of both radii, mm.
    common_mm: float = 0.15
    #: The leak's growth of the radius loss per drive, mm.
    leak_mm_per_drive: float = 0.06
    #: The drive (index within the car's drives) the leak starts with
    #: (default: half-way, and not before the fifth).
    leak_start: int | None = None


def plan_drives(plan: FleetPlan) -> pd.DataFrame:
    """One row per drive: vehicle, its type, drive index, date, odometer,
    the wear of each rear wheel (mm of radius) and the parts of it."""
    rng = np.random.default_rng(plan.seed)
    rows = []
    start = dt.date(2026, 9, 7)
    for v in range(plan.vehicles):
        kind = VEHICLES[v % len(VEHICLES)]
        rate_rl = plan.wear_mm_per_1000km * rng.uniform(0.8, 1.2)
        rate_rr = rate_rl * rng.uniform(0.9, 1.1)
        worn0 = rng.uniform(0.0, 2.0, size=2)
        odo = float(rng.uniform(5000, 40000))
        day = start + dt.timedelta(days=int(rng.integers(0, 3)))
        leak_wheel = ("rl" if plan.leak.index(v) % 2 == 0 else "rr") if v in plan.leak else ""
        # By default after the drives the step test needs as history.
        leak_start = plan.leak_start if plan.leak_start is not None else min(max(plan.drives // 2, 4), plan.drives - 1)
        for k in range(plan.drives):
            if k > 0:
                odo += float(rng.uniform(250, 450))
                day += dt.timedelta(days=int(rng.integers(5, 9)))
            common = float(rng.normal(0.0, plan.common_mm))
            leak = plan.leak_mm_per_drive * (k - leak_start + 1) if (v in plan.leak and k >= leak_start) else 0.0
            wear_rl = worn0[0] + rate_rl * odo / 1000.0
            wear_rr = worn0[1] + rate_rr * odo / 1000.0
            rows.append(
                {
                    "vehicle": f"car{v:02d}",
                    "kind": kind,
                    "index": k,
                    "date": day.isoformat(),
                    "odometer_km": round(odo, 1),
                    "wear_rate_rl_mm_per_1000km": rate_rl,
                    "wear_rate_rr_mm_per_1000km": rate_rr,
                    "common_mm": common,
                    "leak_wheel": leak_wheel,
                    "leak_mm": leak,
                    "radius_loss_rl_mm": wear_rl + common + (leak if leak_wheel == "rl" else 0.0),
                    "radius_loss_rr_mm": wear_rr + common + (leak if leak_wheel == "rr" else 0.0),
                    "seed": plan.seed * 1000 + v * 100 + k,
                }
            )
    return pd.DataFrame(rows)


def simulate_fleet(plan: FleetPlan, out: Path, sensor_bridge: Path, threads: int = 2) -> Path:
    """Write every drive and ``manifest.csv``, ``truth.csv`` into ``out``; the manifest's path."""
    out.mkdir(parents=True, exist_ok=True)
    drives = plan_drives(plan)

    def one(r) -> str:
        name = f"{r.vehicle}-{r.index:03d}"
        path = out / name
        if not (path / "truth.toml").exists():
            wear = f"{r.radius_loss_rl_mm:.6f},{r.radius_loss_rr_mm:.6f},0,0"
            args = [
                str(sensor_bridge),
                "simulate",
                "--scenario",
                plan.scenario,
                "--vehicle",
                r.kind,
                "--seed",
                str(r.seed),
                "--duration",
                str(plan.duration_s),
                f"--wear={wear}",
                "--out",
                str(path),
            ]
            done = subprocess.run(args, capture_output=True, text=True)
            if done.returncode != 0:
                raise RuntimeError(f"sensor-bridge simulate {name}: {done.stderr.strip()}")
        return name

    with ThreadPoolExecutor(threads) as pool:
        names = list(pool.map(one, drives.itertuples()))
    drives["drive"] = names
    truth = []
    for name in names:
        t = _circumferences(out / name / "truth.toml")
        truth.append(t)
    drives["true_c_rl_m"] = [t[0] for t in truth]
    drives["true_c_rr_m"] = [t[1] for t in truth]
    drives[["vehicle", "drive", "date", "odometer_km"]].to_csv(out / "manifest.csv", index=False)
    drives.to_csv(out / "truth.csv", index=False)
    return out / "manifest.csv"


def _circumferences(path: Path) -> tuple[float, float]:
    import tomllib

    with open(path, "rb") as f:
        t = tomllib.load(f)
    c = t["circumference_m"]
    return float(c["rl"]), float(c["rr"])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m wheelcal.simfleet", description=__doc__.split("\n\n")[0])
    p.add_argument("out", type=Path)
    p.add_argument("--vehicles", type=int, default=5)
    p.add_argument("--drives", type=int, default=6, help="drives per vehicle")
    p.add_argument("--leak", default="1,3", help="indices of the cars with a slow leak (comma separated, or empty)")
    p.add_argument("--duration", type=float, default=300.0, help="length of each drive, s")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--leak-mm-per-drive", type=float, default=0.06)
    p.add_argument("--sensor-bridge", type=Path, default=Path("target/release/sensor-bridge"))
    a = p.parse_args(argv)
    leak = tuple(int(x) for x in a.leak.split(",") if x.strip())
    plan = FleetPlan(
        vehicles=a.vehicles,
        drives=a.drives,
        leak=leak,
        duration_s=a.duration,
        seed=a.seed,
        leak_mm_per_drive=a.leak_mm_per_drive,
    )
    m = simulate_fleet(plan, a.out, a.sensor_bridge)
    print(f"wrote {m}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
