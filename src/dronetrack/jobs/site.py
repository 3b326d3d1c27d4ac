"""The site of a run: its world frame on the Earth, its protected zones in it, and the
sink that tells the site (and a C2 system) of the run."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from shapely import Polygon

from dronetrack.config.pipeline import crop_box
from dronetrack.config.rig import FIELD_OF_VIEW_DEG, turret_spec
from dronetrack.config.run import ScenarioConfig
from dronetrack.config.site import SapientConfig, ZoneConfig
from dronetrack.errors import ConfigError
from dronetrack.geometry.geodesy import SiteFrame
from dronetrack.jobs.run import RunFolder
from dronetrack.sinks.foxglove.geo import SiteView
from dronetrack.sinks.site_feed import SiteFeed
from dronetrack.zones import AlertMonitor, Zone, circle

if TYPE_CHECKING:
    from dronetrack.sinks.sapient.node import SapientNode

__all__ = [
    "FIELD_OF_VIEW_DEG",
    "open_node",
    "open_site_feed",
    "place",
    "run_folder",
    "site_frame",
    "site_view",
    "site_zones",
    "turret_base",
    "zone_in_world",
]


def turret_base(cfg: ScenarioConfig) -> tuple[float, float, float]:
    """The turret base (the foot of its pan axis) in the world frame [m]; the world
    origin on a moving observer, whose turret rides on a drone."""
    if cfg.observer is not None:
        return (0.0, 0.0, 0.0)
    return turret_spec(cfg.turret).mount.base


def site_frame(cfg: ScenarioConfig) -> SiteFrame | None:
    """The world frame on the Earth that ``[site]`` gives (None without it)."""
    site = cfg.site
    if site is None:
        return None
    return SiteFrame(
        site.latitude_deg,
        site.longitude_deg,
        site.altitude_m,
        site.heading_deg,
        base=turret_base(cfg),
    )


def site_zones(cfg: ScenarioConfig) -> tuple[Zone, ...]:
    """``[[zones]]`` in the world frame (none without them)."""
    site = site_frame(cfg)
    if site is None:
        return ()
    return tuple(zone_in_world(zone, site) for zone in cfg.zones)


def zone_in_world(zone: ZoneConfig, site: SiteFrame) -> Zone:
    """A ``[[zones]]`` entry in the world frame: its vertices or centre, at the site's
    altitude, through the site frame; its heights are world z."""
    heights = {
        "floor": -math.inf if zone.floor_m is None else zone.floor_m,
        "ceiling": math.inf if zone.ceiling_m is None else zone.ceiling_m,
        "margin_m": zone.margin_m or 0.0,
        "margin_s": zone.margin_s or 0.0,
    }
    if zone.centre is not None:
        assert zone.radius_m is not None
        c = site.from_geodetic(zone.centre[0], zone.centre[1], site.altitude_m)
        return circle(zone.name, (float(c[0]), float(c[1])), zone.radius_m, **heights)
    assert zone.polygon is not None
    lat, lon = np.array(zone.polygon, dtype=np.float64).T
    xy = site.from_geodetic(lat, lon, np.full(len(lat), site.altitude_m))[:, :2]
    return Zone(zone.name, Polygon(xy), **heights)


def site_view(cfg: ScenarioConfig) -> SiteView | None:
    """What Foxglove's map shows of the site: its frame and zones (None without [site])."""
    site = site_frame(cfg)
    return None if site is None else SiteView(site, site_zones(cfg))


def open_site_feed(
    cfg: ScenarioConfig,
    folder: Callable[[], Path | None],
    sapient: str | None = None,
    say: Callable[[str], None] | None = None,
    steerable: bool = True,
) -> SiteFeed | None:
    """The sink that tells the site of the run (``sinks.site_feed``): the zones' alerts
    into ``folder()/alerts.jsonl`` and ``say``, and with ``sapient`` (``HOST:PORT``) every
    track and alert to that SAPIENT fusion node; None when there is nothing to tell.
    ``steerable``: whether the turret can take a look-at task (not in a replay)."""
    site = site_frame(cfg)
    if sapient is not None and site is None:
        raise ConfigError(
            "--sapient needs the site's coordinates: add a [site] section with "
            "latitude_deg, longitude_deg and altitude_m (of the turret base) to the "
            "scenario or site file"
        )
    zones = site_zones(cfg)
    link = None
    if sapient is not None:
        assert site is not None
        link = open_node(sapient, cfg, site, say=say, steerable=steerable)
    if not zones and link is None:
        return None
    return SiteFeed(site, AlertMonitor(zones) if zones else None, folder, say, link)


def run_folder(out: Path | None, cfg: ScenarioConfig) -> RunFolder:
    """The run's output folder (``runs/<timestamp>/`` unless ``out``), with ``cfg``'s
    site for tracks.csv's WGS-84 columns (``place``)."""
    from dronetrack.sinks.run_folder import default_run_dir

    return place(RunFolder(out if out is not None else default_run_dir()), cfg)


def place(folder: RunFolder, cfg: ScenarioConfig) -> RunFolder:
    """``folder`` told where ``cfg``'s turret stands: its site and its base."""
    folder.site, folder.base = site_frame(cfg), turret_base(cfg)
    return folder


def open_node(
    endpoint: str,
    cfg: ScenarioConfig,
    site: SiteFrame,
    say: Callable[[str], None] | None = None,
    steerable: bool = True,
) -> SapientNode:
    """The SAPIENT edge node of ``cfg`` on a link to ``endpoint`` (``HOST:PORT``; a bad
    one is a ``ConfigError``).  The link starts connecting at once, in the background:
    a fusion node that is not there yet is said in one line and tried again."""
    from dronetrack import __version__
    from dronetrack.formats.sapient import messages, require_sapient

    require_sapient()
    from dronetrack.sinks.sapient.link import SapientLink, parse_endpoint
    from dronetrack.sinks.sapient.node import CLASSES, SapientNode, node_uuid

    host, port = parse_endpoint(endpoint)
    settings = cfg.sapient if cfg.sapient is not None else SapientConfig()
    node_id = settings.node_id or node_uuid(cfg.name, site.latitude_deg, site.longitude_deg)
    fov = FIELD_OF_VIEW_DEG.get(cfg.sensor.model, (360.0, 180.0))
    reach = _reach(cfg)
    model = f"{cfg.sensor.model} on {cfg.turret.model}"

    def registration() -> Any:
        return messages.registration(
            node_id,
            time.time(),
            name=settings.name,
            short_name=settings.name[:16],
            classes=CLASSES,
            status_period_s=settings.status_period_s,
            field_of_view_deg=fov,
            max_range_m=reach,
            latency_s=cfg.sensor.integration_time_s,
            model=model,
            version=__version__,
        )

    link = SapientLink(host, port, registration, say=say)
    return SapientNode(
        link,
        site,
        node_id=node_id,
        rng=np.random.default_rng(np.random.SeedSequence(cfg.seed).spawn(3)[2]),
        status_period_s=settings.status_period_s,
        field_of_view_deg=fov,
        max_range_m=reach,
        steerable=steerable,
        say=say,
    )


def _reach(cfg: ScenarioConfig) -> float:
    """How far the node sees [m]: the sensor's return limit for its drone when known,
    else the crop box's farthest corner from the turret."""
    evaluation = cfg.pipeline.evaluation
    for known in (evaluation.limit_m, evaluation.reach_m):
        if known is not None:
            return float(known)
    low, high = crop_box(cfg.pipeline, turret_base(cfg))
    corners = np.array(
        [[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])]
    )
    return float(np.max(np.linalg.norm(corners - np.asarray(turret_base(cfg)), axis=1)))
