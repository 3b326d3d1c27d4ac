"""The command side of a Livox host link, SDK 1 and SDK 2 alike: numbered commands sent
to the device until their ACK comes, and the control thread, which receives the ACKs
on the command socket and keeps the link alive.

The control thread sends the protocol's keep-alive every ``heartbeat_period_s`` once
the link is connected, and marks the link dead after ``heartbeat_timeout_s`` without
an answer to it (``livox_keepalive.KeepAlive``).  It wakes at least every 50 ms to see
a stop request.  A caller waiting for an ACK waits ``ack_wait_s`` per try and resends
the command until its deadline, with a new sequence number each time."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Mapping

from dronetrack.errors import ConfigError, DecodeError, DeviceError
from dronetrack.sources.livox.keepalive import KeepAlive
from dronetrack.sources.queues import AckBox
from dronetrack.sources.udp import MAX_DATAGRAM

__all__ = ["LivoxCommands"]


class LivoxCommands:
    """Commands and the keep-alive of the device at ``device_ip`` (see the module
    docstring), over the command socket ``_socks["cmd"]`` that the link binds.

    Counters: ``heartbeats_sent`` and ``heartbeats_missed`` (keep-alives without an
    answer before the next one).  A subclass sets ``sdk`` (names the device before
    discovery), ``device_types``, ``keepalive_name``, ``ack_wait_s`` and
    ``seq_modulus``, and implements the hooks below the ``# -- protocol`` line.
    """

    sdk = "device"
    device_types: Mapping[int, str] = {}  # device type → model name
    keepalive_name = "keep-alive"
    ack_wait_s = 0.5  # one try of a command
    seq_modulus = 0xFFFF  # seq runs 1 … seq_modulus and wraps to 1

    def __init__(self, device_ip: str, heartbeat_period_s: float, heartbeat_timeout_s: float):
        if not 0 < heartbeat_period_s < heartbeat_timeout_s:
            raise ConfigError(
                f"the {self.keepalive_name} period {heartbeat_period_s} s must be positive and "
                f"below its timeout {heartbeat_timeout_s} s"
            )
        self.device_ip = device_ip
        self.heartbeat_period_s = heartbeat_period_s
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.dev_type: int | None = None  # from discovery
        self._socks: dict[str, socket.socket] = {}
        self._stop = threading.Event()
        self._acks = AckBox()
        self._beat = KeepAlive(heartbeat_period_s, heartbeat_timeout_s)
        self._seq = 0
        self._seq_lock = threading.Lock()
        self._connected = False
        self._dead: str | None = None  # why the link is dead

    @property
    def name(self) -> str:
        """The model once discovery named it, else the SDK, and the IP."""
        kind = self.device_types.get(self.dev_type, "") if self.dev_type is not None else ""
        return f"Livox {kind or self.sdk} at {self.device_ip}"

    @property
    def heartbeats_sent(self) -> int:
        return self._beat.sent

    @property
    def heartbeats_missed(self) -> int:
        return self._beat.missed

    # -- protocol: hooks of a subclass ------------------------------------------------

    def _device_address(self) -> tuple[str, int]:
        """Where commands go."""
        raise NotImplementedError

    def _encode_command(self, cmd_id: int, payload: bytes, seq: int, cmd_type: int | None) -> bytes:
        raise NotImplementedError

    def _parse_reply(self, buf: bytes) -> tuple[bool, int, bytes] | None:
        """(answers the keep-alive, seq, ACK payload) of a datagram on the command
        socket, or None to ignore it."""
        raise NotImplementedError

    def _ret_code(self, payload: bytes) -> int | None:
        return payload[0] if payload else None

    def _send_keepalive(self) -> None:
        raise NotImplementedError

    # -- commands --------------------------------------------------------------------

    def _send(self, cmd_id: int, payload: bytes, cmd_type: int | None = None) -> int:
        with self._seq_lock:
            self._seq = self._seq % self.seq_modulus + 1
            seq = self._seq
        frame = self._encode_command(cmd_id, payload, seq, cmd_type)
        sock = self._socks.get("cmd")
        if sock is None:
            raise DeviceError(f"{self.name}: the command socket is closed")
        try:
            sock.sendto(frame, self._device_address())
        except OSError as exc:
            raise DeviceError(f"{self.name}: cannot send a command: {exc}") from exc
        return seq

    def _request(
        self, cmd_id: int, payload: bytes, deadline: float, cmd_type: int | None = None
    ) -> int | None:
        """Send the command until its ACK comes (each try waits ``ack_wait_s``) or
        ``deadline`` passes; the ACK's ret_code, or None without an ACK."""
        ack = self._ask(cmd_id, payload, deadline, cmd_type)
        return None if ack is None else self._ret_code(ack)

    def _ask(
        self, cmd_id: int, payload: bytes, deadline: float, cmd_type: int | None = None
    ) -> bytes | None:
        """As ``_request``, but the ACK's whole payload (None without an ACK)."""
        while True:
            seq = self._send(cmd_id, payload, cmd_type)
            ack = self._acks.wait(seq, min(deadline, time.monotonic() + self.ack_wait_s))
            if ack is not None:
                return ack
            if time.monotonic() >= deadline or self._dead:
                return None

    def _keepalive_answered(self) -> None:
        self._beat.answered(time.monotonic())

    def _control_loop(self) -> None:
        """Receive ACKs; send the keep-alive every period and watch its answers."""
        sock = self._socks["cmd"]
        beat = self._beat
        while not self._stop.is_set():
            now = time.monotonic()
            if self._connected and self._dead is None:
                if beat.expired(now):
                    self._dead = f"no {self.keepalive_name} ACK for {beat.timeout_s:g} s"
                elif beat.due(now):
                    try:
                        self._send_keepalive()
                        beat.was_sent(now, ok=True)
                    except DeviceError:  # a send error shows up as missing answers
                        beat.was_sent(now, ok=False)
            try:
                buf = sock.recv(MAX_DATAGRAM)
            except TimeoutError:
                continue
            except OSError:
                return  # socket closed under us
            try:
                reply = self._parse_reply(buf)
            except DecodeError:
                continue
            if reply is None:
                continue
            keepalive, seq, payload = reply
            if keepalive:
                self._keepalive_answered()
                continue
            self._acks.put(seq, payload)
