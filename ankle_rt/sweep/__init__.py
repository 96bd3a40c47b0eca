"""Robustness sweeps: many simulated runs of one study, sampled over config keys (docs/sweeps.md)."""
