"""Constant load torque on each motor: gravity on the drive, a spring preload, a cable pretension."""

from __future__ import annotations

from ankle_rt.config import Field, Section
from sim_backend.effects.base import Effect, register_effect


@register_effect("torque_offset")
class TorqueOffset(Effect):
    """Resisting torque ``torque_1`` on motor 1 and ``torque_2`` on motor 2 (N m at the gearbox output),
    whatever the motion: unlike friction it does not change sign with the direction of travel."""

    PARAMS = Section({
        "torque_1": Field(float, "N m, constant torque resisting positive motion of motor 1"),
        "torque_2": Field(float, "N m, constant torque resisting positive motion of motor 2", default=0.0),
    })
    cause = "torque_offset"
    elementwise = True      # constants: the batch stacks them into arrays, one call for all plants

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        self.t1 = params["torque_1"]
        self.t2 = params["torque_2"]

    def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
        return self.t1, self.t2
