"""The wheelcal wire types in Python, shared by the example subscribers.

`Pose` and `CircumferenceEstimate` are the `#[repr(C)]` types of
`interfaces::wire` with the same versioned type names (sizes checked below),
so iceoryx2 connects a Python subscriber to the Rust publisher, and a sample
that came over Zenoh decodes the same way once its gateway frame header is
taken off (`decode_frame`; the format is in services/gateway/src/header.rs).
"""

import ctypes
import struct
import sys

MODES = {0: "no_fix", 1: "fused", 2: "dead_reckoning"}
POSE_SERVICE = "wheelcal/odometry/pose"
ESTIMATE_SERVICE = "wheelcal/calibration/estimate"


class Header(ctypes.Structure):
    """interfaces::wire::Header: vehicle-clock time and sequence number."""

    _fields_ = [("t_ns", ctypes.c_int64), ("seq", ctypes.c_uint64)]

    @staticmethod
    def type_name() -> str:
        return "wheelcal/Header/v1"


class Pose(ctypes.Structure):
    """interfaces::wire::Pose: the rear-axle centre in local ENU."""

    _fields_ = [
        ("header", Header),
        ("x_m", ctypes.c_double),
        ("y_m", ctypes.c_double),
        ("yaw_rad", ctypes.c_double),
        ("covariance", ctypes.c_double * 9),
        ("estimate_version", ctypes.c_uint64),
        ("mode", ctypes.c_uint8),
        ("_pad", ctypes.c_uint8 * 7),
    ]

    @staticmethod
    def type_name() -> str:
        return "wheelcal/Pose/v1"


class ModelExtension(ctypes.Structure):
    """interfaces::wire::ModelExtension: one extension of the 2W model."""

    _fields_ = [
        ("effect_code", ctypes.c_uint32),
        ("param_count", ctypes.c_uint32),
        ("params", ctypes.c_double * 4),
    ]

    @staticmethod
    def type_name() -> str:
        return "wheelcal/ModelExtension/v1"


class CircumferenceEstimate(ctypes.Structure):
    """interfaces::wire::CircumferenceEstimate: an accepted calibration."""

    _fields_ = [
        ("header", Header),
        ("version", ctypes.c_uint64),
        ("c_rl_m", ctypes.c_double),
        ("c_rr_m", ctypes.c_double),
        ("sigma_rl_m", ctypes.c_double),
        ("sigma_rr_m", ctypes.c_double),
        ("track_width_m", ctypes.c_double),
        ("gyro_bias_rad_s", ctypes.c_double),
        ("gyro_scale", ctypes.c_double),
        ("quality_m", ctypes.c_double),
        ("extension_count", ctypes.c_uint32),
        ("_pad", ctypes.c_uint32),
        ("extensions", ModelExtension * 8),
    ]

    @staticmethod
    def type_name() -> str:
        return "wheelcal/CircumferenceEstimate/v1"


assert ctypes.sizeof(Pose) == 128 and ctypes.alignment(Pose) == 8
assert ctypes.sizeof(CircumferenceEstimate) == 416


def pose_dict(p: Pose) -> dict:
    return {
        "t_ns": p.header.t_ns,
        "seq": p.header.seq,
        "x_m": p.x_m,
        "y_m": p.y_m,
        "yaw_rad": p.yaw_rad,
        "covariance": list(p.covariance),
        "estimate_version": p.estimate_version,
        "mode": MODES.get(p.mode, f"unknown({p.mode})"),
    }


def estimate_dict(e: CircumferenceEstimate) -> dict:
    return {
        "t_ns": e.header.t_ns,
        "seq": e.header.seq,
        "version": e.version,
        "c_rl_m": e.c_rl_m,
        "c_rr_m": e.c_rr_m,
        "sigma_rl_m": e.sigma_rl_m,
        "sigma_rr_m": e.sigma_rr_m,
        "track_width_m": e.track_width_m,
        "gyro_bias_rad_s": e.gyro_bias_rad_s,
        "gyro_scale": e.gyro_scale,
        "quality_m": e.quality_m,
        "extensions": [
            {"effect_code": x.effect_code, "params": list(x.params)[: x.param_count]}
            for x in list(e.extensions)[: e.extension_count]
        ],
    }


def pose_line(d: dict) -> str:
    """One line of text for a pose dict."""
    return (
        f"t = {d['t_ns'] * 1e-9:10.2f} s  x = {d['x_m']:9.2f} m  y = {d['y_m']:9.2f} m  "
        f"yaw = {d['yaw_rad']:+.3f} rad  {d['mode']:<14}  estimate v{d['estimate_version']}"
    )


# The gateway's frame header (services/gateway/src/header.rs).
FRAME_MAGIC = b"WCGW"
FRAME_HEADER_VERSION = 1
FRAME_HEADER_LEN = 80
KIND_SAMPLE, KIND_END_OF_STREAM = 0, 1
NATIVE_ORDER = 1 if sys.byteorder == "little" else 2


class FrameError(ValueError):
    """A frame that cannot be taken; the message names the key expression."""


def decode_frame(key: str, data: bytes, wire_type):
    """Check a gateway frame against `wire_type` and decode it.

    Returns the sample (a `wire_type` instance), or None for an end-of-stream
    frame; raises FrameError naming `key` for anything else.
    """
    if len(data) < FRAME_HEADER_LEN:
        raise FrameError(f"{key}: frame of {len(data)} bytes is truncated")
    magic, version, order, kind, _r, size, _r2, _gateway, _origin = struct.unpack_from("<4sBBBBIIQQ", data, 0)
    if magic != FRAME_MAGIC:
        raise FrameError(f"{key}: not a wheelcal gateway frame (magic {magic!r})")
    if version != FRAME_HEADER_VERSION:
        raise FrameError(f"{key}: gateway header version {version}, this reads {FRAME_HEADER_VERSION}")
    type_name = data[32:80].split(b"\0", 1)[0].decode("utf-8")
    payload = data[FRAME_HEADER_LEN:]
    if len(payload) != size:
        raise FrameError(f"{key}: frame states {size} payload bytes, has {len(payload)}")
    expected_size = ctypes.sizeof(wire_type)
    if type_name != wire_type.type_name() or (kind == KIND_SAMPLE and size != expected_size):
        raise FrameError(
            f"{key}: type mismatch: the sender publishes {type_name!r} ({size} bytes), "
            f"this side expects {wire_type.type_name()!r} ({expected_size} bytes)"
        )
    if order != NATIVE_ORDER:
        raise FrameError(f"{key}: the payload's byte order is not this host's")
    if kind == KIND_END_OF_STREAM:
        return None
    if kind != KIND_SAMPLE:
        raise FrameError(f"{key}: unknown frame kind {kind}")
    return wire_type.from_buffer_copy(payload)
