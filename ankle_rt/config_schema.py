"""The schema every configuration is validated against (see :mod:`ankle_rt.config`).

One section per concern. Physical parameters are required (no defaults); software options have
stated defaults. Every number has both bounds: a physically plausible range for quantities (the
amplifier's ratings for currents, what the 1 kHz loop can stabilise for gains, positive and bounded
times and masses); ``tests/test_config_safety.py`` walks the schema to keep it that way. Backend
transport sections (``serial``, ``canopen``) and effect parameters are validated by their owners
when they are configured. :func:`check_consistency` checks what one key alone cannot (peak >=
continuous current, configured gains within the run-time gain limits).
"""

from __future__ import annotations

import math
from typing import Any, Callable, Mapping, MutableMapping

import numpy as np

from ankle_rt.command_limits import MAX_TORQUE_KI, MAX_TORQUE_KP, MAX_TORQUE_RATE
from ankle_rt.controller_registry import check_controller_name
from ankle_rt.oscillation import BAND_HZ, band_floor
from ankle_rt.kinematics import motor_ratio
from ankle_rt.loop_setup import torque_feedback
from ankle_rt.notch import AXES, PREFIXES, Notch, cable_scale
from ankle_rt.params import GRAVITY, TransmissionParams
from ankle_rt.references import PROFILE_PARAMS, Gait
from ankle_rt.schema import ConfigError, Field, KeyPath, ListOf, Section, non_negative, positive

# Gains the motor-side loop can stabilise at 250-2000 Hz on the nominal actuator (J = 0.048 kg m^2): beyond
# these the discrete loop rings or the current saturates at every encoder count (bang-bang).
MAX_KP = 1000.0     # N m/rad, motor side
MAX_KD = 20.0       # N m s/rad, motor side
MAX_STIFFNESS = 500.0   # N m/rad at the ankle (a stiff human ankle is ~300)
MAX_DAMPING = 20.0      # N m s/rad at the ankle
ESCON_CONTINUOUS_A = 5.0   # maxon ESCON 50/5 ratings
ESCON_PEAK_A = 15.0
ESCON_PEAK_S = 20.0        # s the peak current may flow
DAY_S = 86400.0

GAINS = Section({
    "kp": non_negative("N m/rad, motor-side position gain", high=MAX_KP),
    "kd": non_negative("N m s/rad, motor-side velocity gain", high=MAX_KD),
})

ACTUATOR = Section({
    "inertia": positive("kg m^2, J at the gearbox output", high=10.0),
    "damping": non_negative("N m s/rad, viscous friction D (counted once)", high=100.0),
    "coulomb": non_negative("N m, Coulomb friction kc", high=100.0),
    "torque_constant": positive("N m/A at the gearbox output", high=100.0),
    "gear_ratio": positive("gearbox reduction", high=10_000.0),
    "encoder_counts_per_rev": Field(int, "counts per revolution at the gearbox output", low=1, high=2**32),
    "friction_smoothing_velocity": positive("rad/s, Coulomb term = kc tanh(v / this) in simulation", high=100.0),
})

TRANSMISSION = Section({
    "cable_stiffness": positive("N/m, k = EA/L", high=1e8),
    # plausible geometry, not only positive: a 1e-300 m pulley made the motor reference 1e298 rad
    "pulley_radius": Field(float, "m, r", low=1e-3, high=0.5),
    "lever_dp": Field(float, "m, R_DP", low=5e-3, high=0.5),
    "lever_ie": Field(float, "m, R_IE", low=5e-3, high=0.5),
    "stiffness_proportional_damping": non_negative("s, beta", high=0.1),
    "form": Field(str, "motor-side cable torque: 'reciprocal' R^-T tau_j, or the paper's eq. 4 k r^2 (theta_m - R theta)",
                  default="reciprocal", choices=("reciprocal", "paper")),
})

FOOT = Section({
    "mass": non_negative("kg", high=20.0),
    "com_dp": Field(float, "m, centre of mass offset for gravity in DP", low=-0.5, high=0.5),
    "inertia_dp": positive("kg m^2", high=1.0),
    "inertia_ie": positive("kg m^2", high=1.0),
})

AMPLIFIER = Section({
    "current_limit_continuous": positive("A, continuous limit (ESCON 50/5: at most 5 A)", high=ESCON_CONTINUOUS_A),
    "current_limit_peak": positive("A, peak limit for < 20 s (ESCON 50/5: at most 15 A; >= the continuous limit)",
                                   high=ESCON_PEAK_A),
})

FRICTION_FF = Section({
    "enabled": Field(bool, "add Coulomb + viscous friction feed-forward to the motor torques", default=False),
    "coulomb": Field(float, "N m; default: actuator.coulomb (the identified value)", default=None, low=0.0,
                     high=100.0),
    "viscous": Field(float, "N m s/rad; default: actuator.damping (the identified value)", default=None, low=0.0,
                     high=100.0),
    "velocity_band": positive("rad/s; the Coulomb term fades linearly to zero inside +/- this band (no chatter)",
                              default=0.05, high=10.0),
    "model": Field(str, "coulomb_viscous: Coulomb + viscous only; identified: also the Stribeck, asymmetric and "
                        "load-dependent friction effects of model_file", default="coulomb_viscous",
                   choices=("coulomb_viscous", "identified")),
    "model_file": Field(str, "identified model: a config such as `diagnose --write-model` writes (relative to "
                             "this file); empty: this config's actuator and sim.effects", default=""),
    "fraction": Field(float, "share of the model's friction the feed-forward cancels (every term scaled): below 1 "
                             "it stays passive on a device with that much less friction than stated",
                      default=1.0, low=0.0, high=1.0),
    "fade_velocity": non_negative("rad/s; the direction-dependent terms fade out with motor speed as "
                                  "exp(-(v / this)^2), leaving friction's damping to fast motion; 0: no fade",
                                  default=0.0, high=100.0),
    "error_band": non_negative("N m at the motor; under the joint-torque loop the direction also follows the "
                               "loop's torque error, saturating at this (breaks stiction before the motor "
                               "moves); 0: from the velocity only", default=0.0, high=100.0),
}, optional=True)

# The joint-torque loop's shipped gains: the noise-bounded loop (issue 19, docs/daemon.md "Sixth pass"; found
# by benchmarks/study_torque_loop_step.py on the sampled linear model with the strain gauges' noise bounded, measured
# with `ankle-rt bench impedance`), with the notches and the IE torque filter below. The gait phases walk on
# config/torque-loop-walk.yaml (the loop shipped before). The step-tuned loop of the same study (a third of the
# torque step's overshoot) makes three times the current noise and trips OSCILLATION on it: docs/daemon.md.
# ki in 1/s, torque_rate in s; cutoff_hz is DP's.
LOOP_DEFAULTS = {"kp_dp": 46.6, "kp_ie": 28.0, "ki_dp": 11.0, "ki_ie": 11.6, "torque_rate_dp": 0.229,
                 "torque_rate_ie": 0.141, "cutoff_hz": 297.0}
CUTOFF_HZ_IE_DEFAULT = 80.0
RATE_DAMPING_DEFAULTS = ((0.0, 0.0), (20.0, 20.0))   # motor_rate_damping_dp/_ie N m s/rad (off), their corners Hz
# The torque loop's clamps [DP, IE] when max_correction_dp / _ie are unset. Where nobody walks (the simulator's
# bench experiments) the correction moves the reflected motor inertia: a 15 N m, 2 Hz push at K_dp 50 (7.5 N m at
# K_ie 25) needs ~115 (~35) N m of it. Where someone walks (the device, the walking scenario) a clamp is also what
# a wrong torque reading adds on top of the wearer's moment, and the walking budget (check_walking_current) and the
# friction feed-forward's (FrictionFeedForward.check_carried) share the motors' peak with it: 30 / 20 N m, within
# both at 100 kg (the budget alone allows 44.09 / 24.49).
MAX_CORRECTION_BENCH, MAX_CORRECTION_WALKED = (150.0, 60.0), (30.0, 20.0)
# The torque loop's gain ceilings (MAX_TORQUE_KP/KI/RATE) are ankle_rt.command_limits' (set_gains
# checks them too): far beyond what the loop's margins allow, so a typo or a non-finite value is refused.
# The clamp's: the DP torque both motors give at the ESCON's 15 A peak (224 N m) and a little more.
MAX_CORRECTION = 250.0
# The disturbance observer and its energy tank (ankle_rt/control/torque_loop.py): shipped values and ceilings.
DOB_HZ_DEFAULT, DOB_INERTIA_DEFAULT, MAX_OBSERVER_DEFAULT = 0.0, 1.0, 20.0
TANK_J_DEFAULT, TANK_CREDIT_DEFAULT = 0.5, 0.8
MAX_DOB_HZ, MAX_OBSERVER, MAX_TANK_J = 200.0, 100.0, 10.0
# The notches [DP, IE] on the torque loop's P and rate terms: a wide one over the free foot's cable mode (DP 98 Hz,
# IE 77 Hz nominal; docs/daemon.md, fourth pass: what lets kp rise with >= 7 dB over cables x0.7-1.3) and a second
# (notch2_*) over the loop's own high-frequency mode, the cable mode a large rate gain moves up (~130-150 Hz with
# the cables stiff). prefix -> ((hz), (zeta), (depth)) [DP, IE].
NOTCH_DEFAULTS = {"notch": ((85.3, 72.3), (0.97, 0.5), (0.47, 0.58)), "notch2": ((0.0, 0.0), (0.5, 0.5), (1.0, 1.0))}
NOTCH_ROLES = {"notch": "band-stop (the free foot's cable mode)",
               "notch2": "second band-stop (the loop's own mode above the cable mode)"}
assert tuple(NOTCH_ROLES) == tuple(NOTCH_DEFAULTS) == PREFIXES
# N/m: the cable stiffness the NOTCH_DEFAULTS centres are placed for, config/nominal-params.yaml's; the loop moves the notch
# to the configured cable as sqrt(transmission.cable_stiffness / this) (ankle_rt.notch)
NOTCH_CABLE_STIFFNESS_DEFAULT = 218800.0
MAX_NOTCH_HZ = 400.0   # below the 1 kHz loop's Nyquist frequency
MAX_CUTOFF_HZ = 400.0  # the torque filter's, shared or per axis
MAX_RATE_CROSSOVER_HZ = 50.0   # the encoder rate source's: above it the gauges' noise is back in the rate term
MAX_RATE_AGREEMENT_NM = 0.5    # ... its stretch believed this far from the gauges at most (25x their noise)
# The high-passed motor-rate damping [DP, IE] (ankle_rt/control/torque_loop.py): a collocated damping of the motor
# above a corner, for the held foot's mode (the motor on the cable and the ground, 10-30 Hz). Off by default.
MAX_RATE_DAMPING, MAX_RATE_DAMPING_HZ = 500.0, 100.0
# The lag [DP, IE] on the P and rate terms (ankle_rt.lag; docs/daemon.md "Fifth pass"): off by default. Its zero
# stays far below the cable modes (the study searched 0.2-15 Hz), its boost is an integral's gain by another name.
MAX_LAG_HZ, MAX_LAG_BOOST = 50.0, 10.0

IMPEDANCE_DEFAULTS = {"stiffness_dp": 20.0, "stiffness_ie": 10.0, "damping_dp": 0.5, "damping_ie": 0.25}
# The gains of a set (what ankle_rt.analysis.gain_set_margin_db checks and set_gains names) and the
# shipped set (what a limiting gain is found against).
IMPEDANCE_GAINS = tuple(IMPEDANCE_DEFAULTS)
LOOP_GAINS = tuple(LOOP_DEFAULTS)
SHIPPED_GAINS = {**IMPEDANCE_DEFAULTS, **LOOP_DEFAULTS}
# the motor-side PD's shipped set (what a limiting PD gain is found against): the paper's step gains,
# config/nominal-params.yaml controller.step_gains
SHIPPED_PD_GAINS = {"kp": 90.0, "kd": 5.0}

IMPEDANCE = Section({
    "stiffness_dp": non_negative("N m/rad at the ankle", default=IMPEDANCE_DEFAULTS["stiffness_dp"], high=MAX_STIFFNESS),
    "stiffness_ie": non_negative("N m/rad at the ankle", default=IMPEDANCE_DEFAULTS["stiffness_ie"], high=MAX_STIFFNESS),
    "damping_dp": non_negative("N m s/rad at the ankle", default=IMPEDANCE_DEFAULTS["damping_dp"], high=MAX_DAMPING),
    "damping_ie": non_negative("N m s/rad at the ankle", default=IMPEDANCE_DEFAULTS["damping_ie"], high=MAX_DAMPING),
    "torque_feedback": Field(str, "joint-torque loop on the strain gauges (controller.torque_loop): auto = on when "
                                  "strain gauges are configured (simulator, or strain_gauges.matrix); off = open loop",
                             default="auto", choices=("auto", "on", "off")),
    "angle_source": Field(str, "the ankle angle of the law: joint_encoders, estimated (through the cables: cannot see "
                               "cable slack), auto = joint encoders when configured (simulator, or "
                               "joint_encoders.counts_per_rev)", default="auto",
                          choices=("auto", "joint_encoders", "estimated")),
    "joint_crossover_hz": non_negative("Hz: under the joint-torque loop with joint encoders in the law, their angle "
                                       "below this and the estimate through the cables above it (no hunting on a "
                                       "slack cable, but not passive on a cable 30 % softer than configured: "
                                       "ankle_rt.joint_blend, docs/daemon.md); 0 = the joint encoders alone",
                                       default=0.0, high=50.0),
}, optional=True)

GAIN_LIMITS = Section({
    "kp": non_negative("N m/rad; largest motor-side kp a set_gains command may ask for", default=500.0, high=MAX_KP),
    "kd": non_negative("N m s/rad; largest motor-side kd a set_gains command may ask for", default=10.0, high=MAX_KD),
    "stiffness": non_negative("N m/rad; largest ankle stiffness (DP and IE) a command may ask for", default=200.0,
                              high=MAX_STIFFNESS),
    "damping": non_negative("N m s/rad; largest ankle damping (DP and IE) a command may ask for", default=5.0,
                            high=MAX_DAMPING),
}, optional=True, doc="run-time gain maxima (the configured gains must lie within them too)")

TORQUE_LOOP = Section({
    "kp_dp": non_negative("N m per N m of joint-torque error, DP", default=LOOP_DEFAULTS["kp_dp"], high=MAX_TORQUE_KP),
    "kp_ie": non_negative("N m per N m of joint-torque error, IE", default=LOOP_DEFAULTS["kp_ie"], high=MAX_TORQUE_KP),
    "ki_dp": non_negative("1/s, integral gain on the DP torque error", default=LOOP_DEFAULTS["ki_dp"],
                          high=MAX_TORQUE_KI),
    "ki_ie": non_negative("1/s, integral gain on the IE torque error", default=LOOP_DEFAULTS["ki_ie"],
                          high=MAX_TORQUE_KI),
    "torque_rate_dp": non_negative("s, gain on the rate of the measured DP torque (damps the motor-on-cable mode)",
                                   default=LOOP_DEFAULTS["torque_rate_dp"], high=MAX_TORQUE_RATE),
    "torque_rate_ie": non_negative("s, gain on the rate of the measured IE torque",
                                   default=LOOP_DEFAULTS["torque_rate_ie"], high=MAX_TORQUE_RATE),
    "torque_rate_source": Field(str, "the torque the rate terms (torque_rate_dp/ie) differentiate: gauges (the strain "
                                     "gauges), or encoders (the cables' stretch from the motor and joint encoders "
                                     "times transmission.cable_stiffness: no gauge noise in the rate; needs joint "
                                     "encoders)", default="gauges", choices=("gauges", "encoders")),
    **{f"torque_rate_crossover_hz_{axis}": Field(
        float, f"Hz, with torque_rate_source encoders: the {axis.upper()} gauge's torque below this, the stretch's "
               f"above (the gauges are right about the torque's size and offset, the encoders quiet)",
        default=5.0, low=0.1, high=MAX_RATE_CROSSOVER_HZ)
       for axis in ("dp", "ie")},
    "torque_rate_agreement_nm": positive("N m, with torque_rate_source encoders: the stretch torque is used only "
                                         "within this of the filtered gauge torque, the gauges' own rate beyond "
                                         "(a slack cable or backlash shows a stretch with no torque behind it; "
                                         "believed up to 10 N m, 0.2 mm of play swings the ankle by degrees)",
                                         default=0.1, high=MAX_RATE_AGREEMENT_NM),
    "cutoff_hz": Field(float, "Hz, first-order low-pass of the measured joint torque (below the 77-98 Hz cable modes); "
                              "per axis: cutoff_hz_dp / cutoff_hz_ie", default=LOOP_DEFAULTS["cutoff_hz"], low=1.0,
                       high=MAX_CUTOFF_HZ),
    "max_correction_dp": positive("N m at the ankle the DP feedback may add (anti-windup; bounds a wrong reading); "
                                  f"unset: {MAX_CORRECTION_BENCH[0]:g} where nobody walks, {MAX_CORRECTION_WALKED[0]:g} "
                                  "on the device or the walking scenario (config check prints it)", default=None,
                                  high=MAX_CORRECTION),
    "max_correction_ie": positive("N m at the ankle the IE feedback may add; unset: "
                                  f"{MAX_CORRECTION_BENCH[1]:g} where nobody walks, {MAX_CORRECTION_WALKED[1]:g} where "
                                  "someone walks", default=None, high=MAX_CORRECTION),
    "dob_hz": non_negative("Hz, low-pass of the disturbance observer cancelling motor-side friction and inertia; "
                           "0 = no observer", default=DOB_HZ_DEFAULT, high=MAX_DOB_HZ),
    "dob_inertia_dp": Field(float, "the observer's nominal DP inertia as a fraction of the reflected motor inertia "
                                   "(1: cancels friction only; less: also inertia)", default=DOB_INERTIA_DEFAULT,
                            low=0.05, high=2.0),
    "dob_inertia_ie": Field(float, "the observer's nominal IE inertia, fraction of the reflected motor inertia",
                            default=DOB_INERTIA_DEFAULT, low=0.05, high=2.0),
    "max_observer_dp": non_negative("N m at the ankle the DP observer may add (bounds a wrong reading)",
                                    default=MAX_OBSERVER_DEFAULT, high=MAX_OBSERVER),
    "max_observer_ie": non_negative("N m at the ankle the IE observer may add", default=MAX_OBSERVER_DEFAULT,
                                    high=MAX_OBSERVER),
    "tank_j": non_negative("J, the energy tank that keeps the observer passive (its capacity)", default=TANK_J_DEFAULT,
                           high=MAX_TANK_J),
    "tank_friction_credit": Field(float, "share of the identified motor friction's dissipation (actuator.coulomb, "
                                         "damping) the tank is credited with", default=TANK_CREDIT_DEFAULT,
                                  low=0.0, high=1.0),
    **{f"{prefix}_hz_{axis}": non_negative(f"Hz, centre of the {axis.upper()} {what} on the P and rate terms; 0 = none",
                                           default=NOTCH_DEFAULTS[prefix][0][i], high=MAX_NOTCH_HZ)
       for prefix, what in NOTCH_ROLES.items() for i, axis in enumerate(("dp", "ie"))},
    "notch_cable_stiffness": positive("N/m, the cable stiffness notch_hz_dp and notch_hz_ie are placed for: the loop "
                                      "runs each notch at notch_hz x sqrt(transmission.cable_stiffness / this), where "
                                      "the configured cable puts the mode it sits on (`config check` prints it). "
                                      "Placing notch_hz for your own cable? Set this to your transmission."
                                      "cable_stiffness too, or the notch is moved a second time",
                                      default=NOTCH_CABLE_STIFFNESS_DEFAULT, high=1e8),
    **{f"{prefix}_zeta_{axis}": Field(float, f"the {axis.upper()} {prefix}'s width (damping ratio of its poles)",
                                      default=NOTCH_DEFAULTS[prefix][1][i], low=0.02, high=2.0)
       for prefix in NOTCH_ROLES for i, axis in enumerate(("dp", "ie"))},
    **{f"{prefix}_depth_{axis}": Field(float, f"the {axis.upper()} {prefix}'s gain at its centre (1 = none)",
                                       default=NOTCH_DEFAULTS[prefix][2][i], low=0.0, high=1.0)
       for prefix in NOTCH_ROLES for i, axis in enumerate(("dp", "ie"))},
    **{f"cutoff_hz_{axis}": Field(float, f"Hz, the {axis.upper()} axis's own low-pass of the measured torque; "
                                         f"unset: cutoff_hz", default=default, low=1.0, high=MAX_CUTOFF_HZ)
       for axis, default in (("dp", None), ("ie", CUTOFF_HZ_IE_DEFAULT))},
    **{f"motor_rate_damping_{axis}": non_negative(
        f"N m s/rad at the ankle, damping on the {axis.upper()} ankle-side motor rate above "
        f"motor_rate_damping_hz_{axis} (high-passed): damps the held foot's mode (the motor on the cable and the "
        f"ground), which the torque-rate term alone leaves ringing; 0 = off", default=RATE_DAMPING_DEFAULTS[0][i],
        high=MAX_RATE_DAMPING)
       for i, axis in enumerate(("dp", "ie"))},
    **{f"motor_rate_damping_hz_{axis}": Field(float, f"Hz, the corner of the {axis.upper()} motor-rate damping's "
                                                     f"high-pass (below it the wearer's motion is not damped; it "
                                                     f"adds motor_rate_damping / (2 pi this) of inertia there)",
                                              default=RATE_DAMPING_DEFAULTS[1][i], low=0.5, high=MAX_RATE_DAMPING_HZ)
       for i, axis in enumerate(("dp", "ie"))},
    **{f"lag_hz_{axis}": non_negative(f"Hz, the zero of the {axis.upper()} lag (s + wz) / (s + wz / lag_boost) on "
                                      f"the P and rate terms: gain lag_boost below it, 1 above; 0 = no lag",
                                      default=0.0, high=MAX_LAG_HZ)
       for axis in ("dp", "ie")},
    **{f"lag_boost_{axis}": Field(float, f"the {axis.upper()} lag's gain at DC (1 = none)", default=1.0,
                                  low=1.0, high=MAX_LAG_BOOST)
       for axis in ("dp", "ie")},
}, optional=True, doc="joint-torque feedback of the impedance controller (docs/daemon.md)")


def torque_loop_cutoffs(torque_loop: Mapping[str, Any]) -> tuple[float, float]:
    """Hz [DP, IE]: each axis's low-pass of the measured torque (``cutoff_hz_dp`` / ``_ie``, unset:
    ``cutoff_hz``); the daemon's loop and the linear model read them here."""
    return tuple(float(torque_loop.get(f"cutoff_hz_{a}") or torque_loop["cutoff_hz"]) for a in ("dp", "ie"))

# The gait-phase controller's shipped parameters, for a 75 kg wearer at normal cadence (tuned on the
# walking scenario with `ankle-rt bench walk`; sources and tuning rule in docs/daemon.md). Per phase:
# (stiffness_dp N m/rad, damping_dp N m s/rad, equilibrium_dp rad, stiffness_ie, damping_ie, equilibrium_ie).
# The dampings are rendered ones (ankle_rt.lead: the law leads the loop's lag and the cable's share of the motor's
# motion): on config/torque-loop-walk.yaml they give the law the motor-rate damping the phases had when they were
# tuned as law coefficients (9, 6, 8, 8, 6 DP; 1.5, 1.5, 1, 1, 1.5 IE), which rendered these.
GAIT_PHASE_DEFAULTS = {
    "early_stance": (400.0, 6.39, -0.02, 100.0, 0.58, 0.0),
    "late_stance": (150.0, 5.5, -0.55, 100.0, 0.58, 0.0),
    "early_swing": (60.0, 7.74, 0.0, 40.0, 0.82, 0.0),
    "late_swing": (100.0, 7.55, 0.0, 40.0, 0.82, 0.0),
    "safe": (150.0, 5.5, 0.0, 60.0, 1.04, 0.0),
}
MAX_EQUILIBRIUM = 0.7   # rad; the configured ankle range bounds it further (40 deg shipped)


def _phase_section(name: str, values: tuple[float, ...]) -> Section:
    k_dp, b_dp, e_dp, k_ie, b_ie, e_ie = values
    return Section({
        "stiffness_dp": non_negative("N m/rad at the ankle, DP", default=k_dp, high=MAX_STIFFNESS),
        "damping_dp": non_negative("N m s/rad, DP", default=b_dp, high=MAX_DAMPING),
        "equilibrium_dp": Field(float, "rad, DP equilibrium angle (dorsiflexion +)", default=e_dp,
                                low=-MAX_EQUILIBRIUM, high=MAX_EQUILIBRIUM),
        "stiffness_ie": non_negative("N m/rad at the ankle, IE", default=k_ie, high=MAX_STIFFNESS),
        "damping_ie": non_negative("N m s/rad, IE", default=b_ie, high=MAX_DAMPING),
        "equilibrium_ie": Field(float, "rad, IE equilibrium angle (inversion +)", default=e_ie,
                                low=-MAX_EQUILIBRIUM, high=MAX_EQUILIBRIUM),
    }, optional=True, doc=f"impedance of the {name.replace('_', ' ')} phase")


GAIT_PHASE = Section({
    **{name: _phase_section(name, values) for name, values in GAIT_PHASE_DEFAULTS.items()},
    "load_on_nm": positive("N m of plantarflexor moment (-sg_dp) above which the foot is loaded (heel strike, "
                           "held one period of the foot's cable mode: heel_strike_hold_s)",
                           default=15.0, high=300.0),
    "load_off_nm": positive("N m below which it is unloaded (toe-off); < load_on_nm: the hysteresis; above what a "
                            "foot off the ground reads (check_gait_load_thresholds)", default=5.0, high=300.0),
    "late_stance_angle": Field(float, "rad of dorsiflexion past which early stance becomes late stance",
                               default=0.08, low=-MAX_EQUILIBRIUM, high=MAX_EQUILIBRIUM),
    "late_stance_load_nm": non_negative("N m of load also needed for late stance", default=80.0, high=300.0),
    "late_swing_angle": Field(float, "rad; early swing becomes late swing above this DP angle ...", default=-0.09,
                              low=-MAX_EQUILIBRIUM, high=MAX_EQUILIBRIUM),
    "late_swing_velocity": Field(float, "rad/s ... and below this DP rate", default=1.0, low=-20.0, high=20.0),
    "min_dwell_s": non_negative("s in a phase before any transition; at most 0.1 s: shorter than every walking "
                                "phase (the shortest on bench walk: late stance, 0.157 s at 100 kg fast; 0.3 s "
                                "faulted the 50 kg wearer at fast cadence)", default=0.05, high=0.1),
    "timeout_s": Field(float, "s in one phase after which the controller falls back to the safe phase; at most "
                              "2 s: no walking phase lasts a stride (the slowest is 1.38 s), and a wearer who stops "
                              "in late stance feels the push-off equilibrium until then", default=1.5, low=0.1,
                       high=2.0),
    "blend_s": Field(float, "s, time constant of the blend of K, B and equilibrium towards the phase's values "
                            "(transitions and live changes: no torque jump)", default=0.02, low=0.001, high=2.0),
}, optional=True, doc="the gait-phase (finite-state) impedance controller (controller.type: gait_phase; docs/daemon.md)")

CONTROLLER = Section({
    "rate_hz": Field(int, "control loop rate", low=250, high=2000),
    "validation_gains": GAINS,
    "step_gains": GAINS,
    "type": Field(str, "pd: motor-side PD (paper eq. 11); impedance: ankle stiffness/damping; gait_phase: "
                  "finite-state impedance over the stride; or the name of "
                  "an installed controller plugin (entry-point group ankle_rt.controllers)", default="pd",
                  check=check_controller_name),
    "params": Section({}, "parameters of a plugin controller (the plugin validates them)", optional=True, open=True),
    "pd_gains": Field(str, "which gain set the PD uses", default="step", choices=("step", "validation")),
    "impedance": IMPEDANCE,
    "gait_phase": GAIT_PHASE,
    "friction_ff": FRICTION_FF,
    "torque_loop": TORQUE_LOOP,
    "gain_limits": GAIN_LIMITS,
    "gain_ramp_s": Field(float, "s; run-time gain changes ramp linearly over this time (bumpless; also the rate "
                                "limit of gain changes, so it cannot be 0)", default=0.2, low=0.01, high=10.0),
    "soft_start_s": non_negative("s; the controller output ramps in over this time after activation; at most 2 s: "
                                 "a wearer may walk meanwhile on the scaled-down output (10 s: the 100 kg wearer "
                                 "pushed the ankle into its range)", default=0.2, high=2.0),
})

ESTIMATION = Section({
    # every controller's damping acts on this velocity, and walking's stance mode (4-6 Hz) needs it nearly
    # unlagged: 10 Hz faulted the walk (OSCILLATION at 100 kg normal; 5 Hz: SG_MISMATCH at 75 kg), 15 Hz did not
    "velocity_cutoff_hz": Field(float, "Hz, first-order low-pass on the backward-difference motor velocity (at "
                                       "least 20 Hz: the damping every controller renders acts on it)",
                                default=100.0, low=20.0, high=1000.0),
    "tare_samples": Field(int, "strain-gauge samples averaged for the tare before activation", default=100,
                          low=1, high=100_000),
}, optional=True)

REFERENCE = Section({
    "profile": Field(str, "the ankle reference run from start-up", default="step",
                     choices=tuple(PROFILE_PARAMS)),
    **PROFILE_PARAMS,
    "ramp_s": non_negative("s; default ramp of a set_reference command", default=1.0, high=60.0),
    "max_rate_rad_s": positive("rad/s; a commanded reference (set_reference, start_profile) moves at most this fast "
                               "(2 rad/s: what the nominal ankle follows at 15 A without the motor-speed fault)",
                               default=2.0, high=20.0),
}, optional=True)

REALTIME = Section({
    "priority": Field(int, "SCHED_FIFO priority of the loop thread; 0 = normal scheduling", default=0,
                      low=0, high=99),
    "cpus": ListOf(Field(int, low=0, high=4095), "CPU affinity of the daemon (empty: any CPU)", default=[]),
    "lock_memory": Field(bool, "mlockall(MCL_CURRENT | MCL_FUTURE) so the loop never page-faults", default=False),
    "timer_slack_ns": Field(int, "prctl(PR_SET_TIMERSLACK) for the loop thread; 0 = leave the default",
                            default=1, low=0, high=10_000_000),
    "spin_us": Field(int, "sleep until this long before a deadline, then spin (real clock)", default=200,
                     low=0, high=2000),
}, optional=True)

LOOP = Section({
    "duration_s": non_negative("s the run lasts; 0 = until stopped (SIGINT/SIGTERM/stop)", default=0.0,
                               high=365 * DAY_S),
    "max_consecutive_overruns": Field(int, "fault (MISSED_DEADLINES) after this many overruns in a row",
                                      default=5, low=1, high=1_000_000),
    "max_stall_s": Field(float, "s; fault (MISSED_DEADLINES) when the loop misses deadlines for longer than this "
                                "in one stall or in overruns in a row", default=0.05, low=0.001, high=10.0),
    "realtime": REALTIME,
}, optional=True)

SAFETY = Section({
    "auto_activate": Field(bool, "activate by itself once the strain gauges are tared (else wait for a command)",
                           default=True),
    "max_motor_speed_rad_s": positive("rad/s at the gearbox output; a larger encoder jump is a fault",
                                      default=30.0, high=200.0),
    "max_sg_step_nm": positive("N m; a larger strain-gauge change between two samples is a fault", default=20.0,
                               high=500.0),
    "sg_rail_nm": positive("N m; a strain-gauge torque this large is a sensor at its rail (0.9 x "
                           "sensors.strain_gauge_range_nm; above the wearer's walking moment)", default=225.0,
                           high=500.0),
    "stale_cycles": Field(int, "fault when the sample sequence does not advance for this many cycles",
                          default=5, low=1, high=1000),
    "i2t_peak_duration_s": positive("s the peak current may flow (ESCON 50/5: at most 20 s); sets the I^2 t budget",
                                    default=20.0, high=ESCON_PEAK_S),
    "oscillation_rms_a": positive("A; a set value's RMS above 20 Hz (either motor) beyond this for "
                                  "safety.oscillation_hold_s is an oscillation fault; below what a 20 Hz oscillation of the "
                                  "continuous current shows it (check_oscillation_limit: 1.97 A at 1 kHz and 5 A continuous)",
                                  default=1.0, high=5.0),
    "oscillation_hold_s": Field(float, "s the band RMS must stay above safety.oscillation_rms_a to fault; at "
                                       "least 0.35 s: a stable loop's saturated step keeps it above for up to "
                                       "~0.3 s (0.1 s faulted the 100 kg walk); at most 1 s: a longer hold only "
                                       "lets a limit cycle between the peak currents run on the wearer",
                                default=0.5, low=0.35, high=1.0),
    "max_actuation_delay_s": non_negative("s between a set value and the motor torque it makes (amplifier, bus, "
                                          "bridge) that the strain-gauge cross-check allows for", default=0.012,
                                          high=0.05),
    "joint_mismatch_rad": positive("rad at the ankle the cables' stretch from the motor and joint encoders may change "
                                   "by beyond twice the gauges' torque (JOINT_MISMATCH): counts, creep and the "
                                   "cables' play (0.2 mm of backlash: 3.5 mrad DP, 8.9 IE); larger lets a flipped sign "
                                   "drive the ankle further first", default=3e-4, high=0.05),
}, optional=True)

LOGGING = Section({
    "enabled": Field(bool, "write a run log", default=True),
    "directory": Field(str, "where timestamped logs go (relative: to the working directory)", default="logs"),
    "ring_records": Field(int, "records the in-memory ring holds (at 1 kHz, 16384 = 16 s of disk stall)",
                          default=16384, low=256, high=1 << 20),
    "flush_interval_s": Field(float, "s between writes of the ring to disk", default=0.05, low=0.005, high=1.0),
    "rotate_size_mb": Field(float, "MB (1e6 bytes); start a new log file before one grows past this (0: never)",
                            default=256.0, low=0.0, high=1e6),
    "rotate_interval_s": Field(float, "s; start a new log file after one has been written this long (0: never)",
                               default=0.0, low=0.0, high=1e7),
    "keep_files": Field(int, "log files kept, the current one counted; older ones are deleted (0: all)",
                        default=0, low=0, high=100000),
    "keep_days": Field(float, "days; log files last written longer ago are deleted (0: kept)",
                       default=0.0, low=0.0, high=36500.0),
    "fault_on_error": Field(bool, "a failed log write (disk full) is a fault (LOG_FAILED); else logging "
                                  "stops, the run goes on and status says why", default=False),
}, optional=True)

DEVICE_RANGE_DEG = 40.0   # deg, +/- DP and IE: the prosthesis's range of motion (the paper, section 2.1)

LIMITS = Section({
    "ankle_range_deg": Field(float, "+/- software limit in DP and IE; at most the device's range of motion, +/-40 deg in "
                                    "both (the paper's section 2.1: set by software limits alone, no end stop)",
                             low=0.0, low_open=True, high=DEVICE_RANGE_DEG),
})

SENSORS = Section({
    "strain_gauge_noise_rms": non_negative("N m per ankle axis", high=10.0),
    "joint_encoder_noise_rms": non_negative("rad per sample, the joint encoders' jitter beyond their count (the "
                                            "noise check counts it with torque_rate_source encoders; measure it)",
                                            default=0.0, high=0.01),
    "strain_gauge_range_nm": positive("N m at the ankle: the strain gauges' full scale (a reading there is a "
                                      "sensor at its rail); safety.sg_rail_nm lies below it", default=250.0,
                                      high=1000.0),
})

# Walking's loads on the ankle, per kg of the wearer (docs/daemon.md "Limits a walker does not trip"):
# the able-bodied peak plantarflexor moment is 1.5-1.6 N m/kg (Winter 1991); the rendered moment
# overshoots it (bench walk), so the rail must sit above this ...
WALKING_PEAK_MOMENT_PER_KG = 2.0   # N m/kg
# ... and the jump check above the fastest change of the joint torque between two samples (the
# walking scenario under the gait-phase controller: 0.13 N m/kg per ms at 50 kg fast, 8.6 N m at 100 kg
# fast; rounded up)
WALKING_TORQUE_STEP_PER_KG = 0.15  # N m/kg per ms
# ... and the motors must render the moment the controller renders (bench walk: up to 1.76 N m/kg,
# rounded up) plus what the joint-torque loop may add, at the peak current (check_walking_current)
WALKING_RENDERED_MOMENT_PER_KG = 1.8  # N m/kg

WEARER = Section({
    "mass_kg": Field(float, "kg, the heaviest wearer the device is set up for: the strain-gauge rail and jump "
                            "checks must let this person walk (docs/daemon.md)", default=100.0, low=20.0,
                     high=150.0),
}, optional=True)

DISTURBANCE = Section({
    "start": non_negative("s, from the start of the simulation", high=365 * DAY_S),
    "stop": positive("s", high=365 * DAY_S),
    "torque_dp": Field(float, "N m at the ankle, DP", low=-200.0, high=200.0),
    "torque_ie": Field(float, "N m at the ankle, IE", low=-200.0, high=200.0),
})

EFFECT = Section({
    "type": Field(str, "effect name from sim_backend.effects"),
}, open=True)

WALKING = Section({
    "mass_kg": Field(float, "kg, the wearer's body mass (the able-bodied moment scales with it)", default=75.0,
                     low=30.0, high=150.0),
    "cadence": Field(str, "slow (87 steps/min), normal (105) or fast (123) level walking (docs/simulator.md)",
                     default="normal", choices=("slow", "normal", "fast")),
    "seed": Field(int, "seed of the stride-to-stride variability", default=0, low=0, high=2**63 - 1),
    "variability": non_negative("scale of the stride-to-stride variability (1 = the documented spread, 0 = none)",
                                default=1.0, high=5.0),
    "start_s": non_negative("s of simulator time of the first heel strike (the foot hangs free before)",
                            default=1.0, high=3600.0),
}, optional=True, doc="the walking scenario (sim.scenario: walking)")

SIM = Section({
    "friction": Field(bool, "baseline Coulomb friction (actuator.coulomb, tanh-smoothed)", default=True),
    "quantization": Field(bool, "encoder quantisation to 2 pi / counts_per_rev", default=True),
    "sensor_noise": Field(bool, "strain-gauge noise of sensors.strain_gauge_noise_rms", default=True),
    "seed": Field(int, "noise seed", default=0, low=0, high=2**63 - 1),
    "substeps": Field(int, "integration substeps per control tick (an effect may raise it to its minimum)",
                      default=2, low=1, high=100),
    "cables": Field(bool, "false: motors off the cables (actuator identification)", default=True),
    "effects": ListOf(EFFECT, "extra effects switched on, each {type: NAME, ...parameters}"),
    "disturbances": ListOf(DISTURBANCE, "ankle disturbance torque pulses"),
    "scenario": Field(str, "none: the foot is free but for sim.disturbances; walking: the wearer's body loads the "
                           "foot in stance (sim.walking, docs/simulator.md)", default="none",
                      choices=("none", "walking")),
    "walking": WALKING,
    "strain_gauge_offset": ListOf(Field(float, low=-200.0, high=200.0), "N m [DP, IE] added to the strain-gauge readings (tared away by the daemon)",
                                  default=[0.0, 0.0], length=2),
    # A busy host stalls a simulated plant, not a device: a real-time run whose plant is simulated in
    # this process uses these instead of loop.max_stall_s / loop.max_consecutive_overruns (a run on
    # hardware never reads them).
    "max_stall_s": Field(float, "s; with a simulated plant in real time, missing deadlines for longer than this "
                                "(one stall or overruns in a row) trips MISSED_DEADLINES (instead of "
                                "loop.max_stall_s)", default=0.5, low=0.001, high=10.0),
    "max_consecutive_overruns": Field(int, "with a simulated plant in real time, this many overruns in a row trip "
                                           "MISSED_DEADLINES (instead of loop.max_consecutive_overruns)",
                                      default=50, low=1, high=1_000_000),
}, optional=True)

CANOPEN = Section({
    "interface": Field(str, "python-can interface: socketcan on the device, virtual in tests", default="socketcan"),
    "channel": Field(str, "python-can channel, e.g. can0", default="can0"),
    "bitrate": Field(int, "bit/s of the CAN bus (physical limit 1 Mbit/s)", default=1_000_000, low=10_000, high=1_000_000),
    "io_node_id": Field(int, "node id of the CiA 401 I/O node (set values, enables, ready, strain gauges, counters)",
                        default=1, low=1, high=127),
    "eds": Field(str, "object dictionary of the I/O node; empty: the shipped hardware/ankle_io.eds", default=""),
    "heartbeat_producer_ms": Field(int, "heartbeat period the I/O node is configured with (0x1017); "
                                   "the SYNC period is always the control period (0x1006)", default=10,
                                   low=1, high=1000),
    "heartbeat_consumer_ms": Field(int, "no heartbeat for this long: LINK_LOST (> producer time)", default=25,
                                   low=2, high=5000),
    "tpdo_wait_us": Field(int, "after the SYNC, poll up to this long for the cycle's TPDOs (real clock only)",
                          default=400, low=0, high=5000),
    "rpdo_timeout_ms": Field(int, "the node's RPDO deadline monitoring (0x1400 sub5): no set values for this long "
                                  "-> outputs to their error values, EMCY 0x8250; 0 = off", default=5, low=0, high=1000),
    "sdo_timeout_s": positive("SDO response timeout during configuration", default=0.5, high=10.0),
    "emulator": Field(str, "lockstep: run the device emulator in this process on the virtual bus, stepped by "
                           "the backend's SYNC (bench tests without hardware); none: a real node",
                      default="none", choices=("none", "lockstep")),
}, optional=True, doc="CANopen transport (backend: canopen)")


def _octal_mode(value: str | int) -> None:
    """Socket permissions: an octal string ('0660') or the int YAML makes of unquoted 0660."""
    bits = int(value, 8) if isinstance(value, str) and value and set(value) <= set("01234567") else value
    if not isinstance(bits, int) or not 0 <= bits <= 0o777:
        raise ValueError(f"expected octal permission bits such as '0660', got {value!r}")


SERVICE = Section({
    "enabled": Field(bool, "open the command socket (ankle-rt ctl)", default=True),
    "socket_path": Field(str, "Unix socket of the command interface; 'auto': /run/ankle-rt/control.sock when "
                              "/run/ankle-rt exists, else $XDG_RUNTIME_DIR/ankle-rt.sock, else /tmp/ankle-rt-UID.sock",
                         default="auto"),
    "socket_mode": Field((str, int), "permissions of the socket file, octal: '0660' lets the service group command",
                         default="0660", check=_octal_mode),
    "poll_period_s": Field(float, "s between command-socket polls from the loop", default=0.01, low=0.001, high=0.1),
    "command_timeout_s": non_negative("s; while active, fault when no valid request arrives for this long "
                                      "(a lost command channel); 0 = off", default=0.0, high=DAY_S),
    "client_timeout_s": Field(float, "s; a client that sends no complete request for this long is disconnected "
                                     "(idle or half-line clients cannot hold the slots)", default=10.0, low=0.1,
                              high=3600.0),
    "watchdog": Field(bool, "feed systemd's watchdog (WATCHDOG=1) from the loop's health when WatchdogSec is set",
                      default=True),
}, optional=True)


LSL = Section({
    "enabled": Field(bool, "publish the cycle records (stream 'ankle-rt') and events (marker stream "
                           "'ankle-rt-events') on the Lab Streaming Layer, from the log writer's thread; needs "
                           "pylsl (the 'lab' extra) and the run log (docs/lab.md)", default=False),
    "source_id": Field(str, "the streams' LSL source id: LabRecorder reconnects to a restarted daemon by it",
                       default="ankle-rt"),
}, optional=True)


# -- hardware backends (serial, canopen): ESCON map, encoders, strain gauges --------------------------
# Calibration values have no default (None when absent): a simulation config need not state them, and a
# hardware backend refuses to start without them, naming the key (hardware/config_values.py).

def _number_row(value: list) -> None:
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and abs(v) < 1e6 for v in value):
        raise ValueError(f"expected a list of finite numbers (|x| < 1e6 N m per count), got {value!r}")


ESCON_AMPLIFIER = Section({
    "mode": Field(str, "set-value input as set in ESCON Studio: analog (+/-10 V) or pwm (10-90 % duty)",
                  choices=("analog", "pwm")),
    "current_at_min": Field(float, "A the amplifier drives at -10 V / 10 % duty (ESCON Studio)", low=-50.0, high=50.0),
    "current_at_max": Field(float, "A the amplifier drives at +10 V / 90 % duty (ESCON Studio)", low=-50.0, high=50.0),
    "sign": Field(int, "+1/-1: motor turns the model's positive way for positive amplifier current (wiring)",
                  choices=(-1, 1)),
    "offset": Field(float, "A driven at the nominal zero set value (measured), compensated", low=-5.0, high=5.0),
    "scale": positive("measured current / current of the ESCON Studio map (gain error), compensated; "
                      "1.0: as mapped", default=1.0, high=2.0),
    "enable_active_high": Field(bool, "ESCON Studio digital input: Enable, high active", default=True),
    "ready_active_high": Field(bool, "ESCON Studio digital output: Ready, high active", default=True),
})

ESCON = Section({
    "amplifiers": ListOf(ESCON_AMPLIFIER, "motor 1, motor 2 (required on hardware; docs/escon-setup.md)",
                         default=None, length=2),
    "dac_bits": Field(int, "resolution of the bridge's bipolar +/-10 V set-value DAC", default=12, low=8, high=16),
    "pwm_counts": Field(int, "PWM timer counts per 100 % duty (pwm mode)", default=10000, low=100, high=65535),
}, optional=True)

ENCODERS = Section({
    "sign": ListOf(Field(int, "+1/-1", choices=(-1, 1)), "per motor encoder (required on hardware)",
                   default=None, length=2),
    "counter_bits": Field(int, "width of the bridge's quadrature counters (required on hardware)",
                          default=None, choices=(16, 32)),
    "stuck_torque": positive("N m of unbalanced motor torque (kt i - R^-T tau_sg) that must move the motor",
                             default=2.0, high=100.0),
    "stuck_time": positive("s without a count while unbalanced: encoder fault", default=0.01, high=10.0),
}, optional=True)

JOINT_ENCODERS = Section({
    "counts_per_rev": Field(int, "absolute joint encoders on a bench; absent: none", default=None, low=1, high=2**32),
    "sign": ListOf(Field(int, "+1/-1", choices=(-1, 1)), "[DP, IE]", default=[1, 1], length=2),
}, optional=True)

STRAIN_GAUGES = Section({
    "matrix": ListOf(Field(list, "N m per count from [channel 1, channel 2]", check=_number_row),
                     "rows DP, IE (required on hardware)", default=None, length=2),
    "tare": ListOf(Field(float, low=-200.0, high=200.0), "N m [DP, IE] subtracted after the matrix; recorded by ankle-rt calibrate",
                   default=None, length=2),
    "rail_low": Field(int, "raw count at or below which a channel is at its rail (broken wire)", default=None,
                      low=-2**31, high=2**31),
    "rail_high": Field(int, "raw count at or above which a channel is at its rail", default=None,
                       low=-2**31, high=2**31),
    "adc_bits": Field(int, "signed ADC resolution (emulator saturation)", default=24, low=8, high=32),
}, optional=True)

SERIAL = Section({
    "port": Field(str, "serial device of the bridge (/dev/ttyACM0) or a pyserial URL (socket://host:port)",
                  default=None),
    "baudrate": Field(int, "bit/s on a UART link (ignored by USB CDC); the 1 kHz frames must fit in 70 %",
                      default=2_000_000, low=9600, high=100_000_000),
    "watchdog_s": Field(float, "the bridge zeroes set values and drops enables after this long without a "
                               "valid command (sent in the CONFIG frame)", default=0.005, low=0.001, high=1.0),
    "sample_wait_s": Field(float, "read() waits at most this long for a new sample (< one period)",
                           default=0.0008, low=0.0, high=0.01),
    "link_timeout_s": Field(float, "no new sample for this long: LINK_LOST", default=0.003, low=0.001, high=1.0),
    "open_timeout_s": positive("wait this long for the bridge to acknowledge its configuration", default=1.0,
                               high=60.0),
    "emulator": Field(str, "lockstep: run the bridge emulator in this process on a pty pair, stepped by each "
                           "command (bench tests; serial.port is then ignored); none: a bridge on serial.port",
                      default="none", choices=("none", "lockstep")),
}, optional=True, doc="serial bridge transport (backend: serial)")


DIAGNOSIS = Section({
    "cogging_periods_per_motor_rev": Field(int, "cogging periods per motor revolution (the motor's pole/slot "
                                                "count): a prior for `ankle-rt diagnose`, which finds the count "
                                                "without it too", default=None, low=1, high=200),
}, optional=True, doc="hints for `ankle-rt diagnose` (optional)")


SCHEMA = Section({
    "backend": Field(str, "backend name: sim, serial or canopen"),
    "diagnosis": DIAGNOSIS,
    "actuator": ACTUATOR,
    "transmission": TRANSMISSION,
    "foot": FOOT,
    "amplifier": AMPLIFIER,
    "controller": CONTROLLER,
    "limits": LIMITS,
    "wearer": WEARER,
    "sensors": SENSORS,
    "sim": SIM,
    "canopen": CANOPEN,
    "service": SERVICE,
    "lsl": LSL,
    "estimation": ESTIMATION,
    "reference": REFERENCE,
    "loop": LOOP,
    "safety": SAFETY,
    "logging": LOGGING,
    "escon": ESCON,
    "encoders": ENCODERS,
    "joint_encoders": JOINT_ENCODERS,
    "strain_gauges": STRAIN_GAUGES,
    "serial": SERIAL,
}, open=False)


def check_consistency(cfg: Mapping[str, Any], origin: Callable[[KeyPath], str]) -> None:
    """What one key alone cannot state: the peak current is not below the continuous one, LSL has the
    run log to publish from, and the configured gains lie within the run-time gain limits
    (``controller.gain_limits``)."""
    amp = cfg["amplifier"]
    if amp["current_limit_peak"] < amp["current_limit_continuous"]:
        raise ConfigError(f"must be >= amplifier.current_limit_continuous ({amp['current_limit_continuous']:g} A), "
                          f"got {amp['current_limit_peak']:g}", origin(("amplifier", "current_limit_peak")),
                          "amplifier.current_limit_peak")
    if cfg["lsl"]["enabled"] and not cfg["logging"]["enabled"]:
        raise ConfigError("needs logging.enabled: true (the log writer's thread publishes the streams)",
                          origin(("lsl", "enabled")), "lsl.enabled")
    ctl = cfg["controller"]
    limits = ctl["gain_limits"]
    checks = [((set_name, gain), limits[gain], ctl[set_name][gain])
              for set_name in ("validation_gains", "step_gains") for gain in ("kp", "kd")]
    checks += [(("impedance", name), limits[name.split("_")[0]], ctl["impedance"][name])
               for name in ("stiffness_dp", "stiffness_ie", "damping_dp", "damping_ie")]
    check_walking_limits(cfg, origin)
    check_walking_current(cfg, origin)
    check_oscillation_limit(cfg, origin)
    check_device_deadlines(cfg, origin)
    check_gait_load_thresholds(cfg, origin)
    check_profile_rate(cfg, origin)
    check_reference_rate_limit(cfg, origin)
    check_notch_frequencies(cfg, origin)
    for (section, name), limit, value in checks:
        if value > limit:
            limit_key = f"controller.gain_limits.{name.split('_')[0]}"
            raise ConfigError(f"must be <= {limit_key} ({limit:g}), got {value:g}",
                              origin(("controller", section, name)), f"controller.{section}.{name}")


def check_oscillation_limit(cfg: Mapping[str, Any], origin: Callable[[KeyPath], str]) -> None:
    """The oscillation detector trips on what the I^2 t budget never catches: a sine at the band's
    corner whose RMS is the continuous current (I^2 t grows only above it) shows the detector at least
    band_floor(BAND_HZ) of that, which must lie above the limit. (Slower oscillations show it less;
    the detector is not meant for them.)"""
    i_cont, limit, rate = (cfg["amplifier"]["current_limit_continuous"], cfg["safety"]["oscillation_rms_a"],
                           cfg["controller"]["rate_hz"])
    most = band_floor(BAND_HZ, 1.0 / rate) * i_cont
    if limit >= most:
        raise ConfigError(f"must be < {most:.3g} A: a {BAND_HZ:g} Hz oscillation of the continuous current "
                          f"(amplifier.current_limit_continuous, {i_cont:g} A RMS: never an OVERCURRENT) shows the "
                          f"detector at least {most:.3g} A at {rate} Hz and must trip it, got {limit:g}",
                          origin(("safety", "oscillation_rms_a")), "safety.oscillation_rms_a")


UNLOADED_NOISE_SIGMAS = 3.0   # gauge noise an unloaded foot's reading must clear, in standard deviations


def check_gait_load_thresholds(cfg: Mapping[str, Any], origin: Callable[[KeyPath], str]) -> None:
    """The gait-phase load thresholds can fire: toe-off (``load_off_nm``) lies above what a foot off the
    ground reads held still - its own gravity moment, at most foot.mass x g x |foot.com_dp|, plus 3 x the
    gauge noise - so an unloaded foot leaves stance (and re-arms the safe phase), and heel strike
    (``load_on_nm``) above toe-off: the hysteresis."""
    gait, foot = cfg["controller"]["gait_phase"], cfg["foot"]
    where = ("controller", "gait_phase", "load_off_nm")
    rest = foot["mass"] * GRAVITY * abs(foot["com_dp"]) + UNLOADED_NOISE_SIGMAS * cfg["sensors"]["strain_gauge_noise_rms"]
    if gait["load_off_nm"] <= rest:
        raise ConfigError(f"must be > {rest:.3g} N m, what a foot off the ground held still reads (its gravity moment "
                          f"foot.mass x g x |foot.com_dp| + {UNLOADED_NOISE_SIGMAS:g} x sensors.strain_gauge_noise_rms): "
                          f"below it toe-off is never detected and the safe phase never re-arms, got "
                          f"{gait['load_off_nm']:g}", origin(where), "controller.gait_phase.load_off_nm")
    if gait["load_off_nm"] >= gait["load_on_nm"]:
        raise ConfigError(f"must be < controller.gait_phase.load_on_nm ({gait['load_on_nm']:g}): the hysteresis, "
                          f"got {gait['load_off_nm']:g}", origin(where), "controller.gait_phase.load_off_nm")


def check_profile_rate(cfg: Mapping[str, Any], origin: Callable[[KeyPath], str]) -> None:
    """A configured sine, chirp or gait profile (a configured profile is not rate-limited at run time; a
    commanded one is, to reference.max_rate_rad_s) asks no motor to move faster than
    safety.max_motor_speed_rad_s. Sine and chirp: at most |R| (|amplitude_dp|, |amplitude_ie|) 2 pi f at
    the highest frequency (the axes' peaks aligned); gait: R (DP rate, IE rate) over the stride's table,
    exactly. Beyond, the loop cannot follow: it runs between the peak currents, below the oscillation
    detector's band (a 5 Hz, 0.6 rad DP sine: +-15 A for 21 s until the I2t, foot +-8 deg; a 0.3 s
    stride at scale 2: the 15 A clamp in 54 % of the cycles for 8 s, no fault)."""
    ref = cfg["reference"]
    name = ref["profile"]
    if name not in ("sine", "chirp", "gait"):
        return
    p = ref[name]
    R = motor_ratio(TransmissionParams(**cfg["transmission"]))
    most = cfg["safety"]["max_motor_speed_rad_s"]
    if name == "gait":      # the motor speed goes as 1 / stride_s
        key, bound, given = "stride_s", ">=", "s with this scale"
        speed = max(abs(R[i, 0] * dp + R[i, 1] * ie) for dp, ie in Gait(p["stride_s"], p["scale"]).rates()
                    for i in range(2))
        limit = p[key] * speed / most
    else:                   # as the frequency
        key = "frequency_hz" if name == "sine" else max(("f0_hz", "f1_hz"), key=lambda k: p[k])
        bound, given = "<=", "Hz with these amplitudes"
        speed = 2.0 * math.pi * p[key] * max(abs(R[i, 0]) * abs(p["amplitude_dp"])
                                             + abs(R[i, 1]) * abs(p["amplitude_ie"]) for i in range(2))
        limit = p[key] * most / max(speed, 1e-300)
    if speed > most:
        raise ConfigError(f"must be {bound} {limit:.3g} {given}: the motors would have to move at up to {speed:.3g} "
                          f"rad/s, beyond safety.max_motor_speed_rad_s ({most:g}); the loop cannot follow and runs "
                          f"between the peak currents, got {p[key]:g}", origin(("reference", name, key)),
                          f"reference.{name}.{key}")


def check_reference_rate_limit(cfg: Mapping[str, Any], origin: Callable[[KeyPath], str]) -> None:
    """reference.max_rate_rad_s, the rate a commanded or CSV reference is limited to, asks no motor to
    move faster than safety.max_motor_speed_rad_s with both axes at that rate (|R| (1, 1)). Up to 20
    rad/s was accepted: a commanded 5 Hz, 0.6 rad DP sine then held the 15 A clamp in a quarter of the
    cycles until the motor-speed fault 0.18 s in."""
    R = motor_ratio(TransmissionParams(**cfg["transmission"]))
    most, rate = cfg["safety"]["max_motor_speed_rad_s"], cfg["reference"]["max_rate_rad_s"]
    per_rad_s = max(abs(R[i, 0]) + abs(R[i, 1]) for i in range(2))   # motor rad/s per ankle rad/s
    if rate * per_rad_s > most:
        raise ConfigError(f"must be <= {most / per_rad_s:.3g} rad/s: at {rate:g} the motors would have to move at up to "
                          f"{rate * per_rad_s:.3g} rad/s, beyond safety.max_motor_speed_rad_s ({most:g}), got {rate:g}",
                          origin(("reference", "max_rate_rad_s")), "reference.max_rate_rad_s")


def check_notch_frequencies(cfg: Mapping[str, Any], origin: Callable[[KeyPath], str]) -> None:
    """A torque-loop notch lies below the loop's Nyquist frequency where the loop runs it (moved to the
    configured cable, :class:`ankle_rt.notch.Notch`): the sampled band-stop has nowhere else to be (the
    schema's MAX_NOTCH_HZ is the 1 kHz loop's; controller.rate_hz goes down to 250 Hz). Checked where the loop
    runs (a controller that uses it); the motor-side PD at 250 Hz keeps the shipped 1 kHz loop's notches."""
    if not torque_loop_used(cfg):
        return
    rate, loop = cfg["controller"]["rate_hz"], cfg["controller"]["torque_loop"]
    k = cfg["transmission"]["cable_stiffness"]
    scale = cable_scale(loop, k)
    for key, hz in ((f"{n}_hz_{a}", hz) for n in PREFIXES for a, hz in zip(AXES, Notch.from_config(loop, k, n).hz)):
        if hz >= 0.5 * rate:
            moved = "" if scale == 1.0 else (
                f" (it runs at {hz:g} Hz: placed for controller.torque_loop.notch_cable_stiffness "
                f"{loop['notch_cable_stiffness']:g} N/m, moved x{scale:.3g} to transmission.cable_stiffness {k:g})")
            raise ConfigError(f"must be < {0.5 * rate / scale:.4g} Hz: the notch must lie below the Nyquist frequency "
                              f"of controller.rate_hz ({rate}), {0.5 * rate:g} Hz{moved}, got {loop[key]:g}",
                              origin(("controller", "torque_loop", key)), f"controller.torque_loop.{key}")


DEVICE_MAX_STALL_S = 0.1           # s: the longest the device may act on old data or old set values
DEVICE_MAX_OVERRUNS = 50           # overruns in a row the device's loop may be told to ride out


def check_device_deadlines(cfg: Mapping[str, Any], origin: Callable[[KeyPath], str]) -> None:
    """On the device (any backend but the simulator) no setting may let it act on old data or old set
    values for longer than DEVICE_MAX_STALL_S: the loop riding out a stall, the loop driving on a
    frozen sample until it sees that the samples stopped, the bridge or I/O node keeping the last set
    values when the host stops sending them. The schema's wider ranges serve simulated runs on busy
    machines (tests, lockstep)."""
    backend = cfg["backend"]
    if backend == "sim":
        return
    most = DEVICE_MAX_STALL_S
    stall = "the last set values stay on the motors while the loop stalls"
    blind = "the loop drives on the last sample until it sees that the samples stopped"
    held = "the last set values stay on the motors when the host stops sending them"
    loop = cfg["loop"]
    # (section, key, value, most, unit, why)
    checks = [("loop", "max_stall_s", loop["max_stall_s"], most, " s", stall),
              ("loop", "max_consecutive_overruns", loop["max_consecutive_overruns"], DEVICE_MAX_OVERRUNS, "", stall),
              ("safety", "stale_cycles", cfg["safety"]["stale_cycles"], most * cfg["controller"]["rate_hz"],
               f" cycles ({most:g} s)", blind)]
    if backend == "serial":
        s = cfg["serial"]
        checks += [("serial", "link_timeout_s", s["link_timeout_s"], most, " s", blind),
                   ("serial", "watchdog_s", s["watchdog_s"], most, " s", f"the bridge's watchdog: {held}")]
    if backend == "canopen":
        co = cfg["canopen"]
        checks += [("canopen", "heartbeat_consumer_ms", co["heartbeat_consumer_ms"], most * 1e3, " ms",
                    f"no heartbeat: {blind}"),
                   ("canopen", "rpdo_timeout_ms", co["rpdo_timeout_ms"] or math.inf, most * 1e3, " ms and not 0 (none)",
                    f"the node's RPDO deadline: {held}")]
    for section, key, value, limit, unit, why in checks:
        if value > limit:
            raise ConfigError(f"must be <= {limit:g}{unit} with backend {backend!r}: {why}, got "
                              f"{cfg[section][key]:g}", origin((section, key)), f"{section}.{key}")


def check_walking_limits(cfg: Mapping[str, Any], origin: Callable[[KeyPath], str]) -> None:
    """The strain-gauge checks fit the gauges and the wearer: the rail is below the gauges' full scale
    (a gauge failed to full scale still trips SG_RAIL) and above the wearer's walking moment, the jump
    check below the rail (a glitch from rest smaller than the rail still trips it), and, on
    the device or the walking scenario, the jump check above walking's fastest torque change per
    sample (a walker never trips them)."""
    safety, mass = cfg["safety"], cfg["wearer"]["mass_kg"]
    rail, full = safety["sg_rail_nm"], cfg["sensors"]["strain_gauge_range_nm"]
    where = ("safety", "sg_rail_nm")
    if rail >= full:
        raise ConfigError(f"must be below sensors.strain_gauge_range_nm ({full:g} N m): a gauge failed to its "
                          f"full scale must still read as at its rail, got {rail:g}", origin(where), "safety.sg_rail_nm")
    need = WALKING_PEAK_MOMENT_PER_KG * mass
    if rail < need:
        raise ConfigError(f"must be >= {need:g} N m for a {mass:g} kg wearer (wearer.mass_kg x "
                          f"{WALKING_PEAK_MOMENT_PER_KG:g} N m/kg, walking's peak moment with margin), got {rail:g}",
                          origin(where), "safety.sg_rail_nm")
    if safety["max_sg_step_nm"] >= rail:
        raise ConfigError(f"must be < safety.sg_rail_nm ({rail:g} N m): a reading jumping from rest by less than the "
                          f"rail must still trip SG_JUMP (at twice the rail it never can), got {safety['max_sg_step_nm']:g}",
                          origin(("safety", "max_sg_step_nm")), "safety.max_sg_step_nm")
    # the jump check per sample: a slower loop sees more change per sample. Checked where someone walks:
    # on the device, or the simulator's walking scenario (a bench config at another rate need not be)
    step = WALKING_TORQUE_STEP_PER_KG * mass * 1000.0 / cfg["controller"]["rate_hz"]
    if walked(cfg) and safety["max_sg_step_nm"] < step:
        raise ConfigError(f"must be >= {step:.3g} N m for a {mass:g} kg wearer at {cfg['controller']['rate_hz']} Hz "
                          f"(walking's fastest torque change per sample with margin), got {safety['max_sg_step_nm']:g}",
                          origin(("safety", "max_sg_step_nm")), "safety.max_sg_step_nm")


def motor_shares(cfg: Mapping[str, Any]) -> np.ndarray:
    """|R^-T|: N m on motor i (at the gearbox output) per N m on ankle axis j [DP, IE] (1/9 and 1/5
    nominal): what each motor carries of an ankle torque."""
    return np.abs(np.linalg.inv(motor_ratio(TransmissionParams(**cfg["transmission"])).T))


def dp_torque_at_peak(cfg: Mapping[str, Any]) -> float:
    """N m of DP ankle torque the motors give with each at ``amplifier.current_limit_peak`` (224 N m
    nominal): what a walk may ask of the motors before the current clamp."""
    peak_nm = cfg["actuator"]["torque_constant"] * cfg["amplifier"]["current_limit_peak"]
    return float(peak_nm / motor_shares(cfg)[:, 0].max())


def walking_budget(cfg: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray, float, str]:
    """(|R^-T| shares, N m per motor for the heaviest wearer's rendered walking moment, a motor's N m at
    the peak current, the moment's description for errors)."""
    share = motor_shares(cfg)
    mass = cfg["wearer"]["mass_kg"]
    need = WALKING_RENDERED_MOMENT_PER_KG * mass
    what = f"its share of a {mass:g} kg wearer's rendered walking moment ({need:g} N m DP: wearer.mass_kg x " \
           f"{WALKING_RENDERED_MOMENT_PER_KG:g} N m/kg)"
    return share, share[:, 0] * need, cfg["actuator"]["torque_constant"] * cfg["amplifier"]["current_limit_peak"], what


def walked(cfg: Mapping[str, Any]) -> bool:
    """Someone walks on this config: the device, or the simulator's walking scenario."""
    return cfg["backend"] != "sim" or cfg["sim"]["scenario"] == "walking"


def torque_loop_used(cfg: Mapping[str, Any]) -> bool:
    """The controller runs the joint-torque loop (impedance or gait phase, :func:`torque_feedback`)."""
    return cfg["controller"]["type"] in ("impedance", "gait_phase") and torque_feedback(cfg)


def correction_shares(cfg: Mapping[str, Any], share: np.ndarray) -> np.ndarray:
    """N m per motor of the larger of the joint-torque loop's two clamps (one wrong reading at a time);
    zero without the loop."""
    ctl = cfg["controller"]
    if not torque_loop_used(cfg):
        return np.zeros(share.shape[0])
    loop = ctl["torque_loop"]
    return np.maximum(share[:, 0] * loop["max_correction_dp"], share[:, 1] * loop["max_correction_ie"])


def walking_correction_limits(cfg: Mapping[str, Any]) -> tuple[float, float] | None:
    """N m [DP, IE]: the largest clamp each axis may have where someone walks (each motor's share of the
    heaviest wearer's walking moment plus its share of that clamp within its torque at the peak current;
    rounded down to 0.01), None where nobody walks or the walking moment alone does not fit."""
    if not walked(cfg):
        return None
    share, walking, motor_peak, _ = walking_budget(cfg)
    if walking.max() > motor_peak:
        return None
    return tuple(math.floor(float(((motor_peak - walking) / share[:, axis]).min()) * 100) / 100 for axis in (0, 1))


def resolve_correction_clamps(cfg: MutableMapping[str, Any]) -> None:
    """Fill an unset ``controller.torque_loop.max_correction_dp`` / ``_ie`` in place: MAX_CORRECTION_WALKED
    where someone walks (:func:`walked`), else MAX_CORRECTION_BENCH."""
    loop, clamps = cfg["controller"]["torque_loop"], MAX_CORRECTION_WALKED if walked(cfg) else MAX_CORRECTION_BENCH
    for key, clamp in zip(("max_correction_dp", "max_correction_ie"), clamps):
        if loop[key] is None:
            loop[key] = clamp


def check_walking_current(cfg: Mapping[str, Any], origin: Callable[[KeyPath], str]) -> None:
    """Where someone walks (on the device, or the simulator's walking scenario), each motor's torque at
    the peak current covers its share of the heaviest wearer's rendered walking moment
    (WALKING_RENDERED_MOMENT_PER_KG x wearer.mass_kg, DP) and, with the joint-torque loop, its share of
    either axis's max_correction beside it. A correction at its clamp is what one wrong or glitching
    reading adds; with one such reading the motors must still render the walk, else it runs at the
    current clamp: max_correction_dp 100 N m held 15 A in 776 cycles of 12 strides at 100 kg fast (up to
    72 ms in a row; a 12 A peak: 580 in 6), max_correction_ie 100 with config/torque-loop-lag-notch.yaml
    73 cycles at the toe-offs. Both corrections at their clamps at once (two wrong readings) do not fit
    beside the walking moment even with the shipped clamps: not required."""
    if not walked(cfg):
        return
    share, walking, motor_peak, what = walking_budget(cfg)
    peak, kt = cfg["amplifier"]["current_limit_peak"], cfg["actuator"]["torque_constant"]
    if walking.max() > motor_peak:
        raise ConfigError(f"must be >= {math.ceil(walking.max() / kt * 100) / 100:g} A: a motor at the peak current gives {motor_peak:.3g} N m, "
                          f"below {what}, {walking.max():.3g} N m, got {peak:g}",
                          origin(("amplifier", "current_limit_peak")), "amplifier.current_limit_peak")
    if not correction_shares(cfg, share).any():
        return
    loop = cfg["controller"]["torque_loop"]
    for axis, (name, most) in enumerate(zip(("dp", "ie"), walking_correction_limits(cfg))):
        key = f"max_correction_{name}"
        if loop[key] > most:
            raise ConfigError(f"must be <= {most:g} N m: a motor at the peak current gives {motor_peak:.3g} N m, and "
                              f"{what} plus its share of the correction must fit in it, got {loop[key]:g}",
                              origin(("controller", "torque_loop", key)), f"controller.torque_loop.{key}")
