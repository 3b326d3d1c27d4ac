"""The one ``dronetrack`` app every command registers on, and what the commands share:
the viewer files beside a run folder, the run report and the ``interrupted`` exit."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from dronetrack import __version__
from dronetrack.cli.helpformat import ReadableGroup, ReadableTyper
from dronetrack.cli.output import (
    err_console,
    print_kernel_note,
    print_metrics,
)
from dronetrack.errors import RunInterruptedError

if TYPE_CHECKING:
    from dronetrack.config.run import ScenarioConfig
    from dronetrack.jobs.run import RunFolder, RunResult
    from dronetrack.seams import Sink
    from dronetrack.sinks.foxglove.geo import SiteView
    from dronetrack.sinks.view import ViewerSink


__all__ = [
    "INTERRUPTED",
    "RunInterruptedError",
    "app",
    "report_run",
    "run_outputs",
    "say_line",
    "show_site",
    "site_outputs",
    "stop_if_interrupted",
]

app = ReadableTyper(
    cls=ReadableGroup,
    add_completion=False,
    no_args_is_help=True,
    context_settings={"help_option_names": ["-h", "--help"]},
    pretty_exceptions_enable=False,
    rich_markup_mode="rich",
    help="Detect and track small drones with LiDAR on a pan-tilt turret.",
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"dronetrack {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    """Detect and track small drones with LiDAR on a pan-tilt turret."""


INTERRUPTED = 130  # 128 + SIGINT, as a shell reports a command killed by Ctrl-C


@contextmanager
def run_outputs(
    folder: RunFolder,
    foxglove: Path | None,
    rerun: Path | None,
    start: float = 0.0,
    publish: str | None = None,
    ros_domain_id: int | None = None,
    site: SiteView | None = None,
) -> Iterator[list[ViewerSink]]:
    """The viewer files a run writes besides its folder (and ``--publish ros2``'s
    publisher), closed after the block; if the block fails, or Ctrl-C stops it at
    once, the folder keeps the frames done.  ``site``: the map a viewer that has one
    shows too (Foxglove's)."""
    from dronetrack.sinks.viewers import close_viewers, open_viewers

    try:
        viewers = open_viewers(
            foxglove, rerun, start=start, publish=publish, ros_domain_id=ros_domain_id
        )
        if site is not None:
            show_site(viewers, site)
        try:
            yield viewers
        finally:
            close_viewers(viewers)
    except BaseException:
        folder.close()
        raise


def show_site(viewers: Iterable[object], site: SiteView) -> None:
    """Give ``site`` to each viewer with a map (``show_site``)."""
    for viewer in viewers:
        show = getattr(viewer, "show_site", None)
        if show is not None:
            show(site)


@contextmanager
def site_outputs(
    cfg: ScenarioConfig, folder: RunFolder, sapient: str | None, steerable: bool = True
) -> Iterator[list[Sink]]:
    """The sink that tells the site of the run (zone alerts, ``--sapient``), as a list
    of none or one, closed after the block: each alert is said in one line."""
    from dronetrack.jobs.site import open_site_feed

    feed = open_site_feed(cfg, lambda: folder.out_dir, sapient, say=say_line, steerable=steerable)
    try:
        yield [] if feed is None else [feed]
    finally:
        if feed is not None:
            feed.close()


def say_line(text: str) -> None:
    """One line on standard error, as it is (no markup)."""
    err_console.print(text, markup=False, highlight=False, soft_wrap=True)


def report_run(folder: RunFolder, run: RunResult, metrics: dict[str, Any]) -> None:
    """After a run's folder is written: the kernels' compile time if it compiled, then
    one ``interrupted`` line (exit 130) if Ctrl-C ended it, else the metrics table."""
    print_kernel_note(run.kernels)
    outside = metrics.get("outside_field_pct")
    if outside:
        err_console.print(
            f"warning: the drone spends {outside:.1f} % of the run outside the detection area "
            "(the crop box and the field of regard); see outside_field_pct in metrics.json",
            markup=False,
            highlight=False,
            soft_wrap=True,
        )
    stop_if_interrupted(run.interrupted, f"; kept {len(run.log)} frames in {folder.out_dir}")
    print_metrics(metrics, folder.out_dir)


def stop_if_interrupted(interrupted: bool, note: str = "") -> None:
    """End a command whose loop Ctrl-C stopped (after it wrote what it had): one
    ``interrupted`` line, ending with ``note``, and exit code 130."""
    if interrupted:
        raise RunInterruptedError(note)
