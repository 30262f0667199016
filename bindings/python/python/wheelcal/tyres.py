"""Tyres watched across drives: each vehicle's rear circumferences over
date and odometer, the slow wear trend of each wheel, and an alert when one
wheel steps against the other.

The input is one row per calibrated drive (what :mod:`wheelcal.fleet`
writes): ``vehicle``, ``drive``, ``date``, ``odometer_km``, ``c_rl_m``,
``c_rr_m``, ``sigma_rl_m``, ``sigma_rr_m`` and ``sigma_diff_m`` (the
calibration's 1-sigma of ``c_rr - c_rl``; NaN when it did not say: the two
wheel sigmas combined then). Refused drives (no circumference) are left
out.

Wear (:func:`wear_trends`): a straight line of each wheel's circumference
against the odometer, weighted by the drives' sigmas; the slope's sigma is
the larger of what the reported sigmas give and what the scatter about the
line gives (so a drive-to-drive effect the sigmas do not carry, such as
temperature or load, widens it instead of hiding).

Steps (:func:`step_alerts`): temperature and load move both rear tyres
alike, a leak one. So the test is on the difference ``d = c_rr - c_rl``:
each drive's ``d`` against the line of the vehicle's own earlier drives
(differential wear is slow and linear in the odometer; a leak is not),
and against the same line without the last LAG of them when there are
enough (so a leak growing slowly does not drag the baseline with it; the
larger |z| of the two counts), in
units of ``sigma = sqrt(s_drive^2 + s_line^2)``, where ``s_drive`` is the
larger of the drive's reported difference sigma and the scatter of the
history about its line, and ``s_line`` is the line's prediction sigma.
``|z| > 5`` is an alert; the wheel is the one whose circumference fell
(``d`` rising: the left one). A drive that alerted stays out of the
history, so a leak does not teach the baseline to accept it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

#: z beyond which a step of the left/right difference is an alert.
ALERT_Z = 5.0
#: Earlier drives needed before a drive is tested.
MIN_HISTORY = 4
#: The most recent drives of the history left out of the baseline when the
#: history is long enough (it keeps MIN_HISTORY): a leak growing by less
#: than ALERT_Z sigma per drive would otherwise enter the baseline drive by
#: drive and be followed by it; against the settled history it adds up.
LAG = 3


def _rows(table: pd.DataFrame) -> pd.DataFrame:
    need = ["vehicle", "drive", "date", "odometer_km", "c_rl_m", "c_rr_m", "sigma_rl_m", "sigma_rr_m"]
    missing = [c for c in need if c not in table.columns]
    if missing:
        raise ValueError(f"the drive table lacks the columns {', '.join(missing)}")
    t = table.copy()
    if "sigma_diff_m" not in t.columns:
        t["sigma_diff_m"] = np.nan
    t = t[np.isfinite(t["c_rl_m"].astype(float)) & np.isfinite(t["c_rr_m"].astype(float))]
    t = t.sort_values(["vehicle", "odometer_km", "date", "drive"]).reset_index(drop=True)
    combined = np.hypot(t["sigma_rl_m"].astype(float), t["sigma_rr_m"].astype(float))
    t["sigma_d_m"] = t["sigma_diff_m"].astype(float).where(np.isfinite(t["sigma_diff_m"].astype(float)), combined)
    t["d_m"] = t["c_rr_m"].astype(float) - t["c_rl_m"].astype(float)
    return t


@dataclass
class Line:
    """A weighted straight line y = a + b (x - x0), with its covariance."""

    x0: float
    a: float
    b: float
    cov: np.ndarray
    #: RMS of the residuals about the line, corrected for the two
    #: parameters (NaN with two points or fewer).
    scatter: float
    #: sqrt(chi^2 / dof) of the residuals against the reported sigmas.
    scale: float

    def predict(self, x: float) -> tuple[float, float]:
        """The line at x and its 1-sigma."""
        j = np.array([1.0, x - self.x0])
        return self.a + self.b * (x - self.x0), float(math.sqrt(max(j @ self.cov @ j, 0.0)))


def fit_line(x: np.ndarray, y: np.ndarray, sigma: np.ndarray) -> Line:
    """Weighted least squares of y on x; the covariance scaled up by the
    scatter when the residuals exceed the reported sigmas (never down)."""
    x, y, sigma = (np.asarray(v, dtype=float) for v in (x, y, sigma))
    n = len(x)
    x0 = float(np.mean(x)) if n else 0.0
    s = np.where(np.isfinite(sigma) & (sigma > 0), sigma, np.nan)
    if np.all(np.isnan(s)):
        s = np.ones(n)
    s = np.where(np.isnan(s), np.nanmax(s), s)
    w = 1.0 / s**2
    if n >= 2 and np.ptp(x) > 0:
        A = np.stack([np.ones(n), x - x0], axis=1)
    else:
        A = np.ones((n, 1))
    N = A.T @ (A * w[:, None])
    cov = np.linalg.inv(N)
    p = cov @ (A.T @ (w * y))
    r = y - A @ p
    dof = n - A.shape[1]
    scale = float(math.sqrt(np.sum(w * r**2) / dof)) if dof > 0 else 1.0
    scatter = float(math.sqrt(np.sum(r**2) / dof)) if dof > 0 else float("nan")
    cov = cov * max(scale, 1.0) ** 2
    if A.shape[1] == 1:
        full = np.zeros((2, 2))
        full[0, 0] = cov[0, 0]
        return Line(x0, float(p[0]), 0.0, full, scatter, scale)
    return Line(x0, float(p[0]), float(p[1]), cov, scatter, scale)


def wear_trends(table: pd.DataFrame, *, exclude: set[str] | None = None) -> pd.DataFrame:
    """Per vehicle and rear wheel: the circumference's slope against the
    odometer (m per 1000 km) with its 1-sigma, the fitted circumference at
    the first and last odometer reading, the drives used. ``exclude``:
    drives to leave out (e.g. those that alerted)."""
    t = _rows(table)
    if exclude:
        t = t[~t["drive"].isin(exclude)]
    out = []
    for vehicle, g in t.groupby("vehicle", sort=True):
        for wheel in ("rl", "rr"):
            if len(g) < 2:
                continue
            line = fit_line(g["odometer_km"], g[f"c_{wheel}_m"], g[f"sigma_{wheel}_m"])
            lo, hi = float(g["odometer_km"].min()), float(g["odometer_km"].max())
            out.append(
                {
                    "vehicle": vehicle,
                    "wheel": wheel,
                    "drives": len(g),
                    "slope_m_per_1000km": 1000.0 * line.b,
                    "sigma_slope_m_per_1000km": 1000.0 * math.sqrt(line.cov[1, 1]),
                    "c_first_m": line.predict(lo)[0],
                    "c_last_m": line.predict(hi)[0],
                    "odometer_first_km": lo,
                    "odometer_last_km": hi,
                    "scatter_m": line.scatter,
                    "chi_scale": line.scale,
                }
            )
    return pd.DataFrame(out)


@dataclass
class Alert:
    """A step of one rear wheel against the other."""

    vehicle: str
    #: The wheel whose circumference fell against the other (`rl` or `rr`).
    wheel: str
    #: The first drive that shows it.
    first_drive: str
    #: Every drive that shows it (|z| > ALERT_Z), in odometer order.
    drives: list[str] = field(default_factory=list)
    #: The step of c_rr - c_rl at the first drive against the history, m.
    step_m: float = 0.0
    #: Its z at the first drive.
    z: float = 0.0

    def message(self) -> str:
        return (
            f"{self.vehicle}: the {self.wheel.upper()} tyre's rolling circumference stepped "
            f"{abs(self.step_m) * 1000:.2f} mm against the other ({self.z:+.1f} sigma of the "
            f"vehicle's own history) from drive {self.first_drive}; drives showing it: "
            f"{', '.join(self.drives)}: check its pressure"
        )


def step_table(table: pd.DataFrame) -> pd.DataFrame:
    """Per drive: the left/right difference, what the vehicle's history
    predicts for it, the sigma used and z (NaN before MIN_HISTORY drives)."""
    t = _rows(table)
    rows = []
    for vehicle, g in t.groupby("vehicle", sort=True):
        history: list[int] = []
        for i in range(len(g)):
            r = g.iloc[i]
            z = pred = s = s_drive = float("nan")
            if len(history) >= MIN_HISTORY:
                # Against the whole history, and against it without its last
                # LAG drives (when long enough): the larger |z| counts.
                lag = min(LAG, len(history) - MIN_HISTORY)
                best = None
                for keep in sorted({len(history), len(history) - lag}):
                    h = g.iloc[history[:keep]]
                    line = fit_line(h["odometer_km"], h["d_m"], h["sigma_d_m"])
                    p, s_line = line.predict(float(r["odometer_km"]))
                    scatter = line.scatter if math.isfinite(line.scatter) else 0.0
                    sd = max(float(r["sigma_d_m"]), scatter)
                    sg = math.hypot(sd, s_line)
                    zz = (float(r["d_m"]) - p) / sg
                    if best is None or abs(zz) > abs(best[0]):
                        best = (zz, p, sd, sg)
                z, pred, s_drive, s = best
            alert = math.isfinite(z) and abs(z) > ALERT_Z
            if not alert:
                history.append(i)
            rows.append(
                {
                    "vehicle": vehicle,
                    "drive": r["drive"],
                    "date": r["date"],
                    "odometer_km": r["odometer_km"],
                    "d_m": r["d_m"],
                    "predicted_d_m": pred,
                    "sigma_drive_m": s_drive,
                    "sigma_m": s,
                    "z": z,
                    "alert": alert,
                }
            )
    return pd.DataFrame(rows)


def step_alerts(table: pd.DataFrame) -> list[Alert]:
    """The alerts: per vehicle and wheel, the drives whose left/right
    difference stepped beyond ALERT_Z sigma of the vehicle's history."""
    steps = step_table(table)
    alerts: list[Alert] = []
    for vehicle, g in steps.groupby("vehicle", sort=True):
        for _, r in g[g["alert"]].iterrows():
            # d = c_rr - c_rl rising: the left one fell.
            wheel = "rl" if r["d_m"] > r["predicted_d_m"] else "rr"
            found = next((a for a in alerts if a.vehicle == vehicle and a.wheel == wheel), None)
            if found is None:
                alerts.append(
                    Alert(
                        vehicle=vehicle,
                        wheel=wheel,
                        first_drive=r["drive"],
                        drives=[r["drive"]],
                        step_m=float(r["d_m"] - r["predicted_d_m"]),
                        z=float(r["z"]),
                    )
                )
            else:
                found.drives.append(r["drive"])
    return alerts


def circumference_table(table: pd.DataFrame) -> pd.DataFrame:
    """Each vehicle's rear circumferences over date and odometer with their
    sigmas, and the left/right difference with its sigma (one row per
    drive and wheel, plus the difference as wheel ``rr-rl``)."""
    t = _rows(table)
    parts = []
    for wheel, c, s in (("rl", "c_rl_m", "sigma_rl_m"), ("rr", "c_rr_m", "sigma_rr_m"), ("rr-rl", "d_m", "sigma_d_m")):
        p = t[["vehicle", "drive", "date", "odometer_km"]].copy()
        p["wheel"] = wheel
        p["value_m"] = t[c].astype(float)
        p["sigma_m"] = t[s].astype(float)
        parts.append(p)
    return pd.concat(parts, ignore_index=True).sort_values(["vehicle", "wheel", "odometer_km"]).reset_index(drop=True)


def main(argv: list[str] | None = None) -> int:
    """``python -m wheelcal.tyres RESULTS.parquet``: the alerts and the wear trends."""
    import argparse
    import sys

    p = argparse.ArgumentParser(prog="python -m wheelcal.tyres", description="Tyres across a fleet's drives")
    p.add_argument("results", help="the Parquet file of python -m wheelcal.fleet")
    a = p.parse_args(argv)
    table = pd.read_parquet(a.results)
    refused = table[table["refused"].notna()]
    for _, r in refused.iterrows():
        print(f"refused: {r['vehicle']} {r['drive']}: {r['refused']}")
    alerts = step_alerts(table)
    for al in alerts:
        print("ALERT", al.message())
    if not alerts:
        print("no tyre alert")
    shown = {d for al in alerts for d in al.drives}
    trends = wear_trends(table, exclude=shown)
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(trends.to_string(index=False))
    sys.stdout.flush()
    return 1 if alerts else 0


if __name__ == "__main__":
    raise SystemExit(main())
