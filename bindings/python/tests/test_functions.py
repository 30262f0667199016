"""Every function of the package against the command-line tools: on the
real drives beside the repository and on simulated drives, from a path,
an MCAP recording and in-memory columns; the result dicts must equal the
tools' --json output, the errors carry the tools' messages."""

from __future__ import annotations

import json
import subprocess
import threading
import time
from pathlib import Path

import pytest

from conftest import binary, cli_error, cli_json, real_drive, simulate

wheelcal = pytest.importorskip("wheelcal", reason="the wheelcal package is not installed (pip install ./bindings/python)")
pd = pytest.importorskip("pandas", reason="pandas is not installed")
np = pytest.importorskip("numpy", reason="numpy is not installed")


def columns_of(folder: Path) -> dict:
    """The drive folder's CSV files as pandas DataFrames, by stream."""
    return {
        s: pd.read_csv(folder / f"{s}.csv")
        for s in wheelcal.STREAMS
        if (folder / f"{s}.csv").is_file()
    }


# ------------------------------------------------------------------ real drives


def test_calibrate_equals_the_cli_on_a_real_drive(tmp_path):
    drive = real_drive("wid-trial02")
    cli = cli_json(
        [str(binary("calibrator")), "calibrate", str(drive), "--json", str(tmp_path / "c.json"), "--no-progress"],
        tmp_path / "c.json",
    )
    est = wheelcal.calibrate(drive)
    assert est.to_dict() == cli
    assert est.circumference_m == (cli["circumference_m"]["rl"], cli["circumference_m"]["rr"])
    assert isinstance(est.iterations_table(), pd.DataFrame)


def test_calibrate_with_the_diagnosis_equals_the_cli(tmp_path):
    drive = real_drive("wid-trial02")
    cli = cli_json(
        [str(binary("calibrator")), "calibrate", str(drive), "--diagnose", "--json", str(tmp_path / "c.json"), "--no-progress"],
        tmp_path / "c.json",
    )
    assert wheelcal.calibrate(drive, diagnose=True).to_dict() == cli


def test_diagnose_equals_the_cli_on_a_real_drive_and_on_two_drives_of_the_car(tmp_path):
    drive = real_drive("wid-trial02")
    other = real_drive("wid-trial04")
    cli = cli_json(
        [str(binary("calibrator")), "diagnose", str(drive), "--json", str(tmp_path / "d.json"), "--no-progress"],
        tmp_path / "d.json",
    )
    d = wheelcal.diagnose(drive)
    assert d.to_dict() == cli
    assert d.effects == [f["effect"] for f in cli["findings"]]
    cli_both = cli_json(
        [str(binary("calibrator")), "diagnose", str(drive), str(other), "--json", str(tmp_path / "dd.json"), "--no-progress"],
        tmp_path / "dd.json",
    )
    both = wheelcal.diagnose([drive, other])
    assert isinstance(both, wheelcal.DrivesDiagnosis)
    assert both.to_dict() == cli_both
    assert [x.to_dict() for x in both.drives][0]["findings"] == cli["findings"]


def test_info_equals_the_cli_on_a_real_drive():
    drive = real_drive("comma2k19-seg40")
    cli = cli_json([str(binary("calibrator")), "info", str(drive), "--json"])
    i = wheelcal.info(drive)
    assert i.to_dict() == cli
    assert len(i.streams_table()) == len(cli["drive"]["streams"])


def test_evaluate_equals_the_cli_with_an_estimate_file_and_nominal(tmp_path):
    cal_drive, eval_drive = real_drive("wid-trial02"), real_drive("wid-trial04")
    est_path = tmp_path / "est.json"
    cli_json([str(binary("calibrator")), "calibrate", str(cal_drive), "--json", str(est_path), "--no-progress"], est_path)
    cli = cli_json(
        [str(binary("odometry")), "evaluate", str(eval_drive), "--estimate", str(est_path), "--json", str(tmp_path / "e.json")],
        tmp_path / "e.json",
    )
    assert wheelcal.evaluate(eval_drive, est_path).to_dict() == cli
    # The Calibration object itself as the estimate: the same numbers.
    from_object = wheelcal.evaluate(eval_drive, wheelcal.calibrate(cal_drive)).to_dict()
    assert from_object["outages"] == cli["outages"]
    nominal = cli_json(
        [str(binary("odometry")), "evaluate", str(eval_drive), "--json", str(tmp_path / "n.json")],
        tmp_path / "n.json",
    )
    assert wheelcal.evaluate(eval_drive).to_dict() == nominal


def test_columns_of_a_real_drive_calibrate_as_its_folder(tmp_path):
    drive = real_drive("wid-trial02")
    folder = wheelcal.calibrate(drive).to_dict()
    mem = wheelcal.drive_from_columns(columns_of(drive), drive / "vehicle.toml", name="mem")
    assert mem.warnings == []
    assert wheelcal.calibrate(mem).to_dict() == folder
    # A dict of numpy arrays per stream, and the mapping straight into calibrate.
    arrays = {s: {c: df[c].to_numpy() for c in df.columns} for s, df in columns_of(drive).items()}
    assert wheelcal.calibrate(arrays, vehicle=drive).to_dict() == folder


def test_an_mcap_recording_gives_what_its_folder_gives(tmp_path):
    drive = real_drive("comma2k19-seg40")
    mcap = tmp_path / "d.mcap"
    subprocess.run([str(binary("sensor-bridge")), "convert", str(drive), str(mcap)], check=True, capture_output=True)
    cli = cli_json([str(binary("calibrator")), "info", str(mcap), "--json"])
    assert wheelcal.info(mcap).to_dict() == cli
    assert wheelcal.calibrate(mcap).to_dict()["circumference_m"] == wheelcal.calibrate(drive).to_dict()["circumference_m"]


# ------------------------------------------------------------ simulated drives


def test_every_function_on_a_simulated_drive_from_columns_equals_the_cli(sim_drive, tmp_path):
    cal = binary("calibrator")
    c_cli = cli_json([str(cal), "calibrate", str(sim_drive), "--json", str(tmp_path / "c.json"), "--no-progress"], tmp_path / "c.json")
    d_cli = cli_json([str(cal), "diagnose", str(sim_drive), "--json", str(tmp_path / "d.json"), "--no-progress"], tmp_path / "d.json")
    i_cli = cli_json([str(cal), "info", str(sim_drive), "--json"])
    e_cli = cli_json(
        [str(binary("odometry")), "evaluate", str(sim_drive), "--estimate", str(tmp_path / "c.json"), "--json", str(tmp_path / "e.json")],
        tmp_path / "e.json",
    )
    mem = wheelcal.drive_from_columns(columns_of(sim_drive), sim_drive)
    assert wheelcal.calibrate(mem).to_dict() == c_cli
    assert wheelcal.diagnose(mem).to_dict() == d_cli
    assert wheelcal.evaluate(mem, tmp_path / "c.json").to_dict()["outages"] == e_cli["outages"]
    assert wheelcal.evaluate(sim_drive, tmp_path / "c.json").to_dict() == e_cli
    # info names the drive's streams as the folder's summary does; from a path it is the CLI's.
    assert wheelcal.info(sim_drive).to_dict() == i_cli
    assert wheelcal.info(mem).to_dict()["fit_quality"] == i_cli["fit_quality"]


def test_the_gil_is_released_while_rust_works(sim_drive):
    """Two threads calibrate in about the time of one when two cores exist."""
    import os

    if (os.cpu_count() or 1) < 2:
        pytest.skip("one core: nothing to run in parallel")
    d = wheelcal.read_drive(sim_drive)
    ticks = []
    done = threading.Event()

    def tick():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=tick)
    t.start()
    start = time.perf_counter()
    wheelcal.calibrate(d)
    took = time.perf_counter() - start
    done.set()
    t.join()
    during = [x for x in ticks if start < x < start + took]
    if took < 0.05:
        pytest.skip(f"the calibration took {took:.3f} s: too short to see the ticker")
    # With the GIL held for the whole calibration the ticker could not run at all.
    assert len(during) >= 10, (took, len(during))


# ------------------------------------------------------------------- errors


def test_errors_carry_the_cli_message(tmp_path):
    missing = tmp_path / "no-such-drive"
    stderr = cli_error([str(binary("calibrator")), "calibrate", str(missing), "--no-progress"])
    with pytest.raises(wheelcal.WheelcalError) as e:
        wheelcal.calibrate(missing)
    # anyhow prints the chain on separate lines; the exception joins it with ": ".
    stderr = stderr.split("Stack backtrace:")[0]
    chain = [line.strip().split(": ", 1)[-1] if line.strip()[:1].isdigit() else line.strip() for line in stderr.splitlines()]
    chain = [c.removeprefix("Error: ") for c in chain if c and c != "Caused by:"]
    assert chain, stderr
    for part in chain:
        assert part in str(e.value), (part, str(e.value))


def test_bad_columns_are_named(sim_drive):
    cols = columns_of(sim_drive)
    rl = next(c for c in cols["wheels"].columns if c.startswith("rl_"))
    cols["wheels"] = cols["wheels"].rename(columns={rl: "rl_speed"})
    with pytest.raises(wheelcal.WheelcalError, match="rl_speed"):
        wheelcal.drive_from_columns(cols, sim_drive)
    cols = columns_of(sim_drive)
    cols["gnss"] = cols["gnss"].iloc[::-1]
    with pytest.raises(wheelcal.WheelcalError, match="gnss"):
        wheelcal.calibrate(cols, vehicle=sim_drive)
    with pytest.raises(wheelcal.WheelcalError, match="vehicle"):
        wheelcal.calibrate(columns_of(sim_drive))


def test_an_estimate_of_another_vehicle_is_refused_with_the_cli_message(tmp_path):
    wid, comma = real_drive("wid-trial02"), real_drive("comma2k19-seg40")
    est_path = tmp_path / "est.json"
    cli_json([str(binary("calibrator")), "calibrate", str(wid), "--json", str(est_path), "--no-progress"], est_path)
    stderr = cli_error([str(binary("odometry")), "evaluate", str(comma), "--estimate", str(est_path)])
    line = stderr.split("Stack backtrace:")[0].strip().splitlines()[0].removeprefix("Error: ")
    assert "not an estimate of the vehicle" in line, stderr
    with pytest.raises(wheelcal.WheelcalError) as e:
        wheelcal.evaluate(comma, est_path)
    assert str(e.value) == line
