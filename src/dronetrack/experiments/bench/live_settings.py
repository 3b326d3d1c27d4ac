"""What ``dronetrack bench --live`` runs: its settings (``LiveSettings``; the full
measurement ``LIVE_FULL`` and the smoke test ``LIVE_QUICK``) and the command's options
checked against them (``check_mode``, ``live_request``), and the targets its figures
are held to (``LIVE_TARGETS``); ``experiments.bench.live`` runs them."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from dronetrack.errors import ConfigError
from dronetrack.experiments.bench.emulator import TURRETS
from dronetrack.experiments.bench.suite import Target
from dronetrack.formats.ptu import BAUD_RATES

__all__ = [
    "LATENCY_P99_TARGET_MS",
    "LIVE_FULL",
    "LIVE_QUICK",
    "LIVE_TARGETS",
    "RSS_GROWTH_TARGET_PCT",
    "SAPIENT_FIRST_REPORT_MS",
    "SAPIENT_P99_GROWTH_MS",
    "SAPIENT_PAIRS",
    "SAPIENT_RECONNECT_S",
    "LiveRequest",
    "LiveSettings",
    "check_mode",
    "live_request",
]

LATENCY_P99_TARGET_MS = 20.0  # issue 14: p99 ≤ 20 ms at the Avia's full point rate
RSS_GROWTH_TARGET_PCT = 5.0  # issue 14: resident memory flat after warm-up, ≤ 5 %
SAPIENT_P99_GROWTH_MS = 2.0  # issue 31: --sapient adds ≤ 2 ms to the latency's p99
SAPIENT_FIRST_REPORT_MS = 100.0  # issue 31: a track's first report ≤ 100 ms after its frame
SAPIENT_RECONNECT_S = 5.0  # issue 31: a fusion node killed and restarted, rejoined ≤ 5 s
SAPIENT_PAIRS = 3  # latency runs with SAPIENT, alternating with as many without

LIVE_TARGETS: tuple[Target, ...] = (
    Target(("live_latency", "latency_ms_p99"), LATENCY_P99_TARGET_MS, "ms", "live latency p99"),
    Target(("live_soak", "rss_growth_pct"), RSS_GROWTH_TARGET_PCT, "%", "soak memory growth"),
    Target(("live_soak", "packets_lost"), 0.0, "packets", "soak packets lost"),
    Target(("live_soak", "frames_dropped"), 0.0, "frames", "soak frames dropped"),
    Target(
        ("live_latency_sapient", "p99_growth_ms"),
        SAPIENT_P99_GROWTH_MS,
        "ms",
        "SAPIENT: latency p99 growth",
    ),
    Target(
        ("live_latency_sapient", "sapient_first_report_ms_max"),
        SAPIENT_FIRST_REPORT_MS,
        "ms",
        "SAPIENT: first report after its frame",
    ),
    Target(
        ("live_latency_sapient", "sapient_reconnect_s"),
        SAPIENT_RECONNECT_S,
        "s",
        "SAPIENT: fusion node restarted, rejoined",
    ),
    Target(
        ("live_latency_sapient", "frames_dropped"),
        0.0,
        "frames",
        "SAPIENT: frames dropped",
    ),
)


@dataclass(frozen=True, slots=True)
class LiveSettings:
    """How long each live measurement runs [s]: the latency run's flight, the soak's
    flight (0: no soak), its warm-up and sampling period, and the live side's
    background scan (None: the scenario's); the scenario emulated (its LiDAR); and the
    emulated turret driven (``TURRETS``) with, for the PTU, its line's baud rate."""

    latency_s: float = 20.0
    soak_s: float = 600.0
    warmup_s: float = 60.0
    sample_s: float = 5.0
    scan_s: float | None = None
    turret: str = "dynamixel"
    ptu_baud: int = 9600
    scenario: str = "default"
    sapient: bool = False  # the latency run again with a SAPIENT edge node on

    def checked(self) -> LiveSettings:
        """These settings, or ConfigError naming the bad value."""
        if not self.latency_s > 0:
            raise ConfigError(f"the latency run needs a flight of > 0 s, got {self.latency_s}")
        if not self.soak_s >= 0:
            raise ConfigError(f"the soak must be >= 0 s (0: none), got {self.soak_s}")
        if self.soak_s > 0 and not 0 <= self.warmup_s < self.soak_s:
            raise ConfigError(
                f"the soak's warm-up must be >= 0 s and shorter than the soak "
                f"({self.soak_s:g} s), got {self.warmup_s}"
            )
        if not self.sample_s > 0:
            raise ConfigError(f"the soak's sampling period must be > 0 s, got {self.sample_s}")
        if self.turret not in TURRETS:
            raise ConfigError(
                f"a live benchmark drives {' or '.join(TURRETS)}, not {self.turret!r}"
            )
        if self.ptu_baud not in BAUD_RATES:
            rates = ", ".join(map(str, BAUD_RATES))
            raise ConfigError(f"the PTU's baud {self.ptu_baud} is not a standard rate ({rates})")
        return self


LIVE_FULL = LiveSettings()
# a smoke test, not a measurement: a 0.5 s scan, 2 s of latency, a 4 s soak
LIVE_QUICK = LiveSettings(latency_s=2.0, soak_s=4.0, warmup_s=1.0, sample_s=0.5, scan_s=0.5)


@dataclass(frozen=True, slots=True)
class LiveRequest:
    """What ``bench --live`` runs: the settings, whether a turret is driven (``--turret
    none``: a fixed sensor) and the chain (``livox``, or ``ros2``)."""

    settings: LiveSettings
    turret: bool
    chain: str


def check_mode(live: bool, *, suite_options: bool, live_options: bool) -> None:
    """ConfigError if ``bench`` is given the other mode's options: the suite's
    (--rounds, --repeats, --replay-seconds) with --live, or --live's without it."""
    if live and suite_options:
        raise ConfigError("--rounds, --repeats and --replay-seconds time the suite, not --live")
    if not live and live_options:
        raise ConfigError(
            "--latency-s, --soak-s, --warmup-s, --turret, --ptu-baud, --scenario, --ros2 and "
            "--sapient go with --live"
        )


def live_request(
    quick: bool,
    *,
    latency_s: float | None = None,
    soak_s: float | None = None,
    warmup_s: float | None = None,
    turret: str | None = None,
    ptu_baud: int | None = None,
    scenario: str | None = None,
    ros2: bool = False,
    sapient: bool = False,
) -> LiveRequest:
    """``bench --live``'s options over the full (or ``quick``) settings, checked: a
    ConfigError names an option that does not fit (``ptu_baud`` without the PTU,
    ``ros2`` with a turret other than its own, an unknown scenario or a bad value)."""
    from dronetrack.config.scenarios import get_scenario

    if ptu_baud is not None and turret != "ptu":
        raise ConfigError("--ptu-baud goes with --turret ptu")
    if ros2 and turret not in (None, "none"):
        raise ConfigError("--ros2 drives the emulated ROS 2 turret (or --turret none)")
    if scenario is not None:
        get_scenario(scenario)  # an unknown one is an error before anything runs
    fixed = turret == "none"
    given: dict[str, Any] = {"latency_s": latency_s, "soak_s": soak_s, "warmup_s": warmup_s}
    given.update(turret=None if fixed else turret, ptu_baud=ptu_baud, scenario=scenario)
    if sapient:
        from dronetrack.formats.sapient import require_sapient

        require_sapient()
        given["sapient"] = True
    settings = LIVE_QUICK if quick else LIVE_FULL
    settings = replace(settings, **{k: v for k, v in given.items() if v is not None})
    return LiveRequest(settings.checked(), not fixed, "ros2" if ros2 else "livox")
