"""The element-wise maths effects are written in (``Effect.elementwise = True``): it lives in
:mod:`ankle_rt.elementwise` because the controllers use it too; effects import it from here."""

from ankle_rt.elementwise import absolute, clip, exp, pick, positive_part, select, sin, stack, tanh

__all__ = ["absolute", "clip", "exp", "pick", "positive_part", "select", "sin", "stack", "tanh"]
