"""Actuator identification and model validation: the paper's sections 3 and 4 as experiments that
run on any backend (CycleControllers in the daemon's loop) and as offline estimators on interchange
recordings. Baseline estimators for reuse: :func:`estimate_inertia` (J, D), :func:`estimate_viscous`
(kc, kv per direction), :func:`estimate_stiction` (breakaway kc per direction)."""

from ankle_rt.identification.actuator import EXPERIMENTS, ActuatorIdentification, identify, run_experiments
from ankle_rt.identification.friction import AffineFit, fit_affine, fit_through_origin
from ankle_rt.identification.inertia import TorqueStepExperiment, estimate_inertia, motor_response
from ankle_rt.identification.signals import IdentificationError
from ankle_rt.identification.stats import Measured
from ankle_rt.identification.stiction import StictionExperiment, estimate_stiction
from ankle_rt.identification.viscous import VelocityHoldExperiment, estimate_viscous

__all__ = [
    "EXPERIMENTS", "ActuatorIdentification", "identify", "run_experiments", "AffineFit", "fit_affine",
    "fit_through_origin", "TorqueStepExperiment", "estimate_inertia", "motor_response", "IdentificationError",
    "Measured", "StictionExperiment", "estimate_stiction", "VelocityHoldExperiment", "estimate_viscous",
]
