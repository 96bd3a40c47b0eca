"""Joint encoders cross-checked against the motors and the strain gauges (ankle_rt.joint_check, JOINT_MISMATCH):
a flipped sign, a stuck or mis-scaled joint encoder under the impedance law on the joint encoders and the encoder
rate faults before it drives the ankle away; a non-finite joint sample is JOINT_INVALID (issue 19, seventh pass)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ankle_rt.joint_check import JointCrossCheck
from ankle_rt.safety import Fault
from tests.daemon_helpers import mutated_run
from tests.test_torque_rate_source import bench, encoder_base, gauge_base  # noqa: F401  (the fixtures)

ACTIVE_S = 0.1       # the daemon activates after the 100-sample tare


def fault_after(run) -> tuple[str, float, float]:
    """(fault, s from activation to it (inf: none), A: the larger motor's peak |set value| before it)."""
    k = np.flatnonzero(run["fault"] != 0)
    end = k[0] if k.size else len(run["t"])
    peak = max(float(np.abs(run[m][:end]).max()) for m in ("current_cmd_1", "current_cmd_2"))
    return run.summary["fault"], (float(run["t"][k[0]]) - ACTIVE_S if k.size else math.inf), peak


@pytest.mark.parametrize("stiffness", [(50.0, 25.0), (200.0, 100.0)])
@pytest.mark.parametrize("axis", [0, 1])
@pytest.mark.parametrize("source", ["gauges", "encoders"])
def test_a_flipped_joint_encoder_faults_at_rest_before_the_ankle_runs_away(gauge_base, encoder_base, source,
                                                                            axis, stiffness):
    """joint_encoders.sign flipped on one axis, at rest (the issue's plant): the law on the joint encoders has a
    negative stiffness and the ankle runs away (ANKLE_RANGE at 9-12 A, 1-2 s in); the joint encoder parts from
    the motors' estimate by twice the ankle's angle and JOINT_MISMATCH stops it within 1 s of activation,
    the set values below 2 A."""
    def flip(frame, _k):
        frame.values[4 + axis] = -frame.values[4 + axis]

    cfg = bench(encoder_base if source == "encoders" else gauge_base, stiffness)
    fault, after, peak = fault_after(mutated_run(cfg, 2.0, flip))
    assert fault == Fault.JOINT_MISMATCH.name and after <= 1.0 and peak < 2.0, (fault, after, peak)


@pytest.mark.parametrize("axis", [0, 1])
@pytest.mark.parametrize("kind", ["stuck", "half scale"])
def test_a_stuck_or_mis_scaled_joint_encoder_faults_when_the_ankle_moves(encoder_base, kind, axis):
    """A joint encoder stuck from 0.3 s on, or reading half the angle, and a 3 N m push (1.5 N m IE) from 0.5 s:
    the ankle moves 0.06 rad the joint encoder does not show (or half of it), JOINT_MISMATCH within 0.15 s of the push."""
    held = []

    def bad(frame, k):
        if kind == "half scale":
            frame.values[4 + axis] *= 0.5
        elif k >= 300:
            frame.values[4 + axis] = held[0]
        elif k == 299:
            held.append(frame.values[4 + axis])

    size = (3.0, 1.5)[axis]
    push = lambda t: tuple(size if t >= 0.5 and a == axis else 0.0 for a in (0, 1))   # noqa: E731
    run = mutated_run(bench(encoder_base), 1.0, bad, push)
    fault, after, _ = fault_after(run)
    assert fault == Fault.JOINT_MISMATCH.name and 0.5 <= after + ACTIVE_S <= 0.65, (fault, after)


def test_a_half_scale_joint_encoder_under_a_stiff_law_faults_on_the_stretch_against_the_gauges(encoder_base):
    """K_ie 100, the IE joint encoder reading half the angle, a 1.5 N m IE push from 0.5 s: the law renders half the
    stiffness (0.03 rad for 0.015) and the stretch it implies (+1.8 N m) stays within twice the gauges' size (-1.5)
    but against their sign; JOINT_MISMATCH after AGAINST_HOLD_S (0.23-0.25 s after pushes of 1.5-6 N m), where
    before there was none."""
    def half(frame, _k):
        frame.values[5] *= 0.5

    push = lambda t: (0.0, 1.5 if t >= 0.5 else 0.0)   # noqa: E731
    fault, after, _ = fault_after(mutated_run(bench(encoder_base, (200.0, 100.0)), 1.5, half, push))
    assert fault == Fault.JOINT_MISMATCH.name and 0.2 <= after + ACTIVE_S - 0.5 <= 0.3, (fault, after)


@pytest.mark.parametrize("stiffness", [(50.0, 25.0), (200.0, 100.0)])
def test_a_healthy_encoder_loop_under_the_bench_sines_does_not_fault(encoder_base, stiffness):
    """The encoder-rate loop on the issue's plant under the bench's larger sines at 2 Hz, 15 N m DP then 7.5 N m IE
    (the joint encoders agree with the motors' estimate): no fault."""
    push = lambda t: (15.0 * math.sin(4.0 * math.pi * t) if 0.5 <= t < 1.5 else 0.0,          # noqa: E731
                      7.5 * math.sin(4.0 * math.pi * t) if 1.5 <= t < 2.5 else 0.0)
    run = mutated_run(bench(encoder_base, stiffness), 2.6, lambda frame, k: None, push)
    assert run.summary["fault"] == "NONE"


def test_a_batch_checks_each_device_as_alone():
    """JointCrossCheck.stack runs each device's check as it runs alone (the batched daemon cycle)."""
    alone = [JointCrossCheck(1e-3, 1429.0, 220.0, m, w) for m, w in ((3e-4, True), (1e-3, True), (3e-4, True))]
    batch = JointCrossCheck.stack([JointCrossCheck(1e-3, 1429.0, 220.0, m, w)
                                   for m, w in ((3e-4, True), (1e-3, True), (3e-4, True))])
    rng = np.random.default_rng(22)
    est, joint, sg = rng.normal(0.0, 1e-4, (3, 2, 400)), rng.normal(0.0, 1e-4, (3, 2, 400)), rng.normal(0.0, 0.5, (3, 2, 400))
    joint[2, 0] += np.linspace(0.0, 3e-3, 400)          # the third device's DP encoder drifts away
    batch.start(est[:, 0, 0], est[:, 1, 0], joint[:, 0, 0], joint[:, 1, 0], sg[:, 0, 0], sg[:, 1, 0])
    batch.activated()
    for i, c in enumerate(alone):
        c.start(est[i, 0, 0], est[i, 1, 0], joint[i, 0, 0], joint[i, 1, 0], sg[i, 0, 0], sg[i, 1, 0])
        c.activated()
    fired = np.zeros(3, bool)
    for k in range(1, 400):
        got = batch.update(est[:, 0, k], est[:, 1, k], joint[:, 0, k], joint[:, 1, k], sg[:, 0, k], sg[:, 1, k], True)
        want = [c.update(est[i, 0, k], est[i, 1, k], joint[i, 0, k], joint[i, 1, k], sg[i, 0, k], sg[i, 1, k], True)
                for i, c in enumerate(alone)]
        assert list(got) == want
        fired |= got
    assert list(fired) == [False, False, True]
