"""Opening and closing the viewer writers, and what they share.

``open_viewers`` turns the CLI's ``--foxglove FILE.mcap`` and ``--rerun FILE.rrd``
into a list of ``ViewerSink``; ``close_viewers`` finishes every file.  Each SDK is
an optional extra, imported only when its writer is asked for; a missing one
raises ``MissingExtraError`` with a one-line install hint before any file is
created.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path

from dronetrack.errors import ConfigError
from dronetrack.sinks.view import ViewerSink

__all__ = ["close_viewers", "open_viewers"]


def open_viewers(
    foxglove: Path | None,
    rerun: Path | None,
    *,
    start: float = 0.0,
    publish: str | None = None,
    ros_domain_id: int | None = None,
) -> list[ViewerSink]:
    """The writers asked for, in the order (Foxglove, rerun); none when both are None.

    ``start`` [s since the Unix epoch] is added to every frame's time for the
    files' timestamps: 0 for a simulation, the recording's clock for a replay.

    Both SDKs, and that both files can be written, are checked before any file is
    opened, so a missing extra or a bad path leaves no half-written file behind.  An
    existing file is overwritten.  A path that cannot be written raises a one-line
    ``ConfigError`` that names it.
    """
    # Imported here: the writer modules import the helpers of this module.
    from dronetrack.sinks.foxglove.mcap_file import FoxgloveWriter, require_foxglove
    from dronetrack.sinks.rerun_out import RerunWriter, require_rerun
    from dronetrack.sinks.run_folder import prepare_output_file

    if publish is not None and publish not in ("ros2",):
        raise ConfigError(f"--publish {publish!r}: the one choice is ros2")
    if publish is not None:
        from dronetrack.sources.ros2.dds import require_cyclonedds

        require_cyclonedds()
    if foxglove is not None:
        require_foxglove()
    if rerun is not None:
        require_rerun()
    if foxglove is not None:
        prepare_output_file(foxglove, "--foxglove")
    if rerun is not None:
        prepare_output_file(rerun, "--rerun")
    sinks: list[ViewerSink] = []
    try:
        if foxglove is not None:
            sinks.append(_opened(FoxgloveWriter, foxglove, start, "--foxglove"))
        if rerun is not None:
            sinks.append(_opened(RerunWriter, rerun, start, "--rerun"))
        if publish is not None:
            from dronetrack.sinks.ros2_out import Ros2Publisher

            sinks.append(Ros2Publisher(ros_domain_id))
    except BaseException:
        close_viewers(sinks)
        raise
    return sinks


def _opened(
    writer: Callable[[Path, float], ViewerSink], path: Path, start: float, option: str
) -> ViewerSink:
    """``writer(path, start)``, with the SDK's own failure to create the file (an
    ``OSError`` or a ``RuntimeError`` from its native core) as a ``ConfigError``."""
    try:
        return writer(path, start)
    except (OSError, RuntimeError) as err:
        raise ConfigError(f"{option} {path}: cannot write it ({err})") from None


def close_viewers(sinks: Iterable[ViewerSink]) -> None:
    """Close every sink, even when one fails; then raise the first failure."""
    first: BaseException | None = None
    for sink in sinks:
        try:
            sink.close()
        except BaseException as err:
            if first is None:
                first = err
    if first is not None:
        raise first
