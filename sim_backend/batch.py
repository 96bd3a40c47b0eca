"""Many simulated devices stepped at once: the compliant model vectorised over a batch with numpy.

A batch is built from one :class:`~sim_backend.plant.SimulatedPlant` per plant (each from its own
config, so every parameter may differ) and *stacks* them: the state is (8, plants), each parameter an
array over the plants, and the model's own :meth:`CompliantModel.generalized_forces` runs unchanged
on rows of those arrays (it is written element-wise). The linear part uses each plant's exact
discretisation (one matrix product when all plants share it). Effects: an ``elementwise`` effect is
stacked and called once per hook for all plants; any other is called plant by plant (correct,
slower), so a new effect works in a batch without edits. The amplifier limits are the same
:class:`~sim_backend.amplifier.EsconCurrentLimit` law, stacked.

Plants in one batch must share the structure: control period, substeps, the effect types in order,
``sim.cables`` (:meth:`BatchPlant.structure_key` groups configs that can share a batch).
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from ankle_rt.elementwise import stack
from ankle_rt.params import PlantParams
from sim_backend.effects import Effect, build_effects
from sim_backend.model import CompliantModel
from sim_backend.plant import SimulatedPlant, advance, check_disturbances

# strain-gauge noise drawn per plant this many samples at a time: the same stream as the single
# plant's larger blocks (a generator's normals do not depend on the chunking), and the transpose to
# (samples, 2, plants) stays in cache (twice as fast per tick as 4096 at 256 plants)
NOISE_BLOCK = 512


class PlantByPlant:
    """An effect that is not element-wise, run in a batch by calling each plant's instance."""

    def __init__(self, effects: Sequence[Effect]):
        self.effects = list(effects)
        self.kind = type(effects[0])
        self.min_substeps = self.kind.min_substeps
        self.needs_cable_torque = getattr(self.kind, "needs_cable_torque", False)

    def uses(self, hook: str) -> bool:
        return self.kind.uses(hook)

    def _each(self, hook: str, *columns) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.effects)
        cols = [np.broadcast_to(np.asarray(c, dtype=float), (n,)) for c in columns]
        a, b = np.empty(n), np.empty(n)
        for i, e in enumerate(self.effects):
            a[i], b[i] = getattr(e, hook)(*(float(c[i]) for c in cols))
        return a, b

    def motor_torque(self, *args):
        return self._each("motor_torque", *args)

    def cable_torque(self, *args):
        return self._each("cable_torque", *args)

    def command(self, *args):
        return self._each("command", *args)

    def reset(self) -> None:
        for e in self.effects:
            e.reset()


def stack_effects(effects: Sequence[Effect]):
    """One stand-in for the same effect of every plant of a batch."""
    kind = type(effects[0])
    if any(type(e) is not kind for e in effects):
        raise ValueError("a batch needs the same effect types in the same order on every plant")
    if kind.elementwise:
        try:
            return kind.stack(effects)
        except ValueError:        # per-plant data that is not a number (a table, a list)
            pass
    return PlantByPlant(effects)


def stacked_matrix(matrices: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray | None]:
    """One matrix per plant as (rows, columns, plants), einsum's fast layout, and the one matrix
    when every plant has the same (None otherwise)."""
    stacked = np.array(matrices)
    shared = stacked[0] if np.all(stacked == stacked[0]) else None
    return np.ascontiguousarray(stacked.transpose(1, 2, 0)), shared


class BatchModel(CompliantModel):
    """The compliant model of ``len(models)`` plants; ``x`` is (8, plants). Same equations, same
    Heun substeps as :class:`CompliantModel` (whose force code it runs on arrays)."""

    def __init__(self, models: Sequence[CompliantModel]):   # noqa: super().__init__ not called: stacked
        first = models[0]
        for m in models:
            if (m.dt, m.substeps, m.cables) != (first.dt, first.substeps, first.cables) \
                    or len(m.effects) != len(first.effects):
                raise ValueError("a batch needs the same period, substeps, cables and effects on every plant")
        self.n = n = len(models)
        self.dt, self.substeps, self.cables = first.dt, first.substeps, first.cables
        self.linear = first.linear
        self.effects = [stack_effects([m.effects[i] for m in models]) for i in range(len(first.effects))]
        self._motor_fx = [e.motor_torque for e in self.effects if e.uses("motor_torque")]
        self._cable_fx = [e.cable_torque for e in self.effects if e.uses("cable_torque")] if self.cables else []
        self._command_fx = [e.command for e in self.effects if e.uses("command")]
        self._needs_tc = first._needs_tc

        def rows(name: str) -> np.ndarray:   # (entries, plants)
            return np.array([np.atleast_1d(getattr(m, name)) for m in models], dtype=float).T.copy()

        self._Ri, self._RiT = rows("_Ri"), rows("_RiT")
        self._motor_cable = rows("_motor_cable")
        self._beta, self._grav = rows("_beta")[0], rows("_grav")[0]
        self._predict, self._predict_shared = stacked_matrix([m._predict for m in models])
        self._correct, self._correct_shared = stacked_matrix([m._correct for m in models])
        self._torque_rows, self._torque_rows_shared = stacked_matrix([m._torque_rows for m in models])
        self._z = np.zeros((16, n))      # [x; f; g], as CompliantModel's
        self._x_next = np.zeros((8, n))
        self.x = self._z[:8]
        self._xf = self._z[:12]          # [x; f]: what the prediction reads
        self.tau_applied = [np.zeros(n), np.zeros(n)]
        self.load = None

    def reset(self, x0: np.ndarray | None = None) -> None:
        self._z[:] = 0.0
        if x0 is not None:
            self._z[:8] = x0
        for e in self.effects:
            e.reset()

    @staticmethod
    def _linear(stacked: np.ndarray, shared: np.ndarray | None, z: np.ndarray, out: np.ndarray) -> None:
        """out = each plant's matrix @ its column of z (one product when all plants share it)."""
        if shared is not None:
            np.dot(shared, z, out=out)
        else:
            np.einsum("ijn,jn->in", stacked, z, out=out)

    def step(self, tau1, tau2, td_dp=0.0, td_ie=0.0) -> None:
        """Advance every plant one control tick; torques and disturbances are arrays (plants,) or floats."""
        tau1, tau2 = self.command_torque(tau1, tau2)
        self.tau_applied[0], self.tau_applied[1] = tau1, tau2
        z, x, x_next = self._z, self.x, self._x_next
        forces, linear = self.generalized_forces, self._linear
        for _ in range(self.substeps):     # Heun, as CompliantModel.step
            z[8], z[9], z[10], z[11] = forces(x, tau1, tau2, td_dp, td_ie)
            linear(self._predict, self._predict_shared, self._xf, x_next)
            z[12], z[13], z[14], z[15] = forces(x_next, tau1, tau2, td_dp, td_ie)
            linear(self._correct, self._correct_shared, z, x_next)
            x[:] = x_next

    def joint_torque(self) -> tuple[np.ndarray, np.ndarray]:
        """N m [DP, IE] per plant, as CompliantModel.joint_torque (new arrays)."""
        t = np.empty((2, self.n))
        self._linear(self._torque_rows, self._torque_rows_shared, self.x, t)
        return self.with_cable_effects(self.x, t[0], t[1])


class BatchPlant:
    """``len(cfgs)`` simulated devices (:class:`SimulatedPlant` each, stacked): ESCON limits,
    quantised encoders, strain-gauge noise (each plant's own seeded stream, as alone) and the
    configured disturbances. Sensor outputs are arrays over the plants."""

    @staticmethod
    def structure_key(cfg: Mapping[str, Any]) -> tuple:
        """Configs with equal keys can be stepped in one batch."""
        sim = cfg["sim"]
        return (cfg["controller"]["rate_hz"], sim["substeps"], sim["cables"], sim["friction"],
                tuple(e["type"] for e in sim["effects"]), sim["scenario"])

    @staticmethod
    def check_config(cfg: Mapping[str, Any]) -> None:
        """What the config validation leaves to the plant (the effects' own parameters, the
        disturbance pulses), without building it; raises ConfigError naming the key."""
        source = getattr(cfg, "source", "config")
        build_effects(cfg["sim"]["effects"], PlantParams.from_config(cfg), 1.0 / cfg["controller"]["rate_hz"], source)
        check_disturbances(cfg["sim"]["disturbances"], source)

    def __init__(self, cfgs: Sequence[Mapping[str, Any]], source: str = "config"):
        plants = [SimulatedPlant(c, source) for c in cfgs]
        first = plants[0]
        self.n = n = len(plants)
        self.dt = first.dt            # one control period: BatchModel refuses models that differ
        self.model = BatchModel([p.model for p in plants])
        self.amps = [stack([p.amps[k] for p in plants]) for k in range(2)]   # numbers only
        self.kt = np.array([p.kt for p in plants])
        self.counts_per_rad = np.array([p.counts_per_rad for p in plants])
        self.joint_counts_per_rad = np.array([p.joint_counts_per_rad for p in plants])
        self.quantize = np.array([p.quantize for p in plants])
        self.noise_rms = np.array([p.noise_rms for p in plants])
        self.sg_offset = np.array([p.sg_offset for p in plants]).T.copy()       # (2, plants)
        m = max(len(p.disturbances) for p in plants)
        self._dist = np.zeros((4, m, n))     # start, stop, torque_dp, torque_ie per entry and plant
        self._dist[0:2] = np.inf
        for j, p in enumerate(plants):
            for i, d in enumerate(p.disturbances):
                self._dist[:, i, j] = d["start"], d["stop"], d["torque_dp"], d["torque_ie"]
        self.walking = None
        if first.walking is not None:
            from sim_backend.walking import WalkingScenario

            self.walking = self.model.load = WalkingScenario.stack([p.walking for p in plants])
        self.rngs = [p.rng for p in plants]
        self._noise = np.zeros((NOISE_BLOCK, 2, n))          # read per tick: (2, plants) contiguous
        self._draw = np.empty((n, NOISE_BLOCK, 2))           # each plant's stream drawn as alone
        self._noise_i = NOISE_BLOCK
        self.current = [np.zeros(n), np.zeros(n)]
        self.ticks = 0
        self.t = 0.0      # s, ticks * dt (kept with ticks: read every tick)
        self.model.reset()

    def disturbance(self) -> tuple[np.ndarray | float, np.ndarray | float]:
        """N m at the ankle [DP, IE] per plant at the current time."""
        if self._dist.shape[1] == 0:
            return 0.0, 0.0
        t = self.t
        d = self._dist
        on = (d[0] <= t) & (t < d[1])
        return (np.where(on, d[2], 0.0).sum(axis=0), np.where(on, d[3], 0.0).sum(axis=0))

    def step(self, current_1, current_2) -> None:
        """Advance one tick with the set values (A, arrays over the plants) held."""
        advance(self, current_1, current_2)

    # -- sensors ---------------------------------------------------------------------------------
    def motor_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """rad: what the encoders report (floor-quantised where configured)."""
        x, c = self.model.x, self.counts_per_rad
        return self._quantized(x[2], c), self._quantized(x[3], c)

    def ankle_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """rad [DP, IE]: the joint encoders' angles (the true ones, floor-quantised where configured)."""
        x, c = self.model.x, self.joint_counts_per_rad
        return self._quantized(x[0], c), self._quantized(x[1], c)

    def _quantized(self, angle: np.ndarray, counts_per_rad: np.ndarray) -> np.ndarray:
        """rad per plant: ``angle`` floored to its count where the plant quantises."""
        if self.quantize.all():
            return np.floor(angle * counts_per_rad) / counts_per_rad
        return np.where(self.quantize, np.floor(angle * counts_per_rad) / counts_per_rad, angle)

    def strain_gauge_torques(self, joint=None) -> tuple[np.ndarray, np.ndarray]:
        """N m [DP, IE]: joint torque (``joint``, if the caller has it already) plus each plant's
        offset and noise."""
        t0, t1 = self.model.joint_torque() if joint is None else joint
        if self._noise_i >= NOISE_BLOCK:
            for j, rng in enumerate(self.rngs):
                if self.noise_rms[j] > 0.0:
                    rng.standard_normal(out=self._draw[j])
            self._noise[:] = self._draw.transpose(1, 2, 0)
            self._noise_i = 0
        n = self._noise[self._noise_i]
        self._noise_i += 1
        return (t0 + self.noise_rms * n[0] + self.sg_offset[0], t1 + self.noise_rms * n[1] + self.sg_offset[1])

    def cable_torques(self, joint=None) -> tuple[np.ndarray, np.ndarray]:
        """N m: the cable torque each motor feels, R^-T of the joint torque (reciprocal transmission)."""
        t0, t1 = self.model.joint_torque() if joint is None else joint
        RiT = self.model._RiT
        return RiT[0] * t0 + RiT[1] * t1, RiT[2] * t0 + RiT[3] * t1

