"""Generator D: measured-data cases for `ankle-rt diagnose` built from the physics of a real Bowden-cable ankle
and the way a real loop logs it, written without the diagnosis' or generators A/B/C's internals (only their
public interface: a case's recordings, nominal config, truth and whether a flag is expected).

Structure (different from a linear plant with added forces): a fixed 0.1 ms semi-implicit (symplectic)
Euler step of foot, cable and motors, with Coulomb friction solved implicitly per step, so a motor has a true
stuck state and breaks away only when the applied torque exceeds its static level (no tanh). The amplifier is
a first-order current loop (1-2.5 kHz, as an ESCON's) with PWM ripple and its 15 A peak. The controller runs
at ticks that wake late (0-0.4 ms, rare multi-ms stalls) on what a loop sees (1440-line quadrature encoders
through the 81:1 gearbox, gauges with noise and a 16-bit ADC, a filtered difference velocity); its set value
acts from its tick (plus a latency when the case has one) until the next.

Effects in their own forms: breakaway friction above Coulomb with an exponential Stribeck decay, Coulomb of
its own size per direction and motor, capstan friction in the Bowden sheath (1 - exp(-mu * wrap)) times the
cable tension plus its pretension, gear backlash as a true gap between rotor and pulley with a stiff, damped
impact, rotor cogging with a phase, amplitude and harmonics per motor (6-24 periods per motor turn), a
fractional actuation latency, an exponential (sinh) cable stiffening, a constant load per motor.
Outside the vocabulary (expected `unknown`): LuGre bristle friction with soft bristles (pre-sliding
hysteresis), a Coulomb level rippling with pulley angle (cable routing, 20-60 periods per output turn, its sign
following the motion, so not cogging), viscous friction falling as the grease warms over the session.
Calibration and sensor conditions (truth `none`, a flag expected): gauge zero offsets, gauge gain errors, a
torque-constant error, thermal gauge drift, clipped gauges, dropped rows. Conditions that need no flag:
ticks that wake late, a log at half the control rate, isolated stale rows, ankle-encoder eccentricity.
Walking-only logs: stance moment up to 1.0-1.5 N m/kg of a 55-95 kg wearer through the centre of pressure,
a damped ground contact, the free foot in swing.

    python benchmarks/diagnosis_cases_d.py SEED [SEED ...] --out DIR   # write the cases as interchange CSVs
"""

from __future__ import annotations

import argparse
import math
import sys
from functools import partial
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from ankle_rt.config import load_config  # noqa: E402
from ankle_rt.interchange import Recording  # noqa: E402
from benchmarks.diagnosis_cases_c import (COUNTS, GEAR, RATED_TORQUE, SIM_CONFIG, VOCAB, CaseC,  # noqa: E402
                                          write_case_c)

H = 1e-4                                   # s, integration step (10 per 1 ms control tick)
TICK_STEPS = 10
KT = 1.66                                  # N m/A at the output, nominal
R_PULLEY, R_DP, R_IE = 0.0127, 0.05715, 0.03175
OUTSIDE = {"lugre_presliding", "friction_ripple", "viscous_warmup"}
#: calibration and sensor conditions whose truth is `none` with a data warning or calibration finding expected
FLAGGED = {"sg_offset", "sg_gain", "kt_error", "sg_drift", "sg_clip", "dropouts"}
#: real-log conditions that need no flag
QUIET = {"late_ticks", "log_500", "stale_rows", "encoder_eccentricity"}

CaseD = CaseC          # the same fields: seed, effects, conditions, controller, motion, recordings, config, truth


def draw_effect(kind: str, rng: np.random.Generator, motion: str) -> dict:
    """One effect's parameters at a magnitude a real device shows (output-side SI units)."""
    u = rng.uniform
    if kind == "stribeck":
        return {"kind": kind, "static_ratio": u(1.5, 2.6), "v_s": u(0.03, 0.2), "shape": u(0.7, 2.0)}
    if kind == "asymmetric_friction":
        sign = rng.choice([-1.0, 1.0], 2)
        return {"kind": kind, "ratio_1": float(u(1.7, 2.6) ** sign[0]), "ratio_2": float(u(1.5, 2.6) ** sign[1])}
    if kind == "load_dependent_friction":
        mu, wrap = u(0.08, 0.2), u(0.8, 2.2)           # sheath friction coefficient, wrap angle (rad)
        return {"kind": kind, "capstan": 1.0 - math.exp(-mu * wrap), "pretension": u(0.0, 1.5)}
    if kind == "backlash":
        return {"kind": kind, "gap": u(0.006, 0.018)}
    if kind == "cogging":
        periods = int(rng.choice([6, 8, 12, 14, 18, 24])) * GEAR     # the two motors are of one type
        return {"kind": kind, "periods": periods,
                "amp_1": u(0.015, 0.04) * RATED_TORQUE, "amp_2": u(0.015, 0.04) * RATED_TORQUE,
                "phase_1": u(0, 2 * math.pi), "phase_2": u(0, 2 * math.pi), "h2": u(0.1, 0.4), "h3": u(0.0, 0.2)}
    if kind == "delay":
        return {"kind": kind, "latency": u(0.002, 0.008)}
    if kind == "stiffness_nonlinear":   # cable elongation at which the stiffness has risen by cosh(1) = 1.54
        return {"kind": kind, "e0": u(0.6e-3, 1.6e-3) * (2.5 if motion == "walking" else 1.0)}
    if kind == "torque_offset":
        mags = u(0.2, 0.7, 2) * rng.choice([-1.0, 1.0], 2)
        return {"kind": kind, "offset_1": float(mags[0]), "offset_2": float(mags[1])}
    if kind == "lugre_presliding":      # bristle deflection at steady sliding, rad at the output
        return {"kind": kind, "z_ss": u(2e-3, 6e-3)}
    if kind == "friction_ripple":
        return {"kind": kind, "periods": int(rng.integers(20, 61)), "depth": u(0.4, 0.8), "phase": u(0, 2 * math.pi)}
    if kind == "viscous_warmup":
        return {"kind": kind, "cold_ratio": u(2.5, 4.0), "tau": u(8.0, 20.0)}
    raise ValueError(kind)


def draw_condition(kind: str, rng: np.random.Generator) -> dict:
    """One calibration or sensor condition's parameters."""
    u = rng.uniform
    sign = lambda: float(rng.choice([-1.0, 1.0]))  # noqa: E731
    if kind == "sg_offset":
        return {"kind": kind, "dp": sign() * u(0.8, 3.0), "ie": sign() * u(0.3, 1.5)}
    if kind == "sg_gain":
        return {"kind": kind, "dp": 1 + sign() * u(0.1, 0.2), "ie": 1 + sign() * u(0.0, 0.15)}
    if kind == "kt_error":
        return {"kind": kind, "ratio": 1 + sign() * u(0.1, 0.18)}
    if kind == "sg_drift":
        return {"kind": kind, "dp": sign() * u(1.5, 4.0), "ie": sign() * u(0.5, 2.0), "tau": u(10.0, 40.0)}
    if kind == "sg_clip":
        return {"kind": kind, "fraction": u(0.55, 0.8)}
    if kind == "dropouts":
        return {"kind": kind, "fraction": u(0.01, 0.04)}
    if kind == "late_ticks":
        return {"kind": kind, "mean_late_steps": u(0.5, 2.0), "stall_prob": u(0.0005, 0.003)}
    if kind == "log_500":
        return {"kind": kind}
    if kind == "stale_rows":
        return {"kind": kind, "fraction": u(0.002, 0.01)}
    if kind == "encoder_eccentricity":
        return {"kind": kind, "amp": u(0.002, 0.008), "phase": u(0, 2 * math.pi)}
    raise ValueError(kind)


def gait_moment(t: np.ndarray, period: float, peak: float, ie_peak: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Environment torque on the foot over gait cycles (N m; + dorsiflexes the foot) and the stance mask: a
    heel-strike dip, then the centre of pressure moving ahead of the ankle to ``peak`` near 70 % of stance."""
    s = (t % period) / period
    stance = s < 0.6
    v = np.clip(s / 0.6, 0.0, 1.0)
    shape = v ** 2.5 * (1 - v) / (0.714 ** 2.5 * 0.286)
    dp = np.where(stance, peak * shape - 0.12 * peak * np.sin(np.pi * np.clip(v / 0.12, 0, 1)), 0.0)
    ie = np.where(stance, ie_peak * np.sin(2 * np.pi * v), 0.0)
    return dp, ie, stance


def reference(rng: np.random.Generator, t: np.ndarray, motion: str, gait: dict | None) -> tuple[np.ndarray, np.ndarray]:
    """Ankle angle references (rad): a multisine, a log chirp, smoothed random steps, or the walking
    controller's equilibrium (plantarflexion push-off late in stance, dorsiflexed clearance in swing)."""
    if motion == "walking":
        s = (t % gait["period"]) / gait["period"]
        push = np.clip((s - 0.4) / 0.2, 0, 1) * (s < 0.6)
        swing = gait["clearance"] * np.sin(np.pi * np.clip((s - 0.6) / 0.4, 0, 1))
        dp = np.where(s < 0.6, -gait["push_off"] * push, swing)
        return dp, np.zeros_like(t)
    out = []
    for amp in (rng.uniform(0.06, 0.15), rng.uniform(0.04, 0.1)):
        if motion == "multisine":
            f = rng.uniform(0.2, 4.0, int(rng.integers(5, 9)))
            a = 1.0 / (1.0 + (f / 1.0) ** 2)
            x = sum(ai * np.sin(2 * np.pi * fi * t + rng.uniform(0, 2 * np.pi)) for ai, fi in zip(a, f))
        elif motion == "chirp":
            f0, f1 = 0.1, rng.uniform(3.0, 5.0)
            phase = 2 * np.pi * f0 * t[-1] / math.log(f1 / f0) * ((f1 / f0) ** (t / t[-1]) - 1)
            x = np.sin(phase) / (1.0 + (f0 * (f1 / f0) ** (t / t[-1])) ** 2)
        else:
            edges = np.cumsum(rng.uniform(0.4, 1.2, int(t[-1] / 0.4) + 2))
            levels = rng.uniform(-1, 1, len(edges) + 1)
            raw = levels[np.searchsorted(edges, t)]
            alpha = 1 - math.exp(-(t[1] - t[0]) / 0.04)
            x = np.empty_like(raw)
            acc = 0.0
            for i, r in enumerate(raw):        # 40 ms first-order smoothing of the steps
                acc += alpha * (r - acc)
                x[i] = acc
        out.append(amp * x / max(1e-9, float(np.max(np.abs(x)))))
    return out[0], out[1]


class Device:
    """The true device: nominal parameters perturbed as a real unit differs from the data sheet, and the
    effects."""

    def __init__(self, rng: np.random.Generator, effects: list[dict], conditions: dict):
        u = rng.uniform
        self.fx = {d["kind"]: d for d in effects}
        self.J = 0.048 * u(0.9, 1.1)
        self.D = 0.112 * u(0.8, 1.2)
        self.kc = 0.28 * u(0.85, 1.15, 2)
        self.k = 218800.0 * u(0.9, 1.1)
        self.beta = 6.5e-5 * u(0.7, 1.3)
        self.mass = 0.465 * u(0.9, 1.1)
        self.com = 0.0069 * u(0.8, 1.2)
        self.I = (3.7486e-3 * u(0.9, 1.1), 9.3452e-4 * u(0.9, 1.1))
        self.kt = KT * conditions.get("kt_error", {}).get("ratio", 1.0)
        self.amp_tau = 1.0 / (2 * math.pi * u(1000.0, 2500.0))
        self.ripple = u(0.005, 0.02)            # A rms PWM current ripple
        a = self.fx.get("asymmetric_friction")
        self.kc_dir = [(self.kc[i] * math.sqrt(a[f"ratio_{i + 1}"]), self.kc[i] / math.sqrt(a[f"ratio_{i + 1}"]))
                       if a else (self.kc[i], self.kc[i]) for i in range(2)]    # (+, -) per motor


def stick_or_slip(v_free: float, level: float, inertia: float) -> float:
    """Velocity after one step of Coulomb friction solved implicitly: ``v_free`` is the velocity the step would
    reach without it. If friction up to ``level`` (N m) can stop the motor within the step it sticks (exactly
    zero: the applied torque is held, no creep as with a tanh), else it slides with friction at ``level``."""
    if abs(v_free) <= H * level / inertia:
        return 0.0
    return v_free - math.copysign(H * level / inertia, v_free)


def simulate(dev: Device, rng: np.random.Generator, duration: float, t_session: float, ctl: dict, motion: str,
             cond: dict, gait: dict | None, rig: tuple[float, float]) -> dict[str, np.ndarray]:
    """Run the loop for ``duration`` s from session time ``t_session`` (s since the device was cold) and
    return the logged columns (before the logging conditions). ``rig``: the bench's torsion springs on the
    foot (N m/rad, DP and IE; zero for a free foot), which load the cables as a person would."""
    n_ticks = int(round(duration / (H * TICK_STEPS)))
    late = cond.get("late_ticks")
    if late:
        lateness = np.minimum(rng.geometric(1.0 / (1.0 + late["mean_late_steps"]), n_ticks) - 1, 4)
        stalls = rng.random(n_ticks) < late["stall_prob"]
        lateness[stalls] += rng.integers(10, 30, int(stalls.sum()))
        steps = np.maximum.accumulate(np.arange(n_ticks) * TICK_STEPS + lateness)
        steps = np.unique(steps)
    else:
        steps = np.arange(n_ticks) * TICK_STEPS
    t_tick = steps * H
    ref_dp, ref_ie = reference(rng, t_tick, motion, gait)
    if motion == "walking":
        env_dp, env_ie, stance = gait_moment(t_tick + gait["offset"], gait["period"], gait["peak"], gait["ie_peak"])
    else:
        env_dp = env_ie = np.zeros_like(t_tick)
        stance = np.zeros(len(t_tick), bool)

    fx = dev.fx
    J, I_dp, I_ie, k, beta = dev.J, dev.I[0], dev.I[1], dev.k, dev.beta
    K_dp, K_ie = 2 * k * R_DP ** 2, k * R_IE ** 2
    grav = dev.mass * 9.81 * dev.com
    kt, amp_a = dev.kt, 1.0 - math.exp(-H / dev.amp_tau)
    strib = fx.get("stribeck")
    cap = fx.get("load_dependent_friction")
    cog = fx.get("cogging")
    off = fx.get("torque_offset", {"offset_1": 0.0, "offset_2": 0.0})
    offs = (off["offset_1"], off["offset_2"])
    gap = fx.get("backlash", {}).get("gap", 0.0) / 2
    Jr, Jp = (0.85 * J, 0.15 * J) if gap else (J, 0.0)
    kg = 2.0e4
    cg = 2 * 0.3 * math.sqrt(kg * Jr * Jp / (Jr + Jp)) if gap else 0.0
    e0 = fx.get("stiffness_nonlinear", {}).get("e0")
    lugre = fx.get("lugre_presliding")
    ripple = fx.get("friction_ripple")
    warm = fx.get("viscous_warmup")
    latency_steps = fx["delay"]["latency"] / H if "delay" in fx else 0.0

    # state: ankle (q, w), rotor (r, vr), pulley (p, vp), current, bristles
    qd = qi = wd = wi = 0.0
    r = [0.0, 0.0]; vr = [0.0, 0.0]; p = [0.0, 0.0]; vp = [0.0, 0.0]  # noqa: E702
    cur = [0.0, 0.0]; z = [0.0, 0.0]  # noqa: E702
    pending: list[tuple[float, float, float]] = []      # (active from step, set value 1, 2)
    active = (0.0, 0.0)

    n = len(steps)
    cols = {k_: np.empty(n) for k_ in ("t", "motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2",
                                         "sg_torque_dp", "sg_torque_ie", "ankle_dp", "ankle_ie", "ref_dp", "ref_ie")}
    q_enc = 2 * math.pi / COUNTS
    vel = [0.0, 0.0]; last_enc = [0.0, 0.0]  # noqa: E702
    wc = 2 * math.pi * ctl["vel_cutoff"]
    kc_ff = 0.28 * ctl["ff"]
    noise = rng.normal(0.0, 0.02, (n, 2))
    amp_noise = rng.normal(0.0, dev.ripple, (steps[-1] + TICK_STEPS + 1, 2))
    step = 0
    tau_dp = tau_ie = 0.0
    for j in range(n):
        # sensors at the tick
        enc = [round(r[i] / q_enc) * q_enc for i in range(2)]
        dt_tick = (steps[j] - steps[j - 1]) * H if j else TICK_STEPS * H
        dt_v = dt_tick if ctl["true_dt"] else TICK_STEPS * H
        a_v = 1.0 - math.exp(-wc * dt_tick)
        for i in range(2):
            vel[i] += a_v * ((enc[i] - last_enc[i]) / dt_v - vel[i]) if j else 0.0
        last_enc = enc
        sg_dp, sg_ie = tau_dp + noise[j, 0], tau_ie + noise[j, 1]
        # controller (motor-side): theta_m = R theta
        m_ref = ((R_DP * ref_dp[j] + R_IE * ref_ie[j]) / R_PULLEY, (R_DP * ref_dp[j] - R_IE * ref_ie[j]) / R_PULLEY)
        if ctl["kind"] == "pd":
            kp = ctl["kp"] * (ctl["stance_gain"] if stance[j] else 1.0)
            torque = [kp * (m_ref[i] - enc[i]) - ctl["kd"] * vel[i] for i in range(2)]
        else:   # ankle impedance on the motor-estimated angle, tau_m = R^-T tau_ankle
            th_dp = R_PULLEY * (enc[0] + enc[1]) / (2 * R_DP)
            th_ie = R_PULLEY * (enc[0] - enc[1]) / (2 * R_IE)
            w_dp = R_PULLEY * (vel[0] + vel[1]) / (2 * R_DP)
            w_ie = R_PULLEY * (vel[0] - vel[1]) / (2 * R_IE)
            k_dp = ctl["k_stance"] if stance[j] else ctl["k_imp"]
            t_dp = k_dp * (ref_dp[j] - th_dp) - ctl["b_imp"] * w_dp
            t_ie = ctl["k_ie"] * (ref_ie[j] - th_ie) - 0.3 * ctl["b_imp"] * w_ie
            torque = [R_PULLEY / 2 * (t_dp / R_DP + t_ie / R_IE), R_PULLEY / 2 * (t_dp / R_DP - t_ie / R_IE)]
        if kc_ff:
            torque = [torque[i] + kc_ff * math.tanh(vel[i] / 0.05) for i in range(2)]
        iset = [max(-ctl["clamp"], min(ctl["clamp"], torque[i] / KT)) for i in range(2)]
        cols["t"][j] = steps[j] * H
        cols["motor_pos_1"][j], cols["motor_pos_2"][j] = enc
        cols["current_cmd_1"][j], cols["current_cmd_2"][j] = iset
        cols["sg_torque_dp"][j], cols["sg_torque_ie"][j] = sg_dp, sg_ie
        cols["ankle_dp"][j], cols["ankle_ie"][j] = qd, qi
        cols["ref_dp"][j], cols["ref_ie"][j] = ref_dp[j], ref_ie[j]
        pending.append((steps[j] + latency_steps, iset[0], iset[1]))
        # integrate to the next tick
        stop = steps[j + 1] if j + 1 < n else steps[j] + TICK_STEPS
        e_dp, e_ie = env_dp[j], env_ie[j]
        b_ground = gait["ground_damping"] if stance[j] else 0.0
        visc = dev.D
        if warm:      # the grease warms: viscous friction falls from cold_ratio x toward its warm value
            visc *= 1.0 + (warm["cold_ratio"] - 1.0) * math.exp(-(t_session + steps[j] * H) / warm["tau"])
        while step < stop:
            while pending and pending[0][0] <= step:
                _, a1, a2 = pending.pop(0)
                active = (a1, a2)
            pos = p if gap else r
            vpos = vp if gap else vr
            phi_dp = R_PULLEY * (pos[0] + pos[1]) / (2 * R_DP) - qd
            phi_ie = R_PULLEY * (pos[0] - pos[1]) / (2 * R_IE) - qi
            dphi_dp = R_PULLEY * (vpos[0] + vpos[1]) / (2 * R_DP) - wd
            dphi_ie = R_PULLEY * (vpos[0] - vpos[1]) / (2 * R_IE) - wi
            if e0:
                s_dp, s_ie = e0 / R_DP, e0 / R_IE
                el_dp, el_ie = s_dp * math.sinh(phi_dp / s_dp), s_ie * math.sinh(phi_ie / s_ie)
            else:
                el_dp, el_ie = phi_dp, phi_ie
            tau_dp = K_dp * (el_dp + beta * dphi_dp)
            tau_ie = K_ie * (el_ie + beta * dphi_ie)
            load = (R_PULLEY / 2 * (tau_dp / R_DP + tau_ie / R_IE), R_PULLEY / 2 * (tau_dp / R_DP - tau_ie / R_IE))
            # foot
            wd += H * (tau_dp + e_dp - rig[0] * qd - grav * math.sin(qd) - b_ground * wd) / I_dp
            wi += H * (tau_ie + e_ie - rig[1] * qi - b_ground * wi) / I_ie
            qd += H * wd
            qi += H * wi
            for i in range(2):
                cur[i] += amp_a * (max(-15.0, min(15.0, active[i])) - cur[i])
                drive = kt * (cur[i] + amp_noise[step, i]) - visc * vr[i] - offs[i]
                if cog:
                    ph = cog["periods"] * r[i] + cog[f"phase_{i + 1}"]
                    drive -= cog[f"amp_{i + 1}"] * (math.sin(ph) + cog["h2"] * math.sin(2 * ph + 1.0)
                                                    + cog["h3"] * math.sin(3 * ph + 2.0))
                if gap:
                    d = r[i] - p[i]
                    tg = 0.0
                    if d > gap:
                        tg = max(0.0, kg * (d - gap) + cg * (vr[i] - vp[i]))
                    elif d < -gap:
                        tg = min(0.0, kg * (d + gap) + cg * (vr[i] - vp[i]))
                    drive -= tg
                    vp[i] += H * (tg - load[i]) / Jp
                    p[i] += H * vp[i]
                else:
                    drive -= load[i]
                # friction: static / kinetic level for the direction the motor would move in
                v_free = vr[i] + H * drive / Jr
                up = v_free > 0 if v_free != 0 else drive > 0
                level = dev.kc_dir[i][0 if up else 1]
                if strib:
                    level *= 1 + (strib["static_ratio"] - 1) * math.exp(-(abs(vr[i]) / strib["v_s"]) ** strib["shape"])
                if ripple:
                    level *= 1 + ripple["depth"] * math.sin(ripple["periods"] * r[i] + ripple["phase"])
                if cap:
                    level += cap["capstan"] * (cap["pretension"] + abs(load[i]))
                if lugre:      # bristles: F = s0 z + s1 dz/dt, z relaxing to its sliding value
                    s0 = level / lugre["z_ss"]
                    z_ss = math.copysign(lugre["z_ss"], vr[i]) if vr[i] else z[i]
                    z_new = z_ss + (z[i] - z_ss) * math.exp(-H * abs(vr[i]) / lugre["z_ss"])
                    f = s0 * z_new + 0.5 * math.sqrt(s0 * Jr) * (z_new - z[i]) / H
                    z[i] = z_new
                    vr[i] = vr[i] + H * (drive - f) / Jr
                else:
                    vr[i] = stick_or_slip(v_free, level, Jr)
                r[i] += H * vr[i]
            step += 1
    return cols


def apply_log_conditions(cols: dict[str, np.ndarray], cond: dict, rng: np.random.Generator, t0: float,
                         with_refs: bool, with_ankle: bool, t_session: float) -> dict[str, np.ndarray]:
    """What stands between the loop and the file: gauge calibration, drift, ADC and clipping, the ankle
    encoders' resolution and eccentricity, stale and dropped rows, a 500 Hz log, the time origin."""
    out = {k: v.copy() for k, v in cols.items()}
    n = len(out["t"])
    for ax in ("dp", "ie"):
        g = out[f"sg_torque_{ax}"]
        if "sg_gain" in cond:
            g *= cond["sg_gain"][ax]
        if "sg_offset" in cond:
            g += cond["sg_offset"][ax]
        if "sg_drift" in cond:
            d = cond["sg_drift"]
            g += d[ax] * (1 - np.exp(-(out["t"] + t_session) / d["tau"]))
        if "sg_clip" in cond:
            lim = cond["sg_clip"]["fraction"] * float(np.max(np.abs(g)))
            np.clip(g, -lim, lim, out=g)
        out[f"sg_torque_{ax}"] = np.round(g / 7.6e-3) * 7.6e-3          # 16-bit over +-250 N m
        a = out[f"ankle_{ax}"]
        if "encoder_eccentricity" in cond:
            ecc = cond["encoder_eccentricity"]
            a = a + ecc["amp"] * np.sin(a + ecc["phase"]) - ecc["amp"] * math.sin(ecc["phase"])
        out[f"ankle_{ax}"] = np.round(a / (2 * math.pi / 4096)) * (2 * math.pi / 4096)
    if "stale_rows" in cond:
        idx = np.flatnonzero(rng.random(n) < cond["stale_rows"]["fraction"])
        idx = idx[idx > 0]
        for key in ("motor_pos_1", "motor_pos_2", "sg_torque_dp", "sg_torque_ie", "ankle_dp", "ankle_ie"):
            out[key][idx] = out[key][idx - 1]
    keep = np.ones(n, bool)
    if "log_500" in cond:
        keep[1::2] = False
    if "dropouts" in cond:
        frac = cond["dropouts"]["fraction"]
        starts = rng.choice(n - 40, int(frac * n / 8) + 1, replace=False)
        for s in starts:
            keep[s + 1:s + 1 + int(rng.integers(2, 15))] = False
    names = ["t", "motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2", "sg_torque_dp", "sg_torque_ie"]
    names += ["ankle_dp", "ankle_ie"] if with_ankle else []
    names += ["ref_dp", "ref_ie"] if with_refs else []
    res = {k: out[k][keep] for k in names}
    res["t"] = res["t"] + t0
    return res


def make_case_d(seed: int, effects: list[str], conditions: list[str] = (), controller: str = "pd",
                motion: str = "multisine", ident_s: float = 20.0, valid_s: float = 10.0,
                with_refs: bool = False, with_ankle: bool = False) -> CaseD:
    """Simulate one case from its seed: effect and condition kinds are drawn at their own magnitudes."""
    rng = np.random.default_rng([seed, 41])
    fx = [draw_effect(kd, rng, motion) for kd in effects]
    cond = [draw_condition(kd, rng) for kd in conditions]
    cmap = {c["kind"]: c for c in cond}
    walking = motion == "walking"
    if controller == "pd":
        ctl = {"kind": "pd", "kp": rng.uniform(40, 100), "kd": rng.uniform(0.5, 2.5),
               "stance_gain": rng.uniform(1.0, 1.5)}
    else:
        ctl = {"kind": "impedance", "k_imp": rng.uniform(80, 250) if walking else rng.uniform(150, 500),
               "k_stance": rng.uniform(600, 1000), "k_ie": rng.uniform(80, 250), "b_imp": rng.uniform(1.0, 4.0)}
    ctl.update(ff=float(rng.choice([0.0, 0.5, 0.8])),
               clamp=rng.uniform(11.0, 14.0) if walking else rng.uniform(4.0, 5.0),     # walking needs the peak
               vel_cutoff=rng.uniform(40, 150), true_dt=bool(rng.random() < 0.5))
    body = rng.uniform(55, 95)
    gait = {"period": rng.uniform(1.0, 1.25), "peak": body * rng.uniform(1.0, 1.5),
            "ie_peak": body * rng.uniform(-0.12, 0.12), "push_off": rng.uniform(0.15, 0.3),
            "clearance": rng.uniform(0.05, 0.12), "ground_damping": rng.uniform(2.0, 5.0),
            "offset": rng.uniform(0, 1)} if walking else None
    rig = (0.0, 0.0) if walking or rng.random() < 0.35 else (rng.uniform(40, 200), rng.uniform(15, 80))
    dev = Device(np.random.default_rng([seed, 43]), fx, cmap)
    recs, t_session = [], rng.uniform(0.0, 5.0)
    for part, dur in (("ident", ident_s), ("valid", valid_s)):
        m = motion if part == "ident" or walking else str(rng.choice(["multisine", "chirp", "steps"]))
        cols = simulate(dev, rng, dur, t_session, ctl, m, cmap, gait, rig)
        cols = apply_log_conditions(cols, cmap, rng, float(rng.choice([0.0, rng.uniform(50, 3000)])), with_refs,
                                    with_ankle, t_session)
        recs.append(Recording(cols, f"d{seed}_{part}"))
        t_session += dur + rng.uniform(2.0, 10.0)
    words = sorted({d["kind"] for d in fx if d["kind"] in VOCAB})
    if any(d["kind"] in OUTSIDE for d in fx):
        words.append("unknown")
    return CaseD(seed, fx, cond, controller, motion, recs[0], recs[1], load_config(SIM_CONFIG),
                 tuple(words or ["none"]), any(c["kind"] in FLAGGED for c in cond))


def draw_case_d(seed: int) -> dict:
    """The benchmark's mix: 33 % one effect, 25 % two or three, 20 % calibration / sensor (alone or beside one
    effect), 8 % effect-free, 14 % outside the vocabulary (alone or beside one effect); 30 % walking-only
    logs; record lengths 15-30 s; real-log conditions (late ticks, a 500 Hz log, stale rows, encoder
    eccentricity) spread over all."""
    rng = np.random.default_rng([seed, 47])
    u = rng.random()
    vocab = sorted(VOCAB)
    effects: list[str] = []
    conditions: list[str] = []
    if u < 0.33:
        effects = [str(rng.choice(vocab))]
    elif u < 0.58:
        effects = [str(x) for x in rng.choice(vocab, int(rng.integers(2, 4)), replace=False)]
    elif u < 0.78:
        conditions = [str(rng.choice(sorted(FLAGGED)))]
        if rng.random() < 0.4:
            effects = [str(rng.choice(vocab))]
    elif u < 0.86:
        pass
    else:
        effects = [str(rng.choice(sorted(OUTSIDE)))]
        if rng.random() < 0.3:
            effects.append(str(rng.choice(vocab)))
    conditions += [q for q in sorted(QUIET) if rng.random() < {"late_ticks": 0.4, "log_500": 0.1}.get(q, 0.15)]
    motion = str(rng.choice(["multisine", "chirp", "steps", "walking"], p=[0.3, 0.2, 0.2, 0.3]))
    controller = str(rng.choice(["pd", "impedance"], p=[0.5, 0.5]))
    return {"seed": seed, "effects": effects, "conditions": conditions, "controller": controller, "motion": motion,
            "ident_s": float(rng.uniform(15, 30)), "valid_s": float(rng.uniform(6, 12)),
            "with_refs": bool(rng.random() < 0.3), "with_ankle": bool(rng.random() < 0.4)}


write_case_d = partial(write_case_c, prefix="d")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seeds", type=int, nargs="+")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for s in args.seeds:
        case = make_case_d(**draw_case_d(s))
        write_case_d(case, args.out)
        print(f"d{s}: causes {','.join(case.causes)}; flag expected {case.expect_flag}; {case.describe()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
