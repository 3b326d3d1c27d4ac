"""SAPIENT (BSI Flex 335 v2.0): the interface between counter-UAS edge nodes and the
fusion nodes of a command-and-control (C2) system.

- ``sapient_msg/``: dstl's protobuf definitions, vendored as they are under their
  Apache-2.0 licence, and the Python modules protoc compiles from them
  (``tools/sapient_protoc.py``);
- ``framing``: a ``SapientMessage`` on a TCP stream, length-prefixed;
- ``fields``: what every message shares (IDs, timestamps, locations, range-bearings);
- ``registration``, ``tasks``: the node's Registration; the look-at Task and its
  reading;
- ``messages``: every message dronetrack sends and reads, built from plain values.

Needs the optional extra ``[sapient]`` (protobuf and python-ulid): ``require_sapient``
says so in one line.
"""

from __future__ import annotations

import importlib

from dronetrack.errors import MissingExtraError

__all__ = ["ICD_VERSION", "SAPIENT_HINT", "require_sapient"]

# The ICD the Registration names, as dstl's Apex middleware spells it
# (github.com/dstl/Apex-SAPIENT-Middleware, apex_config.json: its v2.0 connection's
# "icd_version" and validation's "supportedIcdVersions")
ICD_VERSION = "BSI Flex 335 v2.0"
SAPIENT_HINT = "SAPIENT needs protobuf and python-ulid: pip install 'dronetrack[sapient]'"


def require_sapient() -> None:
    """Raise ``MissingExtraError`` with the install hint unless the extra imports."""
    for module in ("google.protobuf", "ulid"):
        try:
            importlib.import_module(module)
        except ImportError as err:
            raise MissingExtraError(SAPIENT_HINT) from err
