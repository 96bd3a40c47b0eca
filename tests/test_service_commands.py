"""Commands through Daemon.handle in lockstep: a profile that would take the ankle beyond its range
is refused before it starts (it would otherwise drive the ankle until the range fault trips)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ankle_rt.clock import SimClock
from ankle_rt.daemon import Daemon
from ankle_rt.references import make_profile
from ankle_rt.service.protocol import CommandError, SetReference, StartProfile
from tests.daemon_helpers import reply


@pytest.fixture
def daemon(sim_cfg, tmp_path):
    sim_cfg["safety"]["auto_activate"] = False
    sim_cfg["sim"]["disturbances"] = []
    sim_cfg["reference"]["profile"] = "hold"
    d = Daemon(sim_cfg, SimClock())
    yield d
    d.close()


def reference_deg(daemon) -> list[float]:
    return [round(math.degrees(v), 6) for v in daemon.reference.ref]


@pytest.mark.parametrize("name, params", [
    ("hold", {"dp": 0.3, "ie": -0.1}), ("step", {"dp": -0.4, "ie": 0.2}),
    ("sine", {"amplitude_dp": 0.2, "amplitude_ie": -0.1, "frequency_hz": 3.0, "ie_phase": 1.0}),
    ("chirp", {"amplitude_dp": 0.1, "amplitude_ie": 0.05, "f0_hz": 0.5, "f1_hz": 20.0, "duration_s": 2.0}),
    ("gait", {"stride_s": 1.0, "scale": 1.5}),
])
def test_profile_bounds_enclose_and_reach_its_values(name, params):
    profile = make_profile(name, params)
    values = np.array([profile.value(t) for t in np.arange(0.0, 4.0, 1e-3)])
    (dp_lo, dp_hi), (ie_lo, ie_hi) = profile.bounds()
    assert values[:, 0].min() >= dp_lo - 1e-12 and values[:, 0].max() <= dp_hi + 1e-12
    assert values[:, 1].min() >= ie_lo - 1e-12 and values[:, 1].max() <= ie_hi + 1e-12
    assert values[:, 0].min() == pytest.approx(dp_lo, abs=2e-3) and values[:, 0].max() == pytest.approx(dp_hi, abs=2e-3)
    assert values[:, 1].min() == pytest.approx(ie_lo, abs=2e-3) and values[:, 1].max() == pytest.approx(ie_hi, abs=2e-3)


def test_csv_profile_bounds(tmp_path):
    path = tmp_path / "refs.csv"
    path.write_text("t,ref_dp,ref_ie\n0,0.1,0\n1,-0.2,0.05\n2,0.3,-0.4\n")
    assert make_profile("csv", {"path": str(path)}).bounds() == ((-0.2, 0.3), (-0.4, 0.05))


def test_profiles_beyond_the_ankle_range_are_refused_before_they_start(daemon, tmp_path):
    daemon.run(0.02)
    daemon.handle(SetReference(math.radians(30.0), 0.0, 0.0))
    daemon.run(0.3)                        # ramp 0, but rate limited (reference.max_rate_rad_s, 2 rad/s)
    assert reference_deg(daemon) == [30.0, 0.0]

    refused = [
        StartProfile("step", {"dp": math.radians(15.0)}),            # 30 + 15 > 40 (relative to the reference)
        StartProfile("sine", {"amplitude_dp": math.radians(12.0)}),  # 30 + 12
        StartProfile("gait", {"scale": 2.0}),                        # the stride's dorsiflexion on top of 30
    ]
    for command in refused:
        with pytest.raises(CommandError) as err:
            daemon.handle(command)
        assert err.value.field == "params"
        assert "would take DP to" in err.value.message and "(from 30.0 deg), beyond the ankle range +/-40 deg" in err.value.message
        assert err.value.message.startswith("the profile would take DP")   # not "field 'params': " twice
    csv = tmp_path / "refs.csv"
    csv.write_text("t,ref_dp,ref_ie\n0,0,0\n1,0,0.75\n")
    with pytest.raises(CommandError, match="would take IE to 43.0 deg, beyond"):
        reply(daemon.handle(StartProfile("csv", {"path": str(csv)})))   # absolute: 0.75 rad
    daemon.run(0.02)
    assert reference_deg(daemon) == [30.0, 0.0]  # nothing started

    step_down = {"dp": math.radians(-25.0), "ie": math.radians(-39.0), "start_s": 0.0}  # to (5, -39) deg
    assert daemon.handle(StartProfile("step", step_down))["state"] == "configured"
    daemon.run(0.4)                        # 0.68 rad at reference.max_rate_rad_s (2 rad/s)
    assert reference_deg(daemon) == pytest.approx([5.0, -39.0])


def test_protocol_knows_exactly_the_daemons_profiles():
    """protocol.PROFILE_NAMES is a literal (the ctl client must not import numpy to build its parser)."""
    from ankle_rt.references import PROFILES
    from ankle_rt.service.protocol import PROFILE_NAMES

    assert set(PROFILE_NAMES) == set(PROFILES)
