"""The daemon's control cycle for a batch of simulated devices, vectorised over the batch.

Each plant gets the objects a lockstep daemon would build from its own config (estimator, the
configured controller, safety layer, reference); each kind is stacked into one object whose numbers
are arrays over the batch (``stack()``, :mod:`ankle_rt.elementwise`), and every tick runs the
daemon's own element-wise code on them, in the order of :meth:`ankle_rt.daemon.Daemon.cycle` under a
SimClock: step the plant with the last set values, sample the sensors,
:meth:`~ankle_rt.estimation.Estimator.estimate`, the reference,
:meth:`~ankle_rt.safety.Safety.check_values`, auto-activation (the controller's ``start``),
:meth:`~ankle_rt.safety.Safety.check_reference`, the controller's ``law``,
:meth:`~ankle_rt.safety.Safety.limit_currents` (clamp, I^2 t and the oscillation detector),
:meth:`~ankle_rt.safety.Safety.check_gauges` (the strain-gauge cross-check) and the fault latch
(:meth:`~ankle_rt.safety.Safety.trip`). This module holds only the stacking and the batch's
bookkeeping: the trace, the reference tables, which plants are active.

Any :class:`~ankle_rt.control.base.BatchableController` runs here (the built-in ``pd``,
``impedance`` and ``gait_phase``); a controller that is not one (a plugin) is refused, naming ``controller.type``.
Plants of one batch share the controller type and its ``batch_key()`` (:func:`batch_key` groups
them). ``tests/test_batch_cycle.py`` holds the batch to ``run_lockstep`` run by run. Not modelled
(no sweep exercises them): run-time gain changes, service commands, backend fault bits, amplifier
ready lines and stale samples (the simulator's sequence always advances).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ankle_rt.backend import batch_plant_class
from ankle_rt.config import ConfigError
from ankle_rt.control import build_controller
from ankle_rt.control.base import BatchableController
from ankle_rt.elementwise import select
from ankle_rt.estimation import Estimate, Estimator
from ankle_rt.kinematics import Kinematics
from ankle_rt.params import TransmissionParams
from ankle_rt.references import Hold, reference_from_config
from ankle_rt.safety import Safety, State

CONFIGURED, ACTIVE, FAULT = int(State.CONFIGURED), int(State.ACTIVE), int(State.FAULT)


@dataclass
class BatchTrace:
    """What a batch run recorded, per tick and plant (float32 where it is only for metrics)."""

    t: np.ndarray            # s (ticks,)
    ankle: np.ndarray        # rad (ticks, 2, plants), the joint encoders' angles [DP, IE] (float32 unless asked)
    reference: np.ndarray    # rad (ticks, 2, plants)
    current: np.ndarray      # A (ticks, 2, plants), the limited set values
    fault: np.ndarray        # Fault code per plant (0: none)
    fault_time: np.ndarray   # s per plant (NaN: none)
    activation_time: np.ndarray  # s per plant (NaN: never activated)
    saturated: np.ndarray    # cycles with a set value clamped to the peak current, per plant
    cable_torque_peak: np.ndarray  # N m (2, plants), largest cable torque each motor felt
    slack_events: np.ndarray  # (2, plants): times a motor's cable torque reached slack_torque


def _parts(cfg: Mapping[str, Any]) -> tuple[Kinematics, Any, BatchableController]:
    """The kinematics, reference generator and controller the daemon builds from ``cfg``; ConfigError
    naming ``controller.type`` for a controller the batch cannot run (not batchable: a plugin)."""
    kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
    ref = reference_from_config(cfg)
    ctl = build_controller(cfg, kin, ref.ref)
    if not isinstance(ctl, BatchableController):
        raise ConfigError(f"the batched daemon cycle runs batchable controllers (the built-in pd, impedance and gait_phase), "
                          f"not {cfg['controller']['type']!r} (a plugin runs in the daemon: ankle-rt run --fast)",
                          getattr(cfg, "source", None), "controller.type")
    return kin, ref, ctl


def _controller_key(cfg: Mapping[str, Any], ctl: BatchableController) -> tuple[tuple[str, Any], ...]:
    return (("controller.type", cfg["controller"]["type"]),) + ctl.batch_key()


def batch_key(cfg: Mapping[str, Any]) -> tuple:
    """Configs with equal keys can run in one :class:`BatchRun`: the plant's structure, the
    controller type and the controller's own ``batch_key()``, the gauge cross-check's delay window
    (its rings are one length across a batch). Raises ConfigError naming ``controller.type`` for a
    controller the batch does not run (a plugin)."""
    plant = batch_plant_class(cfg["backend"], getattr(cfg, "source", None)).structure_key(cfg)
    window = (("safety.max_actuation_delay_s", cfg["safety"]["max_actuation_delay_s"]),)
    return plant + window + _controller_key(cfg, _parts(cfg)[2])


class BatchRun:
    """The lockstep daemon of ``len(cfgs)`` configs (one :func:`batch_key`)."""

    def __init__(self, cfgs: Sequence[Mapping[str, Any]], duration_s: float, source: str = "config",
                 slack_torque: float | np.ndarray = math.inf):
        """``slack_torque`` (N m, per plant or one): a motor cable torque this large slackens the
        unloaded side of that motor's cable loop (2 r times the pretension), counted as an event.
        Raises ConfigError naming the key for a controller the batch cannot run as the daemon does
        (a plugin, a mix of controller types or of controller structures)."""
        self.n = n = len(cfgs)
        self.slack_torque = np.broadcast_to(np.asarray(slack_torque, dtype=float), (n,))
        self.plant = batch_plant_class(cfgs[0]["backend"], source)(cfgs, source)
        self.dt = dt = self.plant.dt
        self.ticks = -(-round(duration_s * 1e9) // round(1e9 * dt))
        parts = [_parts(c) for c in cfgs]
        self._check_controllers([_controller_key(c, p[2]) for c, p in zip(cfgs, parts)])
        kins, refs, ctls = zip(*parts)
        self.estimator = Estimator.stack([Estimator(k, dt, c["estimation"]["velocity_cutoff_hz"],
                                                    c["estimation"]["tare_samples"]) for k, c in zip(kins, cfgs)])
        self.controller = type(ctls[0]).stack(ctls)
        self.safety = Safety.stack([Safety(c, dt) for c in cfgs])
        self.inv_kt = 1.0 / np.array([c["actuator"]["torque_constant"] for c in cfgs])
        self.auto_activate = np.array([c["safety"]["auto_activate"] for c in cfgs])
        self.hold = np.array([isinstance(r.profile, Hold) for r in refs])
        self.ramp_s = np.array([c["reference"]["ramp_s"] for c in cfgs])
        self.ref_tables, self.ref_index = self._reference_tables(refs)

    @staticmethod
    def _check_controllers(keys: list[tuple[tuple[str, Any], ...]]) -> None:
        """ConfigError naming the first controller key that differs between the plants (a batch runs
        one controller structure: group configs with batch_key). The plants' own structure is
        checked by the batch plant."""
        for pairs in zip(*keys):
            if len(set(pairs)) > 1:
                raise ConfigError("differs between the plants of one batch (group them with batch_key)", None,
                                  pairs[0][0])

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

    def run(self, dtype: type = np.float32) -> BatchTrace:
        """Run every plant for the duration; returns the trace, its per-tick signals as ``dtype``
        (float32 is plenty for the metrics; float64 to compare with the daemon's records)."""
        n, dt, plant = self.n, self.dt, self.plant
        T = self.ticks
        trace = BatchTrace(t=np.arange(T) * dt, ankle=np.empty((T, 2, n), dtype),
                           reference=np.empty((T, 2, n), dtype), current=np.empty((T, 2, n), dtype),
                           fault=np.zeros(n, int), fault_time=np.full(n, np.nan),
                           activation_time=np.full(n, np.nan), saturated=np.zeros(n, int),
                           cable_torque_peak=np.zeros((2, n)), slack_events=np.zeros((2, n), int))
        estimator, ctl, safety, inv_kt = self.estimator, self.controller, self.safety, self.inv_kt
        est = Estimate()
        slack = np.zeros((2, n), bool)
        set1, set2 = np.zeros(n), np.zeros(n)
        ramp_from = np.zeros((2, n))
        ramp_t0 = np.full(n, np.inf)
        any_hold = bool(self.hold.any())
        ref_tables = self.ref_tables
        shared_ref = ref_tables.shape[2] == 1
        waiting = True       # some plant still waits for its activation
        for k in range(T):
            if k:
                plant.step(set1, set2)
            t = plant.t
            p1, p2 = plant.motor_positions()
            joint = plant.model.joint_torque()
            s0, s1 = plant.strain_gauge_torques(joint)
            j0, j1 = plant.ankle_positions()
            estimator.estimate(t, p1, p2, s0, s1, j0, j1, est)
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
            live = safety.state != FAULT
            code = select(live, safety.check_values(t, p1, p2, s0, s1, est), 0)
            # -- auto-activation (Daemon.activate): soft start from zero, a hold ramps from the ankle
            starting = live & (safety.state == CONFIGURED) & (code == 0) & self.auto_activate & est.tared \
                if waiting else None
            if waiting and starting.any():
                safety.activated(est, starting)
                trace.activation_time[starting] = t
                hs = starting & self.hold
                if hs.any():                     # from the angles the law acts on (Daemon.ankle_now)
                    a0, a1 = ctl.angles(est)
                    ramp_from[0] = np.where(hs, a0, ramp_from[0])
                    ramp_from[1] = np.where(hs, a1, ramp_from[1])
                    ramp_t0 = np.where(hs, t + dt, ramp_t0)
                    r0 = np.where(hs, a0, r0)
                    r1 = np.where(hs, a1, r1)
                ctl.start(est, starting)
            waiting = waiting and bool((safety.state == CONFIGURED).any())
            # -- reference check, control law, current limits (only the active, fault-free plants count)
            active = (safety.state == ACTIVE) & (code == 0)
            code = select(active, safety.check_reference(r0, r1), code)
            controlling = active & (code == 0)
            tq1, tq2 = ctl.law(est, r0, r1)
            code = select(controlling, safety.limit_currents(tq1 * inv_kt, tq2 * inv_kt, controlling), code)
            code = select(controlling & (code == 0), safety.check_gauges(est), code)
            # -- faults latch, set values reach the amplifiers only while active and fault-free
            safety.trip(code, t)
            ok = safety.state == ACTIVE
            set1 = np.where(ok, safety.current[0], 0.0)
            set2 = np.where(ok, safety.current[1], 0.0)
            trace.ankle[k, 0], trace.ankle[k, 1] = j0, j1
            trace.reference[k, 0], trace.reference[k, 1] = r0, r1
            trace.current[k, 0], trace.current[k, 1] = set1, set2
            c = np.abs(plant.cable_torques(joint))
            np.maximum(trace.cable_torque_peak, c, out=trace.cable_torque_peak)
            now_slack = c >= self.slack_torque
            trace.slack_events += now_slack & ~slack
            slack = now_slack
        trace.fault[:] = safety.fault
        trace.fault_time[:] = safety.fault_time
        trace.saturated[:] = safety.saturated
        return trace
