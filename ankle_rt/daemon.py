"""The control daemon: one fixed-rate cycle that reads, estimates, controls, checks and logs.

Cycle (docs/design.md): backend.read -> estimate -> reference -> control -> safety -> backend.write ->
log record -> service tick. The cycle method works on preallocated objects only (sensor frame,
estimate, reference and torque arrays, the log ring), in plain floats, and touches no disk.

:class:`Daemon` is driven by :class:`~ankle_rt.loop.FixedRateLoop` on any clock. :func:`run_lockstep`
runs it on a :class:`~ankle_rt.clock.SimClock` as fast as possible and returns the recorded cycles as
a :class:`RunResult` (tests, identification experiments, ``ankle-rt run --fast``).
"""

from __future__ import annotations

import gc
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping

import numpy as np

from ankle_rt.backend import Backend, SensorFrame, open_backend
from ankle_rt.clock import Clock, SimClock
from ankle_rt.command_limits import gain_maxima, gain_problem, reference_problem
from ankle_rt.config import Config, ConfigError, config_data
from ankle_rt.control import CycleController, build_controller
from ankle_rt.control.gains import GainError
from ankle_rt.control.base import BatchableController
from ankle_rt.control.gait_phase import PHASES, GaitPhaseController
from ankle_rt.estimation import Estimate, EstimateView, Estimator
from ankle_rt.float_buffer import float_buffer
from ankle_rt.interchange import InterchangeError
from ankle_rt.kinematics import Kinematics
from ankle_rt.log.memory import MemoryRecorder
from ankle_rt.log.reader import interchange_columns
from ankle_rt.log.writer import LogWriter, Rotation, log_metadata
from ankle_rt.loop import FixedRateLoop
from ankle_rt.params import TransmissionParams
from ankle_rt.references import (Hold, Profile, RampTo, ReferenceGenerator, make_profile,
                                  max_reference_step, reference_from_config, validate_profile_params)
from ankle_rt.safety import Fault, Safety, State
from ankle_rt.service import protocol as proto
from ankle_rt.service.loader import BackgroundLoader, Job, pause
from ankle_rt.service.profile_process import load_csv_profile

if TYPE_CHECKING:
    from ankle_rt.log.lsl import LslPublisher
    from ankle_rt.service.link import ServiceLink

ACTIVE = int(State.ACTIVE)
CONFIGURED = int(State.CONFIGURED)
FAULT = int(State.FAULT)


class Daemon:
    """Everything one run needs, built from a validated config.

    ``backend``: an opened backend on the same ``clock`` (default: the config's). ``controller``:
    any :class:`CycleController` (default: the config's PD or impedance controller tracking the
    configured reference). ``recorder``: the record sink (a LogWriter or MemoryRecorder) or None.
    ``reference``: the config's controller tracks this generator instead of the configured profile,
    as given (no rate limit): a replay of recorded references on a simulated plant only.
    """

    def __init__(self, cfg: Config, clock: Clock, *, backend: Backend | None = None,
                 controller: CycleController | None = None, recorder: Any = None,
                 service: "ServiceLink | None" = None, reference: ReferenceGenerator | None = None):
        self.cfg = cfg
        self.clock = clock
        rate = cfg["controller"]["rate_hz"]
        self.dt = 1.0 / rate
        self.period_ns = round(1e9 / rate)
        self.kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
        self.kt = cfg["actuator"]["torque_constant"]
        self.inv_kt = 1.0 / self.kt
        est_cfg = cfg["estimation"]
        self.frame = SensorFrame()
        self.est = Estimate()
        self.estimator = Estimator(self.kin, self.dt, est_cfg["velocity_cutoff_hz"], est_cfg["tare_samples"])
        # the safety layer comes from the validated config before any controller (a plugin) is built
        self.safety = Safety(cfg, self.dt)
        self.own_controller = controller is None
        self.reference_commanded = False   # a set_reference / start_profile command chose the reference
        if controller is None:
            self.reference = reference if reference is not None else reference_from_config(cfg)
            self.controller = build_controller(cfg, self.kin, self.reference.ref)
        else:   # an experiment brings its own excitation: no reference (logged as NaN)
            self.reference = ReferenceGenerator(Hold(math.nan, math.nan))
            self.controller = controller
        self.max_reference_step = max_reference_step(cfg)
        self.gain_maxima = gain_maxima(cfg["controller"]["gain_limits"])
        self.loader = BackgroundLoader()
        # N m [motor 1, motor 2]: the controller sets ``torque``, the cycle reads ``_torque_values``
        self._torque_values, self.torque = float_buffer(2)
        # a plugin's output ramps in over controller.soft_start_s after each activation, as the
        # built-ins' (BatchableController) does: they scale their own. No current step at activation.
        self.soft_scale = self.soft_step = 1.0
        self.recorder = recorder
        self.lsl: "LslPublisher | None" = None   # set by open_log when lsl.enabled
        self.log_fault = cfg["logging"]["fault_on_error"]
        self.service = service
        self.auto_activate = cfg["safety"]["auto_activate"]
        self.activations = 0
        self.owns_backend = backend is None
        self.backend = backend if backend is not None else open_backend(cfg, clock)
        if reference is not None and not self.simulated_plant:
            self.close()
            raise ValueError("a reference generator is given only to a simulated plant (a replay): on the device "
                             "every reference is the configured one or a command's, rate limited")
        limits = self.overrun_limits   # asks the opened backend too
        self.loop = FixedRateLoop(clock, self.period_ns, limits["max_consecutive_overruns"],
                                  on_overrun_limit=self._missed_deadlines,
                                  max_stall_ns=round(limits["max_stall_s"] * 1e9))

    # -- the cycle (hot path: no allocation beyond float temporaries, no I/O) -----------------------
    def cycle(self, t_start_ns: int) -> None:
        frame, est, safety, backend = self.frame, self.est, self.safety, self.backend
        backend.read(frame)
        self.estimator.update(frame, est)
        self.reference.update(est.t)
        torque = self.torque
        state = safety.state
        if state == FAULT and safety.fault_time != safety.fault_time:
            # tripped between cycles (missed deadlines): stamped with the first record that shows it
            safety.fault_time = est.t
        if state != ACTIVE:
            torque[0] = torque[1] = 0.0
            safety.current[0] = safety.current[1] = 0.0
        if state != FAULT:
            code = safety.check_sensors(frame, est)
            if code == 0 and state == CONFIGURED and self.auto_activate and est.tared and self.activations == 0:
                self.activate()
                state = ACTIVE
            if code == 0 and state == ACTIVE and self.own_controller:
                ref = self.reference.values
                code = safety.check_reference(ref[0], ref[1])
            if code == 0 and state == ACTIVE:
                self._controller.update(self._controller_est, torque)   # attributes (no property call per cycle)
                tau, scale = self._torque_values, self.soft_scale
                if scale < 1.0:
                    scale = self.soft_scale = min(1.0, scale + self.soft_step)
                code = safety.limit_currents(tau[0] * self.inv_kt * scale, tau[1] * self.inv_kt * scale)
                if code == 0:
                    code = safety.check_gauges(est)
                if code == 0:
                    backend.write(safety.current[0], safety.current[1])
            if code != 0:
                self._fault(code)
        loop = self.loop
        latency_ns = self.clock.now_ns() - t_start_ns
        if self.service is not None:
            self._service_tick(t_start_ns * 1e-9)
        if self.recorder is not None:
            ref, tau = self.reference.values, self._torque_values    # memoryviews: plain floats
            self.recorder.append(
                est.t, est.mp1, est.mp2, est.mv1, est.mv2, est.sg_dp, est.sg_ie, est.joint_dp, est.joint_ie,
                est.dp, est.ie, ref[0], ref[1], tau[0], tau[1],
                safety.current[0], safety.current[1],
                (t_start_ns - loop.start_ns) * 1e-9, frame.seq, loop.last_period_ns * 1e-3, latency_ns * 1e-3,
                loop.stats.overruns, safety.state, safety.fault, frame.faults, self.gait_phase())
            if self.recorder.failed and self.log_fault and safety.state != FAULT:
                self._fault(Fault.LOG_FAILED)

    @property
    def controller(self) -> CycleController:
        return self._controller

    @controller.setter
    def controller(self, controller: CycleController) -> None:
        """Set the controller; the gait-phase law is found here, once (a plugin's own ``phase`` or
        ``gait`` attribute, of any type, never reaches the log record's one-byte code)."""
        self._controller = controller
        self._gait = controller.gait if isinstance(controller, GaitPhaseController) else None
        # a plugin (a controller of the config that is not a built-in) has no soft start of its own, and
        # reads the estimate through a view it cannot write (the checks after it read the sensors')
        self._plugin = self.own_controller and not isinstance(controller, BatchableController)
        self._controller_est = EstimateView(self.est) if self._plugin else self.est

    def _gait_phase_status(self) -> dict | None:
        """The gait-phase controller's phase, per-phase parameters and a change waiting for its stance
        phase's next beginning (None for another controller)."""
        gait = self._gait
        if gait is None:
            return None
        waiting = getattr(self.controller, "deferred", None)
        return {"phase": PHASES[gait.phase], "time_in_phase_s": gait.time, "params": gait.phase_params(),
                "waiting": {PHASES[waiting[0]]: dict(waiting[1])} if waiting is not None else {}}

    def gait_phase(self) -> int:
        """The log record's gait_phase code: 1 + the gait-phase controller's phase, 0 for any other."""
        gait = self._gait
        return 0 if gait is None else gait.phase + 1

    def _service_tick(self, now: float) -> None:
        service = self.service
        service.tick(now, self.loop.consecutive_overruns == 0)
        if self.safety.state == ACTIVE and service.command_channel_lost(now):
            self._fault(Fault.COMMAND_LOST)

    def _fault(self, code: int, t: float | None = None) -> None:
        """Within this cycle: set values to zero, amplifiers off, reason recorded (at ``t``, default
        this cycle's sample time; NaN: the next cycle's)."""
        backend = self.backend
        backend.write(0.0, 0.0)
        backend.deactivate()
        self.safety.current[0] = self.safety.current[1] = 0.0
        self.safety.trip(code, self.est.t if t is None else t)
        if self.service is not None:
            self.service.status(f"FAULT: {Fault(code).description}")

    def _missed_deadlines(self) -> None:
        """The loop's overrun limit, seen after a cycle ended: the fault's time is that of the next
        cycle's sample, the first record that carries it (one fault, one time in the log, the summary
        and ``ctl status``)."""
        self._fault(Fault.MISSED_DEADLINES, math.nan)

    # -- state changes (commands) ----------------------------------------------------------------
    def activate(self) -> None:
        """CONFIGURED/SAFE -> ACTIVE. The first activation runs the configured reference (a configured
        hold is reached by a ramp from the current ankle angle); later ones hold the ankle where it
        is. Raises RuntimeError when not allowed, or when the controller's ``reset`` raises (a
        plugin's): the controller is reset before the amplifiers are enabled, so a refused
        activation leaves the daemon not active."""
        s = self.safety
        if s.state not in (State.CONFIGURED, State.SAFE):
            raise RuntimeError(f"cannot activate in state {State(s.state).name}"
                               + (" (reset the fault first)" if s.state == State.FAULT else ""))
        if not self.est.tared:
            raise RuntimeError("strain gauges not tared yet")
        dp, ie = self.ankle_now()
        if self.activations > 0:
            self.reference.start(Hold(dp, ie))
        elif self.own_controller and not self.reference_commanded and not self.reference.profile.relative:
            # a configured hold is approached from where the ankle is over reference.ramp_s, a CSV
            # profile from there; both at most at reference.max_rate_rad_s
            profile = self.reference.profile
            self.reference.ref[0], self.reference.ref[1] = dp, ie
            if isinstance(profile, Hold):
                self.reference.start(RampTo(profile.dp, profile.ie, self.cfg["reference"]["ramp_s"]))
        try:
            self.controller.reset(self._controller_est)
        except Exception as exc:   # a plugin's reset may raise anything; nothing is enabled yet
            raise RuntimeError(f"cannot activate: the controller's reset raised {type(exc).__name__}: {exc}") from None
        soft_s = self.cfg["controller"]["soft_start_s"]
        self.soft_scale = 0.0 if self._plugin and soft_s > 0.0 else 1.0
        self.soft_step = self.dt / soft_s if soft_s > 0.0 else 1.0
        self.backend.activate()
        s.activated(self.est)
        self.activations += 1
        if self.service is not None:
            self.service.mark_command_channel(self.clock.now_ns() * 1e-9)
            self.service.status("active")

    def deactivate(self) -> None:
        """ACTIVE -> SAFE: set values zero, amplifiers off."""
        self.backend.write(0.0, 0.0)
        self.backend.deactivate()
        self.torque[0] = self.torque[1] = 0.0
        if self.safety.state in (State.ACTIVE, State.CONFIGURED):
            self.safety.state = State.SAFE
        if self.service is not None:
            self.service.status("safe")

    def reset_fault(self) -> None:
        """FAULT -> SAFE (explicit acknowledgement). Raises RuntimeError in any other state."""
        self.safety.reset()
        if self.service is not None:
            self.service.status("safe")

    def request_stop(self) -> None:
        """Go safe now and end the loop after this cycle (the stop command, handled inside a cycle;
        a signal handler only calls ``loop.stop()`` and lets :meth:`run` go safe)."""
        if self.safety.state == State.ACTIVE:
            self.deactivate()
        self.loop.stop()

    def set_gains(self, **gains: float) -> None:
        """Ramp to new gains (over controller.gain_ramp_s: the rate limit). Raises GainError naming a
        gain that is not finite or beyond controller.gain_limits, or an equilibrium angle beyond the
        ankle range (checked here for any controller, as the protocol does); nothing changes then."""
        setter = getattr(self.controller, "set_gains", None)
        if setter is None:
            raise ValueError("this controller has no run-time gains")
        self._check_gain_maxima(gains)
        setter(**gains)

    def _check_gain_maxima(self, gains: dict[str, float]) -> None:
        for name, value in gains.items():
            if name == "phase":                    # the phase's name: the controller checks it
                continue
            if name in proto.PHASE_FIELDS:         # an equilibrium angle: within the ankle range, any controller
                what, problem = repr(name), reference_problem(value, self.safety.ankle_limit)
            else:
                what, problem = f"gain {name!r}", gain_problem(name, value, self.gain_maxima)
            if problem:
                raise GainError(name, f"{what} {problem}")

    def _set_gains_checked(self, gains: dict[str, float]) -> dict | proto.Pending:
        """The set_gains command. A controller whose gain check is slow (``check_gains``: the built-in
        controllers' stability margins over the whole ramp) is checked by the background loader, off
        the loop thread, and the gains applied when the check passes (Pending reply); any other
        controller's gains (a plugin without the check) are set at once."""
        check = getattr(self.controller, "check_gains", None)
        if check is None:
            self.set_gains(**gains)
            return {"state": State(self.safety.state).name.lower()}
        self._check_gain_maxima(gains)
        controller = self.controller
        job = self._in_background(lambda: check(**gains), "a gain change check", next(iter(gains), "cmd"))

        def finish() -> dict | None:
            if not job.done:
                return None
            if isinstance(job.error, GainError):
                raise proto.CommandError(job.error.gain, str(job.error))
            if job.error is not None:
                raise job.error
            if self.controller is not controller:   # swapped meanwhile: the check was not for this one
                raise proto.CommandError("cmd", "the controller changed while its gains were checked; "
                                                "nothing changed")
            controller.apply_gains(**gains)
            waiting = getattr(controller, "deferred", None)    # a stance or swing phase's change for its next beginning
            return {"state": State(self.safety.state).name.lower(),
                    **({"waiting": PHASES[waiting[0]]} if waiting is not None else {})}

        return proto.Pending(finish)

    def _command_reference(self, profile: Profile) -> None:
        """Start a commanded reference; from now on the reference is rate limited."""
        self.reference.start(profile)
        self.reference.max_step = self.max_reference_step
        self.reference_commanded = True

    def _start_csv(self, params: dict) -> proto.Pending:
        """Load a CSV profile off the loop thread (parsed in a child process, handed over by the
        background loader); the reply comes when it is loaded and started."""
        running = self.loader.pending()
        if running is not None:
            raise proto.CommandError("params.path", f"busy: still loading {running.what}")
        checked = validate_profile_params("csv", params)
        path = checked["path"]
        job = self.loader.submit(lambda: load_csv_profile(path, pause), path)
        return proto.Pending(lambda: self._finish_csv(job))

    def _finish_csv(self, job: Job) -> dict | None:
        """The Pending reply's poll: None while loading, else start the profile (or refuse it)."""
        if not job.done:
            return None
        if isinstance(job.error, InterchangeError):
            raise proto.CommandError("params.path", str(job.error))
        if job.error is not None:
            raise job.error
        self._check_reach(job.result)
        self._command_reference(job.result)
        return {"state": State(self.safety.state).name.lower(), "loaded_rows": len(job.result.t)}

    # -- the command interface ---------------------------------------------------------------------
    def handle(self, command: proto.Command) -> dict | proto.Pending:
        """Execute one parsed command (from the socket, in the loop thread); reply data or CommandError.
        A CSV profile is read by the background loader: the reply is then a Pending one (never a file
        read in the loop thread)."""
        try:
            if isinstance(command, proto.Status):
                return self.status()
            if isinstance(command, proto.Activate):
                self.activate()
            elif isinstance(command, proto.Deactivate):
                self.deactivate()
            elif isinstance(command, proto.ResetFault):
                self.reset_fault()
            elif isinstance(command, proto.Stop):
                self.request_stop()
            elif isinstance(command, proto.SetReference):
                ramp = self.cfg["reference"]["ramp_s"] if command.ramp is None else command.ramp
                for key, value in (("dp", command.dp), ("ie", command.ie)):
                    problem = reference_problem(value, self.safety.ankle_limit)
                    if problem:
                        raise proto.CommandError(key, problem)
                self._command_reference(RampTo(command.dp, command.ie, ramp))
            elif isinstance(command, proto.SetGains):
                return self._set_gains_checked(command.given())
            elif isinstance(command, proto.StartProfile) and command.name == "csv":
                return self._start_csv(dict(command.params))
            elif isinstance(command, proto.StartProfile):
                params = dict(command.params)
                if command.name == "hold":   # "hold here": an axis not given stays where the ankle is
                    self._hold_here(params)
                profile = make_profile(command.name, params)
                self._check_reach(profile)
                self._command_reference(profile)
            elif isinstance(command, proto.ListControllers):
                return self._list_controllers()
            elif isinstance(command, proto.SetController):
                return self._set_controller(command)
            else:
                raise proto.CommandError("cmd", f"not supported: {type(command).__name__}")
        except proto.CommandError:   # already names its field (a ValueError: keep it from the catch-all below)
            raise
        except RuntimeError as exc:
            raise proto.CommandError("cmd", str(exc)) from None
        except ConfigError as exc:  # a profile parameter, keyed params.<key>
            raise proto.CommandError(exc.key or "params", exc.message) from None
        except InterchangeError as exc:  # the csv profile's file
            raise proto.CommandError("params.path", str(exc)) from None
        except GainError as exc:
            raise proto.CommandError(exc.gain, str(exc)) from None
        except ValueError as exc:  # set_gains on a controller without run-time gains
            raise proto.CommandError("cmd", str(exc)) from None
        return {"state": State(self.safety.state).name.lower()}

    # -- controllers at run time -------------------------------------------------------------------
    def _in_background(self, fn: Callable[[], Any], what: str, field: str) -> Job:
        """Submit ``fn`` to the background loader (an entry-point scan or a plugin import may take tens
        of ms: never in the loop thread); refused, naming ``field``, while another job runs."""
        running = self.loader.pending()
        if running is not None:
            raise proto.CommandError(field, f"busy: still loading {running.what}")
        return self.loader.submit(fn, what)

    def _list_controllers(self) -> proto.Pending:
        """The built-in and installed controllers (found off the loop thread) and the running one."""
        job = self._in_background(_available_controllers, "the controller list", "cmd")

        def poll() -> dict | None:
            if not job.done:
                return None
            if job.error is not None:
                raise proto.CommandError("cmd", f"cannot list the controllers: {job.error}")
            return {"controllers": job.result, "current": self.cfg["controller"]["type"]}
        return proto.Pending(poll)

    def _set_controller(self, command: proto.SetController) -> proto.Pending:
        """Replace the controller while not active: the config with the new ``controller.type`` and
        ``controller.params`` goes through the config's own validation, and the controller is built,
        off the loop thread; the loop thread swaps it in if the daemon is still not active."""
        if not self.own_controller:
            raise proto.CommandError("cmd", "this run's controller was given by an experiment, not the config")
        if self.safety.state == State.ACTIVE:
            raise proto.CommandError("cmd", "cannot switch the controller while active (deactivate first)")
        data = config_data(self.cfg)
        data["controller"]["type"] = command.type
        data["controller"].pop("params", None)
        if command.params:
            data["controller"]["params"] = dict(command.params)
        job = self._in_background(lambda: self._build_controller(data), f"controller {command.type!r}", "type")

        def poll() -> dict | None:
            if not job.done:
                return None
            if isinstance(job.error, ConfigError):
                key = job.error.key or "controller.type"
                raise proto.CommandError({"controller.type": "type"}.get(key, key.removeprefix("controller.")),
                                         job.error.message)
            if job.error is not None:
                raise job.error
            if self.safety.state == State.ACTIVE:   # activated while it was being built
                raise proto.CommandError("cmd", "cannot switch the controller while active (deactivate first)")
            self.cfg, self.controller = job.result
            return {"state": State(self.safety.state).name.lower(), "controller": command.type}
        return proto.Pending(poll)

    def _build_controller(self, data: dict) -> tuple[Config, CycleController]:
        """The validated config (the schema and cross-key checks of load_config) and its controller."""
        from ankle_rt.config import config_from_data

        cfg = config_from_data(data, lambda key: "the set_controller command", getattr(self.cfg, "source", "<memory>"))
        return cfg, build_controller(cfg, self.kin, self.reference.ref)

    def ankle_now(self) -> tuple[float, float]:
        """rad [DP, IE]: where the ankle is for the running controller's reference, the angle its law
        compares the reference with (:meth:`BatchableController.angles`: the joint encoders when the
        impedance law takes them, ``controller.impedance.angle_source``), else (a plugin, readings not
        finite) the estimate through the cables. Holding this angle commands no torque step."""
        est, controller = self.est, self._controller
        if isinstance(controller, BatchableController):
            dp, ie = controller.angles(est)
            if math.isfinite(dp + ie):
                return dp, ie
        return est.dp, est.ie

    def _hold_here(self, params: dict) -> None:
        """Fill the axes ``params`` does not give with :meth:`ankle_now`; refused (naming the axis)
        while the estimate is not valid: gauges not tared yet (the angle still moves with the tare),
        or not finite (a sensor fault)."""
        for key, value in zip(("dp", "ie"), self.ankle_now()):
            if key in params:
                continue
            if not self.est.tared or not math.isfinite(value):
                why = "the strain gauges are not tared yet" if not self.est.tared else f"it is {value!r}"
                raise proto.CommandError(f"params.{key}", f"hold here needs the ankle estimate, and {why}: "
                                                          f"give params.{key} in rad")
            params[key] = value

    def _check_reach(self, profile: Profile) -> None:
        """Refuse (before it starts) a profile that would take the reference beyond the ankle range."""
        limit = self.safety.ankle_limit
        for axis, name, (low, high) in zip((0, 1), ("DP", "IE"), profile.bounds()):
            start = float(self.reference.ref[axis]) if profile.relative else 0.0
            worst = low + start if abs(low + start) > abs(high + start) else high + start
            if abs(worst) > limit:
                raise proto.CommandError("params", f"the profile would take {name} to {math.degrees(worst):.1f} deg"
                                                   f"{f' (from {math.degrees(start):.1f} deg)' if start else ''}, "
                                                   f"beyond the ankle range +/-{math.degrees(limit):.3g} deg")

    def status(self) -> dict:
        s, est = self.safety, self.est
        gains = getattr(self.controller, "gains", None)
        return {
            "state": State(s.state).name.lower(),
            "fault": Fault(s.fault).name.lower(), "fault_description": Fault(s.fault).description,
            "fault_time_s": s.fault_time,
            "t": est.t,
            "ankle_deg": [math.degrees(v) for v in est.ankle_pos],
            "reference_deg": [math.degrees(v) for v in self.reference.ref],
            "motor_pos_rad": est.motor_pos.tolist(), "motor_vel_rad_s": est.motor_vel.tolist(),
            "sg_torque_nm": est.sg_torque.tolist(), "current_a": list(s.current),
            "controller": self.cfg["controller"]["type"] if self.own_controller else type(self.controller).__name__,
            "gains": gains.as_dict() if hasattr(gains, "as_dict") else None,
            "gait_phase": self._gait_phase_status(),
            "loop": self.loop.stats.summary(),
            "backend": self.backend.counters(),
            "log": self.recorder.status() if self.recorder is not None else None,
            "lsl": self.lsl.status() if self.lsl is not None else None,
        }

    # -- running ---------------------------------------------------------------------------------
    def run(self, duration_s: float | None) -> None:
        """Run the loop for ``duration_s`` (None or 0: until stopped) with the GC frozen, then go safe.
        A run ended by request_stop (signal, stop command) logs one last cycle showing the safe state."""
        duration_ns = round(duration_s * 1e9) if duration_s else None
        gc.collect()
        gc.freeze()
        gc.disable()
        try:
            self.loop.run(self.cycle, duration_ns)
        finally:
            gc.enable()
            gc.unfreeze()
            if self.safety.state == State.ACTIVE:
                self.deactivate()
            else:
                self.backend.deactivate()
        if self.loop.stop_requested or (self.safety.state == State.FAULT and math.isnan(self.safety.fault_time)):
            self.cycle(self.clock.now_ns())   # the safe state (or a fault tripped after the last cycle) on record

    def close(self) -> None:
        """Safe state, then release what this daemon opened (backend, log)."""
        self.backend.deactivate()
        if self.owns_backend:
            self.backend.close()
        if self.recorder is not None:
            self.recorder.close()
        if self.service is not None:
            self.service.close()
        self.loader.close()

    def open_log(self, path: str | Path, retention_pattern: str = "") -> None:
        """Record every cycle into a run log file at ``path`` (ring, flush, rotation and retention from
        the config's ``logging``; ``retention_pattern``: which files of its directory retention counts,
        default this log's parts). Raises OSError when it cannot be created."""
        log = self.cfg["logging"]
        meta = self.log_metadata()
        self.lsl = self._lsl_publisher(meta)
        self.recorder = LogWriter(path, meta, log["ring_records"], log["flush_interval_s"],
                                  Rotation.from_config(log, retention_pattern), tap=self.lsl)

    def _lsl_publisher(self, meta: dict[str, Any]) -> "LslPublisher | None":
        """The Lab Streaming Layer publisher the log writer's thread drives, when ``lsl.enabled`` and the
        clock is real (lockstep time is not the lab's clock). Raises ConfigError without pylsl."""
        from ankle_rt.control.gait_phase import PHASE_NAMES
        from ankle_rt.log.lsl import LslPublisher, LslUnavailable

        if not self.cfg["lsl"]["enabled"] or self.clock.simulated:
            return None
        try:
            return LslPublisher(self.cfg["controller"]["rate_hz"], self.cfg["lsl"]["source_id"],
                                lambda: self.loop.start_ns * 1e-9, meta["states"], meta["faults"],
                                info={"config": str(meta["config"]), "backend": meta["backend"],
                                      "controller": self.cfg["controller"]["type"]}, phases=PHASE_NAMES)
        except LslUnavailable as exc:
            raise ConfigError(str(exc), getattr(self.cfg, "source", None), "lsl.enabled") from None

    @property
    def simulated_plant(self) -> bool:
        """True when the plant is simulated in this process (the sim backend, or a transport's lockstep
        emulator): nothing physical moves. Both the config and the opened backend must say so (a
        backend handed in, or a transport given its own bus or port, counts as hardware unless it
        says otherwise: :attr:`Backend.simulated_plant`)."""
        backend = self.cfg["backend"]
        configured = backend == "sim" or self.cfg.get(backend, {}).get("emulator") == "lockstep"
        return configured and self.backend.simulated_plant

    @property
    def overrun_limits(self) -> Mapping[str, Any]:
        """The config section whose ``max_stall_s`` and ``max_consecutive_overruns`` trip
        MISSED_DEADLINES: ``sim`` for a simulated plant on the real clock (a busy host stalls the
        simulation, not a device), ``loop`` otherwise (hardware always; lockstep has no stalls)."""
        return self.cfg["sim"] if self.simulated_plant and not self.clock.simulated else self.cfg["loop"]

    def log_metadata(self) -> dict[str, Any]:
        """The run log header's metadata. ``controller_config`` is the config's controller section the
        run started with (type, gains, ramps; what ``validate --from`` replays), null when an
        experiment plugged its own controller in. ``sim_disturbances``: the ankle torques the simulated
        plant applied (``sim.disturbances``, replayed by ``validate --from``), null on real hardware."""
        return log_metadata(config=getattr(self.cfg, "source", "<memory>"), backend=self.cfg["backend"],
                            clock="simulated" if self.clock.simulated else "monotonic",
                            rate_hz=self.cfg["controller"]["rate_hz"], torque_constant=self.kt,
                            controller=type(self.controller).__name__,
                            controller_config=self.cfg["controller"] if self.own_controller else None,
                            sim_disturbances=self.cfg["sim"]["disturbances"] if self.simulated_plant else None,
                            states={s.name: int(s) for s in State}, faults={f.name: int(f) for f in Fault})


def _available_controllers() -> dict[str, str]:
    """:func:`ankle_rt.controller_registry.available_controllers`, imported where it runs: on the
    background loader's thread (the first import of the registry and importlib.metadata reads files;
    an experiment's daemon has not imported them at start-up)."""
    from ankle_rt.controller_registry import available_controllers

    return available_controllers()


@dataclass
class RunResult:
    """The recorded cycles of a run as numpy columns.

    ``columns`` holds every log field (docs/design.md interchange names: t, motor_pos_1/2, current_cmd_1/2,
    sg_torque_dp/ie, ankle_dp/ie (joint encoders), ref_dp/ie; plus est_ankle_dp/ie, motor_vel_1/2,
    torque_cmd_1/2, state, fault, ...). ``summary`` has the loop statistics and counters.
    """

    records: np.ndarray
    summary: dict[str, Any] = field(default_factory=dict)

    @property
    def columns(self) -> dict[str, np.ndarray]:
        return {name: self.records[name] for name in self.records.dtype.names}

    def __getitem__(self, name: str) -> np.ndarray:
        return self.records[name]

    def __len__(self) -> int:
        return len(self.records)

    def interchange(self) -> dict[str, np.ndarray]:
        """Columns for :func:`ankle_rt.interchange.write_csv` (joint encoders only when present)."""
        return interchange_columns(self.records)


def run_lockstep(cfg: Config, duration_s: float, *, controller: CycleController | None = None,
                 backend: Backend | None = None, log_path: str | Path | None = None,
                 reference: ReferenceGenerator | None = None) -> RunResult:
    """Run the real loop against a SimClock as fast as possible for ``duration_s`` of simulated time.

    ``controller=None``: the config's controller and reference profile. ``backend=None``: the
    config's backend, opened on a fresh SimClock (closed again at the end); a given backend keeps its
    own clock (``backend.clock``, which must be a SimClock) and stays open. ``log_path``: also write
    the records as a run log there. ``reference``: as :class:`Daemon` takes it (a replay).
    """
    clock = backend.clock if backend is not None else SimClock()
    if not getattr(clock, "simulated", False):
        raise ValueError("run_lockstep needs a backend on a SimClock")
    daemon = Daemon(cfg, clock, backend=backend, controller=controller, reference=reference)
    recorder = daemon.recorder = MemoryRecorder(-(-round(duration_s * 1e9) // daemon.period_ns) + 1)
    try:
        daemon.run(duration_s)
    finally:
        daemon.close()
    if log_path is not None:
        recorder.save(log_path, daemon.log_metadata())
    summary = {"loop": daemon.loop.stats.summary(), "saturated_cycles": daemon.safety.saturated,
               "fault": Fault(daemon.safety.fault).name, "tare_nm": list(daemon.estimator.offset),
               "records_dropped": recorder.dropped}
    return RunResult(records=recorder.records.copy(), summary=summary)
