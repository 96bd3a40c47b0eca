"""Safety in lockstep: every fault drives the safe outputs within the cycle that sees it, the log
names it, the fault latches until an explicit reset; the loop's overrun policy on a SimClock."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ankle_rt.backend import BackendFault
from ankle_rt.clock import SimClock
from ankle_rt.daemon import run_lockstep
from ankle_rt.safety import Fault, State
from ankle_rt.service import protocol as proto
from tests.daemon_helpers import InjectingBackend, lockstep_daemon, reply, run_cycles, variant

AT = 300   # cycle of the injection; the daemon is active from cycle 99 (after the 100-sample tare)


def _set(attr, index, value):
    def mutate(frame, _cycle):
        getattr(frame, attr)[index] = value
    return mutate


def _add(attr, index, value):
    def mutate(frame, _cycle):
        getattr(frame, attr)[index] += value
    return mutate


def _bits(bits):
    def mutate(frame, _cycle):
        frame.faults = bits
    return mutate


def _seq(frame, _cycle):
    frame.seq = 123456


CASES = [
    # (name, mutate, expected fault, cycles between the injection and the fault)
    ("motor jump", _add("motor_pos", 0, 0.5), Fault.MOTOR_JUMP, 0),
    ("strain-gauge jump", _add("sg_torque", 1, 25.0), Fault.SG_JUMP, 0),
    ("strain gauge at rail", _set("sg_torque", 0, 300.0), Fault.SG_RAIL, 0),   # beyond safety.sg_rail_nm (225)
    ("NaN encoder", _set("motor_pos", 1, math.nan), Fault.SENSOR_INVALID, 0),
    ("NaN joint encoder", _set("ankle_pos", 0, math.nan), Fault.JOINT_INVALID, 0),   # the bridge's invalid bit
    ("amplifier not ready", _set("amp_ready", 0, False), Fault.AMP_NOT_READY, 0),
    ("joint encoder beyond range", _set("ankle_pos", 1, math.radians(45)), Fault.ANKLE_RANGE, 0),
    ("stale samples", _seq, Fault.SENSOR_STALE, 5),
    ("backend: link lost", _bits(BackendFault.LINK_LOST), Fault.LINK_LOST, 0),
    ("backend: bus-off", _bits(BackendFault.BUS_OFF), Fault.BUS_OFF, 0),
    ("backend: device fault", _bits(BackendFault.DEVICE_FAULT), Fault.DEVICE_FAULT, 0),
    ("backend: encoder fault", _bits(BackendFault.ENCODER_FAULT), Fault.ENCODER_FAULT, 0),
    ("backend: amp not ready", _bits(BackendFault.AMP_NOT_READY), Fault.AMP_NOT_READY, 0),
    ("backend: strain-gauge rail", _bits(BackendFault.STRAIN_GAUGE_RAIL), Fault.SG_RAIL, 0),
    ("backend: stale sample", _bits(BackendFault.STALE_SAMPLE), Fault.SENSOR_STALE, 0),
]


def check_fault_cycle(rec, backend, k, fault):
    """The record of cycle k shows FAULT with its reason and zero set values; the amplifiers were
    disabled in cycle k; nothing was sent afterwards and the fault stays latched."""
    state = rec["state"]
    assert np.all(state[:k] != State.FAULT), "fault before the cause"
    assert state[k] == State.FAULT and rec["fault"][k] == fault
    assert backend.deactivated_at and backend.deactivated_at[0] == k
    assert not backend.active
    assert np.all(rec["current_cmd_1"][k:] == 0.0) and np.all(rec["current_cmd_2"][k:] == 0.0)
    assert np.all(state[k:] == State.FAULT) and np.all(rec["fault"][k:] == fault)


@pytest.mark.parametrize("name, mutate, fault, delay", CASES, ids=[c[0] for c in CASES])
def test_fault_goes_safe_within_the_cycle_and_is_logged(sim_cfg, name, mutate, fault, delay):
    backend = InjectingBackend(sim_cfg, SimClock(), at=AT, mutate=mutate)
    res = run_lockstep(sim_cfg, 0.4, backend=backend)
    check_fault_cycle(res.records, backend, AT + delay, fault)


def test_ankle_beyond_the_software_limit_trips_as_it_crosses(sim_cfg):
    cfg = variant(sim_cfg, limits={"ankle_range_deg": 8.0})     # the 10 deg DP step overshoots it
    backend = InjectingBackend(cfg, SimClock())
    rec = run_lockstep(cfg, 1.5, backend=backend).records
    lim = math.radians(8.0)
    beyond = (np.abs(rec["est_ankle_dp"]) > lim) | (np.abs(rec["ankle_dp"]) > lim)
    k = int(np.flatnonzero(beyond)[0])
    check_fault_cycle(rec, backend, k, Fault.ANKLE_RANGE)


class Constant:
    """A controller that asks for a fixed motor torque (N m) on both motors."""

    def __init__(self, torque):
        self.torque = torque

    def reset(self, est):
        pass

    def update(self, est, out):
        out[0] = out[1] = self.torque


def test_current_limit_clamps_to_peak_and_i2t_trips(sim_cfg):
    cfg = variant(sim_cfg, safety={"i2t_peak_duration_s": 0.05})
    backend = InjectingBackend(cfg, SimClock())
    rec = run_lockstep(cfg, 0.4, controller=Constant(40.0), backend=backend).records
    kt, pk = cfg["actuator"]["torque_constant"], cfg["amplifier"]["current_limit_peak"]
    sent = rec["current_cmd_1"][rec["state"] == State.ACTIVE]
    assert sent.max() == pk                                # 40 N m / kt = 24 A, clamped to 15 A
    # the I^2 t estimate from the commanded (clamped) currents crosses the budget in the fault cycle
    i = np.clip(rec["torque_cmd_1"] / kt, -pk, pk) * (rec["state"] != State.CONFIGURED)
    budget = (pk ** 2 - cfg["amplifier"]["current_limit_continuous"] ** 2) * 0.05
    q, k = 0.0, None
    for n, x in enumerate(i):
        q = max(0.0, q + (x * x - 25.0) / cfg["controller"]["rate_hz"])
        if q >= budget:
            k = n
            break
    check_fault_cycle(rec, backend, k, Fault.OVERCURRENT)


def test_nan_controller_output_trips(sim_cfg):
    backend = InjectingBackend(sim_cfg, SimClock())
    rec = run_lockstep(sim_cfg, 0.2, controller=Constant(math.nan), backend=backend).records
    check_fault_cycle(rec, backend, 99, Fault.OUTPUT_INVALID)


class SlowFrom:
    """A controller whose cycles take 1.5 periods (on the SimClock) from cycle ``at`` on."""

    def __init__(self, clock, at, period_ns):
        self.clock, self.at, self.period_ns, self.n = clock, at, period_ns, -1

    def reset(self, est):
        pass

    def update(self, est, out):
        self.n += 1
        out[0] = out[1] = 0.0
        if est.t >= self.at * 1e-3:
            self.clock.advance(self.period_ns * 3 // 2)


def test_consecutive_overruns_trip_missed_deadlines(sim_cfg):
    clock = SimClock()
    backend = InjectingBackend(sim_cfg, clock)
    d = lockstep_daemon(sim_cfg, backend=backend, controller=SlowFrom(clock, AT, 1_000_000))
    run_cycles(d, 400)
    rec = d.recorder.records
    n = sim_cfg["loop"]["max_consecutive_overruns"]
    k = int(np.flatnonzero(rec["t"] >= AT * 1e-3)[0])       # first slow cycle
    # the n-th overrun in a row ends cycle k + n - 1: the amplifiers go off right then, and the
    # next record carries the fault
    assert backend.deactivated_at[0] == k + n - 1
    assert rec["state"][k + n - 1] == State.ACTIVE
    assert rec["state"][k + n] == State.FAULT and rec["fault"][k + n] == Fault.MISSED_DEADLINES
    assert np.all(rec["current_cmd_1"][k + n:] == 0.0)


def test_overrun_policy_counts_skips_and_never_bursts(sim_cfg):
    clock = SimClock()

    class OneSlowCycle:
        def reset(self, est):
            pass

        def update(self, est, out):
            out[0] = out[1] = 0.0
            if abs(est.t - 0.2) < 1e-9:
                clock.advance(2_500_000)        # this cycle takes 2.5 periods

    d = lockstep_daemon(sim_cfg, backend=InjectingBackend(sim_cfg, clock), controller=OneSlowCycle())
    run_cycles(d, 400)
    rec = d.recorder.records
    st = d.loop.stats
    assert st.overruns == 1 and st.skipped == 2 and d.loop.consecutive_overruns == 0
    starts = np.round(rec["loop_time"] * 1e6).astype(int)   # µs
    gaps = np.diff(starts)
    slow = int(np.flatnonzero(np.abs(rec["t"] - 0.2) < 1e-9)[0])
    assert gaps[slow] == 3000                     # the next cycle waits for the next free deadline
    assert np.all(np.delete(gaps, slow) == 1000)  # no catch-up burst, grid kept
    assert rec["overruns"][-1] == 1 and np.all(rec["state"][-1] == State.ACTIVE)
    # the plant did not lose the skipped time: its sample time jumps 3 ms too
    assert rec["t"][slow + 1] - rec["t"][slow] == pytest.approx(0.003)


def test_lost_command_channel_trips_when_configured(sim_cfg, tmp_path):
    from ankle_rt.service.link import ServiceLink

    cfg = variant(sim_cfg, service={"command_timeout_s": 0.05, "socket_path": str(tmp_path / "s.sock")})
    backend = InjectingBackend(cfg, SimClock())
    d = lockstep_daemon(cfg, backend=backend)
    d.service = ServiceLink(cfg, d.handle, environ={})
    try:
        run_cycles(d, 300)
    finally:
        d.close()
    rec = d.recorder.records
    k = int(np.flatnonzero(rec["state"] == State.FAULT)[0])
    assert rec["fault"][k] == Fault.COMMAND_LOST
    assert rec["t"][k] - rec["t"][99] == pytest.approx(0.051, abs=1.5e-3)
    assert backend.deactivated_at[0] == k


def test_reset_is_needed_to_leave_the_fault_and_activation_holds_the_ankle(sim_cfg):
    backend = InjectingBackend(sim_cfg, SimClock(), at=AT, mutate=_bits(BackendFault.DEVICE_FAULT))
    d = lockstep_daemon(sim_cfg, backend=backend)
    run_cycles(d, AT + 10)
    assert d.safety.state == State.FAULT
    with pytest.raises(proto.CommandError) as err:
        d.handle(proto.Activate())
    assert err.value.field == "cmd" and "reset" in err.value.message
    backend.mutate = None
    assert d.handle(proto.ResetFault())["state"] == "safe"
    assert d.handle(proto.Activate())["state"] == "active"
    run_cycles(d, 50)
    rec = d.recorder.records
    assert rec["state"][-1] == State.ACTIVE and rec["fault"][-1] == Fault.NONE
    # after a fault the reference holds where the ankle was, not the configured step
    assert abs(rec["ref_dp"][-1] - rec["est_ankle_dp"][AT + 10]) < 1e-3


def test_commands_with_bad_fields_are_refused_naming_the_field(sim_cfg):
    d = lockstep_daemon(sim_cfg)
    run_cycles(d, 150)
    with pytest.raises(proto.CommandError) as err:
        reply(d.handle(proto.SetGains(stiffness_dp=10.0)))   # the PD has no stiffness (checked off the loop thread)
    assert err.value.field == "stiffness_dp"
    with pytest.raises(proto.CommandError) as err:
        d.handle(proto.StartProfile("sine", {"frequency_hz": -1.0}))
    assert err.value.field == "params.frequency_hz"
    with pytest.raises(proto.CommandError) as err:
        d.handle(proto.StartProfile("sine", {"amplitude": 0.1}))
    assert err.value.field == "params.amplitude"
    status = d.handle(proto.Status())
    assert status["state"] == "active" and status["gains"] == {"kp": 90.0, "kd": 5.0}
    run_cycles(d, 10)
    assert d.safety.state == State.ACTIVE


def test_set_values_reach_the_amplifiers_only_while_active(sim_cfg):
    cfg = variant(sim_cfg, reference={"profile": "hold", "hold": {"dp": 0.05, "ie": 0.02}})
    backend = InjectingBackend(cfg, SimClock(), at=AT, mutate=_bits(BackendFault.LINK_LOST))
    d = lockstep_daemon(cfg, backend=backend)
    run_cycles(d, AT + 50)
    backend.mutate = None                              # the link is back
    d.handle(proto.ResetFault())
    run_cycles(d, 50)                                  # SAFE: sensors read, nothing sent
    state = d.recorder.records["state"]
    nonzero = [(k, i1, i2) for k, i1, i2 in backend.writes if i1 != 0.0 or i2 != 0.0]
    assert len(nonzero) > 100
    assert all(state[k] == State.ACTIVE for k, _, _ in nonzero)
    assert all(k < AT for k, _, _ in nonzero)
    assert np.all(state[AT + 50:] == State.SAFE)


def test_no_set_value_drives_a_motor_beyond_the_governor_speed_faster(sim_cfg):
    """Safety9: a configured step under an accepted PD (kp 500, kd 10; 22 deg DP) drove the motors at
    the 15 A clamp past safety.max_motor_speed_rad_s: MOTOR_JUMP, the amplifiers off at 30 rad/s and
    the unpowered foot coasting on to 144 deg. A set value may no longer drive a motor that turns
    faster than GOVERNOR_SHARE of the limit faster still: the step is taken at up to 24.4 rad/s and
    the ankle stops at the target."""
    cfg = variant(sim_cfg, controller={"step_gains": {"kp": 500.0, "kd": 10.0},
                                       "gain_limits": {**sim_cfg["controller"]["gain_limits"], "kp": 500.0, "kd": 10.0}},
                  reference={"step": {"dp": 0.38, "ie": 0.0, "start_s": 0.5}}, sim={"disturbances": []})
    r = run_lockstep(cfg, 1.5)
    most = cfg["safety"]["max_motor_speed_rad_s"]
    speed = np.maximum(np.abs(np.diff(r["motor_pos_1"])), np.abs(np.diff(r["motor_pos_2"]))) / np.diff(r["t"])
    assert r.summary["fault"] == "NONE"
    from ankle_rt.safety import GOVERNOR_SHARE

    assert GOVERNOR_SHARE * most < speed.max() < (GOVERNOR_SHARE + 0.05) * most    # it got there and no further
    assert np.degrees(np.abs(r["ankle_dp"]).max()) < 0.38 * 180 / math.pi + 2.0
    assert abs(r["ankle_dp"][-1] - 0.38) < 0.01


def test_the_governor_takes_only_the_current_that_would_speed_a_fast_motor_up(sim_cfg):
    from ankle_rt.safety import Safety

    from ankle_rt.estimation import Estimate

    est = Estimate()
    est.joint_dp = est.joint_ie = 0.0      # the simulator's joint encoders read

    def moving(safety, v1, v2):
        """``safety`` after two samples 1 ms apart with the motors at v1, v2 (rad/s)."""
        safety.state = State.ACTIVE
        assert safety.check_values(0.0, 0.0 * v1, 0.0 * v2, 0.0, 0.0, est) is not None
        assert np.all(safety.check_values(1e-3, 1e-3 * v1, 1e-3 * v2, 0.0, 0.0, est) == 0)
        return safety

    g = Safety(sim_cfg, 1e-3).governor_speed
    for v1, v2, sent, kept in [(g + 1.0, -(g + 1.0), (5.0, -5.0), (0.0, 0.0)),      # would speed them up
                               (g + 1.0, -(g + 1.0), (-5.0, 5.0), (-5.0, 5.0)),     # brakes them
                               (g - 1.0, 0.0, (5.0, 5.0), (5.0, 5.0))]:             # below the governor
        s = moving(Safety(sim_cfg, 1e-3), v1, v2)
        assert s.limit_currents(*sent) == 0 and s.current == pytest.approx(list(kept))
    # the batched cycle runs the same code on arrays (one device per column)
    b = moving(Safety.stack([Safety(sim_cfg, 1e-3), Safety(sim_cfg, 1e-3)]),
               np.array([g + 1.0, g + 1.0]), np.array([-(g + 1.0), 0.0]))
    b.limit_currents(np.array([5.0, -5.0]), np.array([-5.0, -5.0]))
    assert [list(c) for c in b.current] == [[0.0, -5.0], [0.0, -5.0]]
