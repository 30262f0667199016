#!/usr/bin/env python3
"""Print the odometry's poses, read from the wheelcal process graph over iceoryx2.

The wire types hold across languages: `Pose` (in wheelcal_wire.py, beside
this file) is the `#[repr(C)]` `interfaces::wire::Pose` (128 bytes) with the
same versioned type name, so iceoryx2 connects this subscriber to the Rust
publisher. zenoh_pose_subscriber.py reads the same poses over Zenoh.

    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install iceoryx2==0.10.0
    /tmp/venv/bin/python examples/python/pose_subscriber.py [--count N] [--json]

It ends by itself when the odometry signals the end of the pose stream (the
end-of-stream event on the pose topic, sent when the odometry's wheel stream
ends and when it stops), after --count poses, or on Ctrl-C.

The graph is chosen like every wheelcal process does: WHEELCAL_IOX_PREFIX and
WHEELCAL_IOX_ROOT (unset: iceoryx2's defaults). The service settings must be
those of `interfaces::bus` (whoever creates the service first decides them).
"""

import argparse
import json
import os
import sys

import iceoryx2 as iox

# The wire types and their decoding, shared with zenoh_pose_subscriber.py.
from wheelcal_wire import POSE_SERVICE, Pose, pose_dict, pose_line

# interfaces::bus: lossless stream settings and event ids.
STREAM_BUFFER = 1024
MAX_SUBSCRIBERS = 8
MAX_PUBLISHERS = 2
MAX_NODES = 32
EVENT_END_OF_STREAM = 2
EVENT_PUBLISHER_DROPPED = 3
EVENT_PUBLISHER_DEAD = 4


def make_config():
    config = iox.config.default()
    prefix = os.environ.get("WHEELCAL_IOX_PREFIX")
    root = os.environ.get("WHEELCAL_IOX_ROOT")
    if prefix:
        config.global_cfg.prefix = iox.FileName.new(prefix)
    if root:
        config.global_cfg.root_path = iox.Path.new(root.rstrip("/") + "/")
    return config


def event_id(activation) -> int:
    value = activation.id.as_value
    return value() if callable(value) else value


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=0, help="stop after N poses (0: run until Ctrl-C)")
    parser.add_argument("--json", action="store_true", help="one JSON object per pose")
    args = parser.parse_args()

    iox.set_log_level_from_env_or(iox.LogLevel.Warn)
    node = iox.NodeBuilder.new().config(make_config()).create(iox.ServiceType.Ipc)
    name = iox.ServiceName.new(POSE_SERVICE)
    service = (
        node.service_builder(name)
        .publish_subscribe(Pose)
        .enable_safe_overflow(False)
        .subscriber_max_buffer_size(STREAM_BUFFER)
        .history_size(0)
        .subscriber_max_borrowed_samples(2)
        .max_subscribers(MAX_SUBSCRIBERS)
        .max_publishers(MAX_PUBLISHERS)
        .max_nodes(MAX_NODES)
        .open_or_create()
    )
    event = (
        node.service_builder(name)
        .event()
        .max_notifiers(2 * MAX_PUBLISHERS)
        .max_listeners(2 * MAX_SUBSCRIBERS)
        .max_nodes(MAX_NODES)
        .notifier_dropped_event(iox.EventId.new(EVENT_PUBLISHER_DROPPED))
        .notifier_dead_event(iox.EventId.new(EVENT_PUBLISHER_DEAD))
        .open_or_create()
    )
    subscriber = service.subscriber_builder().buffer_size(STREAM_BUFFER).create()
    listener = event.listener_builder().create()
    waitset = iox.WaitSetBuilder.new().create(iox.ServiceType.Ipc)
    _guard = waitset.attach_notification(listener)
    _tick = waitset.attach_interval(iox.Duration.from_millis(100))
    print(f"listening on {POSE_SERVICE}", file=sys.stderr, flush=True)

    received = 0
    while True:
        _ids, result = waitset.wait_and_process()
        ended = False
        for activation in listener.try_wait():  # drain, or the waitset spins
            if event_id(activation) == EVENT_END_OF_STREAM:
                ended = True
        while True:
            sample = subscriber.receive()
            if sample is None:
                break
            pose = sample.payload().contents
            d = pose_dict(pose)
            sample.delete()
            received += 1
            if args.json:
                print(json.dumps(d), flush=True)
            else:
                print(pose_line(d), flush=True)
            if args.count and received >= args.count:
                return 0
        if result in (iox.WaitSetRunResult.Interrupt, iox.WaitSetRunResult.TerminationRequest):
            return 0
        if ended:
            # The odometry says so when its wheel stream ends, and when it stops.
            print(f"pose stream ended after {received} poses", file=sys.stderr)
            return 0


if __name__ == "__main__":
    sys.exit(main())
