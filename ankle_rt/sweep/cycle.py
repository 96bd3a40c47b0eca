"""The daemon's control cycle for a batch of simulated devices, vectorised over the batch.

Each plant gets the objects a lockstep daemon would build from its own config (estimator, the
configured PD or impedance controller, safety layer, reference) and their numbers are stacked into
arrays. Every tick then does what :meth:`ankle_rt.daemon.Daemon.cycle` does under a SimClock, for
all plants at once: step the plant with the last set values, sample the sensors, estimate (backward
difference + low-pass, strain-gauge tare), reference, sensor checks, auto-activation with the soft
start, the control law (the impedance controller's joint-torque loop and the friction feed-forward,
coulomb_viscous or identified, are the daemon's own element-wise code, stacked), the current clamp
and I^2 t limit, and a latched fault that zeroes the set values. ``tests/test_batch_cycle.py`` holds
it to ``run_lockstep`` run by run. Only the built-in ``pd``, ``impedance`` and ``gait_phase``
controllers are batched (the gait-phase law stacked element-wise, :class:`GaitPhaseLaw`; a plugin
is refused, naming ``controller.type``); plants of one batch share the controller type and, for
impedance and gait_phase, whether the joint-torque loop is closed (:func:`batch_key` groups them).
Not modelled (no sweep exercises them): run-time gain changes, service commands, backend fault
injection, stale samples (the simulator's sequence always advances).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ankle_rt.backend import batch_plant_class
from ankle_rt.config import ConfigError
from ankle_rt.control import build_controller
from ankle_rt.control.friction import FrictionFeedForward
from ankle_rt.control.gait_phase import GaitPhaseController, GaitPhaseLaw
from ankle_rt.control.impedance import ImpedanceController
from ankle_rt.control.torque_loop import JointTorqueLoop, torque_feedback
from ankle_rt.estimation import Estimator
from ankle_rt.kinematics import Kinematics
from ankle_rt.params import TransmissionParams
from ankle_rt.references import Hold, reference_from_config
from ankle_rt.safety import Fault, Safety

CONFIGURED, ACTIVE, FAULTED = 0, 1, 2


@dataclass
class BatchTrace:
    """What a batch run recorded, per tick and plant (float32 where it is only for metrics)."""

    t: np.ndarray            # s (ticks,)
    ankle: np.ndarray        # rad (ticks, 2, plants), true joint angles [DP, IE]
    reference: np.ndarray    # rad (ticks, 2, plants)
    current: np.ndarray      # A (ticks, 2, plants), the limited set values
    fault: np.ndarray        # Fault code per plant (0: none)
    fault_time: np.ndarray   # s per plant (NaN: none)
    activation_time: np.ndarray  # s per plant (NaN: never activated)
    saturated: np.ndarray    # cycles with a set value clamped to the peak current, per plant
    cable_torque_peak: np.ndarray  # N m (2, plants), largest cable torque each motor felt
    slack_events: np.ndarray  # (2, plants): times a motor's cable torque reached slack_torque


def first_fault(code: np.ndarray, checks: list[tuple[np.ndarray, int]]) -> np.ndarray:
    """``code`` (a fault per plant, 0: none) with, where it is 0, the first of ``checks``
    [(condition per plant, fault)] that holds, in order (as Safety returns its first failing check)."""
    bad = checks[0][0]
    for cond, _ in checks[1:]:
        bad = bad | cond
    if not bad.any():
        return code
    first = np.zeros_like(code)
    for cond, fault in reversed(checks):
        first = np.where(cond, int(fault), first)
    return np.where(code == 0, first, code)


BATCHED_CONTROLLERS = ("pd", "impedance", "gait_phase")    # built-ins win over plugins of the same name


def batch_key(cfg: Mapping[str, Any]) -> tuple:
    """Configs with equal keys can run in one :class:`BatchRun`: the plant's structure, the
    controller type and, for impedance, whether the joint-torque loop is closed. Raises ConfigError
    naming ``controller.type`` for a controller the batch does not run (a plugin)."""
    name = cfg["controller"]["type"]
    if name not in BATCHED_CONTROLLERS:
        raise ConfigError(f"the batched daemon cycle runs the built-in pd, impedance and gait_phase controllers, not {name!r} "
                          "(a plugin runs in the daemon: ankle-rt run --fast)", getattr(cfg, "source", None),
                          "controller.type")
    return batch_plant_class(cfg["backend"], getattr(cfg, "source", None)).structure_key(cfg) + (name, torque_feedback(cfg) if name in ("impedance", "gait_phase") else None)


def _column(objects: Sequence[Any], get) -> np.ndarray:
    return np.array([get(o) for o in objects], dtype=float)


class BatchRun:
    """The lockstep daemon of ``len(cfgs)`` configs (one :func:`batch_key`)."""

    def __init__(self, cfgs: Sequence[Mapping[str, Any]], duration_s: float, source: str = "config",
                 slack_torque: float | np.ndarray = math.inf):
        """``slack_torque`` (N m, per plant or one): a motor cable torque this large slackens the
        unloaded side of that motor's cable loop (2 r times the pretension), counted as an event.
        Raises ConfigError naming the key for a controller the batch cannot run as the daemon does
        (a plugin, a mix of controller types or of open- and closed-loop impedance)."""
        self.n = n = len(cfgs)
        self.slack_torque = np.broadcast_to(np.asarray(slack_torque, dtype=float), (n,))
        self.plant = batch_plant_class(cfgs[0]["backend"], source)(cfgs, source)
        self.dt = dt = self.plant.dt
        self.ticks = -(-round(duration_s * 1e9) // round(1e9 * dt))
        kins = [Kinematics.from_params(TransmissionParams(**c["transmission"])) for c in cfgs]
        ests = [Estimator(k, dt, c["estimation"]["velocity_cutoff_hz"], c["estimation"]["tare_samples"])
                for k, c in zip(kins, cfgs)]
        self.Ri = _column(ests, lambda e: e.Ri).T
        self.Ki = np.array([_column(ests, lambda e: e.Ki0), _column(ests, lambda e: e.Ki1)])
        self.alpha = _column(ests, lambda e: e.alpha)
        self.tare_samples = _column(ests, lambda e: e.tare_samples)
        self.auto_activate = np.array([c["safety"]["auto_activate"] for c in cfgs])

        refs = [reference_from_config(c) for c in cfgs]
        self._check_controllers(cfgs)
        ctls = [build_controller(c, k, r.ref) for c, k, r in zip(cfgs, kins, refs)]
        self.impedance = isinstance(ctls[0], ImpedanceController)
        # the gait-phase controller: its law (element-wise) stacked; the impedance actuation below serves it
        self.gait = GaitPhaseLaw.stack([c.law for c in ctls]) if isinstance(ctls[0], GaitPhaseController) else None
        self.gains = np.array([c.gains.values for c in ctls]).T      # (gains, plants) in the law's order
        self.soft_step = _column(ctls, lambda c: c.gains.soft_step)
        self.ff_any = any(c.friction.enabled for c in ctls)
        self.ff = FrictionFeedForward.stack([c.friction for c in ctls])
        closed = self.impedance and ctls[0].torque_loop is not None
        self.torque_loop = JointTorqueLoop.stack([c.torque_loop for c in ctls]) if closed else None
        self.law_matrix = _column(ctls, lambda c: c.RiT if self.impedance else c.R).T   # (4, plants)
        self.inv_kt = 1.0 / np.array([c["actuator"]["torque_constant"] for c in cfgs])

        safeties = [Safety(c, dt) for c in cfgs]
        self.ankle_limit = _column(safeties, lambda s: s.ankle_limit)
        self.check_estimated = np.array([s.check_estimated_ankle for s in safeties])
        self.max_motor_speed = _column(safeties, lambda s: s.max_motor_speed)
        self.max_sg_step = _column(safeties, lambda s: s.max_sg_step)
        self.sg_rail = _column(safeties, lambda s: s.sg_rail)
        self.i_peak = _column(safeties, lambda s: s.i_peak)
        self.i_cont2 = _column(safeties, lambda s: s.i_cont2)
        self.i2t_budget = _column(safeties, lambda s: s.i2t_budget)

        self.hold = np.array([isinstance(r.profile, Hold) for r in refs])
        self.ramp_s = np.array([c["reference"]["ramp_s"] for c in cfgs])
        self.ref_tables, self.ref_index = self._reference_tables(refs)

    @staticmethod
    def _check_controllers(cfgs: Sequence[Mapping[str, Any]]) -> None:
        """ConfigError naming the key unless the batch runs every plant's controller as the daemon does."""
        keys = {batch_key(c)[-2:] for c in cfgs}
        if len(keys) != 1:
            key = "controller.type" if len({k[0] for k in keys}) > 1 else "controller.impedance.torque_feedback"
            raise ConfigError("differs between the plants of one batch (group them with batch_key)", None, key)

    def _reference_tables(self, refs) -> tuple[np.ndarray, np.ndarray]:
        """rad (ticks, 2, profiles): each distinct configured profile sampled at the cycle times,
        and which one each plant follows. Holds are ramped to at activation (see run)."""
        keys: dict[str, int] = {}
        tables, index = [], []
        for r in refs:
            p = r.profile
            key = repr((type(p).__name__, sorted(vars(p).items())))
            if key not in keys:
                keys[key] = len(tables)
                table = np.empty((self.ticks, 2))
                for k in range(self.ticks):
                    r.update(k * self.dt)
                    table[k] = r.ref
                tables.append(table)
            index.append(keys[key])
        return np.stack(tables, axis=2), np.array(index)

    def run(self) -> BatchTrace:
        """Run every plant for the duration; returns the trace."""
        n, dt, plant = self.n, self.dt, self.plant
        T = self.ticks
        trace = BatchTrace(t=np.arange(T) * dt, ankle=np.empty((T, 2, n), np.float32),
                           reference=np.empty((T, 2, n), np.float32), current=np.empty((T, 2, n), np.float32),
                           fault=np.zeros(n, int), fault_time=np.full(n, np.nan),
                           activation_time=np.full(n, np.nan), saturated=np.zeros(n, int),
                           cable_torque_peak=np.zeros((2, n)), slack_events=np.zeros((2, n), int))
        slack = np.zeros((2, n), bool)
        state = np.full(n, CONFIGURED)
        set1, set2 = np.zeros(n), np.zeros(n)
        v1, v2 = np.zeros(n), np.zeros(n)
        lp1 = lp2 = ls0 = ls1 = None
        tare0, tare1 = np.zeros(n), np.zeros(n)
        off0, off1 = np.zeros(n), np.zeros(n)
        scale = np.ones(n)
        q1, q2 = np.zeros(n), np.zeros(n)
        ramp_from = np.zeros((2, n))
        ramp_t0 = np.full(n, np.inf)
        g = self.gains
        M = self.law_matrix
        pk = self.i_peak
        t_prev = math.nan
        no_fault = np.zeros(n, int)
        last_tare = int(self.tare_samples.max())
        any_hold = bool(self.hold.any())
        ref_tables = self.ref_tables
        shared_ref = ref_tables.shape[2] == 1
        waiting = True       # some plant still waits for its activation
        ff, ff_any, loop = self.ff, self.ff_any, self.torque_loop
        x = plant.model.x
        for k in range(T):
            if k:
                plant.step(set1, set2)
            t = plant.t
            p1, p2 = plant.motor_positions()
            joint = plant.model.joint_torque()
            s0, s1 = plant.strain_gauge_torques(joint)
            j0, j1 = plant.model.x[0], plant.model.x[1]     # true angles (joint encoders), this tick only
            # -- estimate (Estimator.update)
            h = t - t_prev
            if h > 0.0:
                a = self.alpha
                v1 += a * ((p1 - lp1) / h - v1)
                v2 += a * ((p2 - lp2) / h - v2)
            if k < last_tare:
                taring = k < self.tare_samples
                tare0 += np.where(taring, s0, 0.0)
                tare1 += np.where(taring, s1, 0.0)
                cnt = np.minimum(k + 1, self.tare_samples)
                off0, off1 = tare0 / cnt, tare1 / cnt
            tared = k + 1 >= self.tare_samples
            e0, e1 = s0 - off0, s1 - off1
            Ri = self.Ri
            a0 = Ri[0] * p1 + Ri[1] * p2 - self.Ki[0] * e0
            a1 = Ri[2] * p1 + Ri[3] * p2 - self.Ki[1] * e1
            # -- reference (a configured hold is ramped to from the ankle at activation)
            if shared_ref:                      # one profile for all: plain floats, broadcast
                r0, r1 = float(ref_tables[k, 0, 0]), float(ref_tables[k, 1, 0])
            else:
                r0, r1 = ref_tables[k, 0][self.ref_index], ref_tables[k, 1][self.ref_index]
            ramping = self.hold & (t >= ramp_t0) if any_hold else None
            if any_hold and ramping.any():
                tau = t - ramp_t0       # RampTo.value
                f = np.where(tau >= self.ramp_s, 1.0, np.clip(tau / np.maximum(self.ramp_s, 1e-12), 0.0, 1.0))
                r0 = np.where(ramping, ramp_from[0] + f * (r0 - ramp_from[0]), r0)
                r1 = np.where(ramping, ramp_from[1] + f * (r1 - ramp_from[1]), r1)
            # -- sensor checks (Safety.check_sensors), first failing check wins
            live = state != FAULTED
            rail, lim = self.sg_rail, self.ankle_limit
            checks = [(~np.isfinite(p1 + p2 + s0 + s1 + t), Fault.SENSOR_INVALID),
                      ((np.abs(s0) >= rail) | (np.abs(s1) >= rail), Fault.SG_RAIL)]
            if lp1 is not None:
                allowed = self.max_motor_speed * max(h, dt)
                checks += [((np.abs(p1 - lp1) > allowed) | (np.abs(p2 - lp2) > allowed), Fault.MOTOR_JUMP),
                           ((np.abs(s0 - ls0) > self.max_sg_step) | (np.abs(s1 - ls1) > self.max_sg_step),
                            Fault.SG_JUMP)]
            checks += [(self.check_estimated & ((np.abs(a0) > lim) | (np.abs(a1) > lim)), Fault.ANKLE_RANGE),
                       ((np.abs(j0) > lim) | (np.abs(j1) > lim), Fault.ANKLE_RANGE)]
            code = np.where(live, first_fault(no_fault, checks), 0)
            t_prev, lp1, lp2, ls0, ls1 = t, p1, p2, s0, s1
            # -- auto-activation (Daemon.activate): soft start from zero, a hold ramps from the ankle
            starting = live & (state == CONFIGURED) & (code == 0) & self.auto_activate & tared if waiting else None
            if waiting and starting.any():
                state = np.where(starting, ACTIVE, state)
                scale = np.where(starting, 0.0, scale)
                trace.activation_time[starting] = t
                hs = starting & self.hold
                if hs.any():
                    ramp_from[0] = np.where(hs, a0, ramp_from[0])
                    ramp_from[1] = np.where(hs, a1, ramp_from[1])
                    ramp_t0 = np.where(hs, t + dt, ramp_t0)
                    r0 = np.where(hs, a0, r0)
                    r1 = np.where(hs, a1, r1)
                if loop is not None:        # ImpedanceController.reset
                    loop.reset_state(e0, e1, starting)
                if self.gait is not None:   # GaitPhaseController.reset
                    self.gait.start(starting)
            # -- control law (MotorPD / ImpedanceController.update), soft start, friction feed-forward
            controlling = (state == ACTIVE) & (code == 0)
            scale = np.minimum(scale + self.soft_step, 1.0)
            ff1 = ff2 = 0.0
            if self.impedance:
                w0 = Ri[0] * v1 + Ri[1] * v2
                w1 = Ri[2] * v1 + Ri[3] * v2
                if self.gait is not None:   # GaitPhaseController.update (restarted at activation)
                    u0, u1 = self.gait.update(-e0, a0, w0, a1, w1)
                else:
                    u0 = g[0] * (r0 - a0) - g[2] * w0
                    u1 = g[1] * (r1 - a1) - g[3] * w1
                if loop is not None:
                    u0, u1 = loop.update(u0, u1, e0, e1, scale >= 1.0)
                if ff_any:          # each motor's friction sees the cable torque it feels, R^-T tau_sg
                    ff1 = ff.torque(v1, M[0] * e0 + M[1] * e1)
                    ff2 = ff.torque(v2, M[2] * e0 + M[3] * e1)
                tq1 = scale * (M[0] * u0 + M[1] * u1 + ff1)
                tq2 = scale * (M[2] * u0 + M[3] * u1 + ff2)
            else:
                if ff_any:
                    ff1, ff2 = ff.torque(v1), ff.torque(v2)
                tq1 = scale * (g[0] * (M[0] * r0 + M[1] * r1 - p1) - g[1] * v1 + ff1)
                tq2 = scale * (g[0] * (M[2] * r0 + M[3] * r1 - p2) - g[1] * v2 + ff2)
            # -- current limits (Safety.limit_currents)
            i1, i2 = tq1 * self.inv_kt, tq2 * self.inv_kt
            bad = ~np.isfinite(i1 + i2)
            code = first_fault(code, [(controlling & bad, Fault.OUTPUT_INVALID)])
            over = (np.abs(i1) > pk) | (np.abs(i2) > pk)
            trace.saturated += controlling & ~bad & over
            i1, i2 = np.clip(i1, -pk, pk), np.clip(i2, -pk, pk)
            n1 = q1 + (i1 * i1 - self.i_cont2) * dt
            n2 = q2 + (i2 * i2 - self.i_cont2) * dt
            q1 = np.where(controlling & ~bad, np.maximum(n1, 0.0), q1)
            q2 = np.where(controlling & ~bad, np.maximum(n2, 0.0), q2)
            code = first_fault(code, [(controlling & ~bad & ((n1 > self.i2t_budget) | (n2 > self.i2t_budget)),
                                       Fault.OVERCURRENT)])
            # -- faults latch, set values reach the amplifiers only while active and fault-free
            tripped = live & (code != 0)
            if tripped.any():
                trace.fault[tripped] = code[tripped]
                trace.fault_time[tripped] = t
                state = np.where(tripped, FAULTED, state)
            waiting = waiting and bool((state == CONFIGURED).any())
            ok = state == ACTIVE
            set1 = np.where(ok, i1, 0.0)
            set2 = np.where(ok, i2, 0.0)
            trace.ankle[k] = x[0:2]
            trace.reference[k, 0], trace.reference[k, 1] = r0, r1
            trace.current[k, 0], trace.current[k, 1] = set1, set2
            c = np.abs(plant.cable_torques(joint))
            np.maximum(trace.cable_torque_peak, c, out=trace.cable_torque_peak)
            now_slack = c >= self.slack_torque
            trace.slack_events += now_slack & ~slack
            slack = now_slack
        return trace
