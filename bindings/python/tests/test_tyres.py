"""Tyres across drives: the step alert and the wear trend, on made-up
tables and on a fleet simulated by the project's simulator and calibrated
by the calibrator."""

from __future__ import annotations

import math

import pytest

from conftest import binary

pytest.importorskip("wheelcal", reason="the wheelcal package is not installed (pip install ./bindings/python)")
np = pytest.importorskip("numpy", reason="numpy is not installed")
pd = pytest.importorskip("pandas", reason="pandas is not installed")

from wheelcal import fleet, simfleet, tyres  # noqa: E402


def table(n=12, *, common=None, step_at=None, step_m=0.0, step_wheel="rl", sigma=1e-5, seed=3):
    """One vehicle's drives: both wheels wear 0.7 mm per 1000 km, the
    difference carries noise of `sigma`, `common` moves both wheels alike
    per drive, a step shrinks one wheel from drive `step_at` on."""
    rng = np.random.default_rng(seed)
    rows = []
    for k in range(n):
        odo = 10000.0 + 400.0 * k
        c = 1.95 - 0.7e-6 * odo + (common[k] if common is not None else 0.0)
        c_rl = c + rng.normal(0, 1e-3)
        c_rr = c_rl + 2e-3 + rng.normal(0, sigma)
        if step_at is not None and k >= step_at:
            if step_wheel == "rl":
                c_rl -= step_m
            else:
                c_rr -= step_m
        rows.append(
            dict(vehicle="v", drive=f"d{k}", date=f"2026-10-{k + 1:02d}", odometer_km=odo, c_rl_m=c_rl, c_rr_m=c_rr,
                 sigma_rl_m=1e-3, sigma_rr_m=1e-3, sigma_diff_m=sigma)
        )
    return pd.DataFrame(rows)


def test_no_alert_from_temperature_or_load_moving_both_wheels():
    # Both wheels moving by 200 times the difference's sigma, drive to drive.
    common = np.random.default_rng(1).normal(0, 2e-3, 12)
    assert tyres.step_alerts(table(common=common)) == []


def test_a_step_of_one_wheel_alerts_naming_the_wheel_and_the_drives():
    for wheel in ("rl", "rr"):
        alerts = tyres.step_alerts(table(step_at=8, step_m=2e-4, step_wheel=wheel))
        assert len(alerts) == 1
        a = alerts[0]
        assert a.wheel == wheel
        assert a.first_drive == "d8"
        assert a.drives == ["d8", "d9", "d10", "d11"]
        assert "d8" in a.message() and wheel.upper() in a.message()


def test_a_step_below_five_sigma_does_not_alert():
    assert tyres.step_alerts(table(step_at=8, step_m=2e-5)) == []


def test_the_sigma_is_the_history_scatter_when_the_reported_one_is_too_small():
    t = table(sigma=3e-5, seed=4)
    t["sigma_diff_m"] = 1e-7  # the drives claim far better than they scatter
    steps = tyres.step_table(t)
    tested = steps.dropna(subset=["z"])
    assert (tested["sigma_drive_m"] > 1e-5).all()
    assert tyres.step_alerts(t) == []


def test_the_wear_trend_of_made_up_drives_is_the_truth_within_two_sigma():
    w = tyres.wear_trends(table(common=np.random.default_rng(2).normal(0, 5e-4, 12)))
    for _, r in w.iterrows():
        assert abs(r["slope_m_per_1000km"] - (-0.7e-3)) < 2 * r["sigma_slope_m_per_1000km"], r


def test_a_table_without_its_columns_is_an_error_naming_them():
    with pytest.raises(ValueError, match="odometer_km"):
        tyres.step_alerts(table().drop(columns=["odometer_km"]))


def test_a_simulated_fleet_alerts_each_leak_and_no_other_car(tmp_path):
    """4 cars over 9 drives a week apart, slow wear on both rear tyres,
    a temperature/load change of both per drive, a slow leak on one tyre of
    cars 1 and 2 from their fifth drive on (0.02 mm of radius more each
    drive); each drive 200 s, simulated and calibrated."""
    sb = binary("sensor-bridge")
    plan = simfleet.FleetPlan(vehicles=4, drives=9, leak=(1, 2), duration_s=200.0, seed=7,
                              leak_mm_per_drive=0.02, leak_start=5)
    manifest = simfleet.simulate_fleet(plan, tmp_path, sb)
    truth = pd.read_csv(tmp_path / "truth.csv")
    m = fleet.read_manifest(manifest)
    rows = pd.DataFrame([fleet.drive_row(r.vehicle, r.drive, r.date, r.odometer_km, with_diagnosis=False)
                         for r in m.itertuples()])
    assert rows["refused"].isna().all(), rows["refused"].tolist()
    rows["drive"] = [p.rsplit("/", 1)[-1] for p in rows["drive"]]
    alerts = tyres.step_alerts(rows)
    steps = tyres.step_table(rows).merge(truth[["drive", "index", "leak_mm", "leak_wheel"]], on="drive")
    by_car = {a.vehicle: a for a in alerts}
    assert set(by_car) == {"car01", "car02"}, [a.message() for a in alerts]
    for car, a in by_car.items():
        s = steps[steps["vehicle"] == car]
        assert a.wheel == s["leak_wheel"].iloc[-1]
        # The first drive whose leak (as circumference) exceeds 5 sigma of the test.
        shows = s[2 * math.pi * s["leak_mm"] / 1000 > tyres.ALERT_Z * s["sigma_m"]]
        assert len(shows), s
        first_shown = int(shows["index"].iloc[0])
        alerted = int(s.loc[s["drive"] == a.first_drive, "index"].iloc[0])
        assert alerted >= 5, "an alert before the leak began"
        assert alerted - first_shown <= 1, (car, first_shown, alerted)
    # The wear trend of every wheel, the drives that alerted left out, against the truth.
    shown = {d for a in alerts for d in a.drives}
    trends = tyres.wear_trends(rows, exclude=shown)
    t0 = truth.groupby("vehicle").first()
    for _, r in trends.iterrows():
        # mm of radius per 1000 km -> m of circumference per 1000 km
        true = -2 * math.pi * t0.loc[r["vehicle"], f"wear_rate_{r['wheel']}_mm_per_1000km"] / 1000
        assert abs(r["slope_m_per_1000km"] - true) < 3 * r["sigma_slope_m_per_1000km"], (r, true)
