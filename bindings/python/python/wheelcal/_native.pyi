"""Type stubs of the native module (Rust, PyO3): each function returns the
JSON text the command-line tool writes with --json."""

from typing import Optional

class WheelcalError(Exception):
    """A drive that cannot be read, calibrated, diagnosed or evaluated: the
    message is the command-line tool's."""

class Drive:
    """A drive read from a path or built from columns."""

    @property
    def name(self) -> str: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def duration_s(self) -> float: ...

def read_drive(
    path: str,
    vehicle: Optional[str] = None,
    topics: Optional[str] = None,
    topic: list[str] = ...,
    skip_corrupt_chunks: bool = False,
    allow_truncated: bool = False,
) -> Drive: ...
def drive_from_columns(
    name: str, vehicle_toml: str, streams: dict[str, dict[str, bytes]]
) -> Drive: ...
def calibrate(drive: Drive, diagnose: bool = False) -> str: ...
def diagnose(drive: Drive, block_s: Optional[float] = None) -> str: ...
def diagnose_drives(drives: list[Drive], block_s: Optional[float] = None) -> str: ...
def info(drive: Drive) -> str: ...
def evaluate(
    drive: Drive,
    estimate_json: Optional[str] = None,
    estimate_source: str = "estimate",
    outage_s: float = 30.0,
    spacing_s: float = 10.0,
) -> str: ...
