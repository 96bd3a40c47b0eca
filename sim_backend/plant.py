"""The simulated device: the compliant model behind ESCON current limits, with the device's sensors.

Shared by the simulated backend and by the hardware emulators, so every path to "the device" runs
the same plant. Stepped once per control tick with the amplifier set values held (zero-order hold).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ankle_rt.config import ConfigError
from ankle_rt.float_buffer import float_buffer
from ankle_rt.loop_setup import joint_encoder_counts
from ankle_rt.params import PlantParams
from sim_backend.amplifier import EsconCurrentLimit
from sim_backend.effects import build_effects
from sim_backend.model import CompliantModel

if TYPE_CHECKING:
    from sim_backend.batch import BatchPlant

NOISE_BLOCK = 4096  # strain-gauge noise samples drawn at a time (refilled in place, no allocation)


def check_disturbances(disturbances: list, source: str | None) -> None:
    """ConfigError naming ``sim.disturbances.<i>.stop`` for a pulse that does not stop after it starts."""
    for i, d in enumerate(disturbances):
        if d["stop"] <= d["start"]:
            raise ConfigError("stop must be after start", source, f"sim.disturbances.{i}.stop")


class SimulatedPlant:
    """Time ``t`` (s) counts from construction; disturbances in the config use that time."""

    def __init__(self, cfg: dict, source: str = "config"):
        self.params = p = PlantParams.from_config(cfg)
        sim = cfg["sim"]
        self.dt = 1.0 / cfg["controller"]["rate_hz"]
        effects = build_effects(sim["effects"], p, self.dt, source)
        self.model = CompliantModel(p, dt=self.dt, substeps=sim["substeps"], friction=sim["friction"],
                                    cables=sim["cables"], effects=effects)
        self.amps = [EsconCurrentLimit(p.amplifier, self.dt) for _ in range(2)]
        self.kt = p.actuator.torque_constant
        self.counts_per_rad = p.actuator.encoder_counts_per_rev / (2.0 * math.pi)
        # the joint encoders' (the bench's 19 bit unless configured): what a stretch from the encoders is read to
        self.joint_counts_per_rad = joint_encoder_counts(cfg) / (2.0 * math.pi)
        self.quantize = sim["quantization"]
        self.noise_rms = p.strain_gauge_noise_rms if sim["sensor_noise"] else 0.0
        self.sg_offset = list(sim["strain_gauge_offset"])
        self.disturbances = sim["disturbances"]
        check_disturbances(self.disturbances, source)
        self._pulses = [(d["start"], d["stop"], d["torque_dp"], d["torque_ie"]) for d in self.disturbances]
        self._pulse_torque = (0.0, 0.0)   # N m [DP, IE]: the pulses on, summed, until _next_switch
        self._next_switch = 0.0           # s: when a pulse next switches on or off (time only grows)
        self.rng = np.random.default_rng(sim["seed"])
        # [DP, IE] per sample, drawn into a numpy view of a buffer read as plain floats
        self._noise_buf, noise = float_buffer(2 * NOISE_BLOCK)
        self._noise = noise.reshape(NOISE_BLOCK, 2)
        self._noise_i = 2 * NOISE_BLOCK   # index of the next DP sample in _noise_buf (steps of 2)
        self.extra_disturbance = [0.0, 0.0]  # N m at the ankle [DP, IE], set by tests and tools
        self.current = [0.0, 0.0]            # A actually driven in the last tick
        self.ticks = 0
        self.t = 0.0      # s, ticks * dt (kept with ticks: read every tick)
        self.walking = None
        if sim["scenario"] == "walking":
            from sim_backend.walking import WalkingScenario

            self.walking = self.model.load = WalkingScenario(sim["walking"])
        self.model.set_rest_at((0.0, 0.0))

    def disturbance(self) -> tuple[float, float]:
        """N m at the ankle [DP, IE] at the current time."""
        if self.t >= self._next_switch:
            self._switch_pulses()
        dp, ie = self.extra_disturbance
        p_dp, p_ie = self._pulse_torque
        return dp + p_dp, ie + p_ie

    def _switch_pulses(self) -> None:
        """Sum the pulses on at the current time, and find when one next switches on or off (the
        pulses are not scanned every tick)."""
        t = self.t
        dp = ie = 0.0
        for start, stop, t_dp, t_ie in self._pulses:
            if start <= t < stop:
                dp += t_dp
                ie += t_ie
        self._pulse_torque = dp, ie
        edges = [edge for pulse in self._pulses for edge in pulse[:2] if edge > t]
        self._next_switch = min(edges, default=math.inf)

    def step(self, current_1: float, current_2: float) -> None:
        """Advance one tick with the set values (A) held; the amplifiers clamp them."""
        # plain floats from here on: numpy scalars (the daemon's set values) cost ~3x per operation
        advance(self, float(current_1), float(current_2))

    # -- sensors ---------------------------------------------------------------------------------
    def encoder_counts(self) -> tuple[int, int]:
        """Quadrature counts at the gearbox output (floor, as a counter does)."""
        x = self.model.x_floats   # plain floats (numpy scalar arithmetic costs ~3x)
        c = self.counts_per_rad
        return math.floor(x[2] * c), math.floor(x[3] * c)

    def motor_positions(self) -> tuple[float, float]:
        """rad: what the encoders report (quantised if configured)."""
        if self.quantize:
            c1, c2 = self.encoder_counts()
            return c1 / self.counts_per_rad, c2 / self.counts_per_rad
        x = self.model.x_floats
        return x[2], x[3]

    def strain_gauge_torques(self) -> tuple[float, float]:
        """N m [DP, IE]: joint torque plus the sensor's offset and noise."""
        t0, t1 = self.model.joint_torque()
        rms = self.noise_rms
        if rms > 0.0:
            k = self._noise_i
            if k >= 2 * NOISE_BLOCK:
                self.rng.standard_normal(out=self._noise)
                k = 0
            self._noise_i = k + 2
            noise = self._noise_buf
            t0 += rms * noise[k]
            t1 += rms * noise[k + 1]
        offset = self.sg_offset
        return t0 + offset[0], t1 + offset[1]

    def ankle_positions(self) -> tuple[float, float]:
        """rad [DP, IE]: the joint encoders' angles (the true ones, quantised if configured)."""
        x = self.model.x_floats
        if self.quantize:
            c = self.joint_counts_per_rad
            return math.floor(x[0] * c) / c, math.floor(x[1] * c) / c
        return x[0], x[1]


def advance(plant: "SimulatedPlant | BatchPlant", current_1: Any, current_2: Any) -> None:
    """One tick of ``plant`` with the set values (A) held: the amplifiers clamp them, the disturbance
    pulses and the walking load act, the model steps. Written element-wise: plain floats for one
    plant, arrays over the plants for a :class:`~sim_backend.batch.BatchPlant`."""
    i1 = plant.amps[0].apply(current_1)
    i2 = plant.amps[1].apply(current_2)
    plant.current[0] = i1
    plant.current[1] = i2
    dp, ie = plant.disturbance()
    if plant.walking is not None:
        plant.walking.advance(plant.t)
    plant.model.step(plant.kt * i1, plant.kt * i2, dp, ie)
    plant.ticks += 1
    plant.t = plant.ticks * plant.dt
