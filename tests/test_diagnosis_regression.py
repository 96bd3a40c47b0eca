"""The statistics under the diagnosis: effective sample size, fractional shifts, the exact
zero-order-hold relation the motor channel relies on, and block cross-validation."""

from __future__ import annotations

import numpy as np
import pytest

from ankle_rt.diagnosis.regression import block_cv_mse, effective_samples, fit, information_criterion, rss_only
from ankle_rt.diagnosis.signals import MotorChannel, shift_rows
from ankle_rt.interchange import Recording


def test_effective_sample_size_of_white_and_ar1_noise():
    rng = np.random.default_rng(7)
    n = 20000
    white = rng.standard_normal(n)
    assert effective_samples(white, 1) == pytest.approx(n, rel=0.1)
    a = 0.8
    ar = np.empty(n)
    ar[0] = 0.0
    e = rng.standard_normal(n)
    for k in range(1, n):
        ar[k] = a * ar[k - 1] + e[k]
    assert effective_samples(ar, 1) == pytest.approx(n * (1 - a) / (1 + a), rel=0.25)
    # two stacked series count separately
    assert effective_samples(np.concatenate([white, white[::-1]]), 2) == pytest.approx(2 * n, rel=0.1)


def test_lean_fits_give_the_same_numbers_bit_for_bit():
    """fit(covariance=False) and rss_only (which scales its X in place) only leave work out (diag24):
    coefficients, residual and RSS are the full fit's to the last bit, and a covariance is refused."""
    rng = np.random.default_rng(3)
    X = np.column_stack([rng.standard_normal(500) * s for s in (1e-3, 1.0, 1e3)] + [np.zeros(500)])
    y = X[:, :3] @ [2.0, -1.0, 0.5] + rng.standard_normal(500)
    full, lean = fit(y, X), fit(y, X, covariance=False)
    assert np.array_equal(full.coef, lean.coef) and np.array_equal(full.residual, lean.residual)
    assert full.rss == lean.rss and lean.xtx_inv is None
    with pytest.raises(ValueError):
        lean.covariance(500.0)
    Xc = X.copy()
    scale = np.sqrt(np.einsum("ij,ij->j", X, X))
    scale[scale == 0.0] = 1.0
    Xs = X / scale
    r = y - Xs @ np.linalg.lstsq(Xs, y, rcond=None)[0]
    assert rss_only(y, Xc) == float(r @ r)
    assert np.array_equal(Xc, Xs)                     # scaled in place


def test_information_criterion_penalises_parameters_by_effective_samples():
    assert information_criterion(1.0, 100, 3, 50.0) - information_criterion(1.0, 100, 2, 50.0) == \
        pytest.approx(np.log(50.0))


def test_fractional_shift_is_linear_interpolation():
    x = np.arange(10.0) ** 2
    shifted = shift_rows(x[:, None], 2.25)[:, 0]
    k = np.arange(10)
    assert np.allclose(shifted[3:], np.interp(k[3:] - 2.25, k, x))
    assert shifted[0] == x[0]


def test_motor_channel_recovers_inertia_exactly_from_a_held_torque():
    """theta of J theta'' = tau with tau held per sample: the filtered second difference equals the
    filtered half-sample-shifted torque / J (no noise, no friction): J to 1e-6, D and kc ~ 0."""
    dt, n, J = 1e-3, 6000, 0.05
    rng = np.random.default_rng(3)
    tau = np.repeat(rng.standard_normal(n // 20), 20) * 0.5
    th = np.zeros(n)
    w = 0.0
    for k in range(n - 1):
        th[k + 1] = th[k] + dt * w + 0.5 * dt * dt * tau[k] / J
        w += dt * tau[k] / J
    rec = Recording({"t": np.arange(n) * dt, "motor_pos_1": th, "motor_torque_1": tau})
    ch = MotorChannel(rec, None, None, 0.01)
    f = fit(ch.target(), ch.baseline_design())
    assert f.coef[0] == pytest.approx(J, rel=1e-6)
    assert abs(f.coef[1]) < 1e-6 and abs(f.coef[2]) < 1e-6


def test_block_cross_validation_rewards_a_true_regressor_not_a_noise_one():
    rng = np.random.default_rng(11)
    n = 4000
    x = np.sin(np.linspace(0, 40, n))
    true_extra = np.cos(np.linspace(0, 97, n))
    noise_extra = rng.standard_normal(n)
    y = 2.0 * x + 0.3 * true_extra + 0.1 * rng.standard_normal(n)
    base = block_cv_mse(y, x[:, None], 1)
    good = block_cv_mse(y, np.column_stack([x, true_extra]), 1)
    bad = block_cv_mse(y, np.column_stack([x, noise_extra]), 1)
    assert np.all(good < 0.5 * base)
    assert np.median(bad / base) > 0.98


def test_filter_is_sosfiltfilt_bit_for_bit():
    """The diagnosis' zero-phase filter runs scipy's own kernel on the columns laid out as rows (diag25):
    every value, its sign and the result's layout are sosfiltfilt's, whatever the input's layout."""
    from scipy.signal import sosfiltfilt

    from ankle_rt.diagnosis.signals import Smoother
    rng = np.random.default_rng(11)
    for dt in (1e-3, 2e-3, 1e-4):
        sm = Smoother.for_period(dt)
        for n, c in ((5000, 1), (3001, 2), (200, 4), (10, 3)):
            x = rng.standard_normal((n, c)) * 10.0 ** rng.uniform(-6, 6, c)
            x[: n // 3] = 0.0
            for xx in (x, np.asfortranarray(x), x[::-1]):
                try:
                    ref = sosfiltfilt(sm.sos, xx, axis=0)
                except ValueError:
                    with pytest.raises(ValueError):
                        sm.smooth(xx, weigh=False)
                    continue
                out = sm.smooth(xx, weigh=False)
                assert np.array_equal(out, ref) and np.array_equal(np.signbit(out), np.signbit(ref))
                assert out.strides == ref.strides


def test_stribeck_mean_is_the_step_mean_bit_for_bit():
    """The cached, in-place Stribeck mean (diag25) is step_mean of the Stribeck shape to the last bit."""
    rng = np.random.default_rng(5)
    n = 3000
    t = np.arange(n) * 1e-3
    pos = np.column_stack([np.sin(2 * np.pi * 0.7 * t), 0.5 * np.cos(2 * np.pi * 1.1 * t)])
    pos = np.round(pos / 1e-4) * 1e-4
    data = {"t": t, "motor_pos_1": pos[:, 0], "motor_pos_2": pos[:, 1],
            "current_cmd_1": rng.standard_normal(n), "current_cmd_2": rng.standard_normal(n)}
    ch = MotorChannel(Recording(data, "stribeck"), 0.1, None, 0.01)
    for e in (1.0, 2.0):
        for vs in (0.02, 0.3, 5.0):
            ref = ch.step_mean(lambda v, sign: np.exp(-np.abs(v / vs) ** e) * sign)
            for _ in range(2):                         # built, then from the cache
                out = ch.stribeck_mean(vs, e)
                assert np.array_equal(out, ref) and np.array_equal(np.signbit(out), np.signbit(ref))


def test_cogging_design_is_the_plain_formula_bit_for_bit():
    """Cogging's design (taper's cosine only inside its transition, the columns written in place, diag25)
    equals the plain formula to the last bit: the taper 0.5 (1 + cos(pi x)) on all samples, the waves
    stacked and filtered, one block per motor."""
    from ankle_rt.diagnosis.candidates import Cogging, CoggingHarmonic
    rng = np.random.default_rng(9)
    n = 4000
    t = np.arange(n) * 1e-3
    pos = np.column_stack([0.3 * np.sin(2 * np.pi * 0.9 * t), 0.2 * np.sin(2 * np.pi * 1.3 * t + 1.0)])
    pos[1500:1700, 0] = pos[1500, 0]                   # a rest
    data = {"t": t, "motor_pos_1": pos[:, 0], "motor_pos_2": pos[:, 1],
            "current_cmd_1": rng.standard_normal(n), "current_cmd_2": rng.standard_normal(n)}
    ch = MotorChannel(Recording(data, "cogging"), 0.1, None, 0.01)

    def taper(rate):
        f = np.abs(rate) / (2.0 * np.pi)
        f1 = min(3.0 * ch.sm.cutoff_hz, 0.15 / ch.dt)
        f2 = min(6.0 * ch.sm.cutoff_hz, 0.3 / ch.dt)
        return 0.5 * (1.0 + np.cos(np.pi * np.clip((f - f1) / (f2 - f1), 0.0, 1.0)))

    for cand in (Cogging(), CoggingHarmonic()):
        for nl in (3.0, 40.0, 486.0, 1944.0):
            waves = []
            for h in range(1, cand.harmonics + 1):
                w = taper(h * nl * ch.vel) * ~ch.resting
                waves += [w * np.sin(h * nl * ch.pos), w * np.cos(h * nl * ch.pos)]
            filtered = ch.sm.smooth(np.hstack(waves))
            ref = np.hstack([ch.per_column(filtered[:, j * 2:(j + 1) * 2]) for j in range(len(waves))])
            X = cand.design(ch, nl).X
            assert np.array_equal(X, ref) and np.array_equal(np.signbit(X), np.signbit(ref))
            assert np.array_equal(Cogging.taper(ch, nl * ch.vel), taper(nl * ch.vel))


def test_projected_grid_rss_agrees_with_the_whole_solve_and_defers_degenerate_systems():
    """A grid search's RSS by projection on the shared columns' QR (selection.Projector, diag25) is the
    whole system's (lstsq) to the last digits; a zero column, an ill-conditioned system or too few rows
    leave it to the whole solve (None)."""
    from ankle_rt.diagnosis.selection import Projector
    rng = np.random.default_rng(21)
    n = 3000
    A = np.column_stack([rng.standard_normal(n) * s for s in (1e-3, 1.0, 1e3)] + [np.ones(n)])
    y = A @ [1.0, 2.0, 3.0, 4.0] + rng.standard_normal(n)
    shared = Projector(y, A)
    for q in (1, 2, 4):
        B = rng.standard_normal((n, q)) * 10.0 ** rng.uniform(-4, 4, q) + 0.3 * A[:, :1] * 1e3
        ref = rss_only(y, np.hstack([A, B]))
        assert shared.rss(None, B) == pytest.approx(ref, rel=1e-12)
        y2 = y + B[:, 0]                                 # a candidate with its own left side (a delay)
        assert shared.rss(y2, B) == pytest.approx(rss_only(y2, np.hstack([A, B])), rel=1e-12)
    assert shared.rss(y + 1.0, np.zeros((n, 0))) == pytest.approx(rss_only(y + 1.0, A.copy()), rel=1e-12)
    assert shared.rss(None, np.column_stack([rng.standard_normal(n), np.zeros(n)])) is None      # zero column
    assert shared.rss(None, A[:, 1:2] * 2.0 + 1e-9 * rng.standard_normal((n, 1))) is None      # collinear
    assert Projector(y, np.column_stack([A, np.zeros(n)])).rss(None, rng.standard_normal((n, 1))) is None
    assert Projector(y[:8], A[:8]).rss(None, rng.standard_normal((8, 1))) is None                # too few rows
