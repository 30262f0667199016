"""A fleet's drives in a batch: one task per drive (calibrate, diagnose),
one Parquet row per drive, on Ray or serially.

    python -m wheelcal.fleet MANIFEST.csv --out RESULTS.parquet [--address ray://...] [--num-cpus N]

The manifest is a CSV with the columns ``vehicle``, ``drive`` (a drive
folder, MCAP or ROS 2 bag path; relative paths are taken from the
manifest's folder), ``date`` and ``odometer_km``. Each drive becomes one
row (:data:`COLUMNS`): its circumferences and sigmas, the effects the
diagnosis found, the warnings, and the reason when the drive was refused,
so no drive is lost. Each task writes its row to its own Parquet file
under ``RESULTS.parts/`` atomically (a temporary file renamed) and skips
the drive when that file exists; the results are then merged in manifest
order. A task whose worker dies is retried (``max_retries``); it either
wrote its file whole or not at all, so the merge neither loses nor
duplicates a drive.

The per-drive function is :func:`drive_row`; :func:`rows_of_pandas` runs
it over a pandas batch for Spark's ``mapInPandas`` (docs/python.md).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Iterable, Iterator

import pandas as pd

from . import WheelcalError, calibrate, diagnose, read_drive

#: The columns of a result row, in order.
COLUMNS = [
    "vehicle",
    "drive",
    "date",
    "odometer_km",
    "c_rl_m",
    "c_rr_m",
    "sigma_rl_m",
    "sigma_rr_m",
    "sigma_diff_m",
    "track_width_m",
    "effects",
    "warnings",
    "refused",
    "diagnosis_refused",
]

MANIFEST_COLUMNS = ["vehicle", "drive", "date", "odometer_km"]


def _num(v) -> float:
    return float(v) if v is not None else math.nan


def drive_row(vehicle: str, drive: str, date: str, odometer_km: float, *, with_diagnosis: bool = True) -> dict:
    """Calibrate and diagnose one drive: its result row. A drive that
    cannot be read or calibrated is a row with ``refused`` set to the
    calibrator's message; one that cannot be diagnosed keeps its
    calibration and says why in ``diagnosis_refused``. Without
    ``with_diagnosis`` the row's ``effects`` stay empty and
    ``diagnosis_refused`` says the diagnosis did not run."""
    row = {
        "vehicle": str(vehicle),
        "drive": str(drive),
        "date": str(date),
        "odometer_km": float(odometer_km),
        "c_rl_m": math.nan,
        "c_rr_m": math.nan,
        "sigma_rl_m": math.nan,
        "sigma_rr_m": math.nan,
        "sigma_diff_m": math.nan,
        "track_width_m": math.nan,
        "effects": [],
        "warnings": [],
        "refused": None,
        "diagnosis_refused": None,
    }
    try:
        d = read_drive(drive)
        cal = calibrate(d).to_dict()
    except WheelcalError as e:
        row["refused"] = str(e)
        return row
    c, s = cal["circumference_m"], cal.get("sigma_m") or {}
    row.update(
        c_rl_m=float(c["rl"]),
        c_rr_m=float(c["rr"]),
        sigma_rl_m=_num(s.get("rl")),
        sigma_rr_m=_num(s.get("rr")),
        sigma_diff_m=_num(s.get("difference")),
        track_width_m=float(cal["track_width_m"]),
        warnings=[f"[{w.get('code')}] {w.get('message')}" for w in cal.get("warnings", [])],
    )
    if not with_diagnosis:
        row["diagnosis_refused"] = "not run (with_diagnosis=False)"
        return row
    try:
        row["effects"] = diagnose(d).effects
    except WheelcalError as e:
        row["diagnosis_refused"] = str(e)
    return row


def rows_of_pandas(batches: Iterable[pd.DataFrame]) -> Iterator[pd.DataFrame]:
    """For Spark's ``mapInPandas``: each batch of manifest rows to its
    result rows (``schema`` = :data:`SPARK_SCHEMA`)."""
    for batch in batches:
        rows = [drive_row(r.vehicle, r.drive, r.date, r.odometer_km) for r in batch.itertuples()]
        yield pd.DataFrame(rows, columns=COLUMNS)


#: The result rows' schema in Spark's DDL, for ``mapInPandas``.
SPARK_SCHEMA = (
    "vehicle string, drive string, date string, odometer_km double, c_rl_m double, c_rr_m double, "
    "sigma_rl_m double, sigma_rr_m double, sigma_diff_m double, track_width_m double, "
    "effects array<string>, warnings array<string>, refused string, diagnosis_refused string"
)


def read_manifest(path: Path) -> pd.DataFrame:
    """The manifest's rows, drive paths made absolute against its folder;
    a missing column or a bad odometer is an error naming the file."""
    try:
        m = pd.read_csv(path, dtype={"vehicle": str, "drive": str, "date": str})
    except (OSError, pd.errors.ParserError) as e:
        raise SystemExit(f"cannot read the manifest {path}: {e}")
    missing = [c for c in MANIFEST_COLUMNS if c not in m.columns]
    if missing:
        raise SystemExit(f"{path}: the manifest lacks the columns {', '.join(missing)} (needs {', '.join(MANIFEST_COLUMNS)})")
    try:
        m["odometer_km"] = m["odometer_km"].astype(float)
    except ValueError as e:
        raise SystemExit(f"{path}: odometer_km: {e}")
    base = path.resolve().parent
    m["drive"] = [str(p if os.path.isabs(p) else base / p) for p in m["drive"]]
    return m[MANIFEST_COLUMNS].reset_index(drop=True)


def part_name(index: int, row: dict) -> str:
    """The file of one manifest row's result (stable across runs)."""
    key = json.dumps([row[c] for c in MANIFEST_COLUMNS], default=str)
    return f"{index:06d}-{hashlib.sha1(key.encode()).hexdigest()[:12]}.parquet"


def arrow_schema():
    """The result rows' Arrow schema."""
    import pyarrow as pa

    text = [(c, pa.string()) for c in ("vehicle", "drive", "date")]
    numbers = [(c, pa.float64()) for c in COLUMNS[3:10]]
    lists = [(c, pa.list_(pa.string())) for c in ("effects", "warnings")]
    reasons = [(c, pa.string()) for c in ("refused", "diagnosis_refused")]
    return pa.schema(text + numbers + lists + reasons)


def write_part(row: dict, path: Path) -> None:
    """Write one row as a Parquet file atomically (temporary file, fsync, rename)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist([{c: row[c] for c in COLUMNS}], schema=arrow_schema())
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as f:
        pq.write_table(table, f)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def run_one(index: int, row: dict, parts: str, crash_once: str | None = None, with_diagnosis: bool = True) -> str:
    """One task: the drive's row into its part file, unless already there.
    ``crash_once`` (testing only): a marker path; when it does not exist
    yet, the task creates it and kills its own process halfway, as a
    worker lost mid-batch."""
    path = Path(parts) / part_name(index, row)
    if path.exists():
        return str(path)
    result = drive_row(row["vehicle"], row["drive"], row["date"], row["odometer_km"], with_diagnosis=with_diagnosis)
    if crash_once is not None and not os.path.exists(crash_once):
        Path(crash_once).write_text(f"{os.getpid()}\n")
        os._exit(17)
    write_part(result, path)
    return str(path)


def merge(manifest: pd.DataFrame, parts: Path, out: Path) -> pd.DataFrame:
    """The parts in manifest order into ``out`` (atomically); every
    manifest row must have its part."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    tables = []
    for i, row in enumerate(manifest.to_dict("records")):
        p = parts / part_name(i, row)
        if not p.exists():
            raise RuntimeError(f"drive {row['drive']} (manifest row {i + 2}) has no result: {p} is missing")
        tables.append(pq.read_table(p))
    table = pa.concat_tables(tables) if tables else arrow_schema().empty_table()
    tmp = out.with_name(f".{out.name}.tmp")
    pq.write_table(table, tmp)
    os.replace(tmp, out)
    return table.to_pandas()


def run(
    manifest_path: Path,
    out: Path,
    *,
    serial: bool = False,
    address: str | None = None,
    num_cpus: int | None = None,
    max_retries: int = 3,
    crash_once: dict[int, str] | None = None,
    with_diagnosis: bool = True,
) -> pd.DataFrame:
    """Run the batch; the merged rows."""
    manifest = read_manifest(manifest_path)
    parts = out.with_name(out.name + ".parts")
    parts.mkdir(parents=True, exist_ok=True)
    rows = manifest.to_dict("records")
    crash_once = crash_once or {}
    if serial:
        for i, row in enumerate(rows):
            run_one(i, row, str(parts), None, with_diagnosis)
    else:
        import ray

        if address is not None:
            ray.init(address=address)
        else:
            ray.init(num_cpus=num_cpus, include_dashboard=False)
        try:
            # By reference to the importable module (not `__main__`, which
            # `python -m wheelcal.fleet` runs), so workers import it.
            from wheelcal import fleet as importable

            task = ray.remote(num_cpus=1, max_retries=max_retries)(importable.run_one)
            refs = [task.remote(i, row, str(parts), crash_once.get(i), with_diagnosis) for i, row in enumerate(rows)]
            ray.get(refs)
        finally:
            ray.shutdown()
    return merge(manifest, parts, out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m wheelcal.fleet", description=__doc__.split("\n\n")[0])
    p.add_argument("manifest", type=Path, help="CSV: vehicle, drive, date, odometer_km")
    p.add_argument("--out", type=Path, required=True, help="the merged Parquet file")
    p.add_argument("--address", help="a Ray cluster to join (ray.init(address=...)); default: a local one")
    p.add_argument("--num-cpus", type=int, help="CPUs of the local Ray cluster (default: all)")
    p.add_argument("--max-retries", type=int, default=3, help="retries of a task whose worker dies")
    p.add_argument("--serial", action="store_true", help="no Ray: one drive after the other in this process")
    p.add_argument("--no-diagnosis", action="store_true", help="calibrate only (the rows' effects stay empty)")
    p.add_argument(
        "--crash-once",
        action="append",
        default=[],
        metavar="INDEX=MARKER",
        help="testing: the first attempt of manifest row INDEX's task kills its worker (MARKER: a file path it creates)",
    )
    a = p.parse_args(argv)
    crash = {}
    for item in a.crash_once:
        i, _, marker = item.partition("=")
        crash[int(i)] = marker
    start = time.perf_counter()
    rows = run(
        a.manifest,
        a.out,
        serial=a.serial,
        address=a.address,
        num_cpus=a.num_cpus,
        max_retries=a.max_retries,
        crash_once=crash,
        with_diagnosis=not a.no_diagnosis,
    )
    took = time.perf_counter() - start
    refused = rows["refused"].notna().sum()
    print(f"{len(rows)} drives ({refused} refused) in {took:.1f} s; wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
