"""The fleet batch: on a local Ray cluster of 2 workers its rows equal a
serial run's; a worker killed mid-batch loses and duplicates nothing; a
refused drive is a row with its reason; the per-drive function runs over
pandas batches as Spark's mapInPandas calls it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import binary, simulate

pytest.importorskip("wheelcal", reason="the wheelcal package is not installed (pip install ./bindings/python)")
pd = pytest.importorskip("pandas", reason="pandas is not installed")
pytest.importorskip("pyarrow", reason="pyarrow is not installed")

from wheelcal import fleet, simfleet  # noqa: E402


@pytest.fixture(scope="module")
def manifest(tmp_path_factory) -> Path:
    """6 short simulated drives of 3 vehicles, and one drive that cannot be read."""
    out = tmp_path_factory.mktemp("fleet")
    plan = simfleet.FleetPlan(vehicles=3, drives=2, leak=(), duration_s=150.0, seed=11)
    path = simfleet.simulate_fleet(plan, out, binary("sensor-bridge"))
    m = pd.read_csv(path)
    broken = out / "broken"
    broken.mkdir()
    (broken / "vehicle.toml").write_text("track_width_m = 1.5\nnominal_circumference_m = 1.9\n")
    (broken / "wheels.csv").write_text("t_s,rl_rad_s,rr_rad_s\n0,1,1\n0.01,1,1\n")
    m = pd.concat([m, pd.DataFrame([dict(vehicle="car09", drive="broken", date="2026-10-01", odometer_km=100.0)])])
    m.to_csv(path, index=False)
    return path


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "wheelcal.fleet", *args], capture_output=True, text=True, timeout=900)


def comparable(df):
    return df.drop(columns=[]).to_dict("records")


@pytest.fixture(scope="module")
def serial(manifest, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial") / "rows.parquet"
    done = run_cli(str(manifest), "--out", str(out), "--serial")
    assert done.returncode == 0, done.stderr
    return pd.read_parquet(out)


def test_every_drive_is_a_row_and_a_refused_one_says_why(serial, manifest):
    m = pd.read_csv(manifest)
    assert len(serial) == len(m)
    assert list(serial["vehicle"]) == list(m["vehicle"])
    broken = serial[serial["vehicle"] == "car09"].iloc[0]
    assert "broken" in broken["refused"], broken["refused"]
    ok = serial[serial["vehicle"] != "car09"]
    assert ok["refused"].isna().all()
    assert ok["c_rl_m"].between(1.8, 2.3).all() and (ok["sigma_rl_m"] > 0).all()
    assert list(serial.columns) == fleet.COLUMNS


def test_ray_with_two_workers_equals_the_serial_run_and_survives_a_killed_worker(serial, manifest, tmp_path):
    pytest.importorskip("ray", reason="ray is not installed")
    out = tmp_path / "rows.parquet"
    marker = tmp_path / "killed-once"
    done = run_cli(str(manifest), "--out", str(out), "--num-cpus", "2", "--crash-once", f"2={marker}")
    assert done.returncode == 0, done.stderr[-3000:]
    # The worker of row 2's first attempt did die (it wrote its pid, then _exit).
    assert marker.exists()
    rows = pd.read_parquet(out)
    pd.testing.assert_frame_equal(rows, serial)
    parts = sorted(p.name for p in (out.parent / "rows.parquet.parts").iterdir())
    assert len(parts) == len(serial), parts  # one file per drive, no temporary left


def test_a_rerun_reuses_the_parts_and_gives_the_same_rows(serial, manifest, tmp_path):
    out = tmp_path / "rows.parquet"
    assert run_cli(str(manifest), "--out", str(out), "--serial").returncode == 0
    stamps = {p: p.stat().st_mtime_ns for p in (tmp_path / "rows.parquet.parts").iterdir()}
    assert run_cli(str(manifest), "--out", str(out), "--serial").returncode == 0
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps
    pd.testing.assert_frame_equal(pd.read_parquet(out), serial)


def test_the_per_drive_function_over_pandas_batches_as_spark_calls_it(serial, manifest):
    m = fleet.read_manifest(manifest)
    batches = [m.iloc[:3], m.iloc[3:]]
    got = pd.concat(list(fleet.rows_of_pandas(iter(batches))), ignore_index=True)
    assert list(got.columns) == fleet.COLUMNS
    pd.testing.assert_series_equal(got["c_rl_m"], serial["c_rl_m"])
    assert got["refused"].notna().sum() == 1


def test_a_manifest_without_its_columns_is_refused_naming_them(tmp_path):
    bad = tmp_path / "m.csv"
    bad.write_text("vehicle,drive\nv,d\n")
    done = run_cli(str(bad), "--out", str(tmp_path / "o.parquet"), "--serial")
    assert done.returncode != 0
    assert "date" in done.stderr and "odometer_km" in done.stderr and str(bad) in done.stderr


def test_ray_by_address_joins_a_running_cluster(serial, manifest, tmp_path):
    """`--address`: the batch joins a cluster this test starts (and stops)."""
    ray = pytest.importorskip("ray", reason="ray is not installed")
    ray.init(num_cpus=2, include_dashboard=False)
    try:
        address = ray.get_runtime_context().gcs_address
        out = tmp_path / "rows.parquet"
        done = run_cli(str(manifest), "--out", str(out), "--address", address)
        assert done.returncode == 0, done.stderr[-3000:]
        pd.testing.assert_frame_equal(pd.read_parquet(out), serial)
    finally:
        ray.shutdown()
