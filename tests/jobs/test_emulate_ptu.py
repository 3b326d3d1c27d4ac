"""The emulated rig of a PTU-E46 scenario driven by the real host-side clients on
loopback: the Livox SDK 1 client over UDP and the PTU driver on the emulated unit's
pseudo-terminal, paced at 9600 baud."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from dronetrack.actuators.ptu.line import open_line
from dronetrack.actuators.ptu.turret import PtuTurret
from dronetrack.actuators.ptu.uri import parse_ptu_uri
from dronetrack.config.run import TurretConfig
from dronetrack.config.scenarios import get_scenario
from dronetrack.jobs.emulate import emulated_rig
from dronetrack.sim.turret import TurretPlant
from dronetrack.sources.livox.sdk1 import LivoxClient, LivoxEndpoint
from dronetrack.types import TurretCommand

TAU = 10.0 / 9600.0


@pytest.mark.slow
def test_a_ptu_scenarios_goals_move_the_simulated_turret_with_its_dynamics() -> None:
    cfg = get_scenario("default")  # a 0.5 s scan, 2.5 s of flight, the PTU-E46
    background = cfg.pipeline.background.model_copy(update={"scan_s": 0.5})
    pipeline = cfg.pipeline.model_copy(update={"background": background})
    turret = TurretConfig(model="ptu-e46")
    cfg = cfg.model_copy(update={"duration_s": 2.5, "pipeline": pipeline, "turret": turret})
    rig = emulated_rig(cfg, any_ports=True)
    spec = rig.world.plant.spec
    assert spec.name == "ptu-e46"
    assert rig.ptu is not None
    endpoint = LivoxEndpoint("127.0.0.1", None, 0, 0, 0, rig.address[1])
    with rig, LivoxClient(endpoint, discover_s=0.1) as client:
        assert rig.turret_uri == f"ptu://{rig.serial_device}"
        line = open_line(parse_ptu_uri(rig.turret_uri))
        ptu = PtuTurret(line, turret=spec, poll_hz=0)
        try:
            at_rest = ptu.state()
            client.open(timeout_s=3.0)  # the scenario clock starts
            time.sleep(0.2)
            start = ptu.state()
            assert (start.pan, start.tilt) == (at_rest.pan, at_rest.tilt)
            goal = (start.pan + 0.4, start.tilt - 0.25)
            before = time.monotonic()
            ptu.command(TurretCommand(0.0, *goal))
            after = time.monotonic()
            sent = b"PP%d TP%d " % tuple(ptu.goals)
            states = []
            deadline = time.monotonic() + 1.5
            while time.monotonic() < deadline:
                client.read(0.0)
                states.append(ptu.state())
                time.sleep(0.02)
        finally:
            ptu.close()
        anchor = rig.device.stream_start
    # The simulator's turret alone, each goal queued when the unit had it whole: the
    # write started in [before, after - its replies' time], then its bytes crossed the
    # line (pan's goal at its delimiter, tilt's at the end).
    pan_at = before + (sent.index(b" ") + 1) * TAU - anchor
    tilt_at = before + len(sent) * TAU - anchor
    plant = TurretPlant(spec, pan=start.pan, tilt=start.tilt, t0=pan_at)
    plant.command_axis("pan", pan_at, goal[0])
    plant.command_axis("tilt", tilt_at, goal[1])
    t, pan, tilt = plant.advance(pan_at + 3.0)
    # A state is stamped between its two queries (1.5 bytes from each), and the write's
    # start is known to (after - before) less the 21 bytes of the exchange.
    omega = spec.pan.rate
    uncertain = max(after - before - 21 * TAU, 0.0) + 1.5 * TAU + 0.005
    tol = omega * uncertain + 2 * spec.pan.resolution
    s = np.array([st.stamp - anchor for st in states])
    got = np.array([[st.pan, st.tilt] for st in states])
    want = np.column_stack([np.interp(s, t, pan), np.interp(s, t, tilt)])
    err = np.abs(got - want)
    assert err.max() <= tol, (err.max(), tol)
    q = spec.pan.resolution
    np.testing.assert_allclose(got[-1], goal, atol=q)
    moving = (s > pan_at + 0.05) & (s < pan_at + 0.1)
    rates = np.array([[st.pan_rate, st.tilt_rate] for st in states])[moving]
    assert np.all(rates[:, 0] > 0)
    assert np.all(rates[:, 1] < 0)
    assert np.all(np.abs(rates) <= omega * 1.1)
    assert rig.ptu.refused == 0
    assert math.isclose(rig.ptu.axes["P"].resolution_arcsec, 46.44)


def test_the_ptu_moves_before_any_lidar_host_samples() -> None:
    """No LiDAR host: a goal sent to the emulated PTU moves it there, as a real unit's."""
    cfg = get_scenario("default")
    cfg = cfg.model_copy(update={"duration_s": 0.5, "turret": TurretConfig(model="ptu-e46")})
    rig = emulated_rig(cfg, any_ports=True)
    spec = rig.world.plant.spec
    with rig:
        ptu = PtuTurret(open_line(parse_ptu_uri(rig.turret_uri)), turret=spec, poll_hz=0)
        try:
            start = ptu.state()
            goal = (start.pan + 0.4, start.tilt - 0.25)
            ptu.command(TurretCommand(0.0, *goal))
            states = []
            for _ in range(100):  # 100 reads, each two queries at 9600 baud: ≤ 2 s
                states.append(ptu.state())
                if np.allclose([states[-1].pan, states[-1].tilt], goal, atol=spec.pan.resolution):
                    break
        finally:
            ptu.close()
    assert not rig.started.is_set()
    got = np.array([[s.pan, s.tilt] for s in states])
    np.testing.assert_allclose(got[-1], goal, atol=spec.pan.resolution)
    assert len(states) > 2  # it moved through reads, not in a jump
    # towards the goal, past it by at most the simulated turret's own braking error
    alone = TurretPlant(spec, pan=start.pan, tilt=start.tilt)
    alone.command(TurretCommand(0.0, *goal))
    _, pan, tilt = alone.advance(3.0)
    q = spec.pan.resolution
    assert np.all(got[:, 0] <= pan.max() + q)
    assert np.all(got[:, 1] >= tilt.min() - q)
    assert np.all(np.diff(got[: len(got) // 2], axis=0) * [1, -1] >= -q)
