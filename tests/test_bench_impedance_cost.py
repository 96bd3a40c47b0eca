"""`bench impedance` divides its wall time by the simulated cycles it ran: simulated_s must count
every lockstep run the experiment makes, the torque-step runs included."""

from __future__ import annotations

import pytest

import ankle_rt.daemon
from ankle_rt.bench.impedance import Experiment, bench_config, run_impedance, simulated_s
from ankle_rt.config import load_config
from ankle_rt.paths import default_config_path


@pytest.mark.parametrize("step_nm", [(0.0, 0.0), (6.0, 3.0)])
def test_simulated_time_counts_every_lockstep_run(monkeypatch, step_nm):
    durations = []
    original = ankle_rt.daemon.run_lockstep

    def counting(cfg, duration, **kw):
        durations.append(duration)
        return original(cfg, duration, **kw)

    monkeypatch.setattr(ankle_rt.daemon, "run_lockstep", counting)
    cfg = bench_config(load_config(default_config_path()), stiffness=(100.0, 50.0), damping=(0.5, 0.25),
                       torque_feedback="auto", friction_ff=None, effects=[])
    exp = Experiment(pulses_nm=((3.0,), ()), pulse_s=0.3, rest_s=0.2, sine_hz=(), sine_nm=((), ()), axes=("dp",),
                     step_nm=step_nm, step_s=0.2)
    run_impedance(cfg, exp)
    assert len(durations) == (3 if any(step_nm) else 1)
    assert sum(durations) == pytest.approx(simulated_s(exp))
