"""Friction feed-forward: the identified Coulomb + viscous friction of each motor, added to the
controller's motor torque so the position loop does not have to build up an error to overcome it.

``tau_ff = kc * sat(v / v_band) + D * v`` with the filtered motor velocity ``v`` (rad/s). Inside the
band ``|v| < v_band`` the Coulomb term fades linearly to zero, so velocity noise around standstill
(one encoder count per cycle is 0.054 rad/s) does not make the command chatter between +kc and -kc.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ankle_rt.config import Config


class FrictionFeedForward:
    def __init__(self, coulomb: float, viscous: float, velocity_band: float, enabled: bool = True):
        """``coulomb`` N m, ``viscous`` N m s/rad, ``velocity_band`` rad/s (> 0)."""
        self.kc = coulomb
        self.d = viscous
        self.inv_band = 1.0 / velocity_band
        self.enabled = enabled

    @classmethod
    def from_config(cls, cfg: "Config") -> "FrictionFeedForward":
        """``controller.friction_ff``; missing coefficients default to the actuator's identified ones."""
        f = cfg["controller"]["friction_ff"]
        a = cfg["actuator"]
        kc = a["coulomb"] if f["coulomb"] is None else f["coulomb"]
        d = a["damping"] if f["viscous"] is None else f["viscous"]
        return cls(kc, d, f["velocity_band"], f["enabled"])

    def torque(self, v: float) -> float:
        """N m for motor velocity ``v`` rad/s (0 when switched off)."""
        if not self.enabled:
            return 0.0
        x = v * self.inv_band
        s = 1.0 if x > 1.0 else (-1.0 if x < -1.0 else x)
        return self.kc * s + self.d * v
