"""``dronetrack sapient-listen``: a minimal SAPIENT fusion node, to see what a run sends
to a C2 system (``--sapient``) without one."""

from __future__ import annotations

import math
import sys
from contextlib import nullcontext
from pathlib import Path
from typing import Annotated

import typer

from dronetrack.cli.app import app, say_line
from dronetrack.errors import ConfigError

__all__ = ["sapient_listen"]

_Port = Annotated[
    int,
    typer.Option(
        "--port",
        min=0,
        max=65535,
        help="TCP port to listen on; 0: any free one (said at the start).",
        show_default="5020, Apex's for BSI Flex 335 v2.0 edge nodes",
    ),
]
_Host = Annotated[str, typer.Option("--host", help="Address to listen on (0.0.0.0: every one).")]
_Out = Annotated[
    Path | None,
    typer.Option("--out", help="Write every message received as a JSON line to this file."),
]
_LookAt = Annotated[
    str | None,
    typer.Option(
        "--look-at",
        metavar="LAT,LON[,ALT]",
        help="Send each edge node that registers a look-at task for this WGS-84 point "
        "(degrees, and metres above the ellipsoid).",
    ),
]
_TaskAfter = Annotated[
    float,
    typer.Option("--task-after", min=0.0, help="Seconds after a node registers to send it."),
]
_Duration = Annotated[
    float | None,
    typer.Option(
        "--duration", min=0.0, help="Stop after this many seconds.", show_default="Ctrl-C"
    ),
]
_MaxFrame = Annotated[
    int,
    typer.Option("--max-frame-bytes", min=16, help="Refuse a message longer than this."),
]


def parse_look_at(text: str) -> tuple[float, float, float | None]:
    """``LAT,LON[,ALT]`` as numbers; ``ConfigError`` in one line otherwise."""
    parts = text.split(",")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    ok = (
        len(values) in (2, 3)
        and all(math.isfinite(v) for v in values)
        and -90 <= values[0] <= 90
        and -180 <= values[1] <= 180
    )
    if not ok:
        raise ConfigError(
            f"--look-at {text!r}: give LAT,LON[,ALT] in degrees (and metres), "
            "e.g. 47.4005,19.2004,140"
        )
    return values[0], values[1], values[2] if len(values) == 3 else None


@app.command("sapient-listen")
def sapient_listen(
    port: _Port = 5020,
    host: _Host = "127.0.0.1",
    out: _Out = None,
    look_at: _LookAt = None,
    task_after: _TaskAfter = 2.0,
    duration: _Duration = None,
    max_frame_bytes: _MaxFrame = 1024 * 1024,
) -> None:
    """Listen as a SAPIENT fusion node: acknowledge edge nodes' registrations, print a
    line per message, write them as JSON lines, and task them to look at a point."""
    import time

    from dronetrack.cli.app import stop_if_interrupted
    from dronetrack.formats.sapient import require_sapient
    from dronetrack.interrupt import handling_sigterm, stop_requested, stoppable

    require_sapient()
    from dronetrack.sinks.run_folder import prepare_output_file
    from dronetrack.sinks.sapient.listen import FusionNode

    point = parse_look_at(look_at) if look_at is not None else None
    if out is not None:
        prepare_output_file(out, "--out")
    with out.open("a") if out is not None else nullcontext() as fh:
        try:
            node = FusionNode(
                port,
                host,
                out=fh,
                say=say_line,
                look_at=point,
                task_after_s=task_after,
                max_frame_bytes=max_frame_bytes,
                check_rules=True,
            )
        except OSError as err:
            raise ConfigError(f"cannot listen on {host}:{port}: {err.strerror or err}") from None
        say_line(f"sapient-listen: listening on {host}:{node.port} (BSI Flex 335 v2.0)")
        sys.stderr.flush()
        end = time.monotonic() + duration if duration is not None else float("inf")
        try:
            with handling_sigterm(), stoppable():
                node.serve(lambda: stop_requested() or time.monotonic() >= end)
        finally:
            node.close()
        stop_if_interrupted(stop_requested(), f"; {node.received} messages received")
    say_line(f"sapient-listen: {node.received} messages received")
