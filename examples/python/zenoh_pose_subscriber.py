#!/usr/bin/env python3
"""Print the odometry's poses and the calibrator's estimates, read over Zenoh.

The wheelcal `gateway` carries topics between hosts over Zenoh: each sample
is the `#[repr(C)]` wire type's bytes behind an 80-byte frame header (type
name, size, byte order). This script connects to a gateway that sends
`pose` and/or `estimate` (`gateway --out pose,estimate --listen tcp/0.0.0.0:7447`),
checks each frame's header and decodes the sample with the same types as
pose_subscriber.py (wheelcal_wire.py, beside this file). The latest estimate
is asked for at start, so it comes even when it was published long ago.

    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install eclipse-zenoh==1.10.2
    /tmp/venv/bin/python examples/python/zenoh_pose_subscriber.py \\
        --connect tcp/192.168.1.20:7447 [--namespace NS] [--count N] [--json]

Ctrl-C stops it.
"""

import argparse
import json
import queue
import sys

import zenoh

from wheelcal_wire import (
    ESTIMATE_SERVICE,
    POSE_SERVICE,
    CircumferenceEstimate,
    FrameError,
    Pose,
    decode_frame,
    estimate_dict,
    pose_dict,
    pose_line,
)


def key(namespace: str, service: str) -> str:
    namespace = namespace.strip("/")
    return f"{namespace}/{service}" if namespace else service


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--connect", default="tcp/127.0.0.1:7447", help="the gateway's Zenoh endpoint")
    parser.add_argument("--namespace", default="", help="the gateway's --namespace")
    parser.add_argument("--count", type=int, default=0, help="stop after N poses (0: run until Ctrl-C)")
    parser.add_argument("--json", action="store_true", help="one JSON object per sample")
    args = parser.parse_args()

    config = zenoh.Config()
    config.insert_json5("mode", '"client"')
    config.insert_json5("connect/endpoints", json.dumps([args.connect]))
    config.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(config)

    pose_key = key(args.namespace, POSE_SERVICE)
    estimate_key = key(args.namespace, ESTIMATE_SERVICE)
    inbox: "queue.Queue[tuple[str, bytes]]" = queue.Queue()

    def on_sample(sample):
        inbox.put((str(sample.key_expr), sample.payload.to_bytes()))

    _subs = [session.declare_subscriber(k, on_sample) for k in (pose_key, estimate_key)]
    # The latest estimate (the gateway keeps it and answers queries).
    for reply in session.get(estimate_key):
        if reply.ok is not None:
            inbox.put((estimate_key, reply.ok.payload.to_bytes()))
    print(f"listening on {pose_key} and {estimate_key} via {args.connect}", file=sys.stderr, flush=True)

    poses = 0
    try:
        while True:
            k, data = inbox.get()
            wire_type = Pose if k == pose_key else CircumferenceEstimate
            try:
                sample = decode_frame(k, data, wire_type)
            except FrameError as e:
                print(f"rejected: {e}", file=sys.stderr, flush=True)
                continue
            if sample is None:
                print(f"{k}: end of stream", file=sys.stderr, flush=True)
                continue
            if wire_type is Pose:
                d = pose_dict(sample)
                poses += 1
                print(json.dumps({"topic": "pose", **d}) if args.json else pose_line(d), flush=True)
            else:
                d = estimate_dict(sample)
                if args.json:
                    print(json.dumps({"topic": "estimate", **d}), flush=True)
                else:
                    print(
                        f"estimate v{d['version']}: c_rl = {d['c_rl_m']:.4f} m, c_rr = {d['c_rr_m']:.4f} m",
                        flush=True,
                    )
            if args.count and poses >= args.count:
                return 0
    except KeyboardInterrupt:
        return 0
    finally:
        session.close()


if __name__ == "__main__":
    sys.exit(main())
