"""The UDP side of a Livox host client: its sockets, bound on all interfaces as the
Livox SDKs bind them and polled so that a thread sees a stop request, and the local
address the host reaches a device from."""

from __future__ import annotations

import socket

from dronetrack.errors import DeviceError

__all__ = ["MAX_DATAGRAM", "POLL_S", "route_source_ip", "udp_socket"]

POLL_S = 0.05  # longest a thread blocks before it looks at the stop request
MAX_DATAGRAM = 2048  # the largest Livox datagram is 1400 bytes


def udp_socket(port: int, what: str, rcvbuf: int = 0) -> socket.socket:
    """A UDP socket bound to ``port`` on all interfaces (as the SDKs bind), polling."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        if rcvbuf:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        sock.bind(("0.0.0.0", port))
    except OSError as exc:
        sock.close()
        raise DeviceError(f"cannot bind UDP port {port} for Livox {what}: {exc}") from exc
    sock.settimeout(POLL_S)
    return sock


def route_source_ip(device_ip: str, device_port: int) -> str:
    """The local address the host sends to ``device_ip`` from (a connected UDP socket
    sends nothing; the kernel only picks the route)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect((device_ip, device_port))
        except OSError as exc:
            raise DeviceError(
                f"Livox device at {device_ip}: no route from this host: {exc}"
            ) from exc
        return str(probe.getsockname()[0])
