"""A ROS 2 bag played on a DDS domain as its nodes would publish it, for the tests.

Written with cyclonedds-python's public API only (``DataWriter.write`` of IDL
samples) and rosbags: each message's CDR bytes, as the bag holds them, are turned
into a sample by cyclonedds' own deserialiser and written by its own serialiser, so
the bytes the subscriber gets are cyclonedds', not dronetrack's.

    python tests/ros2_player.py BAG DOMAIN [--wait-s 30] [--linger-s 0.5]

The clock starts once a reader matches the point topic (at most ``--wait-s``): a
point message is written when its frame ends (header stamp + the period, as a
driver publishes a frame once it is complete), every other message at its log time.
Then the player lingers and leaves the domain, which ends a subscriber's stream.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from rosbags.highlevel import AnyReader

from dronetrack.formats.ros.idl import IDL_TYPES
from dronetrack.formats.ros.livox_msg import livox_typestore

STATIC = "/tf_static"
POINTS = ("sensor_msgs/msg/PointCloud2", "livox_ros_driver2/msg/CustomMsg")


def _qos(topic: str, msg_type: str):
    from cyclonedds.core import Policy, Qos

    if topic == STATIC:
        return Qos(
            Policy.Reliability.Reliable(0),
            Policy.History.KeepLast(1),
            Policy.Durability.TransientLocal,
        )
    depth = 10 if msg_type in POINTS else 100
    return Qos(Policy.Reliability.Reliable(0), Policy.History.KeepLast(depth))


def play(bag: Path, domain: int, wait_s: float, linger_s: float, period_s: float) -> int:
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.topic import Topic

    dp = DomainParticipant(domain)
    events: list[tuple[float, int, str, bytes]] = []
    writers = {}
    with AnyReader([bag], default_typestore=livox_typestore(ros1=False)) as reader:
        conns = [c for c in reader.connections if c.msgtype in IDL_TYPES]
        for c in conns:
            topic = Topic(dp, "rt" + c.topic, IDL_TYPES[c.msgtype])
            writers[c.topic] = (DataWriter(dp, topic, _qos(c.topic, c.msgtype)), c.msgtype)
        for c, t_ns, raw in reader.messages(connections=conns):
            due = t_ns * 1e-9
            if c.msgtype in POINTS:
                due += period_s
            events.append((due, 1 if c.msgtype in POINTS else 0, c.topic, bytes(raw)))
    events.sort(key=lambda e: (e[0], e[1]))
    points = next(w for w, m in writers.values() if m in POINTS)
    end = time.monotonic() + wait_s
    while points.get_publication_matched_status().current_count == 0:
        if time.monotonic() > end:
            print("no subscriber", file=sys.stderr)
            return 1
        time.sleep(0.01)
    time.sleep(0.2)  # the subscriber's /tf readers match too
    t0, start = events[0][0], time.monotonic()
    for due, _, topic, raw in events:
        wait = start + (due - t0) - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        writer, msg_type = writers[topic]
        writer.write(IDL_TYPES[msg_type].deserialize(raw))
    time.sleep(linger_s)
    return 0


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("bag", type=Path)
    ap.add_argument("domain", type=int)
    ap.add_argument("--wait-s", type=float, default=30.0)
    ap.add_argument("--linger-s", type=float, default=0.5)
    ap.add_argument("--period-s", type=float, default=0.1)
    args = ap.parse_args()
    return play(args.bag, args.domain, args.wait_s, args.linger_s, args.period_s)


if __name__ == "__main__":
    sys.exit(main())
