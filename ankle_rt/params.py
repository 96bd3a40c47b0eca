"""Typed physical parameters, built from a validated configuration. SI units, motor side at the
gearbox output."""

from __future__ import annotations

from dataclasses import dataclass

GRAVITY = 9.81  # m/s^2


@dataclass(frozen=True)
class ActuatorParams:
    inertia: float            # kg m^2
    damping: float            # N m s/rad
    coulomb: float            # N m
    torque_constant: float    # N m/A
    gear_ratio: float
    encoder_counts_per_rev: int
    friction_smoothing_velocity: float  # rad/s


@dataclass(frozen=True)
class TransmissionParams:
    cable_stiffness: float    # N/m
    pulley_radius: float      # m
    lever_dp: float           # m
    lever_ie: float           # m
    stiffness_proportional_damping: float  # s
    form: str = "reciprocal"  # or "paper"


@dataclass(frozen=True)
class FootParams:
    mass: float               # kg
    com_dp: float             # m
    inertia_dp: float         # kg m^2
    inertia_ie: float         # kg m^2

    @property
    def gravity_gain(self) -> float:
        """N m: g_DP = gravity_gain * sin(theta_DP)."""
        return self.mass * GRAVITY * self.com_dp


@dataclass(frozen=True)
class AmplifierParams:
    current_limit_continuous: float  # A
    current_limit_peak: float        # A


@dataclass(frozen=True)
class PlantParams:
    actuator: ActuatorParams
    transmission: TransmissionParams
    foot: FootParams
    amplifier: AmplifierParams
    strain_gauge_noise_rms: float    # N m

    @classmethod
    def from_config(cls, cfg: dict) -> "PlantParams":
        return cls(
            actuator=ActuatorParams(**cfg["actuator"]),
            transmission=TransmissionParams(**cfg["transmission"]),
            foot=FootParams(**cfg["foot"]),
            amplifier=AmplifierParams(**cfg["amplifier"]),
            strain_gauge_noise_rms=cfg["sensors"]["strain_gauge_noise_rms"],
        )
