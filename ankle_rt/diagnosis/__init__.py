"""Model-discrepancy diagnosis: from measured data, find what the simulation gets wrong, name the
cause (docs/design.md vocabulary), fit the effect that explains it and measure the gain on held-out data.

Offline tool: needs the analysis extra (scipy; matplotlib for reports). See docs/diagnosis.md.
"""

from ankle_rt.diagnosis.core import Diagnosis, DiagnosisError, diagnose

VOCABULARY = ("none", "stribeck", "asymmetric_friction", "load_dependent_friction", "backlash", "cogging",
              "delay", "stiffness_nonlinear", "torque_offset", "unknown")

__all__ = ["Diagnosis", "DiagnosisError", "VOCABULARY", "diagnose"]
