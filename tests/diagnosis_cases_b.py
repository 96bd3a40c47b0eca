"""Generator B of diagnosis cases: a second, structurally different source of test data (issue 21).

Generator A (tests/diagnosis_cases.py) runs the project's simulator with the project's effect classes,
so the data share the diagnosis' parametrisation of every effect. Generator B shares none of that code:
it integrates the compliant model (docs/design.md: two motors, Bowden cables, the foot) with its own
equations in generalised coordinates and its own integrator (semi-implicit Euler, 10 substeps per
sample), and writes each effect in a form a real device brings rather than the one the diagnosis fits:

- cogging per motor: its own amplitude and phase on each motor, a second harmonic with its own phase,
  14 or 24 periods per motor revolution through the 81:1 gearbox (1134 / 1944 per output turn);
- Stribeck friction with a shape exponent (``exp(-|w/vs|^delta)``, delta 1 or 2), a Coulomb asymmetry of
  its own size per motor, load-dependent friction on the cable torque each motor feels;
- a transport delay of whole samples; backlash as a dead zone per cable (m of cable) or per ankle axis;
  stiffening ``k (1 + |s|/s0)`` (per axis) instead of the cubic form; constant loads per motor;
- calibration and sensor conditions that are not physics: a strain-gauge zero offset, a torque-constant
  error of ~10 %, an encoder scale error, clipped gauges (truth ``none``, a finding expected);
- walking-only logs (a stride-periodic stance load), the ankle impedance controller beside the motor PD,
  irregular sample times (jittered periods, occasional late cycles: the plant runs over the real interval,
  the log records the real instants).

Ground truth per case: the set of cause words (docs/design.md vocabulary) and whether a data warning or
calibration finding is expected (:attr:`CaseB.expect_flag`). :func:`draw_case_b` gives the benchmark's mix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ankle_rt.config import Config, load_config
from ankle_rt.interchange import Recording, write_csv

SIM_CONFIG = Path(__file__).resolve().parent.parent / "config" / "sim.yaml"
SUBSTEPS = 10
CURRENT_NOISE_A = 0.005          # A rms, amplifier current ripple
ANKLE_COUNTS_PER_REV = 2 ** 18   # joint encoders of a bench (absolute, 18 bit)
CONTROLLER_CLAMP_A = 5.0         # A, the controller's clamp (the amplifier's peak is higher)
GEAR = 81

#: physical effects: cause word of each kind
WORDS = {"cogging": "cogging", "stribeck": "stribeck", "asymmetric_friction": "asymmetric_friction",
         "load_dependent_friction": "load_dependent_friction", "delay": "delay", "backlash": "backlash",
         "stiffening": "stiffness_nonlinear", "torque_offset": "torque_offset"}
#: calibration and sensor conditions: truth ``none``, a finding expected
CALIBRATIONS = ("sg_offset", "kt_error", "encoder_scale", "sg_clip")


@dataclass
class CaseB:
    seed: int
    causes: tuple[str, ...]            # sorted vocabulary words, ("none",) when only calibrations
    conditions: list[dict]             # what made the data (effects and calibrations, this module's forms)
    controller: str                    # "pd" or "impedance"
    motion: str                        # "multisine" or "walking"
    jitter: bool
    nominal_cfg: Config
    ident: Recording
    valid: Recording
    expect_flag: bool = False          # a data warning / calibration finding is expected
    kinds: tuple[str, ...] = field(default=())

    def describe(self) -> str:
        return (f"seed={self.seed} causes={list(self.causes)} controller={self.controller} motion={self.motion} "
                f"jitter={self.jitter} conditions={self.conditions}")


class Plant:
    """The compliant model's numbers (perturbed truth) as plain floats, and its conditions."""

    def __init__(self, cfg: Config, conditions: list[dict], rng: np.random.Generator):
        a, tr, foot = cfg["actuator"], cfg["transmission"], cfg["foot"]
        pert = lambda: 1.0 + rng.uniform(-0.15, 0.15)   # noqa: E731
        self.J, self.D, self.kc = a["inertia"] * pert(), a["damping"] * pert(), a["coulomb"] * pert()
        self.ve = a["friction_smoothing_velocity"]
        k = tr["cable_stiffness"] * pert()
        r, ldp, lie = tr["pulley_radius"], tr["lever_dp"], tr["lever_ie"]
        self.r, self.ldp, self.lie = r, ldp, lie
        self.K = (2.0 * k * ldp ** 2, k * lie ** 2)             # N m/rad per ankle axis
        R = np.array([[ldp, lie], [ldp, -lie]]) / r
        self.Ri = np.linalg.inv(R)
        # per-cable stretch s = r R phi (m) and the cable-space stiffness that gives K phi back
        self.C = r * R
        Ci = np.linalg.inv(self.C)
        self.Kc = Ci.T @ np.diag(self.K) @ Ci
        self.beta = tr["stiffness_proportional_damping"]
        self.I = (foot["inertia_dp"], foot["inertia_ie"])
        self.grav = foot["mass"] * 9.81 * foot["com_dp"]
        self.kt_cfg = a["torque_constant"]
        self.kt = self.kt_cfg
        self.counts = a["encoder_counts_per_rev"] / (2 * math.pi)
        self.sg_noise = cfg["sensors"]["strain_gauge_noise_rms"]
        self.peak = cfg["amplifier"]["current_limit_peak"]
        self.cond = {c["kind"]: c for c in conditions}
        if "kt_error" in self.cond:
            self.kt = self.kt_cfg * self.cond["kt_error"]["factor"]

    # -- cable side: joint torque from the stretch (N m per ankle axis) ------------------------------
    def spring(self, p0: float, p1: float) -> tuple[float, float]:
        bl, st = self.cond.get("backlash"), self.cond.get("stiffening")
        if bl is not None and bl["form"] == "cable":
            C, Kc, b = self.C, self.Kc, bl["half_width"]
            s = (C[0, 0] * p0 + C[0, 1] * p1, C[1, 0] * p0 + C[1, 1] * p1)
            z = tuple(x - b if x > b else (x + b if x < -b else 0.0) for x in s)
            if st is not None:  # each cable stiffens on its own taut stretch, k (1 + |z| / s0)
                z = tuple(x * (1.0 + abs(x) / st["s0"]) for x in z)
            f0 = Kc[0, 0] * z[0] + Kc[0, 1] * z[1]
            f1 = Kc[1, 0] * z[0] + Kc[1, 1] * z[1]
            return C[0, 0] * f0 + C[1, 0] * f1, C[0, 1] * f0 + C[1, 1] * f1
        if bl is not None:
            b0, b1 = bl["half_width"] / self.ldp, bl["half_width"] / self.lie
            p0 = p0 - b0 if p0 > b0 else (p0 + b0 if p0 < -b0 else 0.0)
            p1 = p1 - b1 if p1 > b1 else (p1 + b1 if p1 < -b1 else 0.0)
        t0, t1 = self.K[0] * p0, self.K[1] * p1
        if st is not None:      # k (1 + |s| / s0), s0 in m of cable
            t0 *= 1.0 + abs(p0) * self.ldp / st["s0"]
            t1 *= 1.0 + abs(p1) * self.lie / st["s0"]
        return t0, t1

    # -- motor side: resisting torque of friction and effects (N m at the gearbox output) -------------
    def resist(self, i: int, th: float, w: float, tc: float) -> float:
        c = self.cond
        sgn = math.tanh(w / self.ve)
        out = self.D * w + self.kc * sgn
        if "stribeck" in c:
            e = c["stribeck"]
            out += e["excess"] * math.exp(-abs(w / e["velocity"]) ** e["exponent"]) * sgn
        if "asymmetric_friction" in c:        # kc+ = kc + d, kc- = kc - d, own d per motor
            out += c["asymmetric_friction"]["d"][i] * abs(sgn)
        if "load_dependent_friction" in c:
            out += c["load_dependent_friction"]["mu"] * abs(tc) * sgn
        if "cogging" in c:
            e = c["cogging"]
            n = e["periods"]
            out += e["amplitude"][i] * (math.sin(n * th + e["phase"][i])
                                        + e["harmonic"] * math.sin(2 * n * th + e["phase2"][i]))
        if "torque_offset" in c:
            out += c["torque_offset"]["torque"][i]
        return out


def _gait_phase(rng: np.random.Generator, t: np.ndarray) -> np.ndarray:
    """Stride phase (rad, 2 pi per stride) of steady walking: a stride of 1.0-1.25 s varying a little."""
    stride = rng.uniform(1.0, 1.25)
    return 2 * np.pi * t / stride + 0.25 * np.sin(2 * np.pi * t / rng.uniform(6.0, 11.0) + rng.uniform(0, 6.3))


def _multisine(rng: np.random.Generator, t: np.ndarray, f_lo: float, f_hi: float, n: int, rms: float) -> np.ndarray:
    f = np.exp(rng.uniform(np.log(f_lo), np.log(f_hi), n))
    a = rng.uniform(0.5, 1.0, n) / np.sqrt(f)
    x = (a[None, :] * np.sin(2 * np.pi * f[None, :] * t[:, None] + rng.uniform(0, 2 * np.pi, n)[None, :])).sum(1)
    return rms * x / max(float(np.std(x)), 1e-12)


def excitation(rng: np.random.Generator, t: np.ndarray, motion: str) -> tuple[np.ndarray, np.ndarray]:
    """(ankle reference angles [DP, IE] rad, ankle load torque [DP, IE] N m) over the times ``t``."""
    fade = np.minimum(1.0, t / 0.8)[:, None]
    if motion == "walking":
        ph = _gait_phase(rng, t)
        stance = np.clip(np.sin(ph), 0.0, None)            # the foot on the ground half the stride
        push = np.clip(np.sin(2 * ph - 0.6), 0.0, None) * stance
        ref = np.column_stack([0.06 * np.sin(ph + 0.4) + 0.035 * np.sin(2 * ph + 1.1) - 0.02 * push,
                               0.025 * np.sin(ph + 2.0) + 0.01 * np.sin(3 * ph)])
        load = np.column_stack([rng.uniform(3.0, 6.0) * (stance ** 2 + 0.8 * push),
                                rng.uniform(0.8, 2.0) * stance * np.sin(ph + rng.uniform(0, 6.3))])
        load -= load.mean(0)                                # the stance load is carried about the mean
        load += 0.3 * np.column_stack([_multisine(rng, t, 0.3, 5.0, 5, 1.0), _multisine(rng, t, 0.3, 5.0, 5, 0.5)])
    else:
        ref = np.column_stack([_multisine(rng, t, 0.15, 2.5, 6, 0.1), _multisine(rng, t, 0.15, 2.5, 6, 0.05)])
        load = np.column_stack([_multisine(rng, t, 0.2, 5.0, 6, 3.0), _multisine(rng, t, 0.2, 5.0, 6, 1.5)])
    return ref * fade, load * fade


def sample_times(rng: np.random.Generator, n: int, dt: float, jitter: bool) -> np.ndarray:
    """Sample instants (s): regular, or with jittered periods (+-10 %) and a late cycle (1.5-3 periods)
    about once a second, as a loop without real-time scheduling gives them."""
    if not jitter:
        return np.arange(n) * dt
    steps = dt * (1.0 + rng.uniform(-0.1, 0.1, n))
    late = rng.uniform(size=n) < 1e-3
    steps[late] = dt * rng.uniform(1.5, 3.0, int(late.sum()))
    return np.concatenate([[0.0], np.cumsum(steps[:-1])])


def simulate_b(plant: Plant, rng: np.random.Generator, duration_s: float, controller: str, motion: str,
               jitter: bool, dt: float = 1e-3) -> Recording:
    """One experiment in interchange columns: the controller samples the sensors, its set current is
    held over the (possibly irregular) interval while the plant is integrated over it."""
    n = int(round(duration_s / dt))
    t = sample_times(rng, n, dt, jitter)
    ref, load = excitation(rng, t, motion)
    c = plant.cond
    delay = c["delay"]["ticks"] if "delay" in c else 0
    sg_off = c["sg_offset"]["offset"] if "sg_offset" in c else (0.0, 0.0)
    enc = c["encoder_scale"]["factor"] if "encoder_scale" in c else 1.0
    Ri, K, I, beta, J = plant.Ri, plant.K, plant.I, plant.beta, plant.J
    r00, r01, r10, r11 = (float(x) for x in Ri.ravel())
    mref = ref @ np.linalg.inv(Ri).T          # motor references for rigid cables
    noise_i = CURRENT_NOISE_A * rng.standard_normal((n, 2))
    noise_sg = plant.sg_noise * rng.standard_normal((n, 2))
    cols = {k: np.empty(n) for k in ("motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2",
                                     "sg_torque_dp", "sg_torque_ie", "ankle_dp", "ankle_ie")}
    q = [0.0, 0.0, 0.0, 0.0]      # theta_dp, theta_ie, theta_1, theta_2
    v = [0.0, 0.0, 0.0, 0.0]
    queue = [(0.0, 0.0)] * delay
    prev_m = (0.0, 0.0)
    w_est = [0.0, 0.0]
    ka = 2 * math.pi / ANKLE_COUNTS_PER_REV
    kt_cfg, kt = plant.kt_cfg, plant.kt
    kp, kd = rng.uniform(60.0, 90.0), rng.uniform(1.0, 2.0)
    ks = (rng.uniform(25.0, 50.0), rng.uniform(10.0, 25.0))     # impedance, N m/rad
    bs = (rng.uniform(0.2, 0.5), rng.uniform(0.05, 0.15))        # N m s/rad
    tau_j = (0.0, 0.0)
    for k in range(n):
        h_tick = (t[k + 1] - t[k]) if k + 1 < n else dt
        # sensors
        m1 = math.floor(q[2] * plant.counts) / plant.counts * enc
        m2 = math.floor(q[3] * plant.counts) / plant.counts * enc
        sg0 = tau_j[0] + sg_off[0] + noise_sg[k, 0]
        sg1 = tau_j[1] + sg_off[1] + noise_sg[k, 1]
        a0, a1 = math.floor(q[0] / ka) * ka, math.floor(q[1] / ka) * ka
        h_prev = t[k] - t[k - 1] if k else dt
        for i, m in enumerate((m1, m2)):         # first-order filtered finite difference (50 Hz)
            w_est[i] += (1.0 - math.exp(-2 * math.pi * 50.0 * h_prev)) * ((m - prev_m[i]) / h_prev - w_est[i])
        prev_m = (m1, m2)
        # controller (configured torque constant), clamped
        if controller == "pd":
            u1 = (kp * (mref[k, 0] - m1) - kd * w_est[0]) / kt_cfg
            u2 = (kp * (mref[k, 1] - m2) - kd * w_est[1]) / kt_cfg
        else:
            e0 = r00 * m1 + r01 * m2 - sg0 / K[0]
            e1 = r10 * m1 + r11 * m2 - sg1 / K[1]
            d0 = r00 * w_est[0] + r01 * w_est[1]
            d1 = r10 * w_est[0] + r11 * w_est[1]
            ta0 = ks[0] * (ref[k, 0] - e0) - bs[0] * d0
            ta1 = ks[1] * (ref[k, 1] - e1) - bs[1] * d1
            u1 = (r00 * ta0 + r10 * ta1) / kt_cfg          # R^-T tau_ankle
            u2 = (r01 * ta0 + r11 * ta1) / kt_cfg
        u1 = max(-CONTROLLER_CLAMP_A, min(CONTROLLER_CLAMP_A, u1))
        u2 = max(-CONTROLLER_CLAMP_A, min(CONTROLLER_CLAMP_A, u2))
        for name, val in zip(cols, (m1, m2, u1, u2, sg0, sg1, a0, a1)):
            cols[name][k] = val
        # the amplifier: delayed set value, its peak, its ripple, the true torque constant
        queue.append((u1, u2))
        d1_, d2_ = queue.pop(0)
        i1 = max(-plant.peak, min(plant.peak, d1_)) + noise_i[k, 0]
        i2 = max(-plant.peak, min(plant.peak, d2_)) + noise_i[k, 1]
        tm1, tm2 = kt * i1, kt * i2
        ld0, ld1 = float(load[k, 0]), float(load[k, 1])
        h = h_tick / SUBSTEPS
        for _ in range(SUBSTEPS):
            p0 = r00 * q[2] + r01 * q[3] - q[0]
            p1 = r10 * q[2] + r11 * q[3] - q[1]
            dp0 = r00 * v[2] + r01 * v[3] - v[0]
            dp1 = r10 * v[2] + r11 * v[3] - v[1]
            s0, s1 = plant.spring(p0, p1)
            j0, j1 = s0 + beta * K[0] * dp0, s1 + beta * K[1] * dp1
            tc1, tc2 = r00 * j0 + r10 * j1, r01 * j0 + r11 * j1      # R^-T tau_j: what each motor feels
            acc = ((j0 + ld0 - plant.grav * math.sin(q[0])) / I[0], (j1 + ld1) / I[1],
                   (tm1 - tc1 - plant.resist(0, q[2], v[2], tc1)) / J,
                   (tm2 - tc2 - plant.resist(1, q[3], v[3], tc2)) / J)
            for i in range(4):                   # semi-implicit (symplectic) Euler
                v[i] += h * acc[i]
                q[i] += h * v[i]
        p0 = r00 * q[2] + r01 * q[3] - q[0]
        p1 = r10 * q[2] + r11 * q[3] - q[1]
        s0, s1 = plant.spring(p0, p1)
        tau_j = (s0 + beta * K[0] * (r00 * v[2] + r01 * v[3] - v[0]),
                 s1 + beta * K[1] * (r10 * v[2] + r11 * v[3] - v[1]))
    if "sg_clip" in c:    # the logging amplifier's range: the log clips, the controller's own reading does not
        for name, share in zip(("sg_torque_dp", "sg_torque_ie"), c["sg_clip"]["share"]):
            level = share * float(np.max(np.abs(cols[name])))
            cols[name] = np.clip(cols[name], -level, level)
    cols["t"] = t
    return Recording({"t": cols.pop("t"), **cols}, f"generator B ({controller}, {motion})")


def draw_condition(kind: str, rng: np.random.Generator, cfg: Config, motion: str) -> dict:
    """One condition of ``kind`` with a plausible random size (this module's parametrisation)."""
    sign = lambda: float(rng.choice([-1.0, 1.0]))    # noqa: E731
    rated = cfg["actuator"]["torque_constant"] * cfg["amplifier"]["current_limit_continuous"]
    if kind == "cogging":
        amp = rng.uniform(0.012, 0.03) * rated
        return {"kind": kind, "periods": int(rng.choice([14, 24])) * GEAR,
                "amplitude": (amp, amp * rng.uniform(0.6, 1.4)),
                "phase": tuple(rng.uniform(0, 2 * np.pi, 2)), "harmonic": rng.uniform(0.15, 0.4),
                "phase2": tuple(rng.uniform(0, 2 * np.pi, 2))}
    if kind == "stribeck":
        lo = 0.1 if motion == "walking" else 0.04
        return {"kind": kind, "excess": rng.uniform(0.1, 0.3), "velocity": float(np.exp(rng.uniform(np.log(lo),
                np.log(0.3)))), "exponent": float(rng.choice([1.0, 2.0]))}
    if kind == "asymmetric_friction":
        s = sign()
        return {"kind": kind, "d": (s * rng.uniform(0.05, 0.12), s * rng.uniform(0.03, 0.12))}
    if kind == "load_dependent_friction":
        return {"kind": kind, "mu": rng.uniform(0.08, 0.3)}
    if kind == "delay":
        return {"kind": kind, "ticks": int(rng.integers(3, 11))}
    if kind == "backlash":
        return {"kind": kind, "form": str(rng.choice(["cable", "axis"])), "half_width": rng.uniform(8e-5, 4e-4)}
    if kind == "stiffening":
        return {"kind": kind, "s0": rng.uniform(2e-4, 6e-4)}
    if kind == "torque_offset":
        return {"kind": kind, "torque": (sign() * rng.uniform(0.12, 0.4), sign() * rng.uniform(0.12, 0.4))}
    if kind == "sg_offset":
        return {"kind": kind, "offset": (sign() * rng.uniform(0.15, 0.5), sign() * rng.uniform(0.1, 0.3))}
    if kind == "kt_error":
        return {"kind": kind, "factor": 1.0 + sign() * rng.uniform(0.08, 0.12)}
    if kind == "encoder_scale":
        return {"kind": kind, "factor": 1.0 + sign() * rng.uniform(0.01, 0.02)}
    if kind == "sg_clip":
        return {"kind": kind, "share": tuple(rng.uniform(0.6, 0.8, 2))}
    raise ValueError(f"unknown condition kind {kind!r}")


def make_case_b(seed: int, kinds: list[str], controller: str = "pd", motion: str = "multisine",
                jitter: bool = False, ident_s: float = 12.0, valid_s: float = 6.0) -> CaseB:
    """A case with the conditions ``kinds`` (keys of :data:`WORDS` and :data:`CALIBRATIONS`), drawn from ``seed``."""
    rng = np.random.default_rng(seed + 31_000_000)      # the plant and the experiment
    draw = np.random.default_rng(seed + 33_000_000)     # the conditions: same experiment whatever they are
    nominal = load_config(SIM_CONFIG)
    conditions = [draw_condition(k, draw, nominal, motion) for k in kinds]
    plant = Plant(nominal, conditions, rng)
    ident = simulate_b(plant, rng, ident_s, controller, motion, jitter)
    valid = simulate_b(plant, rng, valid_s, controller, motion, jitter)
    causes = tuple(sorted({WORDS[k] for k in kinds if k in WORDS})) or ("none",)
    flag = any(k in CALIBRATIONS for k in kinds)
    return CaseB(seed, causes, conditions, controller, motion, jitter, nominal, ident, valid, flag, tuple(kinds))


def write_case_b(case: CaseB, directory: Path) -> tuple[Path, Path]:
    """Write a case's identification and validation data as interchange CSVs (``b<seed>_ident.csv``,
    ``b<seed>_valid.csv``) for ``ankle-rt diagnose FILE --validation FILE --config config/sim.yaml``."""
    paths = (directory / f"b{case.seed}_ident.csv", directory / f"b{case.seed}_valid.csv")
    for path, rec in zip(paths, (case.ident, case.valid)):
        write_csv(path, rec.columns)
    return paths


#: scenario kinds of generator B and their shares
SCENARIOS_B = (("single", 0.3), ("two", 0.2), ("three", 0.1), ("calibration", 0.15),
               ("calibration_and_effect", 0.1), ("clipped", 0.07), ("none", 0.08))


def draw_case_b(seed: int) -> dict:
    """The keyword arguments of :func:`make_case_b` for one case of the benchmark's B mix."""
    rng = np.random.default_rng(seed + 37_000_000)
    names, shares = zip(*SCENARIOS_B)
    kind = str(rng.choice(names, p=np.array(shares) / sum(shares)))
    effects = list(WORDS)
    count = {"single": 1, "two": 2, "three": 3, "calibration_and_effect": 1}.get(kind, 0)
    kinds = [str(k) for k in rng.choice(effects, count, replace=False)]
    if kind in ("calibration", "calibration_and_effect"):
        kinds.append(str(rng.choice(CALIBRATIONS[:3])))
    if kind == "clipped":
        kinds.append("sg_clip")
    return {"seed": seed, "kinds": kinds, "controller": "impedance" if rng.uniform() < 0.4 else "pd",
            "motion": "walking" if rng.uniform() < 0.5 else "multisine",
            # a calibration case keeps regular stamps: its finding is then not a time-gap warning
            "jitter": bool(rng.uniform() < 0.35) and not any(k in CALIBRATIONS for k in kinds)}
