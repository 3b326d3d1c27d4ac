"""A command-and-control system on the bench: a SAPIENT fusion node in a thread, and the
live run's edge node sending to it, timed (``experiments.bench.live``)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["BenchC2"]


class BenchC2:
    """A fusion node in a thread of this process, and the run's SAPIENT edge node
    sending to it (a site at 47.4° N, 19.2° E is given to the configuration).

    With ``restart_after_s``, that long after the link first registers the fusion node
    is killed (closed with its connections) and started again on the same port
    ``RESTART_GAP_S`` later; ``sapient_reconnect_s`` is the time from its start to
    the link's next registration.  Every wait is bounded."""

    RESTART_GAP_S = 1.0

    def __init__(self, cfg: Any, restart_after_s: float | None = None) -> None:
        from dronetrack.config.site import SiteConfig

        site = SiteConfig(latitude_deg=47.4, longitude_deg=19.2, altitude_m=120.0)
        self.cfg = cfg.model_copy(update={"site": site})
        self.first_receipt: dict[str, float] = {}
        self.restart_after_s = restart_after_s
        self.reconnect_s: float | None = None
        self.feed: Any = None
        self.sink_ms: list[float] = []  # the feed's time per tracking frame [ms]
        self._up_at: float | None = None  # when the restarted fusion node listened
        self._stop = threading.Event()
        self._down = threading.Event()
        self.fusion = self._fusion_node(0)
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _fusion_node(self, port: int) -> Any:
        from dronetrack.sinks.sapient.listen import FusionNode

        return FusionNode(port, received=self._received)

    def _serve(self) -> None:
        while not self._stop.is_set():
            self.fusion.serve(lambda: self._stop.is_set() or self._down.is_set(), 0.05)
            if self._stop.is_set():
                return
            port = self.fusion.port
            self.fusion.close()  # killed: its connections closed
            self._stop.wait(self.RESTART_GAP_S)
            self.fusion = self._fusion_node(port)
            self._up_at = time.monotonic()
            self._down.clear()

    def _kill_and_time(self) -> None:
        """Kill the fusion node ``restart_after_s`` after the link registers, and time
        the link's return once it is started again."""
        assert self.restart_after_s is not None
        link = self.feed.link.link

        def until(condition: Callable[[], bool], timeout_s: float) -> bool:
            deadline = time.monotonic() + timeout_s
            while not condition():
                if time.monotonic() > deadline or self._stop.wait(0.01):
                    return False
            return True

        if not until(lambda: link.stats.registered, 60.0):
            return
        if self._stop.wait(self.restart_after_s):
            return
        self._down.set()
        # down for RESTART_GAP_S: the link has seen its connection close long before
        up = until(lambda: self._up_at is not None, 30.0)
        if up and until(lambda: link.stats.registered, 30.0):
            assert self._up_at is not None
            self.reconnect_s = time.monotonic() - self._up_at

    def _received(self, message: Any) -> None:
        if message.WhichOneof("content") == "detection_report":
            self.first_receipt.setdefault(message.detection_report.object_id, time.perf_counter())

    def sinks(self, folder: Any) -> list[Any]:
        from dronetrack.jobs.site import open_site_feed

        self.feed = open_site_feed(
            self.cfg, lambda: folder.out_dir, f"127.0.0.1:{self.fusion.port}"
        )
        if self.restart_after_s is not None:
            threading.Thread(target=self._kill_and_time, daemon=True).start()
        return [self]

    def write(self, sample: Any, result: Any) -> None:
        """The site feed's write, timed: what SAPIENT costs the loop per frame."""
        start = time.perf_counter()
        self.feed.write(sample, result)
        if result.phase == "track":
            self.sink_ms.append(1000.0 * (time.perf_counter() - start))

    def figures(self) -> dict[str, Any]:
        """The first reports' delays [ms] and what the link sent and dropped."""
        node = self.feed.link
        delays = [
            1000.0 * (self.first_receipt[oid] - t)
            for oid, t in node.first_frames.items()
            if oid in self.first_receipt
        ]
        return {
            "sapient_first_report_ms_max": max(delays) if delays else None,
            "sapient_first_report_ms_median": float(np.median(delays)) if delays else None,
            "sapient_objects": len(node.first_frames),
            "sapient_sent": node.link.stats.sent,
            "sapient_dropped": node.link.stats.dropped,
            "sapient_connects": node.link.stats.connects,
            "sapient_reconnect_s": self.reconnect_s,
            "sapient_sink_ms_p50": float(np.percentile(self.sink_ms, 50)) if self.sink_ms else None,
            "sapient_sink_ms_p99": float(np.percentile(self.sink_ms, 99)) if self.sink_ms else None,
        }

    def close(self) -> None:
        if self.feed is not None:
            self.feed.close()
        self._stop.set()
        self._thread.join(5.0)
        self.fusion.close()
