"""Explicit Runge-Kutta steps with dense output: classic RK4 and DOPRI5.

Butcher tableaux are module-level data (a method is data; tests/test_kernel_
integrators.py checks the row sums and the order conditions).

DOPRI5: Dormand & Prince (1980), "A family of embedded Runge-Kutta formulae",
J. Comput. Appl. Math. 6; 5th-order solution with a 4th-order embedded error
estimate, FSAL.  Error norm and step-size control as in Hairer, Norsett &
Wanner, *Solving ODEs I*, §II.4 (code DOPRI5): ``sc_i = atol + rtol max(|y0_i|,
|y1_i|)``, ``err = sqrt(mean((h sum_j E_j k_j,i / sc_i)^2))``,
``h_new = h min(FAC_MAX, max(FAC_MIN, SAFETY err^(-1/5)))``; the initial step
follows Hairer's ``hinit``.  Dense output: Hairer's 4th-order continuous
extension (coefficients d1..d7 of dopri5.f, ``contd5``); tests compare it with
the equivalent polynomial matrix of SciPy's ``RK45.P``.

RK4: the classic 4-stage method; its dense output is the cubic Hermite
interpolant of the end-point states and derivatives.

DOP853: Dormand & Prince's 8th-order method with the 5th/3rd-order error
estimate of Hairer's DOP853 (``err = |err5|^2 / sqrt(|err5|^2 + 0.01 |err3|^2)``,
step factor exponent -1/8), 12 stages, FSAL (stage 13 = f at the new state,
evaluated only for an accepted step).  Dense output: Hairer's 7th-order
continuous extension, which needs three extra stages (13-15); they are
evaluated lazily (`dop853_dense_prepare`), only for a step that has an output
time or a possible contact event in it.  The coefficients are those of
Hairer's dop853.f as tabulated in SciPy (``integrate/_ivp/dop853_coefficients.py``,
BSD-3), copied here as data; tests check row sums and the order conditions.
"""
from __future__ import annotations

import math

import numpy as np
from .jit import kernel

from .. import catalog
from ..model import CFG_ATOL, CFG_RTOL, Status
from .dynamics import rhs, rhs_inlined
from .workspace import DN_H, DN_TA, FL_DENSE_METHOD, FL_DENSE_READY

RK4_C = np.array([0.0, 0.5, 0.5, 1.0])
RK4_A = np.array([
    [0.0, 0.0, 0.0, 0.0],
    [0.5, 0.0, 0.0, 0.0],
    [0.0, 0.5, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
])
RK4_B = np.array([1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0])

DP5_C = np.array([0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0])
DP5_A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0, 0.0],
    [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0, 0.0],
    [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0, 0.0],
    [35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0, 0.0],
])
# 5th-order weights (= last row of A: FSAL) and the 4th-order embedded weights
DP5_B = np.array([35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0, 0.0])
DP5_BHAT = np.array([5179.0 / 57600.0, 0.0, 7571.0 / 16695.0, 393.0 / 640.0,
                     -92097.0 / 339200.0, 187.0 / 2100.0, 1.0 / 40.0])
DP5_E = DP5_B - DP5_BHAT
# Hairer's dense-output coefficients d_j (dopri5.f)
DP5_D = np.array([-12715105075.0 / 11282082432.0, 0.0, 87487479700.0 / 32700410799.0,
                  -10690763975.0 / 1880347072.0, 701980252875.0 / 199316789632.0,
                  -1453857185.0 / 822651844.0, 69997945.0 / 29380423.0])

DP8_C = np.array([
    0.0, 0.05260015195876773, 0.0789002279381516, 0.1183503419072274, 0.2816496580927726, 0.3333333333333333,
    0.25, 0.3076923076923077, 0.6512820512820513, 0.6, 0.8571428571428571, 1.0, 1.0, 0.1, 0.2,
    0.7777777777777778
])
DP8_A = np.zeros((16, 16))
DP8_A[1, 0] = 0.05260015195876773
DP8_A[2, 0] = 0.0197250569845379
DP8_A[2, 1] = 0.0591751709536137
DP8_A[3, 0] = 0.02958758547680685
DP8_A[3, 2] = 0.08876275643042054
DP8_A[4, 0] = 0.2413651341592667
DP8_A[4, 2] = -0.8845494793282861
DP8_A[4, 3] = 0.924834003261792
DP8_A[5, 0] = 0.037037037037037035
DP8_A[5, 3] = 0.17082860872947386
DP8_A[5, 4] = 0.12546768756682242
DP8_A[6, 0] = 0.037109375
DP8_A[6, 3] = 0.17025221101954405
DP8_A[6, 4] = 0.06021653898045596
DP8_A[6, 5] = -0.017578125
DP8_A[7, 0] = 0.03709200011850479
DP8_A[7, 3] = 0.17038392571223998
DP8_A[7, 4] = 0.10726203044637328
DP8_A[7, 5] = -0.015319437748624402
DP8_A[7, 6] = 0.008273789163814023
DP8_A[8, 0] = 0.6241109587160757
DP8_A[8, 3] = -3.3608926294469414
DP8_A[8, 4] = -0.868219346841726
DP8_A[8, 5] = 27.59209969944671
DP8_A[8, 6] = 20.154067550477894
DP8_A[8, 7] = -43.48988418106996
DP8_A[9, 0] = 0.47766253643826434
DP8_A[9, 3] = -2.4881146199716677
DP8_A[9, 4] = -0.590290826836843
DP8_A[9, 5] = 21.230051448181193
DP8_A[9, 6] = 15.279233632882423
DP8_A[9, 7] = -33.28821096898486
DP8_A[9, 8] = -0.020331201708508627
DP8_A[10, 0] = -0.9371424300859873
DP8_A[10, 3] = 5.186372428844064
DP8_A[10, 4] = 1.0914373489967295
DP8_A[10, 5] = -8.149787010746927
DP8_A[10, 6] = -18.52006565999696
DP8_A[10, 7] = 22.739487099350505
DP8_A[10, 8] = 2.4936055526796523
DP8_A[10, 9] = -3.0467644718982196
DP8_A[11, 0] = 2.273310147516538
DP8_A[11, 3] = -10.53449546673725
DP8_A[11, 4] = -2.0008720582248625
DP8_A[11, 5] = -17.9589318631188
DP8_A[11, 6] = 27.94888452941996
DP8_A[11, 7] = -2.8589982771350235
DP8_A[11, 8] = -8.87285693353063
DP8_A[11, 9] = 12.360567175794303
DP8_A[11, 10] = 0.6433927460157636
DP8_A[12, 0] = 0.054293734116568765
DP8_A[12, 5] = 4.450312892752409
DP8_A[12, 6] = 1.8915178993145003
DP8_A[12, 7] = -5.801203960010585
DP8_A[12, 8] = 0.3111643669578199
DP8_A[12, 9] = -0.1521609496625161
DP8_A[12, 10] = 0.20136540080403034
DP8_A[12, 11] = 0.04471061572777259
DP8_A[13, 0] = 0.056167502283047954
DP8_A[13, 6] = 0.25350021021662483
DP8_A[13, 7] = -0.2462390374708025
DP8_A[13, 8] = -0.12419142326381637
DP8_A[13, 9] = 0.15329179827876568
DP8_A[13, 10] = 0.00820105229563469
DP8_A[13, 11] = 0.007567897660545699
DP8_A[13, 12] = -0.008298
DP8_A[14, 0] = 0.03183464816350214
DP8_A[14, 5] = 0.028300909672366776
DP8_A[14, 6] = 0.053541988307438566
DP8_A[14, 7] = -0.05492374857139099
DP8_A[14, 10] = -0.00010834732869724932
DP8_A[14, 11] = 0.0003825710908356584
DP8_A[14, 12] = -0.00034046500868740456
DP8_A[14, 13] = 0.1413124436746325
DP8_A[15, 0] = -0.42889630158379194
DP8_A[15, 5] = -4.697621415361164
DP8_A[15, 6] = 7.683421196062599
DP8_A[15, 7] = 4.06898981839711
DP8_A[15, 8] = 0.3567271874552811
DP8_A[15, 12] = -0.0013990241651590145
DP8_A[15, 13] = 2.9475147891527724
DP8_A[15, 14] = -9.15095847217987
DP8_B = DP8_A[12, :12].copy()  # 8th-order weights
DP8_E3 = np.array([
    -0.18980075407240762, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585,
    -0.4226823213237919, -0.1521609496625161, 0.20136540080403034, 0.02265179219836082, 0.0
])
DP8_E5 = np.array([
    0.01312004499419488, 0.0, 0.0, 0.0, 0.0, -1.2251564463762044, -0.4957589496572502, 1.6643771824549864,
    -0.35032884874997366, 0.3341791187130175, 0.08192320648511571, -0.022355307863886294, 0.0
])
DP8_D = np.zeros((4, 16))
DP8_D[0, 0] = -8.428938276109013
DP8_D[0, 5] = 0.5667149535193777
DP8_D[0, 6] = -3.0689499459498917
DP8_D[0, 7] = 2.38466765651207
DP8_D[0, 8] = 2.117034582445028
DP8_D[0, 9] = -0.871391583777973
DP8_D[0, 10] = 2.2404374302607883
DP8_D[0, 11] = 0.6315787787694688
DP8_D[0, 12] = -0.08899033645133331
DP8_D[0, 13] = 18.148505520854727
DP8_D[0, 14] = -9.194632392478356
DP8_D[0, 15] = -4.436036387594894
DP8_D[1, 0] = 10.427508642579134
DP8_D[1, 5] = 242.28349177525817
DP8_D[1, 6] = 165.20045171727028
DP8_D[1, 7] = -374.5467547226902
DP8_D[1, 8] = -22.113666853125306
DP8_D[1, 9] = 7.733432668472264
DP8_D[1, 10] = -30.674084731089398
DP8_D[1, 11] = -9.332130526430229
DP8_D[1, 12] = 15.697238121770845
DP8_D[1, 13] = -31.139403219565178
DP8_D[1, 14] = -9.35292435884448
DP8_D[1, 15] = 35.81684148639408
DP8_D[2, 0] = 19.985053242002433
DP8_D[2, 5] = -387.0373087493518
DP8_D[2, 6] = -189.17813819516758
DP8_D[2, 7] = 527.8081592054236
DP8_D[2, 8] = -11.57390253995963
DP8_D[2, 9] = 6.8812326946963
DP8_D[2, 10] = -1.0006050966910838
DP8_D[2, 11] = 0.7777137798053443
DP8_D[2, 12] = -2.778205752353508
DP8_D[2, 13] = -60.19669523126412
DP8_D[2, 14] = 84.32040550667716
DP8_D[2, 15] = 11.99229113618279
DP8_D[3, 0] = -25.69393346270375
DP8_D[3, 5] = -154.18974869023643
DP8_D[3, 6] = -231.5293791760455
DP8_D[3, 7] = 357.6391179106141
DP8_D[3, 8] = 93.40532418362432
DP8_D[3, 9] = -37.45832313645163
DP8_D[3, 10] = 104.0996495089623
DP8_D[3, 11] = 29.8402934266605
DP8_D[3, 12] = -43.53345659001114
DP8_D[3, 13] = 96.32455395918828
DP8_D[3, 14] = -39.17726167561544
DP8_D[3, 15] = -149.72683625798564

NONFINITE = int(Status.NONFINITE)

SAFETY = 0.9
FAC_MIN = 0.2
FAC_MAX = 10.0

# method codes and buffer rows from catalog.INTEGRATORS
RK4_CODE = catalog.integrator("rk4").code
DOPRI5_CODE = catalog.integrator("dopri5").code
DOP853_CODE = catalog.integrator("dop853").code
# row of ws.K holding f at the end of the last step (FSAL), per method code
END_STAGE = np.array([s.end_stage for s in catalog.INTEGRATORS], dtype=np.int64)
# per method code: its order, and the step controller's exponent 1/(q+1) of its error estimate of order q
METHOD_ORDER = np.array([s.order for s in catalog.INTEGRATORS], dtype=np.int64)
ERROR_EXPONENT = np.array([1.0 / (s.error_order + 1) if s.adaptive else 0.0 for s in catalog.INTEGRATORS])


@kernel
def rk4_step(km, cfg, t, y, h, contact, ws, stats):
    """One RK4 step from (t, y) with k1 = ws.f; result in ws.yb, f(yb) in ws.K[4].
    Stages in ws.K[0..3]. Returns a Status code (NONFINITE on NaN/inf)."""
    N = y.shape[0]
    K = ws.K
    for i in range(N):
        K[0, i] = ws.f[i]
    for s in range(1, 4):
        for i in range(N):
            acc = 0.0
            for j in range(s):
                acc += RK4_A[s, j] * K[j, i]
            ws.ys[i] = y[i] + h * acc
        st = rhs(km, cfg, t + RK4_C[s] * h, ws.ys, contact, ws, stats, K[s])
        if st != 0:
            return st
    for i in range(N):
        ws.yb[i] = y[i] + h * (RK4_B[0] * K[0, i] + RK4_B[1] * K[1, i] + RK4_B[2] * K[2, i] + RK4_B[3] * K[3, i])
    st = rhs(km, cfg, t + h, ws.yb, contact, ws, stats, K[4])
    if st != 0:
        return st
    for i in range(N):
        if not (math.isfinite(ws.yb[i]) and math.isfinite(K[4, i])):
            return NONFINITE
    return 0


@kernel
def dopri5_attempt(km, cfg, t, y, h, contact, ws, stats):
    """One DOPRI5 trial step from (t, y) with k1 = ws.f.  Result in ws.yb, stages
    in ws.K (K[6] = f(t + h, yb), FSAL).  Returns (status, err) with Hairer's
    error norm; err = inf when the trial produced NaN or infinity."""
    N = y.shape[0]
    K = ws.K
    for i in range(N):
        K[0, i] = ws.f[i]
    for s in range(1, 7):
        for i in range(N):
            acc = 0.0
            for j in range(s):
                acc += DP5_A[s, j] * K[j, i]
            ws.ys[i] = y[i] + h * acc
        st = rhs_inlined(km, cfg, t + DP5_C[s] * h, ws.ys, contact, ws, stats, K[s])
        if st != 0:
            return st, math.inf
    rtol = cfg[CFG_RTOL]
    atol = cfg[CFG_ATOL]
    acc = 0.0
    for i in range(N):
        ws.yb[i] = ws.ys[i]
        e = 0.0
        for j in range(7):
            e += DP5_E[j] * K[j, i]
        sc = atol + rtol * max(abs(y[i]), abs(ws.yb[i]))
        r = h * e / sc
        acc += r * r
    err = math.sqrt(acc / N)
    if not (err < math.inf):
        err = math.inf
    return 0, err


@kernel
def dop853_attempt(km, cfg, t, y, h, contact, ws, stats):
    """One DOP853 trial step from (t, y) with k1 = ws.f.  Result in ws.yb, stages
    in ws.K[0:12] (K[12] = f(t + h, yb) is left to `dop853_finish`).  Returns
    (status, err) with Hairer's DOP853 error norm; err = inf on NaN/inf."""
    N = y.shape[0]
    K = ws.K
    for i in range(N):
        K[0, i] = ws.f[i]
    for s in range(1, 12):
        for i in range(N):
            acc = 0.0
            for j in range(s):
                acc += DP8_A[s, j] * K[j, i]
            ws.ys[i] = y[i] + h * acc
        st = rhs(km, cfg, t + DP8_C[s] * h, ws.ys, contact, ws, stats, K[s])
        if st != 0:
            return st, math.inf
    rtol = cfg[CFG_RTOL]
    atol = cfg[CFG_ATOL]
    e5 = 0.0
    e3 = 0.0
    for i in range(N):
        acc = 0.0
        a5 = 0.0
        a3 = 0.0
        for j in range(12):
            k = K[j, i]
            acc += DP8_B[j] * k
            a5 += DP8_E5[j] * k
            a3 += DP8_E3[j] * k
        yb = y[i] + h * acc
        ws.yb[i] = yb
        sc = atol + rtol * max(abs(y[i]), abs(yb))
        e5 += (a5 / sc) ** 2
        e3 += (a3 / sc) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0, 0.0
    err = abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * N)
    if not (err < math.inf):
        err = math.inf
    return 0, err


@kernel
def dop853_finish(km, cfg, t, h, contact, ws, stats):
    """FSAL stage of an accepted DOP853 step: K[12] = f(t + h, yb)."""
    ws.flags[FL_DENSE_READY] = 0  # the dense output of this step is not prepared yet
    return rhs(km, cfg, t + h, ws.yb, contact, ws, stats, ws.K[12])


@kernel
def dop853_dense_prepare(km, cfg, contact, ws, stats):
    """Three extra stages and the coefficients ws.F of DOP853's 7th-order dense
    output for the last accepted step (once per step; ws.flags[FL_DENSE_READY] = ready)."""
    if ws.flags[FL_DENSE_READY] == 1:
        return 0
    ta = ws.dense[DN_TA]
    h = ws.dense[DN_H]
    N = ws.ya.shape[0]
    K = ws.K
    for s in range(13, 16):
        for i in range(N):
            acc = 0.0
            for j in range(s):
                acc += DP8_A[s, j] * K[j, i]
            ws.ys[i] = ws.ya[i] + h * acc
        st = rhs(km, cfg, ta + DP8_C[s] * h, ws.ys, contact, ws, stats, K[s])
        if st != 0:
            return st
    F = ws.F
    for i in range(N):
        dy = ws.yb[i] - ws.ya[i]
        F[0, i] = dy
        F[1, i] = h * K[0, i] - dy
        F[2, i] = 2.0 * dy - h * (K[12, i] + K[0, i])
        for r in range(4):
            acc = 0.0
            for j in range(16):
                acc += DP8_D[r, j] * K[j, i]
            F[3 + r, i] = h * acc
    ws.flags[FL_DENSE_READY] = 1
    return 0


@kernel
def hermite_eval(ws, theta, out, kend):
    """Cubic Hermite interpolant of the last step from ya, yb, K[0] = f(ya) and
    K[kend] = f(yb): 4th order, no extra stage (event screening of DOP853)."""
    h = ws.dense[DN_H]
    th = theta
    h00 = (2.0 * th - 3.0) * th * th + 1.0
    h10 = ((th - 2.0) * th + 1.0) * th
    h01 = (3.0 - 2.0 * th) * th * th
    h11 = (th - 1.0) * th * th
    K = ws.K
    for i in range(out.shape[0]):
        out[i] = h00 * ws.ya[i] + h01 * ws.yb[i] + h * (h10 * K[0, i] + h11 * K[kend, i])


@kernel
def initial_step(km, cfg, t, y, contact, ws, stats, hmax, order):
    """Hairer's starting step (hinit) for a method of the given order from
    ws.f = f(t, y); uses ws.ys, ws.yt."""
    N = y.shape[0]
    rtol = cfg[CFG_RTOL]
    atol = cfg[CFG_ATOL]
    d0 = 0.0
    d1 = 0.0
    for i in range(N):
        sc = atol + rtol * abs(y[i])
        d0 += (y[i] / sc) ** 2
        d1 += (ws.f[i] / sc) ** 2
    d0 = math.sqrt(d0 / N)
    d1 = math.sqrt(d1 / N)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, hmax)
    for i in range(N):
        ws.ys[i] = y[i] + h0 * ws.f[i]
    st = rhs(km, cfg, t + h0, ws.ys, contact, ws, stats, ws.yt)
    if st != 0:
        return h0
    d2 = 0.0
    for i in range(N):
        sc = atol + rtol * abs(y[i])
        d2 += ((ws.yt[i] - ws.f[i]) / sc) ** 2
    d2 = math.sqrt(d2 / N) / h0
    dm = max(d1, d2)
    if not (dm < math.inf):
        return h0 * 1e-3
    if dm <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / dm) ** (1.0 / (order + 1.0))
    return min(100.0 * h0, h1, hmax)


@kernel
def dense_eval(ws, theta, out):
    """Dense output of the last accepted step at t = ta + theta h (ws.dense[0:2]),
    from ws.ya, ws.yb, ws.K (DOP853: ws.F, see `dop853_dense_prepare`); method
    code in ws.flags[FL_DENSE_METHOD]."""
    h = ws.dense[DN_H]
    N = out.shape[0]
    K = ws.K
    if ws.flags[FL_DENSE_METHOD] == RK4_CODE:
        hermite_eval(ws, theta, out, 4)
    elif ws.flags[FL_DENSE_METHOD] == DOP853_CODE:
        # Hairer's contd8 (needs dop853_dense_prepare): alternating theta / (1 - theta) factors
        x = theta
        x1 = 1.0 - theta
        F = ws.F
        for i in range(N):
            acc = F[6, i] * x
            acc = (acc + F[5, i]) * x1
            acc = (acc + F[4, i]) * x
            acc = (acc + F[3, i]) * x1
            acc = (acc + F[2, i]) * x
            acc = (acc + F[1, i]) * x1
            acc = (acc + F[0, i]) * x
            out[i] = ws.ya[i] + acc
    else:
        th1 = 1.0 - theta
        for i in range(N):
            y0 = ws.ya[i]
            dy = ws.yb[i] - y0
            hk1 = h * K[0, i]
            r3 = hk1 - dy
            r4 = dy - h * K[6, i] - r3
            r5 = 0.0
            for j in range(7):
                r5 += DP5_D[j] * K[j, i]
            r5 *= h
            out[i] = y0 + theta * (dy + th1 * (r3 + theta * (r4 + th1 * r5)))
