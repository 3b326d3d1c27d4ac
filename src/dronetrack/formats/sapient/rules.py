"""The rules the SAPIENT definitions put on a message through their field options
(``sapient_msg/proto_options.proto``): mandatory fields and oneofs, IDs that must be
ULIDs or UUIDs, and enum values the definitions know.

dstl's Apex middleware checks the same rules before it stores a message
(``sapient_apex_server/validate_proto.py``, with ``strictIdFormat``: a UUID is a
lower-case version-4 UUID, a ULID upper case), so a fusion node built on it may
refuse what breaks them.  ``sapient-listen`` says so; the tests hold every message
dronetrack builds to them.
"""

from __future__ import annotations

import re
from functools import cache
from typing import Any, NamedTuple

from google.protobuf.descriptor import FieldDescriptor

from dronetrack.formats.sapient.sapient_msg import proto_options_pb2

__all__ = ["ULID_PATTERN", "UUID4_PATTERN", "broken_rules"]

# 26 Crockford base-32 characters, upper case, the first at most 7 (128 bits)
ULID_PATTERN = re.compile(r"[0-7][0-9A-HJKMNP-TV-Z]{25}")
UUID4_PATTERN = re.compile(r"[0-9a-f]{8}-[0-9a-f]{4}-4[0-9a-f]{3}-[89ab][0-9a-f]{3}-[0-9a-f]{12}")


class _Rule(NamedTuple):
    """A field's or oneof's options: what proto_options.proto's ValidationOptions say."""

    mandatory: bool
    ulid: bool
    uuid: bool


@cache
def _rule(descriptor: Any) -> _Rule:
    """The rule of a field or oneof descriptor (read once: a descriptor lives as long
    as its pool)."""
    kind = (
        proto_options_pb2.field_options
        if isinstance(descriptor, FieldDescriptor)
        else proto_options_pb2.oneof_options
    )
    options = descriptor.GetOptions().Extensions[kind]
    return _Rule(options.is_mandatory, options.is_ulid, options.is_uuid)


def broken_rules(message: Any, path: str = "") -> list[str]:
    """Each rule ``message`` (any SAPIENT message, of any descriptor pool) breaks, as
    ``field.path: what``; an empty list if it keeps them all.

    A field is present as protobuf's ``ListFields`` sees it: a proto3 field without
    explicit presence that holds its default value counts as missing.  Nested
    messages of the SAPIENT definitions are checked too.
    """
    broken = []
    for oneof in message.DESCRIPTOR.oneofs:
        if _rule(oneof).mandatory and message.WhichOneof(oneof.name) is None:
            broken.append(f"{path}{oneof.name}: none of its fields is set")
    present = dict(message.ListFields())
    for field in message.DESCRIPTOR.fields:
        name = path + field.name
        value = present.get(field)
        rule = _rule(field)
        if value is None:
            if rule.mandatory:
                broken.append(f"{name}: mandatory, missing")
            continue
        for i, item in enumerate(value if field.is_repeated else [value]):
            where = f"{name}[{i}]" if field.is_repeated else name
            broken += _broken_value(field, rule, item, where)
    return broken


def _broken_value(field: Any, rule: _Rule, value: Any, where: str) -> list[str]:
    """The rules one value of ``field`` breaks (its nested message's too)."""
    if rule.ulid and not ULID_PATTERN.fullmatch(value):
        return [f"{where}: {value!r} is no upper-case ULID"]
    if rule.uuid and not UUID4_PATTERN.fullmatch(value):
        return [f"{where}: {value!r} is no lower-case version-4 UUID"]
    if field.type == FieldDescriptor.TYPE_ENUM and value not in field.enum_type.values_by_number:
        return [f"{where}: {value} is no {field.enum_type.name}"]
    if field.type == FieldDescriptor.TYPE_MESSAGE and field.message_type.full_name.startswith(
        "sapient_msg."
    ):
        return broken_rules(value, where + ".")
    return []
