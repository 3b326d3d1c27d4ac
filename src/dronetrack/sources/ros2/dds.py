"""A thin DDS layer for ROS 2 topics, on Eclipse Cyclone DDS (cyclonedds-python).

dronetrack joins a ROS 2 graph as a plain DDS participant (no rclpy): a ROS topic
``/foo`` is the DDS topic ``rt/foo`` of type ``pkg::msg::dds_::Name_``
(``formats.ros.names``), its samples XCDR1 bytes.  Samples cross this layer as
those bytes, written and taken raw: the payload is what rosbags or our numpy codecs
make and read (``formats.ros.msgs``), and the IDL classes of ``formats.ros.idl``
only name and describe the type.  cyclonedds-python's own ``DataWriter.write`` and
``DataReader.take`` (de)serialise through the IDL class, one Python object per
point; here ``ddspy_write`` and ``ddspy_take`` (the calls those two make) carry the
bytes as they are, padded to 4 bytes as ``DataWriter.write`` pads them.

QoS as ROS 2 sets it (rmw ``qos_profiles.h``): ``sensor`` BEST_EFFORT KEEP_LAST 5,
``default`` RELIABLE KEEP_LAST 10, both VOLATILE; ``static`` (``/tf_static``)
RELIABLE KEEP_LAST 1 TRANSIENT_LOCAL, as tf2's static broadcaster (read with KEEP_LAST
100); ``tf`` RELIABLE KEEP_LAST 100, as tf2's listener.  A best-effort
reader takes a reliable writer's samples too (not the other way round), so sensor
topics are read best effort.

The domain is ``--ros-domain-id``, else ``ROS_DOMAIN_ID``, else 0.  Cyclone reads
its configuration (network interface, peers, multicast) from ``CYCLONEDDS_URI``.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from dronetrack.errors import ConfigError, DeviceError, MissingExtraError
from dronetrack.formats.ros.names import QosKind, dds_topic, ros_topic, ros_type

__all__ = [
    "DdsDomain",
    "RawReader",
    "RawWriter",
    "ReaderSet",
    "TopicSeen",
    "domain_id",
    "require_cyclonedds",
]

_HINT = (
    "ROS 2 over DDS needs Eclipse Cyclone DDS for Python: pip install 'dronetrack[ros2]' "
    "(or pip install cyclonedds)"
)
MAX_DOMAIN_ID = 232  # the largest id the DDSI port mapping allows (ROS 2: 0-101, 215-232)


def require_cyclonedds() -> None:
    """MissingExtraError with the install hint unless cyclonedds imports."""
    try:
        import cyclonedds.domain  # noqa: F401
    except ImportError as err:
        raise MissingExtraError(_HINT) from err


def domain_id(given: int | None = None) -> int:
    """``--ros-domain-id``, else ``ROS_DOMAIN_ID``, else 0; ConfigError out of 0-232."""
    if given is None:
        env = os.environ.get("ROS_DOMAIN_ID", "").strip()
        try:
            given = int(env) if env else 0
        except ValueError:
            raise ConfigError(f"ROS_DOMAIN_ID={env!r} is not a number") from None
    if not 0 <= given <= MAX_DOMAIN_ID:
        raise ConfigError(f"ROS 2 domain id {given} is outside 0-{MAX_DOMAIN_ID}")
    return given


def _qos(kind: QosKind, reader: bool = False) -> Any:
    from cyclonedds.core import Policy, Qos
    from cyclonedds.util import duration

    if kind == "sensor":
        return Qos(
            Policy.Reliability.BestEffort,
            Policy.History.KeepLast(5),
            Policy.Durability.Volatile,
        )
    reliable = Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100))
    if kind == "static":
        depth = 100 if reader else 1
        return Qos(reliable, Policy.History.KeepLast(depth), Policy.Durability.TransientLocal)
    if kind == "tf":
        return Qos(reliable, Policy.History.KeepLast(100), Policy.Durability.Volatile)
    return Qos(reliable, Policy.History.KeepLast(10), Policy.Durability.Volatile)


@dataclass(frozen=True, slots=True)
class TopicSeen:
    """A ROS 2 topic some participant on the domain writes or reads, and its type."""

    topic: str
    msg_type: str
    writers: int
    readers: int


class DdsDomain:
    """One DDS participant on ROS 2 domain ``domain``; ``close`` leaves the domain.

    ``writer`` and ``reader`` make raw endpoints of a ROS topic and message type.
    """

    def __init__(self, domain: int | None = None) -> None:
        require_cyclonedds()
        from cyclonedds.core import DDSException
        from cyclonedds.domain import DomainParticipant

        self.domain_id = domain_id(domain)
        try:
            self.participant: Any = DomainParticipant(self.domain_id)
        except DDSException as exc:
            raise DeviceError(
                f"cannot join ROS 2 domain {self.domain_id} with Cyclone DDS ({exc}); check "
                "CYCLONEDDS_URI"
            ) from None
        self._topics: dict[str, Any] = {}
        self._seen: Any = None

    def _topic(self, topic: str, msg_type: str) -> Any:
        from dronetrack.formats.ros.idl import idl_type

        name = dds_topic(topic)
        found = self._topics.get(name)
        if found is not None:
            if found[1] != msg_type:
                raise ConfigError(f"topic {topic} is used as {found[1]} and as {msg_type}")
            return found[0]
        from cyclonedds.topic import Topic

        try:
            cls = idl_type(msg_type)
        except KeyError:
            raise ConfigError(f"dronetrack does not speak ROS 2 message type {msg_type}") from None
        made = Topic(self.participant, name, cls)
        self._topics[name] = (made, msg_type)
        return made

    def writer(self, topic: str, msg_type: str, qos: QosKind = "default") -> RawWriter:
        from cyclonedds.pub import DataWriter

        return RawWriter(DataWriter(self.participant, self._topic(topic, msg_type), _qos(qos)))

    def reader(self, topic: str, msg_type: str, qos: QosKind = "default") -> RawReader:
        from cyclonedds.sub import DataReader

        reader = DataReader(self.participant, self._topic(topic, msg_type), _qos(qos, True))
        return RawReader(reader, topic)

    def topics(self, wait_s: float = 0.0) -> list[TopicSeen]:
        """The ROS 2 topics other participants on the domain write or read (from the
        built-in DCPSPublication and DCPSSubscription topics), after ``wait_s`` seconds
        of discovery at most (returning as soon as the list stops growing, 0.3 s on)."""
        from cyclonedds.builtin import (
            BuiltinDataReader,
            BuiltinTopicDcpsPublication,
            BuiltinTopicDcpsSubscription,
        )

        if self._seen is None:
            self._seen = (
                BuiltinDataReader(self.participant, BuiltinTopicDcpsPublication),
                BuiltinDataReader(self.participant, BuiltinTopicDcpsSubscription),
            )
        own = self.participant.guid
        end = time.monotonic() + wait_s
        found: list[TopicSeen] = []
        steady_since = time.monotonic()
        while True:
            now = self._list(own)
            if now != found:
                found, steady_since = now, time.monotonic()
            t = time.monotonic()
            if t >= end or (found and t - steady_since >= 0.3):
                return found
            time.sleep(0.05)

    def _list(self, own: Any) -> list[TopicSeen]:
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState

        counts: dict[tuple[str, str], list[int]] = {}
        for k, reader in enumerate(self._seen):
            alive = ReadCondition(reader, SampleState.Any | ViewState.Any | InstanceState.Alive)
            for sample in reader.read(N=10_000, condition=alive):
                if getattr(sample, "participant_key", None) == own:
                    continue
                topic = ros_topic(str(sample.topic_name))
                msg_type = ros_type(str(sample.type_name))
                if topic is None or msg_type is None:
                    continue
                counts.setdefault((topic, msg_type), [0, 0])[k] += 1
        return [TopicSeen(t, m, w, r) for (t, m), (w, r) in sorted(counts.items())]

    def close(self) -> None:
        """Delete the participant and everything it made."""
        self._topics.clear()
        self._seen = None
        participant = getattr(self, "participant", None)
        if participant is not None:
            participant.__del__()
            self.participant = None


def _clayer() -> Any:
    """cyclonedds' C layer, whose ``ddspy_write`` and ``ddspy_take`` carry raw samples."""
    import importlib

    return importlib.import_module("cyclonedds._clayer")


class RawWriter:
    """A DDS writer of ready-made XCDR1 samples (with their encapsulation header)."""

    def __init__(self, writer: Any) -> None:
        self.writer = writer
        self.written = 0

    def write(self, raw: bytes) -> None:
        data = bytes(raw)
        data += b"\0" * (-len(data) % 4)
        ret = _clayer().ddspy_write(self.writer._ref, data)
        if ret < 0:
            raise DeviceError(f"DDS write on {self.writer.topic.name} failed (code {ret})")
        self.written += 1

    def matched(self) -> int:
        """How many readers match this writer now."""
        return int(self.writer.get_publication_matched_status().current_count)


class RawReader:
    """A DDS reader that hands over each sample's bytes (with the encapsulation header)."""

    def __init__(self, reader: Any, topic: str) -> None:
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState, WaitSet

        self.reader = reader
        self.topic = topic
        mask = SampleState.NotRead | ViewState.Any | InstanceState.Any
        self.condition = ReadCondition(reader, mask)
        self._waitset = WaitSet(reader.participant)
        self._waitset.attach(self.condition)
        self.ever_matched = False

    def take(self, n: int = 64) -> list[bytes]:
        """Up to ``n`` samples received and not yet taken, oldest first."""
        from cyclonedds.core import InstanceState, SampleState, ViewState

        got = _clayer().ddspy_take(
            self.reader._ref, SampleState.Any | ViewState.Any | InstanceState.Any, n
        )
        if isinstance(got, int):
            raise DeviceError(f"DDS read of {self.topic} failed (code {got})")
        return [bytes(data) for data, info in got if info.valid_data]

    def wait(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for a sample; whether one is there."""
        from cyclonedds.util import duration

        return int(self._waitset.wait(duration(seconds=max(timeout_s, 0.0)))) > 0

    def matched(self) -> int:
        """How many writers match this reader now (and note that one ever did)."""
        n = int(self.reader.get_subscription_matched_status().current_count)
        self.ever_matched = self.ever_matched or n > 0
        return n

    def drain(self, n: int = 64) -> Iterator[bytes]:
        """Every sample waiting now, in batches of ``n``."""
        while True:
            batch = self.take(n)
            yield from batch
            if len(batch) < n:
                return


class ReaderSet:
    """Waits for a sample on any of ``readers``."""

    def __init__(self, readers: list[RawReader]) -> None:
        from cyclonedds.core import WaitSet

        if not readers:
            raise ConfigError("a reader set needs at least one reader")
        self._waitset = WaitSet(readers[0].reader.participant)
        for r in readers:
            self._waitset.attach(r.condition)

    def wait(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for a sample on any reader; whether one is there."""
        from cyclonedds.util import duration

        return int(self._waitset.wait(duration(seconds=max(timeout_s, 0.0)))) > 0
