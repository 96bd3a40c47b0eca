"""The effects library: physical effects the nominal model lacks, switched on from the config.

Each effect is a class registered under a name; ``sim.effects`` in the config lists
``{type: NAME, ...parameters}``. See :mod:`sim_backend.effects.base` for the hooks an effect can use.
"""

from sim_backend.effects.base import EFFECTS, Effect, build_effects, register_effect
from sim_backend.effects import friction  # noqa: F401  (registers the friction effects)
from sim_backend.effects import (  # noqa: F401  (each module registers its effect)
    asymmetric_friction, backlash, cogging, delay, load_dependent_friction, stiffness_nonlinear, stribeck,
    torque_offset,
)

__all__ = ["EFFECTS", "Effect", "build_effects", "register_effect"]
