"""The push-based pipeline: ``step(frame) -> StepResult``, whatever produced the frame.

Per frame:
1. check the frame (time order, finite values, sensor poses) and count problems;
2. transform to the world frame with each point's sensor pose, crop to a box
   (and optionally to a convex hull, seed 003's filter node, and to the field of
   regard: pan, tilt and range from the turret base);
3. while the background is being scanned: add the points to the background model
   and command the scanning raster; when the scan ends, build the model;
4. otherwise subtract the background, optionally remove outliers, detect: cluster
   the foreground and keep the clusters as tentative tracks, confirmed when they
   persist (``detect.tentative``); follow and class every object (``track.multi``,
   ``classify``); choose the candidates the tracker starts or restarts on
   (``pipeline.selection``: while locked on what no drone-class track follows, a
   drone's track; while not locked, after a loss, only those the target could have
   reached since its last fix, the likeliest drone first); then step the tracker:
   predict once per elapsed filter period (through gaps), update with the
   remaining points;
5. command the turret: the estimate when locked, else the candidate the tracker
   starts on (or the track it tries, where predicted: ``pipeline.selection``), a
   look at a cue (a tentative track seen twice), or the search.

Commands are stamped at the frame's end plus the modelled sensor and processing
latency, so a closed loop is deterministic whatever the machine's speed.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from dataclasses import dataclass, replace
from functools import partial

import numpy as np
from numpy.typing import NDArray

from dronetrack.classify.classifier import TrackClassifier
from dronetrack.control.choose import TargetChooser, not_static, worth_a_look
from dronetrack.control.controller import Controller
from dronetrack.detect.lock import SAME_TARGET_M
from dronetrack.detect.tentative import reach
from dronetrack.errors import InputError
from dronetrack.geometry.field import FieldOfRegard, in_field_of_view
from dronetrack.geometry.transforms import FloatArray
from dronetrack.pipeline.acquisition import Acquisition
from dronetrack.pipeline.protect import protected_balls
from dronetrack.pipeline.selection import TargetSelection, rank
from dronetrack.preprocess.background import VoxelBackground
from dronetrack.preprocess.crop import HullCrop, ball_mask, box_mask
from dronetrack.preprocess.foreground import Foreground, extract_foreground
from dronetrack.preprocess.learning import LearningBackground
from dronetrack.preprocess.outliers import radius_outlier_mask, statistical_outlier_mask
from dronetrack.preprocess.range_image import RangeImage
from dronetrack.track.base import CandidateStart, Tracker
from dronetrack.track.clock import FilterClock
from dronetrack.types import (
    Candidates,
    Detections,
    Frame,
    Phase,
    StepResult,
    TrackEstimate,
    Tracks,
    TurretCommand,
)

__all__ = ["OutlierSettings", "Pipeline", "StepResult"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class OutlierSettings:
    """Which outlier filters run on the foreground, and their parameters (SI)."""

    radius: float | None = None  # radius filter off when None
    min_neighbors: int = 3
    mean_k: int | None = None  # statistical filter off when None
    std_mul: float = 1.0


class Pipeline:
    """Preprocessing, detection, tracking and turret control, one frame at a time."""

    def __init__(
        self,
        tracker: Tracker,
        controller: Controller,
        crop_min: FloatArray,
        crop_max: FloatArray,
        background: VoxelBackground | None = None,
        scan_until: float = 0.0,
        outliers: OutlierSettings = OutlierSettings(),
        latency_s: float = 0.0,
        hull: HullCrop | None = None,
        acquisition: Acquisition | None = None,
        field: FieldOfRegard | None = None,
        ranges: RangeImage | None = None,
        classifier: TrackClassifier | None = None,
        chooser: TargetChooser | None = None,
        learning: LearningBackground | None = None,
        field_of_view: tuple[float, float] | None = None,
    ) -> None:
        self.tracker = tracker
        self.controller = controller
        self.crop_min = np.asarray(crop_min, dtype=np.float64)
        self.crop_max = np.asarray(crop_max, dtype=np.float64)
        self.background = background
        self.scan_until = scan_until if background is not None and not background.ready else 0.0
        self.outliers = outliers
        self.latency_s = latency_s
        self.hull = hull
        self.field = field  # the field of regard: points beyond it are no target
        self.counts: Counter[str] = Counter()
        self.clock = FilterClock(tracker.period)  # the filters' time, in whole periods
        self.acquisition = acquisition
        self.classifier = classifier  # each track's class (``classify``)
        # the target the tracker follows among the tracks, and the chooser's turns
        self.selection = TargetSelection(chooser)
        # The background that keeps learning after the scan (``preprocess.learning``).
        self.learning = learning
        self.field_of_view = field_of_view  # the sensor's [rad], where narrower than a circle
        # The scan's range image, for the points near a locked target (``_near_track``).
        self.ranges = ranges if background is not None and not background.ready else None

    def look_at(self, t: float, point: FloatArray) -> bool:
        """A look-at task (a C2 system's, ``sinks.sapient``): the turret's next search
        is centred on world ``point`` (3,) [m] from time ``t`` [s].  False when the
        controller cannot do it (it does not search)."""
        look = getattr(self.controller, "look_at", None)
        return bool(look(t, point)) if look is not None else False

    @property
    def scanning(self) -> bool:
        return self.background is not None and not self.background.ready

    def step(self, frame: Frame) -> StepResult:
        """Process one frame."""
        start = time.perf_counter()
        flags: list[str] = []
        steps = self.clock.advance(frame.end, flags)
        fg = self._foreground(frame, flags)
        t_cmd = frame.end + self.latency_s
        if self.scanning:
            assert self.background is not None
            if steps > 0:
                self.background.insert(fg.points)
                if self.ranges is not None:
                    self.ranges.insert(fg.points)
            command: TurretCommand | None = self.controller.scanning(t_cmd)
            # The scan ends with the frame that ends at scan_until (within half a period).
            if steps > 0 and frame.end >= self.scan_until - 0.5 * self.tracker.period:
                self.background.build()
                if self.ranges is not None:
                    self.ranges.build()
                log.info("background model built: %d cells", len(self.background))
            result = self._result(frame, "scan", None, fg, fg.points, command, start, flags, steps)
        else:
            seen = fg.points  # what the scanned map does not hold: the learning map's input
            fg = self._without_learnt(fg)
            points = self._remove_outliers(fg.points)
            if "time_jump" in flags:
                self.tracker.reset()
                if self.acquisition is not None:
                    self.acquisition.reset()
            found, confirmed, offered, tracks = self._detect(frame, fg, points, steps)
            estimate = self.tracker.step(frame.end, points, steps)
            if not np.all(np.isfinite(estimate.position)):
                flags.append("nonfinite_estimate")
                self.tracker.reset()
                estimate = self.tracker.step(frame.end, np.empty((0, 3)), 0)
            if self.acquisition is not None:
                self.acquisition.lock.update(estimate, offered)
            if tracks is not None:
                tracks = tracks.with_locked(estimate, SAME_TARGET_M)
                if self.acquisition is not None and self.acquisition.objects is not None:
                    self.acquisition.objects.note_lock(tracks, estimate)
                    unlikely = ~worth_a_look(tracks, self.selection.settings.min_p)
                    self.acquisition.objects.note_unlikely(tracks.ids[unlikely])
            if steps > 0:
                self._learn(frame, fg.world, seen, found, tracks, estimate)
            command = None
            if steps > 0:  # the candidates to aim at matter only while not locked
                aims = self.selection.look
                if aims is None and not estimate.tracked:
                    aims = self.selection.aim  # what rule 5 started the tracker on
                    if aims is None:  # it did not run: the reachable candidates
                        aims = self._reachable(frame.end, offered, found, tracks)
                cues = self._cues(frame.end, found, tracks)
                command = self.controller.tracking(t_cmd, estimate, points, aims, cues)
            result = self._result(
                frame, "track", estimate, fg, points, command, start, flags, steps
            )
            if found is not None:
                result = replace(result, detections=found, candidates=confirmed, tracks=tracks)
        for flag in flags:
            self.counts[flag] += 1
        if flags:
            log.debug("frame ending %.3f s: %s", frame.end, ", ".join(flags))
        return result

    def _detect(
        self, frame: Frame, fg: Foreground, points: FloatArray, steps: int
    ) -> tuple[Detections | None, Candidates | None, Candidates | None, Tracks | None]:
        """Cluster the foreground and confirm candidates (a new period's frames only),
        update every object's track and its class, and offer the tracker the confirmed
        candidates whose track is not static (``control.choose``), which the target
        selection starts and restarts the tracker on (``pipeline.selection``).  Returns
        the clusters, the confirmed candidates, those offered and the tracks."""
        if self.acquisition is None or steps == 0:
            return None, None, None, None
        t = frame.end
        found, confirmed = self.acquisition.step(t, points, frame.poses[-1][:3, 3])
        tracks = self._tracks(frame, fg, found, confirmed)
        offered = confirmed if tracks is None else not_static(confirmed, found, tracks)
        if not isinstance(self.tracker, CandidateStart):
            return found, confirmed, offered, tracks
        lock = self.acquisition.lock
        offered = self.selection.step(t, found, tracks, offered, lock, self.tracker)
        return found, confirmed, offered, tracks

    def _tracks(
        self, frame: Frame, fg: Foreground, found: Detections, confirmed: Candidates
    ) -> Tracks | None:
        """Every object's track after this frame's clusters (which stand for the middle
        of the frame's period; ``track.multi``), each with its class (``classify``).
        The ground is learnt from the returns that are not foreground (the background
        map's, and those the crop drops: the floor cuts the ground off), so a drone
        seen against the sky never becomes the ground under itself."""
        objects = self.acquisition.objects if self.acquisition is not None else None
        if objects is None:
            return None
        t = frame.end
        fov, pose = self.field_of_view, frame.poses[-1]
        in_view = None if fov is None else partial(in_field_of_view, pose=pose, fov=fov)
        t_meas = t - 0.5 * frame.duration
        # the tracks keep on or above the ground the classes learn (none without them)
        floor = None if self.classifier is None else self.classifier.ground.height
        tracks = objects.step(t, found, confirmed, t_meas=t_meas, in_view=in_view, floor=floor)
        if self.classifier is None:
            return tracks
        sensor = pose[:3, 3]
        test = self._in_background if self._has_background else None
        return self.classifier.step(
            t, tracks, found, fg.world, fg.index, sensor, test, objects.resting, objects.heirs
        )

    @property
    def _has_background(self) -> bool:
        bg = self.background
        return (bg is not None and bg.ready) or self.learning is not None

    def _in_background(self, points: FloatArray) -> NDArray[np.bool_]:
        """(N,) whether each world point is in the scanned map (not a short scan's:
        ``VoxelBackground.provisional``) or the learnt one, or in a voxel that what no
        track holds has hit lately (``LearningBackground.is_structure``): the classes'
        test of a structure beside a track (*joined*)."""
        out = np.zeros(len(points), dtype=bool)
        bg = self.background
        if bg is not None and bg.ready and not bg.provisional:
            out |= bg.is_background(points)
        if self.learning is not None:
            out |= self.learning.is_structure(points)
        return out

    def _without_learnt(self, fg: Foreground) -> Foreground:
        """The foreground without what the learning map holds (counted as background)."""
        if self.learning is None or len(fg.points) == 0:
            return fg
        learnt = self.learning.is_background(fg.points)
        if not learnt.any():
            return fg
        keep = ~learnt
        return replace(
            fg,
            points=fg.points[keep],
            index=fg.index[keep],
            n_background=fg.n_background + int(np.count_nonzero(learnt)),
        )

    def _learn(
        self,
        frame: Frame,
        world: FloatArray,
        seen: FloatArray,
        found: Detections | None,
        tracks: Tracks | None,
        estimate: TrackEstimate,
    ) -> None:
        """Show the learning map the frame, with what it must not learn: every track that
        may be a drone (``pipeline.protect.protected_balls``, with the chooser's least
        p_drone of a track worth a look), and the turret's target unless its track is
        classed static."""
        if self.learning is None or tracks is None or found is None:
            return
        centres, radii = protected_balls(
            tracks,
            found,
            estimate,
            self.learning.settings.resolution,
            self.selection.settings.min_p,
        )
        if self.learning.observe(
            frame.end, world, frame.points, frame.poses[-1], seen, centres, radii
        ):
            log.debug("frame ending %.3f s: learnt map %d voxels", frame.end, len(self.learning))

    def _reachable(
        self,
        t: float,
        candidates: Candidates | None,
        found: Detections | None,
        tracks: Tracks | None,
    ) -> Candidates | None:
        """The candidates within the lost target's reach (``detect.lock``), the likeliest
        drones first (``found`` and ``tracks``: the frame's clusters and tracks)."""
        if self.acquisition is None or candidates is None:
            return candidates
        score = rank(candidates, found, tracks, self.selection.settings)
        return self.acquisition.lock.reachable(t, candidates, score)

    def _cues(self, t: float, found: Detections | None, tracks: Tracks | None) -> Candidates | None:
        """Tentative tracks worth a look while the tracker is not locked, within reach of
        the last fix (None: no acquisition, or locked)."""
        if self.acquisition is None or self.acquisition.lock.locked:
            return None
        return self._reachable(t, self.acquisition.tracks.cues(t), found, tracks)

    def _foreground(self, frame: Frame, flags: list[str]) -> Foreground:
        if len(frame) == 0:
            flags.append("empty")
            return _no_foreground()
        bg = None if self.scanning else self.background
        try:
            fg = extract_foreground(frame, self.crop_min, self.crop_max, bg)
        except InputError:
            flags.append("bad_pose")
            return _no_foreground()
        if fg.n_nonfinite:
            flags.append("nonfinite_points")
        if (self.hull is not None or self.field is not None) and len(fg.points):
            fg = _keep(fg, self._in_area(fg.points))
        return self._near_track(fg)

    def _in_area(self, points: FloatArray) -> NDArray[np.bool_]:
        """(N,) inside the hull crop and the field of regard, where set (the crop box is
        applied with the background, by ``extract_foreground``)."""
        inside = np.ones(len(points), dtype=bool)
        if self.hull is not None and len(points):
            inside &= self.hull.mask(points)
        if self.field is not None and len(points):
            inside &= self.field.contains(points)
        return inside

    def _near_track(self, fg: Foreground) -> Foreground:
        """Add back the points the background dropped that lie within one frame's reach
        of the locked target (v_max T + g from its last estimate) and clearly in front
        of the scan there (``preprocess/range_image.py``; margin: one voxel)."""
        ranges, lock = self.ranges, self.acquisition.lock if self.acquisition else None
        if ranges is None or not ranges.ready or lock is None or not lock.locked:
            return fg
        assert self.background is not None
        assert lock.estimate is not None
        s = lock.settings
        world = fg.world
        radius = reach(self.tracker.period, s.v_max, s.gate_m)
        near = ball_mask(world, lock.estimate.position, radius)
        near[fg.index] = False
        back = np.flatnonzero(near)
        back = back[box_mask(world[back], self.crop_min, self.crop_max)]
        back = back[self._in_area(world[back])]
        back = back[ranges.in_front(world[back], self.background.resolution)]
        if len(back) == 0:
            return fg
        index = np.concatenate([fg.index, back])
        return replace(
            fg, points=world[index], index=index, n_background=fg.n_background - len(back)
        )

    def _remove_outliers(self, points: FloatArray) -> FloatArray:
        o = self.outliers
        if o.radius is not None and len(points):
            points = points[radius_outlier_mask(points, o.radius, o.min_neighbors)]
        if o.mean_k is not None and len(points):
            points = points[statistical_outlier_mask(points, o.mean_k, o.std_mul)]
        return points

    def _result(
        self,
        frame: Frame,
        phase: Phase,
        estimate: TrackEstimate | None,
        fg: Foreground,
        points: FloatArray,
        command: TurretCommand | None,
        start: float,
        flags: list[str],
        periods: int,
    ) -> StepResult:
        return StepResult(
            t=frame.end,
            phase=phase,
            estimate=estimate,
            n_points=len(points),
            n_returns=len(frame),
            command=command,
            step_ms=1e3 * (time.perf_counter() - start),
            flags=tuple(flags),
            foreground=points,
            periods=periods,
            world=fg.world,
        )


def _keep(fg: Foreground, keep: NDArray[np.bool_]) -> Foreground:
    """The foreground's points where ``keep``; the others count as outside the crop."""
    return replace(
        fg,
        points=fg.points[keep],
        index=fg.index[keep],
        n_outside=fg.n_outside + int(np.count_nonzero(~keep)),
    )


def _no_foreground() -> Foreground:
    return Foreground(np.empty((0, 3)), np.empty(0, dtype=np.int64), 0, 0, 0)
