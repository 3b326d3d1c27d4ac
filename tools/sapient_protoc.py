"""Compile the vendored SAPIENT (BSI Flex 335 v2.0) .proto files into the Python modules
dronetrack imports.

    python3 tools/sapient_protoc.py            # rewrite the modules in place
    python3 tools/sapient_protoc.py --out DIR  # write them under DIR instead

The .proto files under src/dronetrack/formats/sapient/sapient_msg/ are dstl's, as they
are (see the README.md there).  protoc (grpcio-tools' bundled copy) writes modules that
import each other as ``sapient_msg...``; this script rewrites those imports to the
package's own path, so that no top-level ``sapient_msg`` package is needed.  The output
depends only on the .proto files and the grpcio-tools version.
"""

from __future__ import annotations

import argparse
import re
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROTO_ROOT = ROOT / "src" / "dronetrack" / "formats" / "sapient"
PACKAGE = "dronetrack.formats.sapient"
# "from sapient_msg.x import y" and "import sapient_msg.x" at the start of a line
_IMPORT = re.compile(r"^(from|import) sapient_msg(\b)", re.MULTILINE)


def proto_files(root: Path = PROTO_ROOT) -> list[Path]:
    """The vendored .proto files, relative to ``root`` (their import root)."""
    return sorted(p.relative_to(root) for p in (root / "sapient_msg").rglob("*.proto"))


def compile_protos(out: Path, root: Path = PROTO_ROOT) -> list[Path]:
    """Compile every vendored .proto into ``out`` (``*_pb2.py`` and ``*_pb2.pyi``, in
    the same folders), with the imports rewritten; the files written, relative to
    ``out``."""
    from grpc_tools import protoc  # grpcio-tools: the test extra

    include = Path(protoc.__file__).parent / "_proto"  # google/protobuf/*.proto
    with tempfile.TemporaryDirectory() as tmp:
        args = [
            "protoc",
            f"-I{root}",
            f"-I{include}",
            f"--python_out={tmp}",
            f"--pyi_out={tmp}",
            *(str(p) for p in proto_files(root)),
        ]
        if protoc.main(args) != 0:
            raise SystemExit(f"protoc failed on {root}")
        written = []
        for path in sorted(Path(tmp).rglob("*_pb2.py*")):
            rel = path.relative_to(tmp)
            text = _IMPORT.sub(rf"\1 {PACKAGE}.sapient_msg\2", path.read_text())
            target = out / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(text)
            written.append(rel)
    for folder in {out / rel.parent for rel in written}:
        (folder / "__init__.py").touch()
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=PROTO_ROOT, help="where to write them")
    args = parser.parse_args(argv)
    if args.out != PROTO_ROOT and args.out.exists():
        shutil.rmtree(args.out)
    for rel in compile_protos(args.out):
        print(args.out / rel)
    return 0


if __name__ == "__main__":
    sys.exit(main())
