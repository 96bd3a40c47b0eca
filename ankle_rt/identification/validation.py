"""Model validation (the paper's section 4): run a check on the configured backend, or take a recorded
file, drive the simulation with the same references or inputs, and report the error per channel.

Checks:
- ``sine`` (Fig. 7): ankle IE sine tracking under the motor-side PD with the paper's validation gains
  (``controller.validation_gains``, kp = 80 N m/rad, kd = 0.3 N m s/rad) at several frequencies, with
  the cables on. The daemon's own PD and sine reference run it.
- ``step`` (Fig. 6): open-loop torque steps with the motors off the cables (the actuator model).

The simulation side is the model config (``backend: sim``, opened through the backend registry) with
quantisation and strain-gauge noise off: the model's noise-free prediction. It is driven either
- by the references (the recording has ``ref_dp``/``ref_ie``): the daemon loop replays them from a CSV
  reference, closed loop, through the controller the recording was made with (a run log's header
  records it; for an interchange CSV the caller names it; the Fig. 7 check uses the validation PD); or
- by the inputs: the recorded set values (or torques) are applied row by row, open loop, exactly as the
  interchange timing says (each row's input held until the next row).

Error per channel: NRMSE = RMS(measured - simulated) / (max - min of measured), and the largest
absolute error. Motor angles are compared relative to their first sample in open-loop replays (the
simulator starts at zero). A small NRMSE alone does not make a model adequate: a 6 ms actuation delay
in a closed-loop run costs under 2 % NRMSE while `diagnose` explains the error 40x better. So each
measured channel also gets its noise floor, estimated from the data (the scatter of the second
difference, sqrt(Var(d2 x) / 6) for white noise, and never below 0.01 % of the channel's range), and the
error's systematic part (its moving mean over 20 ms). A check passes when every channel's NRMSE is below
the tolerance *and* no channel's systematic error exceeds ``SIGNIFICANCE`` times its noise floor: what
is left then is what the sensors' own noise would leave.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ankle_rt.config import Config, validate
from ankle_rt.identification.inertia import TorqueStepExperiment
from ankle_rt.identification.runner import actuator_config, recording_of, run_lockstep_recording, with_overrides
from ankle_rt.identification.signals import IdentificationError, centred_velocity
from ankle_rt.interchange import PLAUSIBLE_ABS, Recording
from ankle_rt.plotting import MISSING, pyplot
from ankle_rt.references import CsvProfile, ReferenceGenerator

SINE_FREQUENCIES_HZ = (0.5, 1.0, 2.0)
SINE_AMPLITUDE_IE = math.radians(10.0)   # rad, the paper's Fig. 7 moves IE
SINE_START_S = 0.3                       # s after start-up (tare 0.1 s + soft start 0.2 s)
SINE_PERIODS = 3
STEP_TORQUE = 1.5                        # N m: a new experiment, not the identification's 1.0 N m steps
DEFAULT_TOLERANCE = 0.02                 # NRMSE above this on any channel is a discrepancy
#: channels compared for each way of driving the simulation (when present in the recording)
REFERENCE_CHANNELS = ("motor_pos_1", "motor_pos_2", "ankle_dp", "ankle_ie", "current_cmd_1", "current_cmd_2")
INPUT_CHANNELS = ("motor_pos_1", "motor_pos_2", "motor_speed_1", "motor_speed_2", "ankle_dp", "ankle_ie")
#: a channel whose measured range is below its floor is not compared (its NRMSE would be noise over
#: noise): angles 1 mrad, speeds 0.05 rad/s, currents 0.01 A (or N m for torque data)
FLOORS = {"motor_pos": 1e-3, "ankle": 1e-3, "motor_speed": 0.05, "current_cmd": 0.01}
#: a channel disagrees when its systematic error (moving mean of the error over SYSTEMATIC_WINDOW_S)
#: exceeds this many times its noise floor. Measured on the README walkthrough (20 s chirp, PD): the
#: model against its own noisy run <= 0.3x on every channel; with the hidden 6 ms delay 14-19x on the
#: angles (NRMSE 0.18 %, well inside the tolerance), 3-5x on the set values.
SIGNIFICANCE = 5.0
SYSTEMATIC_WINDOW_S = 0.02
NOISE_FLOOR_SHARE = 1e-4     # the noise floor is never taken below this share of the measured range


@dataclass(frozen=True)
class ChannelError:
    name: str
    nrmse: float        # RMS error / measured range
    max_error: float    # largest absolute error, in the channel's unit
    systematic: float = math.nan   # RMS of the error's moving mean (SYSTEMATIC_WINDOW_S), channel's unit
    noise: float = math.nan        # the measured channel's noise floor (channel's unit); nan: not estimated

    @property
    def significance(self) -> float:
        """Systematic error over the noise floor (nan for a derived channel without a noise floor)."""
        return self.systematic / self.noise if self.noise > 0.0 else math.nan

    def significant(self) -> bool:
        return self.significance > SIGNIFICANCE


@dataclass
class Comparison:
    """One check: the measurement, the simulation driven like it, and the error per channel."""

    label: str
    drive: str                     # "reference" or "input"
    measured: Recording
    simulated: Recording
    channels: list[ChannelError]
    flat: list[str]                # channels present but not compared (range below the floor)

    def worst(self) -> ChannelError:
        return max(self.channels, key=lambda c: c.nrmse)

    def systematic(self) -> list[ChannelError]:
        """Channels whose systematic error stands significantly above their noise floor, worst first."""
        return sorted((c for c in self.channels if c.significant()), key=lambda c: -c.significance)

    def passed(self, tolerance: float = DEFAULT_TOLERANCE) -> bool:
        return all(c.nrmse < tolerance for c in self.channels) and not self.systematic()

    def lines(self, tolerance: float = DEFAULT_TOLERANCE) -> list[str]:
        worst = f"worst NRMSE {100 * self.worst().nrmse:.2f} % on {self.worst().name}, tolerance {100 * tolerance:g} %"
        if self.passed(tolerance):
            verdict = f"agrees ({worst}; no systematic error above {SIGNIFICANCE:g}x the noise floor)"
        elif self.worst().nrmse >= tolerance:
            verdict = f"DISCREPANCY ({worst})"
        else:
            top = self.systematic()[0]
            verdict = (f"DISCREPANCY ({worst}, but the error is systematic: {top.significance:.0f}x the noise "
                       f"floor on {top.name}, limit {SIGNIFICANCE:g}x)")
        out = [f"{self.label} (simulation driven by the {self.drive}s): {verdict}"]
        if "controller_config" in self.simulated.extra:
            out.append(f"  replayed under controller: {describe_controller(self.simulated.extra['controller_config'])}")
        out += [f"  {c.name:<15} NRMSE {100 * c.nrmse:7.3f} %   max error {c.max_error:.4g}"
                + (f"   systematic {c.significance:6.1f}x noise floor" if c.noise > 0.0 else "")
                for c in self.channels]
        if self.flat:
            out.append(f"  not compared (measured range below its floor): {', '.join(self.flat)}")
        return out


def _axis_label(name: str, relative: bool) -> str:
    """A compared channel's axis: its name and SI unit (a motor position relative to its start says so)."""
    if name.startswith("motor_speed_"):
        return f"{name} (rad/s)"
    unit = PLAUSIBLE_ABS[name][1] if name in PLAUSIBLE_ABS else ""
    label = f"{name} - start" if relative and name.startswith("motor_pos_") else name
    return f"{label} ({unit})" if unit else label


def _channel(rec: Recording, name: str, relative: bool) -> np.ndarray | None:
    if name.startswith("motor_speed_"):
        pos = f"motor_pos_{name[-1]}"
        return centred_velocity(rec["t"], rec[pos], 0.01) if pos in rec else None
    if name not in rec:
        return None
    x = rec[name]
    return x - x[0] if relative and name.startswith("motor_pos_") else x


def noise_floor(x: np.ndarray) -> float:
    """The noise of a measured channel, from its own samples: sqrt(Var(second difference) / 6) (exact for
    white noise on a smooth signal at the sample rate; an upper bound otherwise), at least
    NOISE_FLOOR_SHARE of its range."""
    return max(float(np.std(np.diff(x, 2))) / math.sqrt(6.0), NOISE_FLOOR_SHARE * float(np.ptp(x)))


def systematic_error(err: np.ndarray, dt: float) -> float:
    """RMS of the error's moving mean over SYSTEMATIC_WINDOW_S: its structured part (white noise at the
    noise floor leaves 1/sqrt(window samples) of itself)."""
    w = max(1, min(len(err), int(round(SYSTEMATIC_WINDOW_S / dt))))
    return float(np.sqrt(np.mean(np.convolve(err, np.full(w, 1.0 / w), "valid") ** 2)))


def compare(measured: Recording, simulated: Recording, names: tuple[str, ...],
            relative: bool) -> tuple[list[ChannelError], list[str]]:
    """NRMSE and max error of every channel in ``names`` present in both recordings, and the names of
    those left out because their measured range is below the floor (``FLOORS``). Measured channels
    (not the speeds derived by smoothing) also get their noise floor and systematic error."""
    n = min(len(measured), len(simulated))
    out, flat = [], []
    for name in names:
        m, s = _channel(measured, name, relative), _channel(simulated, name, relative)
        if m is None or s is None:
            continue
        if np.ptp(m[:n]) < FLOORS[name.rsplit("_", 1)[0]]:
            flat.append(name)
            continue
        err = s[:n] - m[:n]
        measured_channel = not name.startswith("motor_speed_")
        out.append(ChannelError(name, float(np.sqrt(np.mean(err ** 2)) / np.ptp(m[:n])), float(np.max(np.abs(err))),
                                systematic_error(err, measured.dt) if measured_channel else math.nan,
                                noise_floor(m[:n]) if measured_channel else math.nan))
    if not out:
        raise IdentificationError(f"{measured.source}: no channel to compare (none of {', '.join(names)} varies)")
    return out, flat


def model_config(cfg: Config) -> Config:
    """The simulation side: ``cfg``'s parameters on the simulator, noise-free, no disturbances."""
    return with_overrides(cfg, backend="sim", sim={"quantization": False, "sensor_noise": False, "disturbances": []})


def _check_rate(rec: Recording, cfg: Config) -> None:
    period = 1.0 / cfg["controller"]["rate_hz"]
    if abs(rec.dt - period) > 0.01 * period:
        raise IdentificationError(f"{rec.source}: column 't': sample period {rec.dt:.6g} s differs from the "
                                  f"config's loop period {period:.6g} s (controller.rate_hz); resample first")


def pd_validation_overrides(cfg: Config) -> dict:
    """Config overrides for the paper's section 4 PD: motor-side PD with the validation gains, no
    friction feed-forward, no ankle disturbances, the cables on."""
    return {"controller": {"type": "pd", "pd_gains": "validation", "friction_ff": {"enabled": False}},
            "sim": {"disturbances": [], "cables": True}}


def recorded_controller(rec: Recording) -> dict | None:
    """The controller section a run log's header records (validated, defaults filled in), or None for
    an interchange CSV or a log written before the header carried it."""
    section = rec.extra.get("log_meta", {}).get("controller_config")
    if section is None:
        return None
    from ankle_rt.config_schema import CONTROLLER

    def given(data: object) -> object:   # JSON null marks a default (e.g. friction_ff.coulomb): refill it
        return {k: given(v) for k, v in data.items() if v is not None} if isinstance(data, dict) else data
    return validate(given(section), CONTROLLER, lambda _path: f"{rec.source} (log header)", ("controller",))


def recorded_disturbances(rec: Recording) -> list[dict] | None:
    """The ankle disturbances (``sim.disturbances`` items) a run log's header records for a simulated
    plant, or None (hardware, an interchange CSV, an older log)."""
    return rec.extra.get("log_meta", {}).get("sim_disturbances")


def describe_controller(section: dict) -> str:
    """One line naming a controller section's type and gains, for reports."""
    if section["type"] == "impedance":
        imp = section["impedance"]
        text = (f"impedance (stiffness DP/IE {imp['stiffness_dp']:g}/{imp['stiffness_ie']:g} N m/rad, "
                f"damping DP/IE {imp['damping_dp']:g}/{imp['damping_ie']:g} N m s/rad)")
    else:
        gains = section[section["pd_gains"] + "_gains"]
        text = f"pd ({section['pd_gains']}_gains kp {gains['kp']:g} N m/rad, kd {gains['kd']:g} N m s/rad)"
    return text + (" + friction feed-forward" if section["friction_ff"]["enabled"] else "")


def simulate_references(rec: Recording, model_cfg: Config, controller: dict | None = None) -> Recording:
    """Closed loop: the daemon on the model config replays ``rec``'s references through ``controller``
    (a controller config section: the one the recording was made with; default the paper's validation
    PD) and the ankle disturbances the recording's log header says the plant saw (a known input, not
    model error). The result's ``extra["controller_config"]`` is the controller section used."""
    _check_rate(rec, model_cfg)
    overrides = pd_validation_overrides(model_cfg)
    if controller is not None:
        overrides["controller"] = controller
    disturbances = recorded_disturbances(rec)
    if disturbances:
        overrides["sim"]["disturbances"] = disturbances
    cfg = with_overrides(model_config(model_cfg), **overrides)
    t, dp, ie = (rec[name].tolist() for name in ("t", "ref_dp", "ref_ie"))
    # as recorded, steps and all (a configured CSV would be rate limited like a commanded reference)
    replayed = ReferenceGenerator(CsvProfile.from_columns(t, dp, ie, ((min(dp), max(dp)), (min(ie), max(ie)))))
    from ankle_rt.daemon import run_lockstep
    duration = float(rec["t"][-1] - rec["t"][0]) + rec.dt
    sim = recording_of(run_lockstep(cfg, duration, reference=replayed), "simulation (references replayed)")
    sim.extra["controller_config"] = cfg["controller"]
    return sim


def simulate_inputs(rec: Recording, model_cfg: Config) -> Recording:
    """Open loop: the recorded inputs applied to the model, one row per control tick (ZOH)."""
    from ankle_rt.backend import SensorFrame, open_backend
    from ankle_rt.clock import SimClock

    cfg = model_config(model_cfg)
    _check_rate(rec, cfg)
    kt = cfg["actuator"]["torque_constant"]
    current = rec.motor_input(kt) / kt
    if current.shape[1] == 1:
        current = np.column_stack([current[:, 0], np.zeros(len(rec))])
    clock = SimClock()
    period = round(1e9 / cfg["controller"]["rate_hz"])
    n = len(rec)
    cols = {k: np.zeros(n) for k in ("t", "motor_pos_1", "motor_pos_2", "ankle_dp", "ankle_ie")}
    frame = SensorFrame()
    with open_backend(cfg, clock) as backend:
        backend.activate()
        for k in range(n):
            clock.sleep_until(k * period)
            backend.read(frame)
            backend.write(float(current[k, 0]), float(current[k, 1]))
            cols["t"][k] = frame.t
            cols["motor_pos_1"][k], cols["motor_pos_2"][k] = frame.motor_pos
            cols["ankle_dp"][k], cols["ankle_ie"][k] = frame.ankle_pos
    cols["t"] += rec["t"][0]
    return Recording(cols, "simulation (inputs replayed)")


def validate_recording(rec: Recording, model_cfg: Config, drive: str | None = None, label: str = "",
                       controller: dict | None = None) -> Comparison:
    """Compare ``rec`` with the model driven the same way (``drive``: "reference", "input", or None =
    by the references when the recording has them). ``controller``: the controller section the
    recording was made with, for the closed-loop replay (default: the paper's validation PD)."""
    if drive is None:
        drive = "reference" if "ref_dp" in rec and "ref_ie" in rec and np.isfinite(rec["ref_ie"]).all() else "input"
    if drive == "reference":
        for col in ("ref_dp", "ref_ie"):
            if col not in rec:
                raise IdentificationError(f"{rec.source}: column {col!r} missing: needed to drive the simulation by the references")
        sim = simulate_references(rec, model_cfg, controller)
        channels, flat = compare(rec, sim, REFERENCE_CHANNELS, relative=False)
    else:
        sim = simulate_inputs(rec, model_cfg)
        channels, flat = compare(rec, sim, INPUT_CHANNELS, relative=True)
    return Comparison(label or rec.source, drive, rec, sim, channels, flat)


def run_sine_check(cfg: Config, frequency_hz: float) -> Recording:
    """Fig. 7 on the configured backend: IE sine tracking under the validation PD, cables on."""
    if cfg["backend"] != "sim" and not cfg["sim"]["cables"]:
        raise IdentificationError("the sine check needs the cables on (sim.cables: true)")
    duration = SINE_START_S + SINE_PERIODS / frequency_hz
    sine = {"amplitude_dp": 0.0, "amplitude_ie": SINE_AMPLITUDE_IE, "frequency_hz": frequency_hz,
            "start_s": SINE_START_S, "ie_phase": 0.0}
    overrides = pd_validation_overrides(cfg)
    if cfg["backend"] != "sim":
        overrides.pop("sim")
    run_cfg = with_overrides(cfg, reference={"profile": "sine", "sine": sine}, **overrides)
    return run_lockstep_recording(run_cfg, None, duration)


def run_step_check(cfg: Config, repeats: int = 1) -> Recording:
    """Fig. 6 on the configured backend: open-loop torque steps, motors off the cables."""
    acfg, _ = actuator_config(cfg)
    experiment = TorqueStepExperiment(step_torque=STEP_TORQUE, repeats=repeats)
    return run_lockstep_recording(acfg, experiment, experiment.duration_s)


def run_checks(cfg: Config, model_cfg: Config, checks: tuple[str, ...],
               frequencies: tuple[float, ...] = SINE_FREQUENCIES_HZ,
               progress: Callable[[float, float, str], None] | None = None) -> list[Comparison]:
    """Run ``checks`` ("sine", "step") on ``cfg``'s backend and compare each with ``model_cfg``'s simulation.
    ``progress(done, total, what)`` is called before each check and at the end, counting checks."""
    out: list[Comparison] = []
    total = ("step" in checks) + ("sine" in checks) * len(frequencies)
    report = progress or (lambda done, total, what: None)
    if "step" in checks:
        report(0, total, "torque steps")
        rec = run_step_check(cfg)
        out.append(validate_recording(rec, actuator_config(model_config(model_cfg))[0], "input",
                                      f"Fig. 6 torque steps of {STEP_TORQUE:g} N m, motors off the cables"))
    if "sine" in checks:
        for f in frequencies:
            report(len(out), total, f"sine {f:g} Hz")
            rec = run_sine_check(cfg, f)
            out.append(validate_recording(rec, model_cfg, "reference",
                                          f"Fig. 7 IE sine {math.degrees(SINE_AMPLITUDE_IE):g} deg at {f:g} Hz, PD kp/kd "
                                          f"{cfg['controller']['validation_gains']['kp']:g}/{cfg['controller']['validation_gains']['kd']:g}"))
    report(total, total, "done")
    return out


def write_overlays(comparisons: list[Comparison], out_dir: Path) -> list[str]:
    """One PNG per comparison: measured (solid) and simulated (dashed) for each compared channel.
    Returns lines to print (file names, or a plain message when matplotlib is missing)."""
    plt = pyplot()
    if plt is None:
        return [f"plots: {MISSING}; text report only"]
    lines = []
    for k, c in enumerate(comparisons, start=1):
        relative = c.drive == "input"
        fig, axes = plt.subplots(len(c.channels), 1, sharex=True, figsize=(8, 2.2 * len(c.channels)), squeeze=False)
        n = min(len(c.measured), len(c.simulated))
        t = c.measured["t"][:n]
        for ax, ch in zip(axes[:, 0], c.channels):
            ax.plot(t, _channel(c.measured, ch.name, relative)[:n], "-", label="Exp")
            ax.plot(t, _channel(c.simulated, ch.name, relative)[:n], "--", label="Sim")
            ax.set_ylabel(_axis_label(ch.name, relative), fontsize=8)
            ax.set_title(f"NRMSE {100 * ch.nrmse:.2f} %", fontsize=8, loc="right")
        axes[0, 0].legend(fontsize=8)
        axes[0, 0].set_title(c.label, fontsize=9, loc="left")
        axes[-1, 0].set_xlabel("time (s)")
        fig.tight_layout()
        path = out_dir / f"validate_{k}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        lines.append(f"plot: {path}")
    return lines
