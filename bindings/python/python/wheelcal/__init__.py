"""wheelcal from Python: calibrate a car's rear wheel circumferences from a
drive, diagnose the physics the model leaves out, evaluate dead-reckoning
through GNSS outages and summarise a drive.

Every function takes a drive as a path (a drive folder, an MCAP recording,
a ROS 2 bag with ``vehicle=``), a :class:`Drive` (from :func:`read_drive` or
:func:`drive_from_columns`) or a mapping of stream name to a pandas
DataFrame (or a dict of numpy arrays) with ``vehicle=`` given. Results are
plain objects whose :meth:`Result.to_dict` equals the JSON the command-line
tool writes with ``--json`` for the same drive; errors are
:class:`WheelcalError` with the tool's message. The Rust work runs with the
GIL released, so threads calibrate drives in parallel.

    import wheelcal
    est = wheelcal.calibrate("../shared/data/real/wid-trial02")
    print(est.circumference_m, est.sigma_m)
    ev = wheelcal.evaluate("../shared/data/real/wid-trial04", est)
    print(ev["median_error_m"])
"""

from __future__ import annotations

import json
import os
from typing import Any, Iterable, Mapping, Sequence, Union

from . import _native
from ._native import WheelcalError
from ._native import Drive

__all__ = [
    "Drive",
    "Result",
    "Calibration",
    "Diagnosis",
    "DrivesDiagnosis",
    "Evaluation",
    "Info",
    "WheelcalError",
    "read_drive",
    "drive_from_columns",
    "calibrate",
    "diagnose",
    "evaluate",
    "info",
]

STREAMS = ("wheels", "gnss", "imu", "heading", "truth")


class Result:
    """A result: the JSON the command-line tool writes, as a dict.

    ``result["key"]`` and ``result.to_dict()`` read it; ``to_json()`` gives
    the text.
    """

    def __init__(self, data: dict, drive: str):
        self._data = data
        #: The drive the result is of (its path or name).
        self.drive = drive

    def to_dict(self) -> dict:
        """The result as the tool's ``--json`` writes it (a deep copy)."""
        return json.loads(json.dumps(self._data))

    def to_json(self) -> str:
        """The result as JSON text."""
        return json.dumps(self._data, indent=2)

    def __getitem__(self, key: str) -> Any:
        return self._data[key]

    def get(self, key: str, default: Any = None) -> Any:
        return self._data.get(key, default)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.drive!r})"

    def warnings_table(self):
        """The warnings as a pandas DataFrame (code, message)."""
        import pandas as pd

        rows = [
            w if isinstance(w, dict) else {"code": None, "message": w}
            for w in self._data.get("warnings", [])
        ]
        return pd.DataFrame(rows, columns=["code", "message"])


class Calibration(Result):
    """What ``calibrator calibrate --json`` writes (the estimate file)."""

    @property
    def circumference_m(self) -> tuple[float, float]:
        """Rear-left and rear-right circumference, m."""
        c = self._data["circumference_m"]
        return (c["rl"], c["rr"])

    @property
    def sigma_m(self) -> tuple[float | None, float | None]:
        """Their 1-sigma, m (None where the drive cannot determine it)."""
        s = self._data.get("sigma_m") or {}
        return (s.get("rl"), s.get("rr"))

    def iterations_table(self):
        """The per-iteration table as a pandas DataFrame."""
        import pandas as pd

        return pd.DataFrame(self._data.get("iterations", []))


class Diagnosis(Result):
    """What ``calibrator diagnose --json`` writes."""

    @property
    def effects(self) -> list[str]:
        """The effects found (accepted), by id."""
        return [f["effect"] for f in self._data.get("findings", [])]

    def findings_table(self):
        """The findings as a pandas DataFrame."""
        import pandas as pd

        return pd.DataFrame(self._data.get("findings", []))


class DrivesDiagnosis(Result):
    """What ``calibrator diagnose DRIVE DRIVE... --json`` writes: several
    drives of one car, each diagnosed, and the car's effects pooled over
    them (``car``)."""

    @property
    def drives(self) -> list[Diagnosis]:
        """Each drive's own diagnosis."""
        return [Diagnosis(d, p) for d, p in zip(self._data["drives"], self._data["paths"])]


class Evaluation(Result):
    """What ``odometry evaluate --json`` writes."""

    def outages_table(self):
        """The scored outages as a pandas DataFrame."""
        import pandas as pd

        return pd.DataFrame(self._data.get("outages", []))


class Info(Result):
    """What ``calibrator info --json`` prints."""

    def streams_table(self):
        """The streams of the drive summary as a pandas DataFrame."""
        import pandas as pd

        return pd.DataFrame(self._data["drive"].get("streams", []))


DriveLike = Union[str, os.PathLike, Drive, Mapping[str, Any]]


def read_drive(
    path: Union[str, os.PathLike],
    *,
    vehicle: Union[str, os.PathLike, None] = None,
    topics: Union[str, os.PathLike, None] = None,
    topic: Sequence[str] = (),
    skip_corrupt_chunks: bool = False,
    allow_truncated: bool = False,
) -> Drive:
    """Read a drive folder, an MCAP recording or a ROS 2 bag (as the tools
    do with ``--vehicle``, ``--topics``, ``--topic``, ``--skip-corrupt-chunks``,
    ``--allow-truncated``)."""
    return _native.read_drive(
        os.fspath(path),
        os.fspath(vehicle) if vehicle is not None else None,
        os.fspath(topics) if topics is not None else None,
        list(topic),
        skip_corrupt_chunks,
        allow_truncated,
    )


def _vehicle_toml(vehicle: Union[str, os.PathLike, Mapping[str, Any]]) -> str:
    """vehicle.toml text from a mapping, a vehicle.toml path or a drive folder."""
    if isinstance(vehicle, Mapping):
        lines, tables = [], []
        for k, v in vehicle.items():
            if isinstance(v, Mapping):
                tables.append((k, v))
            else:
                lines.append(f"{k} = {_toml_value(v)}")
        for name, table in tables:
            lines.append(f"[{name}]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in table.items()]
        return "\n".join(lines) + "\n"
    path = os.fspath(vehicle)
    if os.path.isdir(path):
        path = os.path.join(path, "vehicle.toml")
    with open(path, encoding="utf-8") as f:
        return f.read()


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    return json.dumps(str(v))


def _column_bytes(stream: str, name: str, values: Any) -> bytes:
    import numpy as np

    try:
        a = np.asarray(values, dtype="<f8")
    except (TypeError, ValueError) as e:
        raise WheelcalError(f"stream `{stream}`, column `{name}`: not numbers: {e}") from None
    if a.ndim != 1:
        raise WheelcalError(f"stream `{stream}`, column `{name}`: not one-dimensional")
    return np.ascontiguousarray(a).tobytes()


def drive_from_columns(
    streams: Mapping[str, Any],
    vehicle: Union[str, os.PathLike, Mapping[str, Any]],
    *,
    name: str = "<columns>",
) -> Drive:
    """A drive from in-memory columns.

    ``streams`` maps ``wheels``, ``gnss``, ``imu``, ``heading``, ``truth`` to
    a pandas DataFrame or a dict of 1-D arrays whose column names are the
    drive format's (``t_s``, ``rl_rad_s``, ``x_m`` or ``lat_deg``, ...);
    NaN is a missing value. ``vehicle`` is a dict of ``vehicle.toml``'s
    keys (a nested dict for ``[gnss]``), a ``vehicle.toml`` path or a drive
    folder to take it from.
    """
    raw: dict[str, dict[str, bytes]] = {}
    for stream, table in streams.items():
        if table is None:
            continue
        columns = table.columns if hasattr(table, "columns") else table.keys()
        raw[stream] = {str(c): _column_bytes(stream, str(c), table[c]) for c in columns}
    return _native.drive_from_columns(name, _vehicle_toml(vehicle), raw)


def _drive(drive: DriveLike, vehicle: Any = None) -> Drive:
    if isinstance(drive, Drive):
        return drive
    if isinstance(drive, Mapping):
        if vehicle is None:
            raise WheelcalError("a drive given as columns needs vehicle= (a dict or a vehicle.toml)")
        return drive_from_columns(drive, vehicle)
    if isinstance(drive, (str, os.PathLike)):
        return read_drive(drive, vehicle=vehicle)
    raise TypeError(f"not a drive: {type(drive).__name__} (a path, a Drive or a mapping of streams)")


def calibrate(drive: DriveLike, *, vehicle: Any = None, diagnose: bool = False) -> Calibration:
    """``calibrator calibrate DRIVE --json`` (``diagnose=True``: ``--diagnose``)."""
    d = _drive(drive, vehicle)
    return Calibration(json.loads(_native.calibrate(d, diagnose)), d.name)


def diagnose(
    drive: Union[DriveLike, Iterable[DriveLike]],
    *,
    vehicle: Any = None,
    block_s: float | None = None,
) -> Union[Diagnosis, DrivesDiagnosis]:
    """``calibrator diagnose DRIVE --json``; a list (or tuple) of drives of
    one car is ``calibrator diagnose DRIVE DRIVE... --json``: each drive
    diagnosed and the car's effects over all of them
    (:class:`DrivesDiagnosis`; ``.drives`` holds each drive's own)."""
    if isinstance(drive, (list, tuple)):
        if len(drive) == 1:
            return diagnose(drive[0], vehicle=vehicle, block_s=block_s)
        if not drive:
            raise WheelcalError("diagnose: no drives given")
        ds = [_drive(x, vehicle) for x in drive]
        return DrivesDiagnosis(json.loads(_native.diagnose_drives(ds, block_s)), ", ".join(d.name for d in ds))
    d = _drive(drive, vehicle)
    return Diagnosis(json.loads(_native.diagnose(d, block_s)), d.name)


def info(drive: DriveLike, *, vehicle: Any = None) -> Info:
    """``calibrator info DRIVE --json``."""
    d = _drive(drive, vehicle)
    return Info(json.loads(_native.info(d)), d.name)


def evaluate(
    drive: DriveLike,
    estimate: Union[Calibration, Mapping[str, Any], str, os.PathLike, None] = None,
    *,
    vehicle: Any = None,
    outage_s: float = 30.0,
    spacing_s: float = 10.0,
) -> Evaluation:
    """``odometry evaluate DRIVE [--estimate EST] --outage S --spacing S --json``.

    ``estimate``: a :class:`Calibration`, its dict, or an estimate file's
    path; None uses vehicle.toml's nominal values.
    """
    d = _drive(drive, vehicle)
    text, source = None, "estimate"
    if isinstance(estimate, Calibration):
        text, source = estimate.to_json(), f"the calibration of {estimate.drive}"
    elif isinstance(estimate, Mapping):
        text = json.dumps(dict(estimate))
    elif estimate is not None:
        source = os.fspath(estimate)
        try:
            with open(source, encoding="utf-8") as f:
                text = f.read()
        except OSError as e:
            raise WheelcalError(f"cannot use the estimate: {source}: {e}") from None
    return Evaluation(json.loads(_native.evaluate(d, text, source, outage_s, spacing_s)), d.name)
