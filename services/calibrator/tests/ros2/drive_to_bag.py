"""Write a drive folder as a ROS 2 bag (rosbag2, MCAP storage, zstd chunks)
with the third-party `rosbags` package, for the calibrator's bag test.

    python drive_to_bag.py DRIVE_FOLDER OUT_BAG EPOCH_NS

Header stamps are EPOCH_NS + round(t_s * 1e9). gnss.csv (lat_deg, lon_deg,
optional sigma_m) -> /fix NavSatFix; imu.csv -> /imu/data Imu (the IMU
accelerations big endian, to exercise both byte orders); wheels.csv
(W_rad_s columns) -> /joint_states JointState with joints
{rear,front}_{left,right}_wheel_joint.
"""

import csv
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.typesys import Stores, get_typestore


def rows(path):
    with open(path, newline="") as f:
        lines = [l for l in f if l.strip() and not l.startswith("#")]
    return list(csv.DictReader(lines))


def main():
    folder, out, epoch_ns = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]

    def header(t_s):
        ns = epoch_ns + round(float(t_s) * 1e9)
        return ns, Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="base_link")

    messages = []  # (ns, topic, bytes)
    for r in rows(folder / "gnss.csv"):
        if r.get("fix") == "0":
            continue
        ns, h = header(r["t_s"])
        sigma = float(r["sigma_m"]) if r.get("sigma_m") else None
        cov = np.zeros(9)
        if sigma is not None:
            cov[0] = cov[4] = sigma * sigma
        msg = T["sensor_msgs/msg/NavSatFix"](
            header=h,
            status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
            latitude=float(r["lat_deg"]),
            longitude=float(r["lon_deg"]),
            altitude=0.0,
            position_covariance=cov,
            position_covariance_type=2 if sigma is not None else 0,
        )
        messages.append((ns, "/fix", ts.serialize_cdr(msg, msg.__msgtype__, little_endian=True)))
    V3, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    for r in rows(folder / "imu.csv"):
        ns, h = header(r["t_s"])
        g = lambda k: float(r[k]) if r.get(k) else 0.0
        acc_cov = np.zeros(9)
        if not r.get("ax_m_s2"):
            acc_cov[0] = -1.0
        msg = T["sensor_msgs/msg/Imu"](
            header=h,
            orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.array([-1.0] + [0.0] * 8),
            angular_velocity=V3(x=g("gx_rad_s"), y=g("gy_rad_s"), z=g("gz_rad_s")),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=V3(x=g("ax_m_s2"), y=g("ay_m_s2"), z=g("az_m_s2")),
            linear_acceleration_covariance=acc_cov,
        )
        messages.append((ns, "/imu/data", ts.serialize_cdr(msg, msg.__msgtype__, little_endian=False)))
    wheels = rows(folder / "wheels.csv")
    names = {
        "rl": "rear_left_wheel_joint",
        "rr": "rear_right_wheel_joint",
        "fl": "front_left_wheel_joint",
        "fr": "front_right_wheel_joint",
    }
    present = [w for w in names if f"{w}_rad_s" in wheels[0]]
    for r in wheels:
        ns, h = header(r["t_s"])
        msg = T["sensor_msgs/msg/JointState"](
            header=h,
            name=[names[w] for w in present],
            position=np.zeros(len(present)),
            velocity=np.array([float(r[f"{w}_rad_s"]) for w in present]),
            effort=np.zeros(0),
        )
        messages.append((ns, "/joint_states", ts.serialize_cdr(msg, msg.__msgtype__, little_endian=True)))

    writer = Writer(out, version=8, storage_plugin=StoragePlugin.MCAP)
    writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer:
        types = {
            "/fix": "sensor_msgs/msg/NavSatFix",
            "/imu/data": "sensor_msgs/msg/Imu",
            "/joint_states": "sensor_msgs/msg/JointState",
        }
        conns = {t: writer.add_connection(t, m, typestore=ts) for t, m in types.items()}
        messages.sort(key=lambda m: m[0])
        for ns, topic, data in messages:
            writer.write(conns[topic], ns, data)


if __name__ == "__main__":
    main()
