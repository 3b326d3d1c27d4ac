"""What the SAPIENT tests share: an independent decoder compiled from the vendored
official .proto files, and a node's Registration."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

PROTO_ROOT = Path(__file__).resolve().parents[1] / "src" / "dronetrack" / "formats" / "sapient"
NODE = "0b6c9f9e-6f0e-4a59-9a5b-6f5d2c1a0e11"  # a version-4 UUID, as node IDs must be


def official_decoder() -> Any:
    """``SapientMessage`` of an independent decoder: the vendored .proto files compiled
    here by protoc into a descriptor set, loaded into a pool of their own (so neither
    the committed modules nor the default pool are involved)."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
    from grpc_tools import protoc

    include = Path(protoc.__file__).parent / "_proto"
    protos = sorted(str(p.relative_to(PROTO_ROOT)) for p in PROTO_ROOT.rglob("*.proto"))
    args = ["protoc", f"-I{PROTO_ROOT}", f"-I{include}", "--include_imports"]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "sapient.pb"
        assert protoc.main([*args, f"--descriptor_set_out={out}", *protos]) == 0
        files = descriptor_pb2.FileDescriptorSet.FromString(out.read_bytes())
    pool = descriptor_pool.DescriptorPool()
    for file in files.file:
        pool.Add(file)
    name = "sapient_msg.bsi_flex_335_v2_0.SapientMessage"
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def node_registration(name: str = "test", t: float | None = None, **kw: Any) -> Any:
    """A LiDAR node's Registration, stamped now unless ``t`` is given."""
    from dronetrack.formats.sapient import messages as m

    return m.registration(
        NODE,
        time.time() if t is None else t,
        name=name,
        short_name=name[:16],
        classes=("drone", "bird", "unknown"),
        status_period_s=5.0,
        field_of_view_deg=(70.4, 77.2),
        max_range_m=190.0,
        latency_s=0.1,
        **kw,
    )
