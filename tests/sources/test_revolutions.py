"""Revolution frames: a spinning head's stream cut at the starts its batches carry, and
the spin-rate and clock helpers of the VLP-16 link."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.sources.assembly import PointBatch
from dronetrack.sources.revolutions import RevolutionAssembler
from dronetrack.sources.velodyne.timing import PacketClock, RevolutionCuts, spin_rpm

HOUR_US = 3_600_000_000
SPAN = 1_327_104  # ns between VLP-16 packets, single return


def _batch(t: list[int], cuts: tuple[int, ...] = ()) -> PointBatch:
    n = len(t)
    xyz = np.column_stack([np.asarray(t, float), np.zeros(n), np.zeros(n)])
    u8 = np.zeros(n, np.uint8)
    first = (min(t), max(t)) if t else None
    return PointBatch(xyz, np.asarray(t, np.int64), u8, u8, firings=first, cuts=cuts)


def test_frames_run_from_one_start_to_the_next() -> None:
    asm = RevolutionAssembler()
    assert asm.push(_batch([5, 8], ())) == []  # before the first start: dropped
    assert asm.before_start == 2
    assert asm.t0_ns is None
    assert asm.push(_batch([9, 10, 11, 99], (10,))) == []
    assert asm.before_start == 3
    assert asm.t0_ns == 10
    done = asm.push(_batch([100, 105, 150, 200, 201], (105, 200)))
    assert [(f.index, f.start_ns, f.period_ns) for f in done] == [(0, 10, 95), (1, 105, 95)]
    assert done[0].points.t_ns.tolist() == [10, 11, 99, 100]
    assert done[1].points.t_ns.tolist() == [105, 150]
    # a late point (before the open revolution) is dropped; a revolution with no point
    # is a frame with none
    done = asm.push(_batch([199, 290], (300,)))
    assert asm.late_points == 1
    assert [(f.start_ns, f.period_ns, len(f.points)) for f in done] == [(200, 100, 3)]
    done = asm.push(_batch([], (400,)))
    assert [(f.start_ns, len(f.points)) for f in done] == [(300, 0)]
    assert asm.flush() == []


def test_a_start_at_or_before_the_open_one_is_ignored() -> None:
    asm = RevolutionAssembler()
    asm.push(_batch([10], (10,)))
    assert asm.push(_batch([11], (10, 5))) == []
    done = asm.push(_batch([20], (20,)))
    assert [(f.start_ns, f.period_ns) for f in done] == [(10, 10)]


@settings(max_examples=80, deadline=None)
@given(
    st.lists(st.integers(0, 10_000), min_size=1, max_size=200),
    st.lists(st.integers(1, 10_000), min_size=2, max_size=12, unique=True),
    st.integers(1, 7),
)
def test_every_point_after_the_first_start_lands_once_in_its_revolution(
    times: list[int], starts: list[int], parts: int
) -> None:
    t = np.sort(np.asarray(times, np.int64))
    cuts = sorted(starts)
    asm = RevolutionAssembler()
    frames = []
    # the stream in batches, each carrying the starts among its own points' span
    edges = np.linspace(0, 10_001, parts + 1).astype(np.int64)
    for lo, hi in itertools.pairwise(edges):
        sel = (t >= lo) & (t < hi)
        mine = tuple(c for c in cuts if lo <= c < hi)
        frames += asm.push(_batch(t[sel].tolist(), mine))
    assert [f.start_ns for f in frames] == cuts[:-1]
    for f, end in zip(frames, cuts[1:], strict=True):
        assert f.start_ns + f.period_ns == end
        inside = t[(t >= f.start_ns) & (t < end)]
        assert f.points.t_ns.tolist() == inside.tolist()
    assert asm.before_start == int((t < cuts[0]).sum())


def test_the_clock_unwraps_the_hour_and_counts_lost_packets() -> None:
    clock = PacketClock()
    # packets 0, 1, then 4 (2 lost), stamped µs past the hour, 2 ms before it turns
    k = np.array([0, 1, 4, 5])
    stamps = (HOUR_US - 2000 + np.rint(k * SPAN / 1000).astype(np.int64)) % HOUR_US
    t = clock.times_ns(stamps, np.full(4, SPAN))
    np.testing.assert_array_equal(t, (HOUR_US - 2000 + np.rint(k * SPAN / 1000)) * 1000)
    assert clock.lost == 2
    # the next read goes on in the new hour, one packet later
    t2 = clock.times_ns(np.array([stamps[-1] + 1327]), np.array([SPAN]))
    assert t2[0] == t[-1] + 1_327_000
    assert clock.lost == 2


def test_revolution_cuts_interpolate_where_the_azimuth_passes_the_cut_angle() -> None:
    t = np.array([0, 100, 200, 300])
    # 89.00°, 89.90°, 90.40°, 90.90°: 90° is passed 10/50 of the way from 89.90° to 90.40°
    cuts = RevolutionCuts(cut_deg=90.0)
    assert cuts.cuts(t, np.array([8900, 8990, 9040, 9090], np.uint16)) == [120]
    # it remembers the last block: 89.80° then, in the next call, 90.20°
    cuts = RevolutionCuts(cut_deg=90.0)
    assert cuts.cuts(t[:1], np.array([8980], np.uint16)) == []
    assert cuts.cuts(t[1:2], np.array([9020], np.uint16)) == [50]
    assert cuts.cuts(t[2:3], np.array([9060], np.uint16)) == []
    # the azimuth falling back below 90° is no start; reaching it again is
    assert cuts.cuts(np.array([400, 500]), np.array([8990, 9000], np.uint16)) == [500]
    # time going back starts afresh: only a block right on the angle starts one
    assert cuts.cuts(np.array([10]), np.array([9000], np.uint16)) == [10]
    assert cuts.cuts(np.array([5]), np.array([9100], np.uint16)) == []


def test_the_spin_rate_comes_from_the_azimuths() -> None:
    t = np.arange(0, 100) * 110_592  # one block of two sequences apart
    step = 600 / 60 * 36_000 * 110.592e-6  # 0.01° a block at 600 rpm
    az = np.rint(np.arange(100) * step) % 36_000
    assert spin_rpm(t, az.astype(np.uint16)) == pytest.approx(600.0, rel=1e-3)
    assert spin_rpm(t[:5], az[:5].astype(np.uint16)) is None  # under 1 ms
