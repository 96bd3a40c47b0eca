"""The compliant model of the prosthesis (docs/design.md "Nominal model"), stepped at control ticks.

The linear part (foot and motor inertias, cable stiffness and damping, viscous friction, linearised
gravity) is discretised exactly once for the substep h = dt / substeps, so the ~100 Hz cable modes
cost nothing in accuracy. What is not linear (Coulomb friction, the rest of gravity, effects) enters
as generalised forces f, held over each substep at the mean of their values at its two ends (Heun
predictor-corrector): second order in h. Holding f at its start value alone is first order; at the
same cost it is 25x less accurate in position (tests/test_model.py, docs/simulator.md).
The motor torque command is held over the whole tick. A fixed-step RK4 on the same equations serves
as the reference solution in the tests.
"""

from __future__ import annotations

import math

import numpy as np

from ankle_rt.linear_model import N_X, LinearModel
from ankle_rt.params import PlantParams
from ankle_rt.discretize import zoh
from sim_backend.effects import Effect
from ankle_rt.elementwise import sin
from ankle_rt.float_buffer import float_buffer
from sim_backend.effects.friction import CoulombFriction


def baseline_friction(p: PlantParams, dt: float) -> CoulombFriction:
    """The nominal Coulomb friction of the actuator parameters, as an effects-library entry."""
    return CoulombFriction({"coulomb": p.actuator.coulomb,
                            "smoothing_velocity": p.actuator.friction_smoothing_velocity}, p, dt)


def heun_matrices(linear: LinearModel, h: float) -> tuple[np.ndarray, np.ndarray]:
    """The exact discretisation (ZOH) of the linear part over a substep ``h`` (s) as Heun's two
    products: ``predict @ [x; f]`` holds the forces f of the substep's start, ``correct @ [x; f; g]``
    the mean of f and of g, the forces at the predicted end (one product each, no mean formed)."""
    Ad, Bd = zoh(linear.A, linear.B, h)
    return np.hstack([Ad, Bd]), np.hstack([Ad, 0.5 * Bd, 0.5 * Bd])


class CompliantModel:
    """State x = [theta_DP, theta_IE, theta_1, theta_2, and their rates] (rad, rad/s)."""

    def __init__(self, params: PlantParams, *, dt: float, substeps: int = 2, friction: bool = True,
                 cables: bool = True, gravity: bool = True, effects: list[Effect] | tuple = ()):
        self.params = params
        self.dt = dt
        self.substeps = max([substeps] + [e.min_substeps for e in effects])
        self.cables = cables
        self.linear = LinearModel.from_params(params, cables=cables, gravity=gravity)
        self.effects: list[Effect] = ([baseline_friction(params, dt)] if friction else []) + list(effects)
        self._motor_fx = [e.motor_torque for e in self.effects if e.uses("motor_torque")]
        self._cable_fx = [e.cable_torque for e in self.effects if e.uses("cable_torque")] if cables else []
        self._command_fx = [e.command for e in self.effects if e.uses("command")]
        # the motor-felt cable torque tc is only worked out when a motor effect reads it
        self._needs_tc = cables and any(
            e.uses("motor_torque") and getattr(e, "needs_cable_torque", False) for e in self.effects)

        kin = self.linear.kin
        self._Ri = kin.R_inv.ravel().tolist()          # phi = Ri theta_m - theta
        self._RiT = kin.R_inv_T.ravel().tolist()
        self._beta = params.transmission.stiffness_proportional_damping
        self._motor_cable = self.linear.cable_Kq[2:4].ravel().tolist()  # motor-felt cable torque rows
        self._grav = params.foot.gravity_gain if gravity else 0.0
        self._torque_rows = self.linear.joint_torque_rows(self._beta)   # linear joint torque = rows @ x

        self._predict, self._correct = heun_matrices(self.linear, dt / self.substeps)
        # the correction with two rows more: the linear joint torque of the corrected state, in the
        # same product (the sensors read it after the step: no product of their own)
        self._correct_torque = np.vstack([self._correct, self._torque_rows @ self._correct])
        # z = [x; f; g]: numpy views of float buffers, so the substeps index and set the entries as
        # plain floats through the buffer (cheaper than numpy item access, and no tolist). Between
        # steps f's first two entries hold the linear joint torque of x (f is worked out afresh
        # before the next step reads it).
        self._zbuf, self._z = float_buffer(N_X + 8)
        self._next_buf, self._x_next = float_buffer(N_X)
        self._xt = self._z[:N_X + 2]   # [x; joint torque]: what a correction writes
        self.x = self._z[:N_X]  # a view: the state lives in the first 8 entries of z
        self.x.flags.writeable = False    # set it with set_state (which keeps the torque beside it)
        self.x_floats = self._zbuf[:N_X]   # the same entries, read as plain floats (the sensors)
        self._xf = self._z[:N_X + 4]   # [x; f]: what the prediction reads
        # the substeps alternate between z and this second buffer (no copy of the state per substep)
        self._zbuf_alt, self._z_alt = float_buffer(N_X + 8)
        self._xt_alt, self._xf_alt = self._z_alt[:N_X + 2], self._z_alt[:N_X + 4]
        self.tau_applied = [0.0, 0.0]   # N m, motor torque command after command effects (last tick)
        # an external load on the foot that depends on its state (the walking scenario's body), or
        # None: ``load.torque(th_dp, th_ie, w_dp, w_ie)`` -> N m [DP, IE], evaluated at every substep
        self.load = None

    # -- state -----------------------------------------------------------------------------------
    def reset(self, x0: np.ndarray | None = None) -> None:
        """State ``x0`` (default: zeros), effects restarted."""
        self._z[:] = 0.0
        self.set_state(np.zeros(N_X) if x0 is None else x0)
        for e in self.effects:
            e.reset()

    def set_state(self, x: np.ndarray) -> None:
        """Set the state (8 entries: rad, rad/s); the effects keep theirs."""
        self._z[:N_X] = x
        self._torque_rows.dot(self._z[:N_X], self._z[N_X:N_X + 2])

    def set_rest_at(self, theta: tuple[float, float]) -> None:
        """Put the foot at ankle angles ``theta`` (rad) with slack-free cables and no motion."""
        x0 = np.zeros(N_X)
        x0[0:2] = theta
        x0[2:4] = self.linear.kin.R @ np.asarray(theta, dtype=float)
        self.reset(x0)

    # -- forces ----------------------------------------------------------------------------------
    def cable_state(self, s: list[float]) -> tuple[float, float, float, float]:
        """(phi_dp, phi_ie, dphi_dp, dphi_ie): cable stretch and its rate in ankle coordinates (rad)."""
        Ri = self._Ri
        return (Ri[0] * s[2] + Ri[1] * s[3] - s[0], Ri[2] * s[2] + Ri[3] * s[3] - s[1],
                Ri[0] * s[6] + Ri[1] * s[7] - s[4], Ri[2] * s[6] + Ri[3] * s[7] - s[5])

    def cable_corrections(self, s: list[float]) -> tuple[float, float]:
        """N m [DP, IE]: the cable effects' corrections to the linear joint torque at the state ``s``."""
        p0, p1, d0, d1 = self.cable_state(s)
        dt0 = dt1 = 0.0
        for fx in self._cable_fx:
            c0, c1 = fx(p0, p1, d0, d1)
            dt0 = dt0 + c0
            dt1 = dt1 + c1
        return dt0, dt1

    def with_cable_effects(self, s: list[float], t0: float, t1: float) -> tuple[float, float]:
        """The linear joint torque ``t0, t1`` (N m) of the state ``s`` plus the cable effects'
        corrections: what the cables deliver (what the strain gauges measure). Element-wise."""
        if self._cable_fx:
            c0, c1 = self.cable_corrections(s)
            t0 = t0 + c0
            t1 = t1 + c1
        return t0, t1

    def generalized_forces(self, s: list[float], tau1: float, tau2: float,
                           td_dp: float, td_ie: float) -> tuple[float, float, float, float]:
        """The non-linear generalised forces f of the state ``s`` (8 floats, indexed), in N m.

        Written element-wise (no augmented assignment, :mod:`~ankle_rt.elementwise`
        maths), so the batch simulator runs this same code on rows of arrays over its plants."""
        th_dp = s[0]
        f0 = td_dp - self._grav * (sin(th_dp) - th_dp)
        f1 = td_ie
        if self.load is not None:
            l0, l1 = self.load.torque(th_dp, s[1], s[4], s[5])
            f0 = f0 + l0
            f1 = f1 + l1
        f2, f3 = tau1, tau2
        d2 = d3 = tc1 = tc2 = 0.0
        if self._cable_fx:
            dt0, dt1 = self.cable_corrections(s)
            RiT = self._RiT
            f0 = f0 + dt0
            f1 = f1 + dt1
            d2 = RiT[0] * dt0 + RiT[1] * dt1   # the motors feel the correction's R^-T image
            d3 = RiT[2] * dt0 + RiT[3] * dt1
            f2 = f2 - d2
            f3 = f3 - d3
        if self._needs_tc:
            mc, b = self._motor_cable, self._beta
            tc1 = mc[0] * s[0] + mc[1] * s[1] + mc[2] * s[2] + mc[3] * s[3] \
                + b * (mc[0] * s[4] + mc[1] * s[5] + mc[2] * s[6] + mc[3] * s[7]) + d2
            tc2 = mc[4] * s[0] + mc[5] * s[1] + mc[6] * s[2] + mc[7] * s[3] \
                + b * (mc[4] * s[4] + mc[5] * s[5] + mc[6] * s[6] + mc[7] * s[7]) + d3
        for fx in self._motor_fx:
            r1, r2 = fx(s[2], s[3], s[6], s[7], tc1, tc2)
            f2 = f2 - r1
            f3 = f3 - r2
        return f0, f1, f2, f3

    def command_torque(self, tau1: float, tau2: float) -> tuple[float, float]:
        """Apply the command effects (delay, ...) to a motor torque command; call once per tick."""
        for fx in self._command_fx:
            tau1, tau2 = fx(tau1, tau2)
        return tau1, tau2

    # -- integration -----------------------------------------------------------------------------
    def step(self, tau1: float, tau2: float, td_dp: float = 0.0, td_ie: float = 0.0) -> None:
        """Advance one control tick with motor torques (N m) and ankle disturbances (N m) held."""
        if self._command_fx:
            tau1, tau2 = self.command_torque(tau1, tau2)
        self.tau_applied[0] = tau1
        self.tau_applied[1] = tau2
        xt, x_next, next_buf = self._xt, self._x_next, self._next_buf
        z, zb, xf, xt_now = self._z, self._zbuf, self._xf, xt    # zb: z's buffer, read and set as floats
        z_alt, zb_alt, xf_alt, xt_alt = self._z_alt, self._zbuf_alt, self._xf_alt, self._xt_alt
        predict, correct = self._predict.dot, self._correct_torque.dot   # bound: ~1/3 cheaper a call than np.dot
        forces = self.generalized_forces
        for _ in range(self.substeps):
            # Heun on the non-linear forces (the linear part is exact): predict the substep holding f
            # from its start, then redo it holding the mean of f at both ends. Holding f alone is first
            # order, and for cable effects (slack, hardening) on the stiff modes it can go unstable.
            zb[8], zb[9], zb[10], zb[11] = forces(zb, tau1, tau2, td_dp, td_ie)
            predict(xf, x_next)
            zb[12], zb[13], zb[14], zb[15] = forces(next_buf, tau1, tau2, td_dp, td_ie)
            correct(z, xt_alt)   # the corrected state and its joint torque, into the other buffer
            z, zb, xf, xt_now, z_alt, zb_alt, xf_alt, xt_alt = z_alt, zb_alt, xf_alt, xt_alt, z, zb, xf, xt_now
        if xt_now is not xt:     # an odd number of substeps ended in the second buffer
            xt[:] = xt_now

    def derivative(self, x: np.ndarray, tau1: float, tau2: float, td_dp: float, td_ie: float) -> np.ndarray:
        """dx/dt of the full model, for the RK4 reference (torques already through command effects)."""
        f = np.array(self.generalized_forces(x.tolist(), tau1, tau2, td_dp, td_ie))
        return self.linear.A @ x + self.linear.B @ f

    # -- outputs ---------------------------------------------------------------------------------
    def joint_torque(self) -> tuple[float, float]:
        """N m [DP, IE]: the joint torque the cables deliver, effects included. The linear part
        K (phi + beta phi') comes with the state from its last correction (or set_state)."""
        t = self._zbuf
        return self.with_cable_effects(self.x_floats, t[N_X], t[N_X + 1])

    def energy(self) -> float:
        """J: kinetic + cable + gravity energy (meaningful for the reciprocal transmission)."""
        x = self.x
        q, v = x[0:4], x[4:8]
        lin = self.linear
        cable = 0.5 * q @ lin.cable_Kq @ q
        gravity = self._grav * (1.0 - math.cos(q[0]))
        return float(0.5 * v @ lin.Mq @ v + cable + gravity)


def rk4_step(model: CompliantModel, x: np.ndarray, h: float, tau1: float, tau2: float,
             td_dp: float = 0.0, td_ie: float = 0.0) -> np.ndarray:
    """One classical RK4 step of the full model (reference solution for tests)."""
    f = model.derivative
    k1 = f(x, tau1, tau2, td_dp, td_ie)
    k2 = f(x + 0.5 * h * k1, tau1, tau2, td_dp, td_ie)
    k3 = f(x + 0.5 * h * k2, tau1, tau2, td_dp, td_ie)
    k4 = f(x + h * k3, tau1, tau2, td_dp, td_ie)
    return x + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
