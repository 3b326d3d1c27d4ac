"""The classify stage: each frame, the ground learnt from the frame's returns, each
track's observation, its life, and its class and p_drone (``observe``, ``features``,
``rules``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from dronetrack.classify.features import TrackLives
from dronetrack.classify.observe import BackgroundTest, observe, view_floor
from dronetrack.classify.return_share import return_share
from dronetrack.classify.rules import ClassRules, classify, in_open_air
from dronetrack.geometry.transforms import FloatArray
from dronetrack.preprocess.ground import GroundGrid
from dronetrack.types import Detections, Tracks

__all__ = ["TrackClassifier"]

# The view's floor from every FLOOR_STRIDE-th row of the ground's sample: an Avia frame's
# 24,000 returns give 750, tens in each 5° sector it sees, where the lowest lie on the
# ground band at the view's floor, densely sampled (0.02 ms a frame)
FLOOR_STRIDE = 4


class TrackClassifier:
    """Classes every track (see the module docstring).

    ``limit_m``: the range beyond which the drone model the site guards returns no
    point (None: not known, the feature is off); ``floor_z``: the crop box's floor [m]
    (what stands on the ground is cut there); ``hover_speed``, ``hover_frames``: v_hover
    and K of the hover test; ``crowd_gap_m``: g_c of the crowded test (None: off);
    ``share``: (r₅₀, s) [m] of the share of frames the drone returns a point
    (``return_share``; None: not known, the test of a track that returns too often is
    off); ``engulf_m``: ε of the engulfed test (the clustering's; None: off);
    ``drone_size_m``: s of the height spread's test (the drone's diagonal).
    """

    def __init__(
        self,
        rules: ClassRules | None = None,
        *,
        limit_m: float | None = None,
        floor_z: float = -np.inf,
        hover_speed: float = 4.0,
        hover_frames: int = 3,
        ground_cell_m: float = 5.0,
        ground_every: int = 10,
        crowd_gap_m: float | None = None,
        share: tuple[float, float] | None = None,
        engulf_m: float | None = None,
        drone_size_m: float = 0.4,
    ) -> None:
        self.rules = rules if rules is not None else ClassRules()
        self.limit_m = limit_m
        self.floor_z = floor_z
        self.hover = (hover_speed, hover_frames)
        self.ground_cell_m = ground_cell_m
        self.ground_every = ground_every
        self.crowd_gap_m = crowd_gap_m
        self.share = share
        self.engulf_m = engulf_m
        self.drone_size_m = drone_size_m
        self.reset()

    def reset(self) -> None:
        """Forget the ground and every track's life."""
        self.ground = GroundGrid(self.ground_cell_m)
        self.lives = TrackLives(
            *self.hover, drone_size_m=self.drone_size_m, ground_cell_m=self.ground_cell_m
        )
        self._frames = 0

    def step(
        self,
        t: float,
        tracks: Tracks,
        found: Detections,
        world: FloatArray,
        foreground: NDArray[np.int64],
        sensor: FloatArray,
        is_background: BackgroundTest | None = None,
        resting: NDArray[np.int64] | None = None,
        heirs: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None,
    ) -> Tracks:
        """``tracks`` after the frame ending at ``t`` with their classes and p_drone.

        ``world`` (N, 3) is every return of the frame and ``foreground`` the rows of it
        that are foreground: the ground is learnt from a sample of the others, every
        ``ground_every`` frames (it changes slowly; a sample of a frame costs 0.15 ms),
        and the view's floor (``observe.view_floor``) from the same sample each frame;
        ``sensor`` (3,) is the sensor's position, ``is_background`` the background
        map's test (None: no map yet).  The propped test probes the foreground and the
        ground's sample of the other returns (a pole outside the map is foreground).
        The lives of the identities ``resting`` (``track.rest``) are kept for an heir
        (``heirs``: new identities and those whose lives they take); those of the other
        tracks that ended are forgotten."""
        stride = self.ground.stride
        keep = np.ones((len(world) + stride - 1) // stride, dtype=bool)
        keep[foreground[foreground % stride == 0] // stride] = False  # every stride-th row
        others = world[::stride][keep]
        if self._frames % self.ground_every == 0:
            self.ground.insert(others, stride=1)
        self._frames += 1
        obs = observe(
            tracks,
            found,
            sensor,
            self.ground.height(tracks.positions[:, :2]),
            floor_z=self.floor_z,
            limit_m=self.limit_m,
            is_background=is_background,
            crowd_gap_m=self.crowd_gap_m,
            floor=view_floor(others[::FLOOR_STRIDE], sensor),
            below=np.concatenate([world[foreground], others]),
            engulf_m=self.engulf_m,
        )
        share = None
        if self.share is not None:
            share = return_share(np.linalg.norm(tracks.positions - sensor, axis=1), *self.share)
        life = self.lives.update(t, tracks, obs, resting, heirs, share)
        classes, p_drone = classify(life, self.rules)
        air = in_open_air(life, self.rules)
        return replace(tracks, classes=classes, p_drone=p_drone, open_air=air)
