"""The device URI of a Livox host client: ``SCHEME://IP[?host=IP&KEY=N…]`` (``livox://``
for SDK 1, ``livox2://`` for SDK 2), read into the keyword fields of the client's
endpoint, with a ConfigError that names what is wrong."""

from __future__ import annotations

import ipaddress
from collections.abc import Mapping
from urllib.parse import parse_qsl, urlsplit

from dronetrack.errors import ConfigError

__all__ = ["parse_device_uri"]


def _ipv4(text: str, what: str, uri: str) -> str:
    try:
        return str(ipaddress.IPv4Address(text))
    except ValueError:
        raise ConfigError(f"{uri!r}: {what} {text!r} is not an IPv4 address") from None


def parse_device_uri(
    uri: str,
    scheme: str,
    sdk: str,
    port_keys: Mapping[str, int],
    choice_keys: Mapping[str, Mapping[str, object]] | None = None,
) -> dict[str, object]:
    """``SCHEME://IP[?host=IP&KEY=N…]`` as keyword fields: ``device_ip``, ``host_ip``
    if given, each port key given (an integer from its lowest value in ``port_keys``
    to 65535) and each choice key given (its text's value in ``choice_keys[key]``);
    ConfigError naming the problem."""
    choices = choice_keys or {}
    try:
        parts = urlsplit(uri)
    except ValueError as exc:
        raise ConfigError(f"{uri!r} is not a URI: {exc}") from None
    if parts.scheme != scheme:
        raise ConfigError(f"{uri!r}: a Livox {sdk} device is given as {scheme}://IP")
    if parts.path not in ("", "/") or parts.fragment:
        raise ConfigError(f"{uri!r}: {scheme}://IP takes no path or fragment")
    netloc = parts.netloc
    if not netloc:
        raise ConfigError(f"{uri!r}: no device IP after {scheme}://")
    if "@" in netloc or ":" in netloc:
        raise ConfigError(
            f"{uri!r}: give only the device's IPv4 address after {scheme}:// "
            "(its command port is the query key device_port)"
        )
    fields: dict[str, object] = {"device_ip": _ipv4(netloc, "device IP", uri)}
    try:
        pairs = parse_qsl(parts.query, keep_blank_values=True, strict_parsing=bool(parts.query))
    except ValueError:
        raise ConfigError(f"{uri!r}: the query is not key=value pairs joined by &") from None
    for key, value in pairs:
        if key in fields or (key == "host" and "host_ip" in fields):
            raise ConfigError(f"{uri!r}: query key {key!r} is given twice")
        if key == "host":
            fields["host_ip"] = _ipv4(value, "host", uri)
        elif key in port_keys:
            low = port_keys[key]
            if not value.isdigit() or not low <= int(value) <= 65535:
                raise ConfigError(f"{uri!r}: {key}={value!r} is not a port in {low}..65535")
            fields[key] = int(value)
        elif key in choices:
            if value not in choices[key]:
                allowed = ", ".join(choices[key])
                raise ConfigError(f"{uri!r}: {key}={value!r} is not one of {allowed}")
            fields[key] = choices[key][value]
        else:
            known = ", ".join(("host", *port_keys, *choices))
            raise ConfigError(f"{uri!r}: unknown query key {key!r} (known: {known})")
    return fields
