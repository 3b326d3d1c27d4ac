"""The classify stage: each frame, the ground learnt from the frame's returns, each
track's observation, its life, and its class and p_drone (``features``, ``rules``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from dronetrack.classify.features import BackgroundTest, TrackLives, observe
from dronetrack.classify.rules import ClassRules, classify
from dronetrack.geometry.transforms import FloatArray
from dronetrack.preprocess.ground import GroundGrid
from dronetrack.types import Detections, Tracks

__all__ = ["TrackClassifier"]


class TrackClassifier:
    """Classes every track (see the module docstring).

    ``reach_m``: the reach of the drone model the site guards (None: not known, the
    feature is off); ``floor_z``: the crop box's floor [m] (what stands on the ground
    is cut there); ``hover_speed``, ``hover_frames``: v_hover and K of the hover test.
    """

    def __init__(
        self,
        rules: ClassRules | None = None,
        *,
        reach_m: float | None = None,
        floor_z: float = -np.inf,
        hover_speed: float = 4.0,
        hover_frames: int = 3,
        ground_cell_m: float = 5.0,
    ) -> None:
        self.rules = rules if rules is not None else ClassRules()
        self.reach_m = reach_m
        self.floor_z = floor_z
        self.hover = (hover_speed, hover_frames)
        self.ground_cell_m = ground_cell_m
        self.reset()

    def reset(self) -> None:
        """Forget the ground and every track's life."""
        self.ground = GroundGrid(self.ground_cell_m)
        self.lives = TrackLives(*self.hover)

    def step(
        self,
        t: float,
        tracks: Tracks,
        found: Detections,
        world: FloatArray,
        sensor: FloatArray,
        is_background: BackgroundTest | None = None,
    ) -> Tracks:
        """``tracks`` after the frame ending at ``t`` with their classes and p_drone;
        ``world`` (N, 3) the frame's returns that are no target (the ground is learnt
        from them), ``sensor`` (3,) the sensor's position, ``is_background`` the
        background map's test (None: no map yet)."""
        self.ground.insert(world)
        obs = observe(
            tracks,
            found,
            sensor,
            self.ground.height(tracks.positions[:, :2]),
            floor_z=self.floor_z,
            reach_m=self.reach_m,
            is_background=is_background,
        )
        life = self.lives.update(t, tracks, obs)
        classes, p_drone = classify(life, self.rules)
        return replace(tracks, classes=classes, p_drone=p_drone)
