"""Issue 10 items 1-3: no command drives a current beyond the limit or stalls the loop; a long stall
while active trips MISSED_DEADLINES; a CSV profile is loaded off the loop thread."""

from __future__ import annotations

import math
import os
import threading

import numpy as np
import pytest

from ankle_rt import daemon as daemon_module
from ankle_rt.references import CsvProfile, Profile
from ankle_rt.safety import Fault, State
from ankle_rt.service.protocol import CommandError, Pending, SetGains, SetReference, StartProfile, parse_command
from ankle_rt.service.protocol import CommandLimits
from tests.daemon_helpers import InjectingBackend, lockstep_daemon, reply, run_cycles


@pytest.fixture
def cfg(sim_cfg):
    sim_cfg["sim"]["disturbances"] = []
    sim_cfg["reference"]["profile"] = "hold"
    return sim_cfg


@pytest.fixture
def daemon(cfg):
    from ankle_rt.clock import SimClock
    clock = SimClock()
    d = lockstep_daemon(cfg, backend=InjectingBackend(cfg, clock))
    yield d
    d.close()


def test_huge_and_non_finite_gains_are_refused(daemon):
    limits = CommandLimits.from_config(daemon.cfg)
    with pytest.raises(CommandError) as err:
        parse_command(b'{"cmd":"set_gains","kp":1e300,"kd":1e300}', limits)
    assert err.value.field == "kp" and "controller.gain_limits" in err.value.message
    run_cycles(daemon, 300)
    for gains in ({"kp": 1e300}, {"kd": 1e300}, {"kp": math.nan}, {"kd": math.inf}, {"kp": -1.0}):
        with pytest.raises(CommandError) as err:
            daemon.handle(SetGains(**gains))
        assert err.value.field == next(iter(gains))
    assert daemon.controller.gains.as_dict() == {"kp": 90.0, "kd": 5.0}


def test_the_protocol_and_the_daemon_refuse_gains_and_references_by_the_same_check(daemon):
    """One check each (ankle_rt.command_limits): a request line and a direct daemon call give the
    same reason, whichever way the command comes in."""
    limits = CommandLimits.from_config(daemon.cfg)
    for line, command in ((b'{"cmd":"set_gains","kd":600}', SetGains(kd=600.0)),
                          (b'{"cmd":"set_reference","dp":0.1,"ie":-0.9}', SetReference(0.1, -0.9))):
        with pytest.raises(CommandError) as parsed:
            parse_command(line, limits)
        with pytest.raises(CommandError) as handled:
            daemon.handle(command)
        assert parsed.value.field == handled.value.field
        assert parsed.value.message in handled.value.message


def test_a_reference_jump_is_rate_limited_and_the_current_stays_within_the_peak(daemon):
    run_cycles(daemon, 300)
    assert daemon.safety.state == State.ACTIVE
    daemon.handle(SetReference(math.radians(39.99), math.radians(-39.99), 0.0))
    run_cycles(daemon, 1500)
    rec = daemon.recorder.records
    step = np.abs(np.diff(rec["ref_dp"][300:]))
    assert step.max() <= daemon.cfg["reference"]["max_rate_rad_s"] * daemon.dt * (1 + 1e-9)
    peak = daemon.cfg["amplifier"]["current_limit_peak"]
    writes = np.array([w[1:] for w in daemon.backend.writes])
    assert np.all(np.abs(writes) <= peak)
    # the ankle reaches the edge of its range and the range fault stops it there (no motor runaway)
    assert rec["fault"][-1] == Fault.ANKLE_RANGE
    limit = math.radians(daemon.cfg["limits"]["ankle_range_deg"] + 0.5)
    assert np.abs(rec["est_ankle_dp"]).max() < limit and np.abs(rec["est_ankle_ie"]).max() < limit


class NaNAt(Profile):
    relative = False

    def __init__(self, tau: float):
        self.tau = tau

    def value(self, tau):
        return (math.nan, 0.0) if tau >= self.tau else (0.0, 0.0)

    def bounds(self):
        return (0.0, 0.0), (0.0, 0.0)


def test_a_non_finite_reference_is_a_fault_before_the_amplifiers_see_it(daemon):
    run_cycles(daemon, 300)
    daemon.reference.start(NaNAt(0.05))
    run_cycles(daemon, 100)
    assert daemon.safety.state == State.FAULT and daemon.safety.fault == Fault.REFERENCE_INVALID
    assert all(math.isfinite(i1) and math.isfinite(i2) for _, i1, i2 in daemon.backend.writes)
    assert daemon.backend.writes[-1][1:] == (0.0, 0.0)


def test_a_long_stall_while_active_trips_missed_deadlines(daemon):
    run_cycles(daemon, 300)
    assert daemon.safety.state == State.ACTIVE
    update = daemon.controller.update

    def stall_once(est, out):
        update(est, out)
        if abs(est.t - 0.35) < 1e-9:
            daemon.clock.advance(1_408_000_000)      # the 12 MB profile load the issue measured
    daemon.controller.update = stall_once
    run_cycles(daemon, 200)
    assert daemon.safety.state == State.FAULT and daemon.safety.fault == Fault.MISSED_DEADLINES
    assert daemon.loop.stats.overruns == 1        # one stall, longer than loop.max_stall_s (50 ms)


def test_a_csv_profile_loads_off_the_loop_thread_and_starts_when_ready(daemon, tmp_path, monkeypatch):
    path = tmp_path / "ref.csv"
    t = np.arange(0, 2.0, 0.001)
    np.savetxt(path, np.column_stack([t, 0.1 * np.sin(t), 0.0 * t]), delimiter=",", header="t,ref_dp,ref_ie",
               comments="")
    threads = []
    real = daemon_module.load_csv_profile

    def spy(*args, **kw):
        threads.append(threading.current_thread())
        return real(*args, **kw)
    monkeypatch.setattr(daemon_module, "load_csv_profile", spy)
    run_cycles(daemon, 300)
    pending = daemon.handle(StartProfile("csv", {"path": str(path)}))
    assert isinstance(pending, Pending)
    data = reply(pending)
    assert data["loaded_rows"] == len(t)
    assert threads and threads[0] is not threading.current_thread()
    run_cycles(daemon, 100)
    profile = daemon.reference.profile
    assert isinstance(profile, CsvProfile) and profile.value(1.0) == pytest.approx((0.1 * math.sin(1.0), 0.0))


def test_a_fifo_as_profile_is_refused_without_blocking(daemon, tmp_path):
    fifo = tmp_path / "ref.csv"
    os.mkfifo(fifo)
    with pytest.raises(CommandError) as err:
        reply(daemon.handle(StartProfile("csv", {"path": str(fifo)})))
    assert err.value.field == "params.path" and "not a regular file (a FIFO)" in err.value.message


def test_only_one_profile_loads_at_a_time(daemon, tmp_path):
    path = tmp_path / "ref.csv"
    path.write_text("t,ref_dp,ref_ie\n0,0,0\n1,0.1,0\n")
    gate = threading.Event()
    first = daemon.loader.submit(gate.wait, "something slow")
    with pytest.raises(CommandError, match="busy: still loading something slow"):
        daemon.handle(StartProfile("csv", {"path": str(path)}))
    gate.set()
    while not first.done:
        gate.wait(0.001)
    assert reply(daemon.handle(StartProfile("csv", {"path": str(path)})))["loaded_rows"] == 2
