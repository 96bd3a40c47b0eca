"""Generator C: measured-data cases for `ankle-rt diagnose`, written without the diagnosis' or the other
generators' code (issue 21: "your generator must be the someone else").

The plant is integrated from docs/design.md's nominal model in generalised coordinates q = [theta_DP,
theta_IE, theta_1, theta_2]: the linear part (inertias, viscous damping, cable springs with their
stiffness-proportional damping) is discretised exactly (matrix exponential, 4 substeps per control tick,
one per distinct tick interval), the nonlinear forces (Coulomb friction, gravity, the effects, the
environment) enter as inputs averaged Heun-style over each substep. The controller runs on the sensors
as a real loop sees them (quantised encoders, noisy gauges, a filtered difference velocity) at the logged
instants, which may jitter; its set value acts from its own instant (plus an actuation latency when the
case has one, resolved to a substep) until the next.

Effects come in the forms a device brings, with this module's own parameters: a Stribeck breakaway of
exponent 0.8-2.2, Coulomb friction of its own size per direction and motor, friction proportional to each
motor's cable torque with a per-motor coefficient, rotor cogging of 6-24 periods per motor turn (x 81) with
a phase, amplitude and second harmonic per motor, a fractional actuation latency, slack and stiffening on
each cable's own stretch (m of cable) or per ankle axis, a constant load per motor. Two effects outside
the vocabulary (expected `unknown`): velocity-squared drag and a viscoelastic cable (a relaxing spring in
parallel). Calibration and sensor conditions (truth `none`, a data warning or calibration finding
expected): gauge zero offsets, a gauge gain error per axis, a torque-constant error, a motor-encoder scale
error, clipped gauges, held gauge samples, dropped rows, slow gauge drift; irregular sample times and a
500 Hz log are conditions that need no flag. The true baseline is perturbed (J, D, kc per motor, k, beta,
the foot) and its Coulomb smoothing is sharper than the nominal one.

    python benchmarks/diagnosis_cases_c.py SEED [SEED ...] --out DIR   # write the cases as interchange CSVs
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.linalg import expm

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from ankle_rt.config import Config, load_config  # noqa: E402
from ankle_rt.interchange import Recording, write_csv  # noqa: E402

SIM_CONFIG = Path(__file__).resolve().parent.parent / "config" / "sim.yaml"
GEAR = 81
RATED_TORQUE = 1.66 * 5.0                 # N m at the output: kt x continuous current
COUNTS = 116640                           # motor encoder counts per output turn
SUBSTEPS = 4

VOCAB = {"stribeck", "asymmetric_friction", "load_dependent_friction", "backlash", "cogging", "delay",
         "stiffness_nonlinear", "torque_offset"}
OUTSIDE = {"quadratic_drag", "viscoelastic_cable"}
#: calibration and sensor conditions: a data warning or calibration finding expected ("jitter" and
#: "rate_500", irregular stamps and a 500 Hz log, need none)
CALIBRATION = {"sg_offset", "sg_gain", "kt_error", "encoder_scale", "sg_clip", "sg_hold", "dropouts", "sg_drift"}


@dataclass
class CaseC:
    """One case: identification and validation recordings, the config diagnose gets, and the truth."""

    seed: int
    effects: list[dict]
    conditions: list[dict]
    controller: str
    motion: str
    ident: Recording
    valid: Recording
    nominal_cfg: Config
    causes: tuple[str, ...] = field(default=())
    expect_flag: bool = False

    def describe(self) -> str:
        def short(d: dict) -> str:
            return d["kind"] + "(" + ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                               for k, v in d.items() if k != "kind") + ")"
        return (f"{self.controller}/{self.motion}; effects: {'; '.join(map(short, self.effects)) or '-'}; "
                f"conditions: {'; '.join(map(short, self.conditions)) or '-'}")

    @property
    def kinds(self) -> list[str]:
        return [d["kind"] for d in self.effects + self.conditions]


class PlantC:
    """The compliant ankle with perturbed parameters and the case's effects (generalised coordinates)."""

    def __init__(self, rng: np.random.Generator, effects: list[dict]):
        u = lambda s: 1.0 + rng.uniform(-s, s)  # noqa: E731
        self.r, self.rdp, self.rie = 0.0127, 0.05715, 0.03175
        self.k = 218800.0 * u(0.1)
        self.beta = 6.5e-5 * u(0.3)
        self.J = [0.048 * u(0.12) for _ in range(2)]
        self.D = [0.112 * u(0.15) for _ in range(2)]
        self.kc = [0.28 * u(0.15) for _ in range(2)]
        self.veps = math.exp(rng.uniform(math.log(0.004), math.log(0.012)))
        self.I = [3.7486e-3 * u(0.1), 9.3452e-4 * u(0.1)]
        self.mgc = 0.465 * 9.81 * 0.0069
        self.K = np.diag([2 * self.k * self.rdp ** 2, self.k * self.rie ** 2])
        r = self.r
        self.R = np.array([[self.rdp, self.rie], [self.rdp, -self.rie]]) / r          # theta_m = R theta
        self.Rinv = np.linalg.inv(self.R)
        self.fx = {d["kind"]: d for d in effects}
        self.relax = np.zeros(2)           # viscoelastic branch's relaxed stretch (rad)
        P = np.hstack([-np.eye(2), self.Rinv])                                          # phi = P q
        Kq = P.T @ self.K @ P
        Dq = self.beta * Kq + np.diag([0.0, 0.0, *self.D])
        Minv = np.diag(1.0 / np.array([*self.I, *self.J]))
        self.A = np.block([[np.zeros((4, 4)), np.eye(4)], [-Minv @ Kq, -Minv @ Dq]])
        self.B = np.vstack([np.zeros((4, 4)), Minv])
        self._disc: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def discrete(self, h_us: int) -> tuple[np.ndarray, np.ndarray]:
        """Exact zero-order-hold discretisation of the linear part over h_us microseconds (cached)."""
        if h_us not in self._disc:
            n = 8
            big = np.zeros((n + 4, n + 4))
            big[:n, :n], big[:n, n:] = self.A, self.B
            e = expm(big * h_us * 1e-6)
            self._disc[h_us] = (e[:n, :n], e[:n, n:])
        return self._disc[h_us]

    def cable(self, phi: tuple[float, float]) -> tuple[float, float]:
        """Effective stretch (rad per axis) after slack and stiffening: what the cable springs act on."""
        bl, st = self.fx.get("backlash"), self.fx.get("stiffness_nonlinear")
        if bl is None and st is None:
            return phi
        per = (bl or st)["per"]
        if per == "cable":   # each cable's own stretch in m: s = r R phi
            s = [self.r * (self.R[i, 0] * phi[0] + self.R[i, 1] * phi[1]) for i in range(2)]
        else:
            s = [self.rdp * phi[0], self.rie * phi[1]]
        z = []
        for si in s:
            if bl is not None:
                h = bl["half_width"]
                si = si - h if si > h else (si + h if si < -h else 0.0)
            if st is not None:
                si = si * (1.0 + (abs(si) / st["hardening_stretch"]) ** (st["exponent"] - 1))
            z.append(si)
        if per == "cable":
            return (float(self.Rinv[0] @ z) / self.r, float(self.Rinv[1] @ z) / self.r)
        return (z[0] / self.rdp, z[1] / self.rie)

    def forces(self, x: list[float], tau_cmd: tuple[float, float],
               tau_env: tuple[float, float]) -> tuple[list[float], tuple[float, float]]:
        """Generalised nonlinear forces at state x and the joint torque the gauges see."""
        th, tm, w = x[0:2], x[2:4], x[6:8]
        Ri = self.Rinv
        phi = (Ri[0, 0] * tm[0] + Ri[0, 1] * tm[1] - th[0], Ri[1, 0] * tm[0] + Ri[1, 1] * tm[1] - th[1])
        dphi = (Ri[0, 0] * w[0] + Ri[0, 1] * w[1] - x[4], Ri[1, 0] * w[0] + Ri[1, 1] * w[1] - x[5])
        eff = self.cable(phi)
        Kd = (self.K[0, 0], self.K[1, 1])
        dtau = [Kd[a] * (eff[a] - phi[a]) for a in range(2)]
        ve = self.fx.get("viscoelastic_cable")
        if ve is not None:
            dtau = [dtau[a] + ve["ratio"] * Kd[a] * (phi[a] - self.relax[a]) for a in range(2)]
        tj = (Kd[0] * (phi[0] + self.beta * dphi[0]) + dtau[0], Kd[1] * (phi[1] + self.beta * dphi[1]) + dtau[1])
        tc = (Ri[0, 0] * tj[0] + Ri[1, 0] * tj[1], Ri[0, 1] * tj[0] + Ri[1, 1] * tj[1])    # R^-T tau_j
        motor = []
        for i in range(2):
            wi = w[i]
            sg = math.tanh(wi / self.veps)
            f = self.kc[i] * sg
            if (e := self.fx.get("stribeck")) is not None:
                f += e["static_excess"][i] * math.exp(-abs(wi / e["velocity"]) ** e["exponent"]) * sg
            if (e := self.fx.get("asymmetric_friction")) is not None:
                f += e["coulomb_plus"][i] * max(sg, 0.0) + e["coulomb_minus"][i] * min(sg, 0.0) - self.kc[i] * sg
            if (e := self.fx.get("load_dependent_friction")) is not None:
                f += e["coefficient"][i] * abs(tc[i]) * sg
            if (e := self.fx.get("cogging")) is not None:
                n = e["periods_per_motor_rev"] * GEAR
                f += (e["amplitude"][i] * math.sin(n * tm[i] + e["phase"][i])
                      + e["harmonic"][i] * math.sin(2 * n * tm[i] + e["harmonic_phase"][i]))
            if (e := self.fx.get("torque_offset")) is not None:
                f += e["torque"][i]
            if (e := self.fx.get("quadratic_drag")) is not None:
                f += e["coefficient"] * wi * abs(wi)
            motor.append(tau_cmd[i] - f - (Ri[0, i] * dtau[0] + Ri[1, i] * dtau[1]))
        foot = [tau_env[0] - self.mgc * math.sin(th[0]) + dtau[0], tau_env[1] + dtau[1]]
        return foot + motor, tj

    def step(self, x: np.ndarray, h_us: int, tau_cmd, tau_env) -> tuple[np.ndarray, tuple[float, float]]:
        """One substep: exact linear part, Heun average of the nonlinear forces."""
        Ad, Bd = self.discrete(h_us)
        lin = Ad @ x
        f0, tj = self.forces(x.tolist(), tau_cmd, tau_env)
        xp = lin + Bd @ np.array(f0)
        f1, _ = self.forces(xp.tolist(), tau_cmd, tau_env)
        xn = lin + Bd @ (0.5 * (np.array(f0) + np.array(f1)))
        if "viscoelastic_cable" in self.fx:
            T = self.fx["viscoelastic_cable"]["time_constant"]
            phi = self.Rinv @ xn[2:4] - xn[0:2]
            self.relax += (phi - self.relax) * (1.0 - math.exp(-h_us * 1e-6 / T))
        return xn, tj


# ---------------------------------------------------------------- experiments

def _multisine(rng: np.random.Generator, t: np.ndarray, f_lo: float, f_hi: float, n: int, amp: float) -> np.ndarray:
    f = np.exp(rng.uniform(math.log(f_lo), math.log(f_hi), n))
    a = rng.uniform(0.3, 1.0, n) / np.sqrt(f / f_lo)
    y = sum(ai * np.sin(2 * np.pi * fi * t + rng.uniform(0, 2 * np.pi)) for ai, fi in zip(a, f))
    return amp * y / max(1e-9, np.max(np.abs(y)))


def _gait(rng: np.random.Generator, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ankle DP angle of a stride (rad), stance flag, and the stance load (N m) for a walking bench."""
    stride = rng.uniform(1.0, 1.3)
    ph = (t / stride) % 1.0
    ang = (0.12 * np.sin(2 * np.pi * ph - 0.4) - 0.08 * np.sin(4 * np.pi * ph + 0.6)
           + 0.03 * np.sin(6 * np.pi * ph)) * rng.uniform(0.8, 1.2)
    stance = ph < 0.6
    peak = rng.uniform(8.0, 25.0)
    load = np.where(stance, -peak * np.sin(np.pi * ph / 0.6) ** 2 * (0.4 + ph / 0.6), 0.0)
    return ang, stance, load


def experiment(rng: np.random.Generator, t: np.ndarray, motion: str) -> dict:
    """Ankle references (rad), environment stiffness (N m/rad, per sample) and external load (N m)."""
    n = len(t)
    if motion == "multisine":
        ref = np.column_stack([_multisine(rng, t, 0.1, 2.5, 8, rng.uniform(0.08, 0.2)),
                               _multisine(rng, t, 0.1, 2.5, 8, rng.uniform(0.04, 0.1))])
        load = np.column_stack([_multisine(rng, t, 0.2, 4.0, 6, rng.uniform(1.0, 5.0)),
                                _multisine(rng, t, 0.2, 4.0, 6, rng.uniform(0.5, 2.0))])
        kenv = np.tile([rng.uniform(0, 60), rng.uniform(0, 20)], (n, 1))
    elif motion == "chirp":
        f0, f1, T = 0.05, rng.uniform(2.0, 4.0), t[-1] - t[0] + 1e-9
        tt = t - t[0]
        phase = 2 * np.pi * (f0 * tt + (f1 - f0) * tt ** 2 / (2 * T))
        ref = np.column_stack([rng.uniform(0.08, 0.18) * np.sin(phase),
                               rng.uniform(0.03, 0.08) * np.sin(1.3 * phase + 1.0)])
        load = np.column_stack([_multisine(rng, t, 0.1, 1.0, 4, rng.uniform(1.0, 4.0)),
                                _multisine(rng, t, 0.1, 1.0, 4, rng.uniform(0.3, 1.5))])
        kenv = np.tile([rng.uniform(10, 80), rng.uniform(5, 30)], (n, 1))
    elif motion == "steps":    # smoothed random steps with holds: rests, reversals, slow crossings
        m = max(3, int((t[-1] - t[0]) / rng.uniform(0.8, 1.6)))
        knots = np.linspace(t[0], t[-1], m)
        ref = np.column_stack([np.interp(t, knots, rng.uniform(-0.2, 0.2, m)),
                               np.interp(t, knots, rng.uniform(-0.08, 0.08, m))])
        k = max(1, int(0.15 / max(1e-4, np.median(np.diff(t)))))
        ref = np.column_stack([np.convolve(np.pad(c, (k, k), mode="edge"), np.ones(2 * k + 1) / (2 * k + 1),
                                           "valid") for c in ref.T])
        load = np.column_stack([_multisine(rng, t, 0.1, 3.0, 5, rng.uniform(2.0, 6.0)),
                                _multisine(rng, t, 0.1, 3.0, 5, rng.uniform(0.5, 2.0))])
        kenv = np.tile([rng.uniform(0, 40), rng.uniform(0, 15)], (n, 1))
    else:   # walking
        ang, stance, gl = _gait(rng, t)
        ref = np.column_stack([ang, 0.02 * np.sin(2 * np.pi * t / 1.15 + rng.uniform(0, 6))])
        load = np.column_stack([gl, 0.15 * gl * rng.uniform(-1, 1) + _multisine(rng, t, 0.3, 3.0, 3, 0.3)])
        kenv = np.column_stack([np.where(stance, rng.uniform(50, 150), 0.0),
                                np.where(stance, rng.uniform(10, 40), 0.0)])
    return {"ref": ref, "load": load, "kenv": kenv}


def sample_times(rng: np.random.Generator, duration: float, period: float, jitter: bool) -> np.ndarray:
    """Tick instants in whole microseconds: regular, or jittered with occasional late cycles."""
    n = int(duration / period)
    d = np.full(n, period)
    if jitter:
        d = period * np.clip(1 + rng.normal(0, rng.uniform(0.03, 0.12), n), 0.5, 1.6)
        late = rng.random(n) < period * rng.uniform(0.5, 2.0)
        d[late] += period * rng.uniform(1.0, 3.0, late.sum())
    us = np.maximum(np.round(d * 1e6).astype(np.int64), 100)
    return np.concatenate([[0], np.cumsum(us)[:-1]])


def simulate(plant: PlantC, rng: np.random.Generator, duration: float, ctl: dict, motion: str,
             conditions: dict, period: float) -> dict[str, np.ndarray]:
    """Run the loop: sensors -> controller -> clamp -> set value held until the next tick (+ latency)."""
    t_us = sample_times(rng, duration, period, "jitter" in conditions)
    t = t_us * 1e-6
    ex = experiment(rng, t, motion)
    enc = conditions.get("encoder_scale", {}).get("scale", 1.0)
    ankle_bits = int(rng.choice([14, 16, 17]))
    q_m, q_a = 2 * np.pi / COUNTS, 2 * np.pi / 2 ** ankle_bits
    kt_true = [1.66 * s for s in conditions.get("kt_error", {}).get("scale", (1.0, 1.0))]
    sg_noise = rng.uniform(0.01, 0.03)
    delay_us = int(round(plant.fx["delay"]["delay"] * 1e6)) if "delay" in plant.fx else 0
    x = np.zeros(8)
    x[0:2] = ex["ref"][0]
    x[2:4] = plant.R @ ex["ref"][0]
    n = len(t)
    out = {k: np.zeros(n) for k in ("m1", "m2", "i1", "i2", "tj_dp", "tj_ie", "a_dp", "a_ie")}
    R, Ri = plant.R, plant.Rinv
    v_hat = np.zeros(2)
    prev = None
    alpha = math.exp(-2 * math.pi * ctl["vel_cutoff"] * period)
    history: list[tuple[int, tuple[float, float]]] = [(-10 ** 9, (0.0, 0.0))]
    tj = (0.0, 0.0)
    for k in range(n):
        # sensors at t_k
        mpos = np.round(x[2:4] * enc / q_m) * q_m
        apos = np.round(x[0:2] / q_a) * q_a
        if prev is not None:
            dtk = (t_us[k] - t_us[k - 1]) * 1e-6 if ctl["true_dt"] else period
            v_hat = alpha * v_hat + (1 - alpha) * (mpos - prev) / dtk
        prev = mpos
        th_ref = ex["ref"][k]
        if ctl["kind"] == "pd":
            tau = ctl["kp"] * (R @ th_ref - mpos) - ctl["kd"] * v_hat
        else:   # ankle impedance on the motor-estimated ankle angle, mapped to the motors by R^-T
            th_hat = Ri @ mpos
            w_hat = Ri @ v_hat
            tau_a = -ctl["k_imp"] * (th_hat - th_ref) - ctl["b_imp"] * w_hat
            tau = Ri.T @ tau_a
        tau = tau + ctl["ff"] * 0.28 * np.tanh(v_hat / 0.05)
        cur = np.clip(tau / 1.66, -ctl["clamp"], ctl["clamp"])
        out["m1"][k], out["m2"][k] = mpos
        out["a_dp"][k], out["a_ie"][k] = apos
        out["i1"][k], out["i2"][k] = cur
        out["tj_dp"][k], out["tj_ie"][k] = tj
        if k == n - 1:
            break
        applied = np.round(cur / 0.0049) * 0.0049 + rng.normal(0, 0.004, 2)
        history.append((int(t_us[k]) + delay_us, (kt_true[0] * applied[0], kt_true[1] * applied[1])))
        span = int(t_us[k + 1] - t_us[k])
        hs = [span // SUBSTEPS + (1 if j < span % SUBSTEPS else 0) for j in range(SUBSTEPS)]
        ts = int(t_us[k])
        for h in hs:
            while len(history) > 1 and history[1][0] <= ts:
                history.pop(0)
            env = (ex["load"][k, 0] - ex["kenv"][k, 0] * (x[0] - th_ref[0]) - 0.5 * x[4],
                   ex["load"][k, 1] - ex["kenv"][k, 1] * (x[1] - th_ref[1]) - 0.1 * x[5])
            x, tj = plant.step(x, h, history[0][1], env)
            ts += h
        _, tj = plant.forces(x.tolist(), (0, 0), (0, 0))
        if not np.all(np.isfinite(x)) or abs(x[0]) > 0.7 or abs(x[1]) > 0.7:
            raise RuntimeError(f"plant left its range at t = {t[k]:.3f} s")
    sg = np.column_stack([out["tj_dp"], out["tj_ie"]]) + rng.normal(0, sg_noise, (n, 2))
    return {"t": t, "motor_pos_1": out["m1"], "motor_pos_2": out["m2"], "current_cmd_1": out["i1"],
            "current_cmd_2": out["i2"], "sg_torque_dp": sg[:, 0], "sg_torque_ie": sg[:, 1],
            "ankle_dp": out["a_dp"], "ankle_ie": out["a_ie"], "ref_dp": ex["ref"][:, 0], "ref_ie": ex["ref"][:, 1]}


def apply_sensor_conditions(cols: dict[str, np.ndarray], conditions: dict, rng: np.random.Generator,
                            t0: float, with_refs: bool) -> dict[str, np.ndarray]:
    """Gauge offsets, gains, drift, clipping, held samples and dropped rows, as the logger records them."""
    t = cols["t"]
    for a, name in enumerate(("sg_torque_dp", "sg_torque_ie")):
        y = cols[name]
        if (c := conditions.get("sg_gain")) is not None:
            y = y * c["gain"][a]
        if (c := conditions.get("sg_offset")) is not None:
            y = y + c["offset"][a]
        if (c := conditions.get("sg_drift")) is not None:
            span = t[-1] - t[0]
            y = y + c["size"][a] * np.sin(np.pi * (t - t[0]) / (span * c["shape"][a]))
        if (c := conditions.get("sg_clip")) is not None and a == c["axis"]:
            hi = c["level"] * np.max(np.abs(y))
            y = np.clip(y, -hi, hi) if c["both"] else (np.minimum(y, hi) if np.max(y) > -np.min(y)
                                                        else np.maximum(y, -hi))
        if (c := conditions.get("sg_hold")) is not None:
            for start in rng.integers(100, len(y) - 100, c["bursts"]):
                y[start:start + c["length"]] = y[start]
        cols[name] = np.round(y / 0.0076) * 0.0076       # 16-bit ADC over +-250 N m
    keep = np.ones(len(t), bool)
    if (c := conditions.get("dropouts")) is not None:
        for start in rng.integers(50, len(t) - 200, c["count"]):
            keep[start:start + int(rng.integers(5, 60))] = False
    out = {k: v[keep] for k, v in cols.items() if with_refs or not k.startswith("ref_")}
    out["t"] = out["t"] + t0
    return out


# ---------------------------------------------------------------- drawing cases

def draw_effect(kind: str, rng: np.random.Generator, motion: str) -> dict:
    """One effect at a plausible magnitude for this hardware, in this module's own parameters."""
    two = lambda lo, hi: [float(rng.uniform(lo, hi)) for _ in range(2)]  # noqa: E731
    if kind == "stribeck":
        vs = rng.uniform(0.08, 0.3) if motion == "walking" else rng.uniform(0.04, 0.25)
        base = rng.uniform(0.08, 0.22)
        return {"kind": kind, "static_excess": [base * rng.uniform(0.85, 1.15) for _ in range(2)],
                "velocity": float(vs), "exponent": float(rng.uniform(0.8, 2.2))}
    if kind == "asymmetric_friction":
        out = {"kind": kind, "coulomb_plus": [], "coulomb_minus": []}
        for _ in range(2):
            d = rng.uniform(0.2, 0.45) * rng.choice([-1, 1]) * 0.28
            out["coulomb_plus"].append(0.28 + d)
            out["coulomb_minus"].append(0.28 - d)
        return out
    if kind == "load_dependent_friction":
        mu = rng.uniform(0.04, 0.12)
        return {"kind": kind, "coefficient": [mu * rng.uniform(0.9, 1.1) for _ in range(2)]}
    if kind == "cogging":
        amp = rng.uniform(0.012, 0.03) * RATED_TORQUE
        return {"kind": kind, "periods_per_motor_rev": int(rng.choice([6, 12, 14, 18, 24])),
                "amplitude": [amp * rng.uniform(0.7, 1.3) for _ in range(2)], "phase": two(0, 2 * np.pi),
                "harmonic": [amp * rng.uniform(0.1, 0.4) for _ in range(2)], "harmonic_phase": two(0, 2 * np.pi)}
    if kind == "delay":
        return {"kind": kind, "delay": float(rng.uniform(0.0025, 0.009))}
    if kind == "backlash":
        return {"kind": kind, "half_width": float(rng.uniform(6e-5, 2.5e-4)), "per": str(rng.choice(["cable", "axis"]))}
    if kind == "stiffness_nonlinear":
        return {"kind": kind, "hardening_stretch": float(rng.uniform(6e-4, 1.5e-3)),
                "exponent": int(rng.choice([3, 3, 2])), "per": str(rng.choice(["cable", "axis"]))}
    if kind == "torque_offset":
        return {"kind": kind, "torque": [float(rng.uniform(0.12, 0.4) * rng.choice([-1, 1])) for _ in range(2)]}
    if kind == "quadratic_drag":
        return {"kind": kind, "coefficient": float(rng.uniform(0.015, 0.04))}
    if kind == "viscoelastic_cable":
        return {"kind": kind, "ratio": float(rng.uniform(0.15, 0.3)), "time_constant": float(rng.uniform(0.2, 1.0))}
    raise ValueError(kind)


def draw_condition(kind: str, rng: np.random.Generator) -> dict:
    """A calibration or sensor condition (truth unchanged; a flag expected for those in CALIBRATION)."""
    sign = lambda: float(rng.choice([-1, 1]))  # noqa: E731
    if kind == "sg_offset":
        return {"kind": kind, "offset": [sign() * rng.uniform(0.1, 0.6), sign() * rng.uniform(0.05, 0.4)]}
    if kind == "sg_gain":
        return {"kind": kind, "gain": [1 + sign() * rng.uniform(0.05, 0.1), 1 + sign() * rng.uniform(0.05, 0.1)]}
    if kind == "kt_error":
        s = 1 + sign() * rng.uniform(0.07, 0.12)
        return {"kind": kind, "scale": (s, s * rng.uniform(0.98, 1.02))}
    if kind == "encoder_scale":
        return {"kind": kind, "scale": 1 + sign() * rng.uniform(0.01, 0.025)}
    if kind == "sg_clip":
        return {"kind": kind, "axis": int(rng.integers(0, 2)), "level": float(rng.uniform(0.6, 0.85)),
                "both": bool(rng.random() < 0.5)}
    if kind == "sg_hold":
        return {"kind": kind, "bursts": int(rng.integers(4, 12)), "length": int(rng.integers(10, 40))}
    if kind == "dropouts":
        return {"kind": kind, "count": int(rng.integers(3, 10))}
    if kind == "sg_drift":
        return {"kind": kind, "size": [sign() * rng.uniform(0.15, 0.5), sign() * rng.uniform(0.1, 0.3)],
                "shape": [float(rng.uniform(1.0, 2.0)), float(rng.uniform(1.0, 2.0))]}
    return {"kind": kind}


def make_case_c(seed: int, effects: list[str], conditions: list[str] = (), controller: str = "pd",
                motion: str = "multisine", ident_s: float = 20.0, valid_s: float = 10.0,
                with_refs: bool = False) -> CaseC:
    """Simulate one case from its seed: effect and condition kinds are drawn at their own magnitudes."""
    rng = np.random.default_rng(seed)
    fx = [draw_effect(k, rng, motion) for k in effects]
    cond = [draw_condition(k, rng) for k in conditions]
    cmap = {c["kind"]: c for c in cond}
    period = 0.002 if "rate_500" in cmap else 0.001
    if controller == "pd":
        ctl = {"kind": "pd", "kp": rng.uniform(40, 100), "kd": rng.uniform(0.5, 2.5)}
    else:
        ctl = {"kind": "impedance", "k_imp": rng.uniform(60, 200), "b_imp": rng.uniform(1.0, 4.0)}
    ctl.update(ff=float(rng.choice([0.0, 0.5, 0.8])), clamp=float(rng.uniform(4.0, 5.0)),
               vel_cutoff=float(rng.uniform(40, 150)), true_dt=bool(rng.random() < 0.5))
    recs = []
    for part, dur in (("ident", ident_s), ("valid", valid_s)):
        plant = PlantC(np.random.default_rng([seed, 7]), fx)      # one device for both records
        m = motion if part == "ident" or motion == "walking" else str(rng.choice(["multisine", "chirp", "steps"]))
        cols = simulate(plant, rng, dur, ctl, m, cmap, period)
        t0 = float(rng.choice([0.0, rng.uniform(100, 5000)]))
        cols = apply_sensor_conditions(cols, cmap, rng, t0, with_refs)
        recs.append(Recording(cols, f"c{seed}_{part}"))
    words = sorted({d["kind"] for d in fx if d["kind"] in VOCAB})
    if any(d["kind"] in OUTSIDE for d in fx):
        words.append("unknown")
    return CaseC(seed, fx, cond, controller, motion, recs[0], recs[1], load_config(SIM_CONFIG),
                 tuple(words or ["none"]), any(c["kind"] in CALIBRATION for c in cond))


def draw_case_c(seed: int) -> dict:
    """The benchmark's mix: 35 % one effect, 27 % two or three, 20 % calibration / sensor (alone or beside
    one effect), 8 % effect-free, 10 % outside the vocabulary; record lengths 15-30 s."""
    rng = np.random.default_rng([seed, 3])
    u = rng.random()
    vocab = sorted(VOCAB)
    effects: list[str] = []
    conditions: list[str] = []
    if u < 0.35:
        effects = [str(rng.choice(vocab))]
    elif u < 0.62:
        effects = [str(x) for x in rng.choice(vocab, int(rng.integers(2, 4)), replace=False)]
    elif u < 0.82:
        conditions = [str(rng.choice(sorted(CALIBRATION)))]
        if rng.random() < 0.4:
            effects = [str(rng.choice(vocab))]
    elif u < 0.90:
        pass
    else:
        effects = [str(rng.choice(sorted(OUTSIDE)))]
    if rng.random() < 0.25:
        conditions.append("jitter")
    elif rng.random() < 0.08:
        conditions.append("rate_500")
    motion = str(rng.choice(["multisine", "chirp", "steps", "walking"], p=[0.35, 0.2, 0.2, 0.25]))
    controller = str(rng.choice(["pd", "impedance"], p=[0.6, 0.4]))
    return {"seed": seed, "effects": effects, "conditions": conditions, "controller": controller, "motion": motion,
            "ident_s": float(rng.uniform(15, 30)), "valid_s": float(rng.uniform(6, 12)),
            "with_refs": bool(rng.random() < 0.3)}


def write_case_c(case: CaseC, directory: Path, prefix: str = "c") -> tuple[Path, Path]:
    """The case's two recordings as interchange CSVs (<prefix><seed>_ident.csv, <prefix><seed>_valid.csv)."""
    paths = []
    for part, rec in (("ident", case.ident), ("valid", case.valid)):
        p = directory / f"{prefix}{case.seed}_{part}.csv"
        write_csv(p, rec.columns)
        paths.append(p)
    return paths[0], paths[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seeds", type=int, nargs="+")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for s in args.seeds:
        case = make_case_c(**draw_case_c(s))
        write_case_c(case, args.out)
        print(f"c{s}: causes {','.join(case.causes)}; flag expected {case.expect_flag}; {case.describe()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
