#!/usr/bin/env python3
"""Generator E: an independent simulator of a two-motor Bowden-cable ankle prosthesis that writes
identification / validation CSVs (interchange format) with known truth, for testing `ankle-rt diagnose`.

Written from the design brief's nominal model (docs/design.md) and the nominal parameters only.  Own effect forms:
  stribeck     tau = As * exp(-(|v|/vs)^delta) * tanh(v/ve)         (delta 0.7..2 per case)
  asymmetric   Coulomb kc+ != kc- per motor (smooth: mean*tanh + half-diff*|tanh|)
  load-dep.    mu * |cable torque on that motor| * tanh(v/ve)
  backlash     dead zone on each axis' stretch, or on each cable's length (per-cable form)
  cogging      sum_h A_h sin(h N theta_m + phi_{i,h}), N = n*81 periods per output rev, per-motor phases
  delay        applied current = commanded current (t - d), d at the integrator step resolution
  stiffness    K*phi*(1+|phi|/s0)  or  K*s0*sign(phi)*expm1(|phi|/s0)
  torque_off   constant load torque on a motor
  outside vocabulary: viscous damping drifting with motor temperature; cable stress relaxation (creep,
  a Maxwell element in parallel with the cable).
Sensor / calibration faults: gauge zero offset, gauge gain, torque constant error (plant kt), motor encoder
scale, gauge clipping, held gauge samples, gauge drift, dropped cycles.

Integration: vectorised RK4 over all runs of a batch, step H (control input held between ticks).
Usage: python gen.py --out DIR [--only ID,ID] [--h 2e-4]

Provenance (ankle-rt, issue 21): written on 2026-11-30 by a helper that read only the design brief (docs/design.md), the paper, the
nominal parameters, config/ and the README, never the diagnosis, its docs or the other generators; kept as
its author wrote it (only the paths made relative to this checkout), so that the figures it gave can be
measured again: docs/diagnosis.md, diag28.
"""
import argparse, json, math, os, sys, time
import numpy as np

# ---------------------------------------------------------------- nominal (config/nominal-params.yaml)
NOM = dict(J=0.048, D=0.112, kc=0.28, kt=1.66, k=218800.0, r=0.0127, a=0.05715, b=0.03175, beta=6.5e-5,
           m=0.465, c=0.0069, Id=3.7486e-3, Ii=9.3452e-4, ve=0.01, counts=116640, sg_noise=0.02)
MAIN = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "config", "sim.yaml"))


def Kax(k, a=NOM['a'], b=NOM['b']):
    return 2 * k * a * a, k * b * b


# ---------------------------------------------------------------- reference profiles (1 ms grid)
def tukey(n, frac=0.1):
    w = np.ones(n)
    m = max(1, int(frac * n / 2))
    ramp = 0.5 * (1 - np.cos(np.pi * np.arange(m) / m))
    w[:m] = ramp
    w[-m:] = ramp[::-1]
    return w


def multisine(t, fmin, fmax, nf, rms, rng):
    f = np.exp(np.linspace(np.log(fmin), np.log(fmax), nf))
    f = f * (1 + 0.03 * rng.standard_normal(nf))
    amp = 1.0 / (1 + (f / 1.0))  # lower amplitude at higher freq (keeps velocities sane)
    ph = rng.uniform(0, 2 * np.pi, nf)
    y = (amp[:, None] * np.sin(2 * np.pi * f[:, None] * t[None, :] + ph[:, None])).sum(0)
    return y / (np.std(y) + 1e-12) * rms


def triangle(t, amp, period, phase=0.0):
    x = ((t / period + phase) % 1.0)
    return amp * (4 * np.abs(x - 0.5) - 1) * -1  # starts at -amp ... use offset to start at 0


def tri0(t, amp, period):
    # triangle starting at 0 going up
    x = (t / period) % 1.0
    return amp * np.where(x < 0.25, 4 * x, np.where(x < 0.75, 2 - 4 * x, 4 * x - 4))


def bench_reference(kind, T, rng, scale_dp=1.0, scale_ie=1.0, t_on=0.3):
    """ankle references on a 1 ms grid, zero before t_on + 0.2."""
    n = int(round(T * 1000)) + 2
    t = np.arange(n) * 1e-3
    rd = np.zeros(n)
    ri = np.zeros(n)
    t0 = t_on + 0.25
    if kind == 'id':
        segs = [('tri', 6.0), ('chirp', 9.0), ('ms', T - t0 - 15.0)]
    else:
        segs = [('ms', 6.0), ('tri', T - t0 - 6.0)]
    ts = t0
    for name, dur in segs:
        m = (t >= ts) & (t < ts + dur)
        tt = t[m] - ts
        if name == 'tri':
            pd_ = rng.uniform(3.5, 6.5)
            pi_ = rng.uniform(2.5, 4.5)
            d = tri0(tt, rng.uniform(0.06, 0.09), pd_) + tri0(tt, 0.02, pd_ / 3.1)
            i = tri0(tt, rng.uniform(0.035, 0.05), pi_)
            w = tukey(m.sum(), 0.08)
        elif name == 'chirp':
            f0, f1 = 0.2, rng.uniform(3.0, 4.0)
            ph = 2 * np.pi * f0 * dur / np.log(f1 / f0) * (np.exp(tt / dur * np.log(f1 / f0)) - 1)
            f = f0 * np.exp(tt / dur * np.log(f1 / f0))
            d = np.minimum(0.09, 0.30 / (2 * np.pi * f)) * np.sin(ph)
            f0i, f1i = 0.3, rng.uniform(3.5, 5.0)
            phi = 2 * np.pi * f0i * dur / np.log(f1i / f0i) * (np.exp(tt / dur * np.log(f1i / f0i)) - 1)
            fi = f0i * np.exp(tt / dur * np.log(f1i / f0i))
            i = np.minimum(0.05, 0.20 / (2 * np.pi * fi)) * np.sin(phi + 1.0)
            w = tukey(m.sum(), 0.05)
        else:
            d = multisine(tt, 0.08, 3.0, 14, 0.045, rng) + 0.02 * np.sin(2 * np.pi * 0.05 * tt)
            i = multisine(tt, 0.1, 3.5, 14, 0.025, rng)
            w = tukey(m.sum(), 0.08)
        rd[m] = d * w * scale_dp
        ri[m] = i * w * scale_ie
        ts += dur
    return rd, ri


def gait_profiles(T, mass, rng, t_start=1.0, stride=1.1, Mpk=1.4):
    """ms grid: stance weight, external DP/IE moments (N m, on the foot), ground angle, ankle reference."""
    n = int(round(T * 1000)) + 2
    t = np.arange(n) * 1e-3
    st = np.zeros(n); Md = np.zeros(n); Mi = np.zeros(n); gd = np.zeros(n); gi = np.zeros(n)
    rd = np.zeros(n); ri = np.zeros(n)
    ts = t_start
    sf = 0.62
    while ts < T:
        S = stride * (1 + 0.03 * rng.standard_normal())
        pk = Mpk * mass * (1 + 0.05 * rng.standard_normal())
        m = (t >= ts) & (t < ts + S)
        tt = (t[m] - ts) / S
        s = tt / sf  # stance progress
        inst = s < 1
        # external DP moment (dorsiflexing, positive), the cable resists
        w = np.clip((s - 0.15) / 0.85, 0, 1)
        M = np.where(s < 0.15, -0.08 * pk * np.sin(np.pi * s / 0.15), pk * np.sin(np.pi * w ** 1.5) ** 1.5)
        Md[m] = np.where(inst, M, 0.0)
        Mi[m] = np.where(inst, 0.08 * mass * np.sin(2 * np.pi * s) * (1 + 0.1 * rng.standard_normal()), 0.0)
        # ground/shank angle during stance and swing reference
        g = np.where(s < 0.15, -0.08 * np.sin(0.5 * np.pi * s / 0.15),
                     -0.08 + 0.20 * np.sin(0.5 * np.pi * np.clip((s - 0.15) / 0.6, 0, 1)) ** 2)
        g = np.where(s > 0.75, g - 0.30 * np.sin(0.5 * np.pi * np.clip((s - 0.75) / 0.25, 0, 1)) ** 2, g)
        gd[m] = np.where(inst, g, 0.0)
        gi[m] = np.where(inst, 0.03 * np.sin(np.pi * s), 0.0)
        # stance engagement ramp over first 4 % (heel contact)
        st[m] = np.where(inst, np.clip(s / 0.04, 0, 1) * np.clip((1 - s) / 0.03, 0, 1), 0.0)
        sw = (tt - sf) / (1 - sf)
        swing_ref = -0.22 * (1 - np.sin(0.5 * np.pi * np.clip(sw / 0.5, 0, 1))) + 0.04 * np.sin(np.pi * np.clip(sw, 0, 1))
        rd[m] = np.where(inst, g, swing_ref)
        ri[m] = np.where(inst, gi[m], 0.0)
        ts += S
    # ramp the first stride's reference in from 0 (stand) to avoid a jump
    return st, Md, Mi, gd, gi, rd, ri


# ---------------------------------------------------------------- the run description
def default_run():
    return dict(
        T=24.0, rate=1000, jitter=None, gaps=0.0, seed=0, kind='id', motion='bench', rig=(0.0, 0.0),
        rig_b=(0.5, 0.2), ankle_enc=True, controller='pd', kp=80.0, kd=2.0, imp=None, ilim=15.0,
        # plant
        J=NOM['J'], D=NOM['D'], kcp=(NOM['kc'], NOM['kc']), kcn=(NOM['kc'], NOM['kc']), kscale=1.0,
        strib=None, mu=(0.0, 0.0), cog=None, delay=0.0, stiff=None, backlash=None, toff=(0.0, 0.0),
        tempvisc=None, creep=None, kt_err=(0.0, 0.0),
        # sensors
        g_off=(0.0, 0.0), g_gain=(1.0, 1.0), enc_scale=(1.0, 1.0), clip=None, held=0.0, drift=(0.0, 0.0),
        walk=None, scale_dp=1.0, scale_ie=1.0, t_global=0.0,
    )


def simulate(runs, H=2e-4, verbose=True):
    """runs: list of dicts (default_run updated). Returns list of dict-of-columns."""
    N = len(runs)
    ar = np.arange(N)
    r, a, b = NOM['r'], NOM['a'], NOM['b']
    cd, ci = r / (2 * a), r / (2 * b)
    Tmax = max(R['T'] for R in runs)
    nsub = int(round(Tmax / H)) + 1
    spm = 1e-3 / H  # substeps per ms
    P = lambda key, idx=None: np.array([(R[key] if idx is None else R[key][idx]) for R in runs], float)
    J = P('J'); kcp1 = P('kcp', 0); kcp2 = P('kcp', 1); kcn1 = P('kcn', 0); kcn2 = P('kcn', 1)
    ve = NOM['ve']
    Kd0, Ki0 = Kax(NOM['k'])
    Kd = Kd0 * P('kscale'); Ki = Ki0 * P('kscale')
    beta = NOM['beta']
    kt1 = NOM['kt'] * (1 + P('kt_err', 0)); kt2 = NOM['kt'] * (1 + P('kt_err', 1))
    mu1 = P('mu', 0); mu2 = P('mu', 1); to1 = P('toff', 0); to2 = P('toff', 1)
    # stribeck
    As = np.array([R['strib']['A'] if R['strib'] else 0.0 for R in runs])
    vs = np.array([R['strib']['vs'] if R['strib'] else 1.0 for R in runs])
    dl = np.array([R['strib']['delta'] if R['strib'] else 1.0 for R in runs])
    # cogging: N periods per output rev, amplitudes (3), phases per motor (2,3)
    cN = np.array([R['cog']['N'] if R['cog'] else 0.0 for R in runs])
    cA = np.array([(list(R['cog']['A']) + [0, 0, 0])[:3] if R['cog'] else [0, 0, 0] for R in runs], float)
    cP = np.array([R['cog']['ph'] if R['cog'] else [[0, 0, 0], [0, 0, 0]] for R in runs], float)
    # backlash
    bl_ax_d = np.array([R['backlash']['b'][0] if R['backlash'] and R['backlash']['form'] == 'axis' else 0.0 for R in runs])
    bl_ax_i = np.array([R['backlash']['b'][1] if R['backlash'] and R['backlash']['form'] == 'axis' else 0.0 for R in runs])
    bl_cab = np.array([R['backlash']['b'] if R['backlash'] and R['backlash']['form'] == 'cable' else 0.0 for R in runs])
    # stiffness
    s_poly_d = np.array([1 / R['stiff']['s0'][0] if R['stiff'] and R['stiff']['form'] == 'poly' else 0.0 for R in runs])
    s_poly_i = np.array([1 / R['stiff']['s0'][1] if R['stiff'] and R['stiff']['form'] == 'poly' else 0.0 for R in runs])
    is_exp = np.array([bool(R['stiff'] and R['stiff']['form'] == 'exp') for R in runs])
    s_exp_d = np.array([R['stiff']['s0'][0] if R['stiff'] and R['stiff']['form'] == 'exp' else 1.0 for R in runs])
    s_exp_i = np.array([R['stiff']['s0'][1] if R['stiff'] and R['stiff']['form'] == 'exp' else 1.0 for R in runs])
    any_exp = is_exp.any()
    # creep (Maxwell element per axis): dz = kc*K*phidot - z/Tc
    cr_k = np.array([R['creep']['frac'] if R['creep'] else 0.0 for R in runs])
    cr_T = np.array([R['creep']['T'] if R['creep'] else 1.0 for R in runs])
    # temperature-dependent viscous damping
    D0 = P('D')
    tv_on = np.array([bool(R['tempvisc']) for R in runs])
    tv_D0 = np.array([R['tempvisc']['D0'] if R['tempvisc'] else 0.0 for R in runs])
    tv_D1 = np.array([R['tempvisc']['D1'] if R['tempvisc'] else 0.0 for R in runs])
    tv_T = np.array([R['tempvisc']['T'] if R['tempvisc'] else 1.0 for R in runs])
    tglob = P('t_global')
    # foot loads
    rkd = P('rig', 0); rki = P('rig', 1); rbd = P('rig_b', 0); rbi = P('rig_b', 1)
    rbd = np.where(rkd > 0, rbd, 0.0); rbi = np.where(rki > 0, rbi, 0.0)
    mg = NOM['m'] * 9.81 * NOM['c']
    Id, Ii = NOM['Id'], NOM['Ii']
    # delay (substeps)
    dsteps = np.array([int(round(R['delay'] / H)) for R in runs])
    L = int(dsteps.max()) + 2
    hist1 = np.zeros((N, L)); hist2 = np.zeros((N, L))

    # -------- time-series on the ms grid
    nms = int(round(Tmax * 1000)) + 2
    REFd = np.zeros((N, nms)); REFi = np.zeros((N, nms))
    ST = np.zeros((N, nms)); MD = np.zeros((N, nms)); MI = np.zeros((N, nms)); GD = np.zeros((N, nms)); GI = np.zeros((N, nms))
    walk_k = np.zeros(N); walk_b = np.zeros(N)
    for j, R in enumerate(runs):
        rng = np.random.default_rng(R['seed'] + 1000)
        if R['walk']:
            W = R['walk']
            st, Md, Mi, gd, gi, rd, ri = gait_profiles(R['T'], W['mass'], rng, stride=W.get('stride', 1.1), Mpk=W.get('Mpk', 1.4))
            n = len(st)
            ST[j, :n] = st; MD[j, :n] = Md; MI[j, :n] = Mi; GD[j, :n] = gd; GI[j, :n] = gi; REFd[j, :n] = rd; REFi[j, :n] = ri
            walk_k[j] = W.get('kc', 400.0); walk_b[j] = W.get('bc', 4.0)
            # blend the reference in from 0 over the first second of walking
            tt = np.arange(n) * 1e-3
            blend = np.clip((tt - 0.5) / 0.5, 0, 1)
            REFd[j, :n] *= blend; REFi[j, :n] *= blend
        else:
            rd, ri = bench_reference(R['kind'], R['T'], rng, R['scale_dp'], R['scale_ie'])
            REFd[j, :len(rd)] = rd; REFi[j, :len(ri)] = ri

    # -------- tick schedule per run (substep indices)
    TICK = np.zeros((N, nsub), bool)
    for j, R in enumerate(runs):
        rng = np.random.default_rng(R['seed'] + 2000)
        per = int(round((1.0 / R['rate']) / H))
        nT = int(R['T'] / H)
        if R['jitter']:
            idx = [0]
            while idx[-1] < nT:
                p = per + rng.integers(-R['jitter'], R['jitter'] + 1)
                if rng.random() < 0.003:
                    p += rng.integers(2, 8) * per // 2
                idx.append(idx[-1] + max(1, p))
            idx = np.array(idx[:-1])
        else:
            idx = np.arange(0, nT, per)
        if R['gaps'] > 0:  # dropped cycles in bursts: the plant runs on with the old set value
            keep = np.ones(len(idx), bool)
            nb = int(R['gaps'] * len(idx) / 4)
            for s0 in rng.integers(600, len(idx) - 10, nb):
                keep[s0:s0 + rng.integers(2, 8)] = False
            idx = idx[keep]
        TICK[j, idx] = True
    any_tick = TICK.any(0)

    # -------- controller parameters
    is_imp = np.array([R['controller'] == 'imp' for R in runs])
    kp = P('kp'); kd = P('kd'); ilim = P('ilim')
    def impp(key, dflt):
        return np.array([(R['imp'] or {}).get(key, dflt) for R in runs], float)
    Ks_st_d = impp('Ks_st_d', 350.0); Ks_st_i = impp('Ks_st_i', 100.0); Bs_st_d = impp('Bs_st_d', 4.0); Bs_st_i = impp('Bs_st_i', 1.0)
    Ks_sw_d = impp('Ks_sw_d', 60.0); Ks_sw_i = impp('Ks_sw_i', 25.0); Bs_sw_d = impp('Bs_sw_d', 1.5); Bs_sw_i = impp('Bs_sw_i', 0.5)
    ktau = impp('ktau', 0.3); Dm = impp('Dm', 1.5)
    es1 = P('enc_scale', 0); es2 = P('enc_scale', 1)
    go_d = P('g_off', 0); go_i = P('g_off', 1); gg_d = P('g_gain', 0); gg_i = P('g_gain', 1)
    rng_noise = np.random.default_rng(12345 + int(sum(R['seed'] for R in runs)))
    qm = 2 * np.pi / NOM['counts']; qa = 2 * np.pi / 65536; qsg = 0.004; qi = 30.0 / 4096
    t_on = 0.3; t_ramp = 0.2

    # -------- state
    X = np.zeros((10, N))
    u1 = np.zeros(N); u2 = np.zeros(N)
    pm1p = np.zeros(N); pm2p = np.zeros(N); w1f = np.zeros(N); w2f = np.zeros(N)
    thdp = np.zeros(N); thip = np.zeros(N); thdf = np.zeros(N); thif = np.zeros(N)
    tlast = np.zeros(N)
    maxrows = [int(R['T'] * R['rate'] * 1.3) + 10 for R in runs]
    cols = ['t', 'motor_pos_1', 'motor_pos_2', 'current_cmd_1', 'current_cmd_2', 'sg_torque_dp', 'sg_torque_ie',
            'ankle_dp', 'ankle_ie', 'ref_dp', 'ref_ie', 'true_tj_dp', 'true_tj_ie', 'true_dp', 'true_ie',
            'applied_1', 'applied_2', 'motor_vel_1', 'motor_vel_2']
    LOG = {c: np.zeros((N, max(maxrows))) for c in cols}
    nrow = np.zeros(N, int)
    Tend = np.array([R['T'] for R in runs])

    def cable(X):
        m1, m2, thd, thi, w1, w2, wd, wi, zd, zi = X
        phd = cd * (m1 + m2) - thd; phi = ci * (m1 - m2) - thi
        phdd = cd * (w1 + w2) - wd; phid = ci * (w1 - w2) - wi
        # per-axis dead zone
        ed = phd - np.clip(phd, -bl_ax_d, bl_ax_d); ei = phi - np.clip(phi, -bl_ax_i, bl_ax_i)
        md_ = np.abs(phd) >= bl_ax_d; mi_ = np.abs(phi) >= bl_ax_i
        # per-cable dead zone (cable lengths)
        p1 = a * ed + b * ei; p2 = a * ed - b * ei
        q1 = p1 - np.clip(p1, -bl_cab, bl_cab); q2 = p2 - np.clip(p2, -bl_cab, bl_cab)
        ed = (q1 + q2) / (2 * a); ei = (q1 - q2) / (2 * b)
        rm = ((np.abs(p1) >= bl_cab) & (np.abs(p2) >= bl_cab))
        rated = phdd * md_ * rm; ratei = phid * mi_ * rm
        # stiffness
        fd = ed * (1 + np.abs(ed) * s_poly_d); fi = ei * (1 + np.abs(ei) * s_poly_i)
        if any_exp:
            xd = np.minimum(np.abs(ed) / s_exp_d, 30); xi = np.minimum(np.abs(ei) / s_exp_i, 30)
            fd = np.where(is_exp, np.sign(ed) * s_exp_d * np.expm1(xd), fd)
            fi = np.where(is_exp, np.sign(ei) * s_exp_i * np.expm1(xi), fi)
        tjd = Kd * (fd + beta * rated) + zd; tji = Ki * (fi + beta * ratei) + zi
        return tjd, tji, phdd, phid

    def deriv(X, ua1, ua2, t, st, Md, Mi, gd, gi):
        m1, m2, thd, thi, w1, w2, wd, wi, zd, zi = X
        tjd, tji, phdd, phid = cable(X)
        c1 = cd * tjd + ci * tji; c2 = cd * tjd - ci * tji
        Dt = np.where(tv_on, tv_D1 + (tv_D0 - tv_D1) * np.exp(-(t + tglob) / tv_T), D0)
        t1 = np.tanh(w1 / ve); t2 = np.tanh(w2 / ve)
        f1 = 0.5 * (kcp1 + kcn1) * t1 + 0.5 * (kcp1 - kcn1) * np.abs(t1)
        f2 = 0.5 * (kcp2 + kcn2) * t2 + 0.5 * (kcp2 - kcn2) * np.abs(t2)
        f1 = f1 + (As * np.exp(-(np.abs(w1) / vs) ** dl) + mu1 * np.abs(c1)) * t1
        f2 = f2 + (As * np.exp(-(np.abs(w2) / vs) ** dl) + mu2 * np.abs(c2)) * t2
        g1 = cN * m1; g2 = cN * m2
        cg1 = cA[:, 0] * np.sin(g1 + cP[:, 0, 0]) + cA[:, 1] * np.sin(2 * g1 + cP[:, 0, 1]) + cA[:, 2] * np.sin(3 * g1 + cP[:, 0, 2])
        cg2 = cA[:, 0] * np.sin(g2 + cP[:, 1, 0]) + cA[:, 1] * np.sin(2 * g2 + cP[:, 1, 1]) + cA[:, 2] * np.sin(3 * g2 + cP[:, 1, 2])
        dw1 = (kt1 * ua1 - Dt * w1 - f1 - cg1 - to1 - c1) / J
        dw2 = (kt2 * ua2 - Dt * w2 - f2 - cg2 - to2 - c2) / J
        tdd = -rkd * thd - rbd * wd + st * (Md - walk_k * (thd - gd) - walk_b * wd) - mg * np.sin(thd)
        tdi = -rki * thi - rbi * wi + st * (Mi - walk_k * 0.3 * (thi - gi) - walk_b * 0.3 * wi)
        dwd = (tjd + tdd) / Id; dwi = (tji + tdi) / Ii
        dzd = cr_k * Kd * phdd - zd / cr_T; dzi = cr_k * Ki * phid - zi / cr_T
        return np.array([w1, w2, wd, wi, dw1, dw2, dwd, dwi, dzd, dzi])

    t0w = time.time()
    for n in range(nsub):
        t = n * H
        k = min(int(t * 1000 + 1e-9), nms - 1)
        st, Md, Mi, gd, gi = ST[:, k], MD[:, k], MI[:, k], GD[:, k], GI[:, k]
        if any_tick[n]:
            tk = TICK[:, n] & (t < Tend)
            if tk.any():
                tjd, tji, _, _ = cable(X)
                pm1 = np.round(es1 * X[0] / qm) * qm; pm2 = np.round(es2 * X[1] / qm) * qm
                pad = np.round(X[2] / qa) * qa; pai = np.round(X[3] / qa) * qa
                sgd = np.round((gg_d * tjd + go_d + NOM['sg_noise'] * rng_noise.standard_normal(N)) / qsg) * qsg
                sgi = np.round((gg_i * tji + go_i + NOM['sg_noise'] * rng_noise.standard_normal(N)) / qsg) * qsg
                dt = np.maximum(t - tlast, 1e-4)
                al = dt / (dt + 1 / (2 * np.pi * 150))
                w1n = w1f + al * ((pm1 - pm1p) / dt - w1f); w2n = w2f + al * ((pm2 - pm2p) / dt - w2f)
                rd, ri = REFd[:, k], REFi[:, k]
                gate = np.clip((t - t_on) / t_ramp, 0, 1)
                # PD on the motors
                tau1 = kp * (rd / cd * 0.5 + ri / ci * 0.5 - pm1) - kd * w1n
                tau2 = kp * (rd / cd * 0.5 - ri / ci * 0.5 - pm2) - kd * w2n
                # impedance: ankle estimate from motor encoders and gauges (worn device)
                thd_h = cd * (pm1 + pm2) - sgd / Kd0; thi_h = ci * (pm1 - pm2) - sgi / Ki0
                ald = dt / (dt + 1 / (2 * np.pi * 30))
                thdf_n = thdf + ald * ((thd_h - thdp) / dt - thdf); thif_n = thif + ald * ((thi_h - thip) / dt - thif)
                stance = st > 0.01
                Ksd = np.where(stance, Ks_st_d, Ks_sw_d); Ksi = np.where(stance, Ks_st_i, Ks_sw_i)
                Bsd = np.where(stance, Bs_st_d, Bs_sw_d); Bsi = np.where(stance, Bs_st_i, Bs_sw_i)
                Td = Ksd * (rd - thd_h) - Bsd * thdf_n; Ti = Ksi * (ri - thi_h) - Bsi * thif_n
                Td2 = Td + ktau * (Td - sgd); Ti2 = Ti + ktau * (Ti - sgi)
                it1 = cd * Td2 + ci * Ti2 - Dm * w1n; it2 = cd * Td2 - ci * Ti2 - Dm * w2n
                tau1 = np.where(is_imp, it1, tau1); tau2 = np.where(is_imp, it2, tau2)
                i1 = np.clip(gate * tau1 / NOM['kt'], -ilim, ilim); i2 = np.clip(gate * tau2 / NOM['kt'], -ilim, ilim)
                i1 = np.round(i1 / qi) * qi; i2 = np.round(i2 / qi) * qi
                u1 = np.where(tk, i1, u1); u2 = np.where(tk, i2, u2)
                pm1p = np.where(tk, pm1, pm1p); pm2p = np.where(tk, pm2, pm2p)
                w1f = np.where(tk, w1n, w1f); w2f = np.where(tk, w2n, w2f)
                thdp = np.where(tk, thd_h, thdp); thip = np.where(tk, thi_h, thip)
                thdf = np.where(tk, thdf_n, thdf); thif = np.where(tk, thif_n, thif)
                tlast = np.where(tk, t, tlast)
                js = np.nonzero(tk)[0]
                rw = nrow[js]
                for c, v in (('t', np.full(N, t)), ('motor_pos_1', pm1), ('motor_pos_2', pm2), ('current_cmd_1', i1),
                             ('current_cmd_2', i2), ('sg_torque_dp', sgd), ('sg_torque_ie', sgi), ('ankle_dp', pad),
                             ('ankle_ie', pai), ('ref_dp', rd), ('ref_ie', ri), ('true_tj_dp', tjd), ('true_tj_ie', tji),
                             ('true_dp', X[2]), ('true_ie', X[3]), ('motor_vel_1', X[4]), ('motor_vel_2', X[5])):
                    LOG[c][js, rw] = v[js]
                nrow[js] += 1
        # delay line on the applied current
        slot = n % L
        hist1[:, slot] = u1; hist2[:, slot] = u2
        ua1 = hist1[ar, (n - dsteps) % L]; ua2 = hist2[ar, (n - dsteps) % L]
        if n < L:
            ua1 = np.where(n - dsteps < 0, 0.0, ua1); ua2 = np.where(n - dsteps < 0, 0.0, ua2)
        # RK4
        k1 = deriv(X, ua1, ua2, t, st, Md, Mi, gd, gi)
        k2 = deriv(X + 0.5 * H * k1, ua1, ua2, t + 0.5 * H, st, Md, Mi, gd, gi)
        k3 = deriv(X + 0.5 * H * k2, ua1, ua2, t + 0.5 * H, st, Md, Mi, gd, gi)
        k4 = deriv(X + H * k3, ua1, ua2, t + H, st, Md, Mi, gd, gi)
        X = X + (H / 6) * (k1 + 2 * k2 + 2 * k3 + k4)
        if verbose and n % 20000 == 0:
            print(f'  step {n}/{nsub}  t={t:.2f}s  wall {time.time() - t0w:.1f}s', file=sys.stderr, flush=True)
        if not np.all(np.isfinite(X)):
            bad = np.nonzero(~np.all(np.isfinite(X), 0))[0]
            raise RuntimeError(f'non-finite state at t={t} in runs {bad}')
    out = []
    for j in range(N):
        out.append({c: LOG[c][j, :nrow[j]].copy() for c in cols})
    return out


# ---------------------------------------------------------------- post-hoc sensor artefacts
def post_sensor(d, R, rng):
    if R['clip']:
        c = R['clip']
        d['sg_torque_dp'] = np.clip(d['sg_torque_dp'], -c[0], c[0])
        d['sg_torque_ie'] = np.clip(d['sg_torque_ie'], -c[1], c[1])
    if R['drift'] != (0.0, 0.0):
        frac = (d['t'] - d['t'][0]) / (d['t'][-1] - d['t'][0])
        d['sg_torque_dp'] = d['sg_torque_dp'] + R['drift'][0] * frac
        d['sg_torque_ie'] = d['sg_torque_ie'] + R['drift'][1] * frac
    if R['held'] > 0:
        n = len(d['t'])
        nep = int(R['held'] * n / 12)
        for s in rng.integers(500, n - 40, nep):
            L = rng.integers(4, 25)
            for c in ('sg_torque_dp', 'sg_torque_ie'):
                d[c][s:s + L] = d[c][s]
    return d


def write_csv(path, d, ankle_enc):
    cols = ['t', 'motor_pos_1', 'motor_pos_2', 'current_cmd_1', 'current_cmd_2', 'sg_torque_dp', 'sg_torque_ie']
    if ankle_enc:
        cols += ['ankle_dp', 'ankle_ie']
    cols += ['ref_dp', 'ref_ie']
    fmt = {'t': '%.6f'}
    with open(path, 'w') as f:
        f.write(','.join(cols) + '\n')
        M = np.column_stack([d[c] for c in cols])
        fm = ['%.6f'] + ['%.9g'] * (len(cols) - 1)
        np.savetxt(f, M, fmt=fm, delimiter=',')


# ---------------------------------------------------------------- the cases
def build_cases():
    C = []

    def case(cid, sset, truth, note, cfg=None, **kw):
        R = default_run(); R.update(kw)
        C.append(dict(id=cid, set=sset, truth=sorted(truth), note=note, cfg=cfg, run=R))

    rig = (350.0, 120.0)
    # ---------------- S1: single effects
    case('s1_stribeck_exp', 'S1', ['stribeck'], 'Stribeck exp(-|v|/vs), free foot, PD 80/2',
         strib=dict(A=0.22, vs=0.06, delta=1.0), seed=11)
    case('s1_stribeck_gauss', 'S1', ['stribeck'], 'Stribeck exp(-(v/vs)^2) on a linear rig, PD 90/5',
         strib=dict(A=0.18, vs=0.15, delta=2.0), rig=rig, kp=90, kd=5, seed=12)
    case('s1_asym', 'S1', ['asymmetric_friction'], 'Coulomb kc+/kc- = 0.40/0.20 (m1), 0.22/0.36 (m2)',
         kcp=(0.40, 0.22), kcn=(0.20, 0.36), seed=13)
    case('s1_loadfric', 'S1', ['load_dependent_friction'], 'mu=0.08 x |cable torque| per motor, rig',
         mu=(0.08, 0.08), rig=(450.0, 150.0), seed=14)
    case('s1_backlash_axis', 'S1', ['backlash'], 'dead zone per axis 0.004/0.003 rad of stretch, rig',
         backlash=dict(form='axis', b=(0.004, 0.003)), rig=rig, kp=90, kd=5, seed=15)
    case('s1_backlash_cable', 'S1', ['backlash'], 'dead zone per cable, 0.15 mm of cable length, rig',
         backlash=dict(form='cable', b=0.00015), rig=rig, kp=90, kd=5, seed=16)
    case('s1_cogging_1h', 'S1', ['cogging'], 'cogging N=24*81=1944/rev, 0.08 N m, per-motor phases',
         cog=dict(N=1944, A=[0.08], ph=[[0.3, 0, 0], [2.1, 0, 0]]), seed=17)
    case('s1_cogging_3h', 'S1', ['cogging'], 'cogging N=10*81=810/rev, harmonics 0.06/0.03/0.015, rig',
         cog=dict(N=810, A=[0.06, 0.03, 0.015], ph=[[1.0, 0.4, 2.0], [-0.5, 1.7, 0.2]]), rig=rig, seed=18)
    case('s1_delay_4ms', 'S1', ['delay'], 'actuation delay 4 ms, PD 90/5, free foot',
         delay=0.004, kp=90, kd=5, seed=19)
    case('s1_delay_9ms', 'S1', ['delay'], 'actuation delay 9 ms, PD 90/5, rig',
         delay=0.009, kp=90, kd=5, rig=rig, seed=20)
    case('s1_stiff_poly', 'S1', ['stiffness_nonlinear'], 'K*phi*(1+|phi|/s0), s0=0.015/0.02 rad, stiff rig',
         stiff=dict(form='poly', s0=(0.015, 0.02)), rig=(500.0, 150.0), kp=90, kd=5, seed=21)
    case('s1_stiff_exp', 'S1', ['stiffness_nonlinear'], 'K*s0*expm1(|phi|/s0), s0=0.02/0.03 rad, stiff rig',
         stiff=dict(form='exp', s0=(0.02, 0.03)), rig=(500.0, 150.0), kp=90, kd=5, seed=22)
    case('s1_offset', 'S1', ['torque_offset'], 'constant load +0.5 N m on motor 1, -0.3 on motor 2',
         toff=(0.5, -0.3), seed=23)
    case('s1_none_cal', 'S1', ['none'], 'no effect; torque constant +10 % (plant kt 1.826) and gauge gain 1.08/0.95',
         kt_err=(0.10, 0.10), g_gain=(1.08, 0.95), rig=rig, seed=24)
    case('s1_unknown_tempvisc', 'S1', ['unknown'], 'viscous damping falls 0.30->0.10 as the motors warm (tau 12 s)',
         tempvisc=dict(D0=0.30, D1=0.10, T=12.0), seed=25)
    case('s1_unknown_creep', 'S1', ['unknown'], 'cable stress relaxation: Maxwell element 0.4 K, T 0.3 s, rig',
         creep=dict(frac=0.4, T=0.3), rig=rig, kp=90, kd=5, seed=26)

    # ---------------- S2: mixtures
    case('s2_strib_cog_delay', 'S2', ['stribeck', 'cogging', 'delay'], 'Stribeck + cogging 1215/rev + 3 ms delay',
         strib=dict(A=0.2, vs=0.08, delta=1.3), cog=dict(N=1215, A=[0.07, 0.02], ph=[[0.2, 1.0, 0], [1.4, 0.1, 0]]),
         delay=0.003, kp=90, kd=5, seed=31)
    case('s2_asym_load', 'S2', ['asymmetric_friction', 'load_dependent_friction'], 'asymmetric Coulomb + mu 0.06, rig',
         kcp=(0.36, 0.30), kcn=(0.22, 0.20), mu=(0.06, 0.06), rig=(450.0, 150.0), seed=32)
    case('s2_backlash_stiff', 'S2', ['backlash', 'stiffness_nonlinear'], 'axis dead zone 0.003 + poly stiffening s0 0.02',
         backlash=dict(form='axis', b=(0.003, 0.003)), stiff=dict(form='poly', s0=(0.02, 0.025)), rig=(500.0, 150.0),
         kp=90, kd=5, seed=33)
    case('s2_offset_strib', 'S2', ['torque_offset', 'stribeck'], 'load offset 0.6/0.6 N m (a spring preload) + Stribeck',
         toff=(0.6, 0.6), strib=dict(A=0.2, vs=0.1, delta=0.8), seed=34)
    case('s2_clip_load_cog', 'S2', ['load_dependent_friction', 'cogging'], 'mu 0.07 + cogging 648/rev; gauges clip at 18/6 N m',
         mu=(0.07, 0.07), cog=dict(N=648, A=[0.08], ph=[[0.0, 0, 0], [1.0, 0, 0]]), rig=(450.0, 150.0),
         clip=(18.0, 6.0), seed=35)
    case('s2_delay_asym_cog_gain', 'S2', ['delay', 'asymmetric_friction', 'cogging'],
         '5 ms delay + asym Coulomb + cogging 1620/rev; gauge gain 1.10/1.10 (calibration)',
         delay=0.005, kcp=(0.38, 0.38), kcn=(0.22, 0.22), cog=dict(N=1620, A=[0.07], ph=[[0.5, 0, 0], [2.5, 0, 0]]),
         g_gain=(1.10, 1.10), kp=90, kd=5, rig=rig, seed=36)

    # ---------------- S3: real-device conditions
    W = lambda m, **k: dict(mass=m, **k)
    case('s3_walk75_none', 'S3', ['none'], 'walking 75 kg, impedance, no joint encoders, no effect',
         walk=W(75), controller='imp', ankle_enc=False, T=20.0, seed=41)
    case('s3_walk100_loadfric_ilim', 'S3', ['load_dependent_friction'],
         'walking 100 kg, mu 0.04, no joint enc, current limit 7 A (own config)',
         walk=W(100, Mpk=1.5), controller='imp', ankle_enc=False, mu=(0.04, 0.04), ilim=7.0, T=20.0, seed=42,
         cfg={'amplifier': {'current_limit_peak': 7.0}})
    case('s3_walk50_cogging', 'S3', ['cogging'], 'walking 50 kg, cogging 972/rev 2 harmonics, per-motor phases',
         walk=W(50, Mpk=1.3), controller='imp', ankle_enc=False, cog=dict(N=972, A=[0.09, 0.04], ph=[[0.0, 0.7, 0], [2.0, 2.9, 0]]),
         T=20.0, seed=43)
    case('s3_imp_rig_asym', 'S3', ['asymmetric_friction'], 'impedance controller on a rig (bench, joint enc), asym Coulomb',
         controller='imp', imp=dict(Ks_sw_d=200.0, Ks_sw_i=60.0, Bs_sw_d=2.0, Bs_sw_i=0.6), rig=(200.0, 80.0),
         kcp=(0.42, 0.42), kcn=(0.24, 0.24), seed=44)
    case('s3_jitter_stribeck', 'S3', ['stribeck'], 'jittered sample stamps (0.8-1.2 ms + rare late cycles), Stribeck',
         jitter=1, strib=dict(A=0.2, vs=0.07, delta=1.0), seed=45)
    case('s3_500hz_delay', 'S3', ['delay'], '500 Hz control + log, 6 ms delay, own config rate_hz 500',
         rate=500, delay=0.006, kp=90, kd=5, seed=46, cfg={'controller': {'rate_hz': 500}})
    case('s3_500hz_none_gauge', 'S3', ['none'], '500 Hz log (default config), gauge gain 0.9 and zero offsets 0.6/-0.3 N m, rig',
         rate=500, g_gain=(0.9, 0.9), g_off=(0.6, -0.3), rig=rig, seed=47)
    case('s3_gaps_cogging', 'S3', ['cogging'], 'dropped cycles (~1 % in bursts of 2-7), cogging 1296/rev',
         gaps=0.01, cog=dict(N=1296, A=[0.08], ph=[[0.9, 0, 0], [0.1, 0, 0]]), seed=48)
    case('s3_gaugeoff_offset', 'S3', ['torque_offset'], 'true load offset -0.45/+0.35 N m and gauge zero offsets 0.5/0.3 N m',
         toff=(-0.45, 0.35), g_off=(0.5, 0.3), rig=rig, seed=49)
    case('s3_encscale_none', 'S3', ['none'], 'motor encoder scale 0.985 (both), no effect, rig',
         enc_scale=(0.985, 0.985), rig=rig, seed=50)
    case('s3_held_stiff', 'S3', ['stiffness_nonlinear'], 'held gauge samples (2 % of rows) + exp stiffening',
         held=0.02, stiff=dict(form='exp', s0=(0.025, 0.03)), rig=(500.0, 150.0), kp=90, kd=5, seed=51)
    case('s3_offnominal_none', 'S3', ['none'], 'device off nominal (J+15 %, D-20 %, kc+20 %, cable k-15 %), default config',
         J=0.048 * 1.15, D=0.112 * 0.8, kcp=(0.336, 0.336), kcn=(0.336, 0.336), kscale=0.85, rig=rig, seed=52)
    case('s3_ownconfig_delay', 'S3', ['delay'], 'device J 0.055, D 0.09, kc 0.33, cable 0.9 k with its own config; 3 ms delay',
         J=0.055, D=0.09, kcp=(0.33, 0.33), kcn=(0.33, 0.33), kscale=0.9, delay=0.003, kp=90, kd=5, rig=rig, seed=53,
         cfg={'actuator': {'inertia': 0.055, 'damping': 0.09, 'coulomb': 0.33},
              'transmission': {'cable_stiffness': 218800.0 * 0.9}})
    case('s3_walk_drift_strib', 'S3', ['stribeck'], 'walking 75 kg + gauge drift 0.6/0.2 N m over the run + Stribeck',
         walk=W(75), controller='imp', ankle_enc=False, strib=dict(A=0.25, vs=0.08, delta=1.0), drift=(0.6, 0.2),
         T=20.0, seed=54)
    # ---------------- X: probes added after the first scoring run, to explain misses (not scored)
    case('x_nominal_free', 'X', ['none'], 'control: no effect, free foot, joint encoders', seed=61)
    case('x_nominal_rig', 'X', ['none'], 'control: no effect, rig, joint encoders', rig=rig, kp=90, kd=5, seed=62)
    case('x_cog_free_noenc', 'X', ['cogging'], 's1_cogging_1h without joint encoders',
         cog=dict(N=1944, A=[0.08], ph=[[0.3, 0, 0], [2.1, 0, 0]]), ankle_enc=False, seed=17)
    case('x_stiff_poly_walk_enc', 'X', ['stiffness_nonlinear'], 'walking 75 kg with joint encoders, poly stiffening s0 0.03/0.03',
         walk=W(75), controller='imp', stiff=dict(form='poly', s0=(0.03, 0.03)), T=20.0, seed=63)
    case('x_backlash_walk_enc', 'X', ['backlash'], 'walking 75 kg with joint encoders, axis dead zone 0.003/0.003',
         walk=W(75), controller='imp', backlash=dict(form='axis', b=(0.003, 0.003)), T=20.0, seed=64)
    case('x_stiff_poly_soft', 'X', ['stiffness_nonlinear'], 's1_stiff_poly with a weaker nonlinearity (s0 0.05/0.06)',
         stiff=dict(form='poly', s0=(0.05, 0.06)), rig=(500.0, 150.0), kp=90, kd=5, seed=21)
    case('x_creep_slow', 'X', ['unknown'], 'creep: Maxwell element 0.5 K, T 2 s, rig',
         creep=dict(frac=0.5, T=2.0), rig=rig, kp=90, kd=5, seed=65)
    case('x_walk_strib_nodrift', 'X', ['stribeck'], 's3_walk_drift_strib without the gauge drift',
         walk=W(75), controller='imp', ankle_enc=False, strib=dict(A=0.25, vs=0.08, delta=1.0), T=20.0, seed=54)
    case('x_walk_drift_none', 'X', ['none'], 'walking 75 kg, gauge drift 0.6/0.2 N m only',
         walk=W(75), controller='imp', ankle_enc=False, drift=(0.6, 0.2), T=20.0, seed=66)
    case('x_bench_strib_big_drift', 'X', ['none'], 'bench rig, no effect, gauge drift 1.5/0.5 N m over the run',
         drift=(1.5, 0.5), rig=rig, seed=67)
    case('x_cog_2916', 'X2', ['cogging'], 'cogging N=36*81=2916/rev, 0.08 N m, free foot, no joint enc',
         cog=dict(N=2916, A=[0.08], ph=[[0.3, 0, 0], [2.1, 0, 0]]), ankle_enc=False, seed=71)
    case('x_cog_3888', 'X2', ['cogging'], 'cogging N=48*81=3888/rev, 0.08 N m, free foot, no joint enc',
         cog=dict(N=3888, A=[0.08], ph=[[0.3, 0, 0], [2.1, 0, 0]]), ankle_enc=False, seed=72)
    case('x_backlash_softrig', 'X2', ['backlash'], 'axis dead zone 0.004/0.003 on a soft rig (120/40 N m/rad)',
         backlash=dict(form='axis', b=(0.004, 0.003)), rig=(120.0, 40.0), kp=90, kd=5, seed=73)
    case('x_stiff_poly_softrig', 'X2', ['stiffness_nonlinear'], 'poly stiffening s0 0.015/0.02 on a soft rig (120/40)',
         stiff=dict(form='poly', s0=(0.015, 0.02)), rig=(120.0, 40.0), kp=90, kd=5, seed=74)
    return C


def write_config(path, cfg):
    import yaml
    d = {'include': [MAIN]}
    d.update(cfg)
    with open(path, 'w') as f:
        yaml.safe_dump(d, f, sort_keys=False)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--out', required=True)
    ap.add_argument('--only', default='')
    ap.add_argument('--h', type=float, default=2e-4)
    ap.add_argument('--sets', default='S1,S2,S3', help='comma list of case sets (X = probes)')
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    cases = [c for c in build_cases() if c['set'] in args.sets.split(',')]
    if args.only:
        keep = set(args.only.split(','))
        cases = [c for c in cases if c['id'] in keep]
    runs = []
    for c in cases:
        R = dict(c['run'])
        Rv = dict(R)
        Rv['kind'] = 'val'; Rv['seed'] = R['seed'] + 500
        Rv['T'] = R['T'] * 0.5 if not R['walk'] else 12.0
        Rv['t_global'] = R['T'] + 5.0
        runs += [R, Rv]
    t0 = time.time()
    res = simulate(runs, H=args.h)
    print(f'simulated {len(runs)} runs in {time.time() - t0:.1f} s', file=sys.stderr)
    truth = {}
    sanity = {}
    for i, c in enumerate(cases):
        d = os.path.join(args.out, c['id'])
        os.makedirs(d, exist_ok=True)
        cfgpath = MAIN
        if c['cfg']:
            cfgpath = os.path.join(d, 'config.yaml')
            write_config(cfgpath, c['cfg'])
        for j, name in ((0, 'id.csv'), (1, 'val.csv')):
            R = runs[2 * i + j]
            dd = post_sensor(res[2 * i + j], R, np.random.default_rng(R['seed'] + 3000))
            write_csv(os.path.join(d, name), dd, R['ankle_enc'])
            s = dict(rows=len(dd['t']), max_abs_current=float(max(np.abs(dd['current_cmd_1']).max(), np.abs(dd['current_cmd_2']).max())),
                     frac_at_limit=float(np.mean(np.maximum(np.abs(dd['current_cmd_1']), np.abs(dd['current_cmd_2'])) >= R['ilim'] - 0.01)),
                     max_abs_dp_deg=float(np.degrees(np.abs(dd['true_dp']).max())), max_abs_ie_deg=float(np.degrees(np.abs(dd['true_ie']).max())),
                     max_abs_tj_dp=float(np.abs(dd['true_tj_dp']).max()), max_abs_tj_ie=float(np.abs(dd['true_tj_ie']).max()),
                     max_motor_vel=float(max(np.abs(dd['motor_vel_1']).max(), np.abs(dd['motor_vel_2']).max())),
                     rms_track_dp_deg=float(np.degrees(np.sqrt(np.mean((dd['true_dp'] - dd['ref_dp']) ** 2)))))
            sanity[f"{c['id']}/{name}"] = s
        truth[c['id']] = dict(set=c['set'], causes=c['truth'], note=c['note'], config=cfgpath,
                              ankle_encoders=c['run']['ankle_enc'],
                              params={k: v for k, v in c['run'].items() if v not in (None, 0.0, (0.0, 0.0)) and k not in ('kind',)})
    with open(os.path.join(args.out, 'truth.json'), 'w') as f:
        json.dump(truth, f, indent=1, default=str)
    with open(os.path.join(args.out, 'sanity.json'), 'w') as f:
        json.dump(sanity, f, indent=1)
    for k, s in sanity.items():
        print(f"{k:38s} rows {s['rows']:6d} |i|max {s['max_abs_current']:5.2f} lim {s['frac_at_limit']:.3f} "
              f"dp {s['max_abs_dp_deg']:5.1f} ie {s['max_abs_ie_deg']:5.1f} tj {s['max_abs_tj_dp']:6.1f}/{s['max_abs_tj_ie']:5.1f} "
              f"vm {s['max_motor_vel']:5.2f} trk {s['rms_track_dp_deg']:.2f}")


if __name__ == '__main__':
    main()
