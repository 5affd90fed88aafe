"""
Randomised independent twin tugs: the default tug identification on tugs it never saw.

  python -m bench run tug_random [--quick] [--seeds 1000-1019] [--starts 4] [--trials 12,6,3]
                                 [--data DIR]

Each seed draws a twin tug of its own (this module's code, not ``data.generate``): the
published Table 3 coefficients (config/qiuxin_tug.yaml) each moved by a factor uniform in
[0.85, 1.15]; a thrust curve that is not the package's polynomial in shape (either F = k n|n| +
k1 n or F = k |n|^p sign(n), p in [1.8, 2.2]; astern thrust a ratio in [0.6, 0.9] of ahead); an
azimuth drive drawn among three structures (``--drives``): a rate-saturated position loop with
a first-order rate lag (alpha_dot_cmd = clip(Kp (alpha_c - alpha), +-rate_max), alpha'' =
(alpha_dot_cmd - alpha') / tau, Kp in [1.5, 3] 1/s, tau in [0.08, 0.3] s, rate_max in [0.5,
1.0] rad/s; the structure the package's ``twin_azimuth`` writes since the 29 November 2026
change, so no longer independent), a linear second order without a limit (natural frequency in
[1.5, 4] rad/s, damping ratio in [0.6, 1.2]) and a rate-limited first order (alpha' =
clip((alpha_c - alpha) / T, +-rate_max), T in [0.3, 1] s), recorded as the mean angle over each
sample interval (the angle acting over it: the repository's convention, doc/guides/tug.md);
sensor noise of the RTK/INS class (core.actuators.twin_azimuth_trials.Noise: 1.5 cm, 0.3 deg
heading, 1 cm/s, 0.2 deg/s, azimuth 0.2 deg, shaft 0.02 rev/s, load cell 0.3 N) times a factor
in [0.5, 2]; a rate in [2, 10] Hz. The hull (surge_decoupled, Pedersen's Coriolis form) is
integrated by RK4 at a step of at most 0.02 s, all manoeuvres of a twin at once. Manoeuvres:
the paper's Table 2 (straights from rest at 3, 5, 7, 10 rev/s; +20/20 azimuth zigzags closed on
heading at those speeds; turns of 10-30 deg at 7 rev/s), and held out: mirrored zigzags at 4
and 8 rev/s, turns of -15 and -25 deg at 6 rev/s, two random command sequences, one
differential run. A bollard-pull table (-max .. max rev/s, astern rows included) goes with each
twin.

Per twin: the default ``tune --ship qiuxin_tug --bollard-pull bollard.csv`` (the command, on the
twin's channel CSVs) with the paper's 12 manoeuvres, 6 and 3 (``--trials``); with 12 also
``--starts`` identifications from the ship's values perturbed (every coefficient times a
factor log-uniform in [0.5, 1.5], as bench/tug_logo.py's convergence). Each model is scored
as bench/tug_logo.py scores (``mt.evaluate``, free run from the true start driven by the true
inputs, pooled relative error ||y_model - y|| / ||y|| of u, v, r on the held-out runs against
the noise-free truth), checked (mass matrix positive definite, no divergence on its own
identification trials) and LO -> GO's cost set beside GO's from the ship's values.

The seeds reported are pre-registered in bench/tug_random_preregistration.md (1000-1019 with
the loop drive alone; 1100-1119 with the three); develop on others (0-9).
"""
from __future__ import annotations

import argparse
import dataclasses
from dataclasses import dataclass
import math
from pathlib import Path
import tempfile
import time

import mmg_tuner as mt
from mmg_tuner.core.trial import Trial
from mmg_tuner.tuning import lo_go
import numpy as np

HALF_T5 = (1.165, 2.225, 2.925)
"""Half the paper's Table 5 velocity errors (u / v / r %, 22 coefficients)."""
RTK = {'position_m': 0.015, 'heading_rad': math.radians(0.3), 'speed_ms': 0.01,
       'yaw_rate_rad_s': math.radians(0.2), 'shaft_rps': 0.02,
       'azimuth_rad': math.radians(0.2), 'bollard_n': 0.3}
HULL = ('m11', 'm22', 'm23', 'm32', 'm33', 'X_u', 'X_absu_u', 'X_uuu', 'Y_v', 'Y_absv_v',
        'Y_vvv', 'Y_absr_v', 'Y_r', 'Y_absv_r', 'Y_absr_r', 'N_v', 'N_absv_v', 'N_absr_v',
        'N_r', 'N_absr_r', 'N_rrr', 'N_absv_r')
GEOMETRY = ((-0.8, -0.163), (-0.8, 0.163))   # (x, y) of the port and starboard thrusters [m]
H_MAX = 0.02   # the twin's integration step at most [s]
DRIVES = ('loop', 'second-order', 'first-order')
"""The twins' azimuth drive structures: a rate-saturated loop with the motor's lag (the form
``twin_azimuth`` writes), a linear second order (eq. 9 without a limit) and a rate-limited
first order (a steering gear's), which the package's drive only approximates."""
MAX_RPS = 12.0
MAX_AZ = math.radians(45.0)


@dataclass(frozen=True)
class TwinTug:
    """One randomised twin: its hull, thrust curve, azimuth drive, noise and rate."""

    seed: int
    hull: dict
    thrust_shape: str          # 'quadratic+linear' or 'power'
    k: float                   # N / (rev/s)^2 (quadratic+linear) or N / (rev/s)^p (power)
    k1: float                  # N / (rev/s), the linear term (quadratic+linear)
    power: float               # p (power)
    astern_ratio: float
    kp: float                  # azimuth position loop gain [1/s]
    tau: float                 # azimuth rate lag [s]
    rate_max: float            # azimuth rate limit [rad/s]
    noise_factor: float
    rate_hz: float
    drive: str = 'loop'        # 'loop', 'second-order' or 'first-order' (the azimuth drive)
    wn: float = 0.0            # natural frequency [rad/s] (second-order)
    zeta: float = 0.0          # damping ratio (second-order)
    t1: float = 0.0            # time constant [s] (first-order)

    def thrust(self, n):
        """Thrust per thruster [N] at shaft speed n [rev/s] (either sign)."""
        n = np.asarray(n, dtype=float)
        a = np.abs(n)
        f = (self.k * a * a + self.k1 * a if self.thrust_shape == 'quadratic+linear'
             else self.k * a ** self.power)
        return np.where(n >= 0, f, -self.astern_ratio * f)

    def describe(self) -> str:
        shape = (f'{self.k:.3f} n|n| + {self.k1:.3f} n' if self.thrust_shape != 'power'
                 else f'{self.k:.3f} |n|^{self.power:.2f}')
        drive = {'loop': f'Kp {self.kp:.2f} 1/s, lag {self.tau:.2f} s, rate '
                         f'{self.rate_max:.2f} rad/s',
                 'second-order': f'second order wn {self.wn:.2f} rad/s, zeta {self.zeta:.2f}',
                 'first-order': f'first order T {self.t1:.2f} s, rate {self.rate_max:.2f} '
                                'rad/s'}[self.drive]
        return (f'seed {self.seed}: thrust {shape} (astern x {self.astern_ratio:.2f}), azimuth '
                f'{drive}; noise x {self.noise_factor:.2f}, {self.rate_hz:.1f} Hz')


def draw_twin(seed: int, base: dict, drives: tuple[str, ...] = ()) -> TwinTug:
    """
    Draw twin ``seed`` around the published coefficients ``base`` (name -> value).

    ``drives``: the azimuth drive structures to draw from (empty: the saturated loop alone,
    as every seed before the others were added).
    """
    rng = np.random.default_rng([43, seed])
    hull = {n: base[n] * rng.uniform(0.85, 1.15) for n in HULL}
    shape = 'quadratic+linear' if rng.uniform() < 0.5 else 'power'
    f10 = 40.0 * rng.uniform(0.85, 1.15)   # N per thruster at 10 rev/s
    if shape == 'power':
        p = rng.uniform(1.8, 2.2)
        k, k1 = f10 / 10 ** p, 0.0
    else:
        p = 2.0
        share = rng.uniform(0.05, 0.3)   # of the thrust at 10 rev/s from the linear term
        k, k1 = (1 - share) * f10 / 100, share * f10 / 10
    tw = TwinTug(seed, hull, shape, k, k1, p, rng.uniform(0.6, 0.9), rng.uniform(1.5, 3.0),
                 rng.uniform(0.08, 0.3), rng.uniform(0.5, 1.0), rng.uniform(0.5, 2.0),
                 float(rng.choice([2.0, 2.5, 4.0, 5.0, 8.0, 10.0])))
    if not drives:
        return tw
    # the azimuth drive's structure (its own stream: the draws above are those of every seed
    # before drives were added)
    d = np.random.default_rng([43, seed, 9])
    kind = str(d.choice(drives))
    return dataclasses.replace(tw, drive=kind, wn=d.uniform(1.5, 4.0), zeta=d.uniform(0.6, 1.2),
                               t1=d.uniform(0.3, 1.0))


# ------------------------------------------------------------------------------ manoeuvres
@dataclass(frozen=True)
class Manoeuvre:
    """straight / zigzag / turning / random / differential; n [rev/s]; steer [deg]."""

    name: str
    kind: str
    n: float
    steer: float = 0.0
    duration_s: float = 100.0
    approach_s: float = 20.0
    seed: int = 0


IDENTIFICATION = (
    [Manoeuvre(f'straight_{n:g}', 'straight', n, duration_s=60.0, approach_s=0.0)
     for n in (3, 5, 7, 10)]
    + [Manoeuvre(f'zigzag20_{n:g}', 'zigzag', n, 20.0) for n in (3, 5, 7, 10)]
    + [Manoeuvre(f'turn{a:g}_7', 'turning', 7.0, a) for a in (10, 15, 20, 30)])
"""The paper's Table 2: 12 manoeuvres."""
SUBSETS = {12: [m.name for m in IDENTIFICATION],
           6: ['straight_5', 'straight_10', 'zigzag20_5', 'zigzag20_10', 'turn15_7',
               'turn30_7'],
           3: ['straight_7', 'zigzag20_7', 'turn20_7']}
HELD_OUT = (
    [Manoeuvre(f'zigzag-20_{n:g}', 'zigzag', n, -20.0) for n in (4, 8)]
    + [Manoeuvre(f'turn{a:g}_6', 'turning', 6.0, a) for a in (-15, -25)]
    + [Manoeuvre(f'random_{s}', 'random', 9.0, 30.0, duration_s=150.0, approach_s=5.0, seed=s)
       for s in (1, 2)]
    + [Manoeuvre('differential', 'differential', 8.0, 0.0, duration_s=100.0, approach_s=10.0)])


def _open_loop(m: Manoeuvre, t: np.ndarray, rng: np.random.Generator):
    """(n_port, n_stbd, az_cmd_port, az_cmd_stbd) of an open-loop manoeuvre (zigzag: + side)."""
    T = t.size
    on = t >= m.approach_s
    n_p, n_s = np.full(T, m.n), np.full(T, m.n)
    az = np.zeros(T)
    if m.kind in ('zigzag', 'turning'):
        az = np.where(on, math.radians(m.steer), 0.0)
        return n_p, n_s, az, az.copy()
    if m.kind == 'random':
        edges = np.cumsum(rng.uniform(4.0, 12.0, int(m.duration_s // 4) + 2))
        k = np.searchsorted(edges, t)
        n_p = rng.uniform(3.0, m.n, k.max() + 1)[k]
        n_s = np.clip(n_p + rng.normal(0, 1.5, k.max() + 1)[k], 2.0, MAX_RPS)
        lim = math.radians(m.steer)
        a_p = rng.uniform(-lim, lim, k.max() + 1)[k]
        a_s = np.clip(a_p + rng.normal(0, 0.2, k.max() + 1)[k], -MAX_AZ, MAX_AZ)
        return n_p, n_s, a_p * on, a_s * on
    if m.kind == 'differential':
        edges = np.cumsum(rng.uniform(15.0, 25.0, 8))
        d = rng.uniform(0.2, 0.5, 9) * np.sign(rng.uniform(-1, 1, 9))
        d = d[np.searchsorted(edges, t - m.approach_s)] * on
        return m.n * (1 + d), m.n * (1 - d), az, az.copy()
    return n_p, n_s, az, az.copy()


# ------------------------------------------------------------------------------- the twin
def _rhs(tw: TwinTug, hull: dict, x: np.ndarray, n_p, n_s, c_p, c_s) -> np.ndarray:
    """
    d/dt of the state (trials, 10): x, y, psi, u, v, r, alpha_p, rate_p, alpha_s, rate_s.

    M nu_dot + C(nu) nu + D(nu) nu = tau (Pedersen's form, written out here), the azimuth
    drive as a rate-saturated position loop with a first-order rate lag.
    """
    h = hull
    psi, u, v, r = x[:, 2], x[:, 3], x[:, 4], x[:, 5]
    ap, wp, as_, ws = x[:, 6], x[:, 7], x[:, 8], x[:, 9]
    fp, fs = tw.thrust(n_p), tw.thrust(n_s)
    (xp, yp), (xs, ys) = GEOMETRY
    X = fp * np.cos(ap) + fs * np.cos(as_)
    Y = fp * np.sin(ap) + fs * np.sin(as_)
    N = fp * (xp * np.sin(ap) - yp * np.cos(ap)) + fs * (xs * np.sin(as_) - ys * np.cos(as_))
    au, av, ar = np.abs(u), np.abs(v), np.abs(r)
    d11 = -h['X_u'] - h['X_absu_u'] * au - h['X_uuu'] * u * u
    d22 = -h['Y_v'] - h['Y_absv_v'] * av - h['Y_absr_v'] * ar - h['Y_vvv'] * v * v
    d23 = -h['Y_r'] - h['Y_absv_r'] * av - h['Y_absr_r'] * ar
    d32 = -h['N_v'] - h['N_absv_v'] * av - h['N_absr_v'] * ar
    d33 = -h['N_r'] - h['N_absv_r'] * av - h['N_absr_r'] * ar - h['N_rrr'] * r * r
    c13 = -h['m22'] * v - h['m23'] * r
    c23 = h['m11'] * u
    fx = X - c13 * r - d11 * u
    fy = Y - c23 * r - d22 * v - d23 * r
    fn = N + c13 * u + c23 * v - d32 * v - d33 * r
    det = h['m22'] * h['m33'] - h['m23'] * h['m32']
    du = fx / h['m11']
    dv = (h['m33'] * fy - h['m23'] * fn) / det
    dr = (h['m22'] * fn - h['m32'] * fy) / det
    c, s = np.cos(psi), np.sin(psi)
    out = np.empty_like(x)
    out[:, 0] = u * c - v * s
    out[:, 1] = u * s + v * c
    out[:, 2] = r
    out[:, 3], out[:, 4], out[:, 5] = du, dv, dr
    for j, (a, w, cmd) in enumerate(((ap, wp, c_p), (as_, ws, c_s))):
        if tw.drive == 'second-order':   # linear, no rate limit
            out[:, 6 + 2 * j] = w
            out[:, 7 + 2 * j] = tw.wn ** 2 * (cmd - a) - 2 * tw.zeta * tw.wn * w
        elif tw.drive == 'first-order':   # a steering gear's rate-limited first order
            out[:, 6 + 2 * j] = np.clip((cmd - a) / tw.t1, -tw.rate_max, tw.rate_max)
            out[:, 7 + 2 * j] = 0.0
        else:
            want = np.clip(tw.kp * (cmd - a), -tw.rate_max, tw.rate_max)
            out[:, 6 + 2 * j] = w
            out[:, 7 + 2 * j] = (want - w) / tw.tau
    return out


def sail(tw: TwinTug, manoeuvres, hull: dict | None = None) -> list[dict]:
    """
    Sail the manoeuvres (all at once); return per manoeuvre the true record at the twin's rate.

    A zigzag reverses its azimuth order when the heading has changed by 20 deg from its value
    at the start of the steer (to the side the order turns it), checked at every step.
    """
    hull = tw.hull if hull is None else hull
    dt = 1.0 / tw.rate_hz
    sub = max(1, math.ceil(dt / H_MAX - 1e-9))
    h = dt / sub
    T = int(round(max(m.duration_s for m in manoeuvres) * tw.rate_hz)) + 1
    t = dt * np.arange(T)
    K = len(manoeuvres)
    cmds = [_open_loop(m, t, np.random.default_rng([7, m.seed, tw.seed]))
            for m in manoeuvres]
    n_p = np.array([c[0] for c in cmds]).T
    n_s = np.array([c[1] for c in cmds]).T
    a_p = np.array([c[2] for c in cmds]).T
    a_s = np.array([c[3] for c in cmds]).T
    n_p, n_s = np.clip(n_p, -MAX_RPS, MAX_RPS), np.clip(n_s, -MAX_RPS, MAX_RPS)
    zig = np.array([m.kind == 'zigzag' for m in manoeuvres])
    steer = np.array([math.radians(m.steer) for m in manoeuvres])
    k0 = np.array([int(round(m.approach_s * tw.rate_hz)) for m in manoeuvres])
    sign = np.ones(K)
    psi0 = np.full(K, np.nan)
    x = np.zeros((K, 10))
    rec = np.zeros((T, K, 10))
    angle = np.zeros((T, K, 2))   # the mean angle over each interval: what acts over it
    for k in range(T):
        live = zig & (k >= k0)
        if live.any():
            psi0 = np.where(live & np.isnan(psi0), x[:, 2], psi0)
            # + azimuth turns the tug to port (psi falls): "done" when psi moved 20 deg that way
            moved = -(x[:, 2] - psi0) * sign * np.sign(steer)
            flip = live & (moved >= math.radians(20.0))
            sign = np.where(flip, -sign, sign)
            a_p[k:, flip] = a_s[k:, flip] = (sign * steer)[flip]
        rec[k] = x
        if k == T - 1:
            angle[k] = x[:, [6, 8]]
            break
        args = (n_p[k], n_s[k], a_p[k], a_s[k])
        mean = 0.5 * x[:, [6, 8]] / sub
        for i in range(sub):
            k1 = _rhs(tw, hull, x, *args)
            k2 = _rhs(tw, hull, x + 0.5 * h * k1, *args)
            k3 = _rhs(tw, hull, x + 0.5 * h * k2, *args)
            k4 = _rhs(tw, hull, x + h * k3, *args)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            mean += (0.5 if i == sub - 1 else 1.0) * x[:, [6, 8]] / sub
        angle[k] = mean
        if not np.all(np.isfinite(x)) or np.max(np.abs(x[:, 3:6])) > 50:
            raise RuntimeError(f'twin seed {tw.seed} diverged at t = {t[k]:.1f} s')
    out = []
    for j, m in enumerate(manoeuvres):
        L = int(round(m.duration_s * tw.rate_hz)) + 1
        out.append({'name': m.name, 't': t[:L], 'states': rec[:L, j, :6].copy(),
                    'n_port': n_p[:L, j].copy(), 'n_stbd': n_s[:L, j].copy(),
                    'azimuth_port': angle[:L, j, 0].copy(), 'azimuth_stbd': angle[:L, j, 1].copy(),
                    'azimuth_cmd_port': a_p[:L, j].copy(), 'azimuth_cmd_stbd': a_s[:L, j].copy()})
    return out


def to_trials(tw: TwinTug, runs: list[dict], noisy: bool, rng: np.random.Generator
              ) -> list[Trial]:
    """Return the runs as channel trials, as their sensors record them (noisy) or exact."""
    f = tw.noise_factor if noisy else 0.0
    out = []
    for run in runs:
        T = len(run['t'])
        st = run['states'].copy()
        st[:, 0:2] += rng.normal(0, f * RTK['position_m'], (T, 2))
        st[:, 2] += rng.normal(0, f * RTK['heading_rad'], T)
        st[:, 3:5] += rng.normal(0, f * RTK['speed_ms'], (T, 2))
        st[:, 5] += rng.normal(0, f * RTK['yaw_rate_rad_s'], T)
        inputs = {c: run[c].copy() for c in ('n_port', 'n_stbd', 'azimuth_port', 'azimuth_stbd',
                                             'azimuth_cmd_port', 'azimuth_cmd_stbd')}
        for c, sd in (('n_port', 'shaft_rps'), ('n_stbd', 'shaft_rps'),
                      ('azimuth_port', 'azimuth_rad'), ('azimuth_stbd', 'azimuth_rad')):
            inputs[c] = inputs[c] + rng.normal(0, f * RTK[sd], T)
        out.append(Trial(run['t'].copy(), st, name=run['name'], inputs=inputs))
    return out


def bollard_table(tw: TwinTug, rng: np.random.Generator) -> np.ndarray:
    """(n, thrust) rows from -10 to 12 rev/s (astern rows included), the load cell's noise."""
    n = np.arange(-10.0, MAX_RPS + 1e-9, 1.0)
    return np.column_stack([n, tw.thrust(n) + rng.normal(0, tw.noise_factor * RTK['bollard_n'],
                                                         n.size)])


def write_twin(tw: TwinTug, folder: Path, trials: list[Trial], table: np.ndarray) -> list[Path]:
    """Write the trials as channel CSVs and the bollard table; return the CSV paths."""
    from mmg_tuner.data.csv_io import write_trial_csv
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for tr in trials:
        p = folder / f'{tr.name}.csv'
        write_trial_csv(tr, p)
        paths.append(p)
    (folder / 'bollard.csv').write_text('n,thrust\n' + ''.join(
        f'{a:g},{b:.6g}\n' for a, b in table))
    return paths


def make_twin(seed: int, base: dict, drives: tuple[str, ...] = ()) -> dict:
    """Return a twin's draw, its noisy identification and held-out trials and their truth."""
    for attempt in range(20):   # a draw whose truth diverges is no tug: the next one
        tw = draw_twin(seed + 100_000 * attempt, base, drives)
        try:
            ident = sail(tw, IDENTIFICATION)
            held = sail(tw, HELD_OUT)
            break
        except RuntimeError:
            continue
    else:
        raise RuntimeError(f'seed {seed}: no draw of 20 sails')
    rng = np.random.default_rng([11, seed])
    return {'twin': tw, 'train': to_trials(tw, ident, True, rng),
            'train_truth': to_trials(tw, ident, False, rng),
            'test_truth': to_trials(tw, held, False, rng),
            'bollard': bollard_table(tw, rng)}


# ------------------------------------------------------------------------------- scoring
def substeps_for(dt: float) -> int:
    """Integration steps per sample for the scoring: steps of at most 0.1 s."""
    return max(1, math.ceil(dt / 0.1 - 1e-9))


def score(ship, truth: list[Trial]) -> dict:
    """Pooled free-run relative errors [%] of u, v, r against the noise-free truth (None: fail)."""
    ev = mt.evaluate(ship, truth, restart_every_s=0, horizons=(1,),
                     substeps=substeps_for(truth[0].dt))
    return {k: None if v is None else 100 * float(v) for k, v in ev.relative.pooled.items()}


def physical(ship, train: list[Trial]) -> tuple[bool, bool]:
    """(mass matrix positive definite, free runs of its own trials stay finite and bounded)."""
    M = lo_go.mass_matrix(ship, ship.params)
    S = 0.5 * (M + M.T)
    pd = bool(np.all(np.isfinite(S)) and np.min(np.linalg.eigvalsh(S)) > 0)
    ok = True
    for tr in train:
        run = mt.simulate(ship, tr, substeps=substeps_for(tr.dt), integrator='rk4')
        vel = run.states[:, 3:6]
        top = np.max(np.abs(tr.states[:, 3:6]), axis=0)
        bounded = np.max(np.abs(vel), axis=0) <= 10 * np.maximum(top, 1e-3)
        if not (np.all(np.isfinite(vel)) and np.all(bounded)):
            ok = False
    return pd, ok


def beats_half(rel: dict) -> bool:
    return all(rel[q] is not None and rel[q] <= h for q, h in zip('uvr', HALF_T5))


def run_cli(csvs: list[Path], bollard: Path, out: Path) -> tuple[int, str]:
    """Run the default ``tune --ship qiuxin_tug --bollard-pull``; return (exit code, output)."""
    import contextlib
    import io

    from mmg_tuner.cli.common import run_command
    from mmg_tuner.cli.tune import command
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
        rc = run_command(command, [*map(str, csvs), '--ship', 'qiuxin_tug', '--bollard-pull',
                                   str(bollard), '--out', str(out), '--quiet'])
    return rc, buf.getvalue()


def perturbed(tug, rng: np.random.Generator) -> dict:
    """Every coefficient times a factor log-uniform in [0.5, 1.5] (bench/tug_logo.py's)."""
    lo, hi = math.log(0.5), math.log(1.5)
    return {n: tug[n] * math.exp(rng.uniform(lo, hi)) for n in HULL}


def one_twin(seed: int, tug, starts: int, counts: list[int], folder: Path,
             drives: tuple[str, ...] = DRIVES) -> list[dict]:
    """Every row of one twin: the command per trial count, then the perturbed starts."""
    base = {n: tug[n] for n in HULL}
    tw = make_twin(seed, base, drives)
    twin = tw['twin']
    by_name = {t.name: t for t in tw['train']}
    d = folder / f'seed{seed}'
    csvs = write_twin(twin, d / 'csv', tw['train'], tw['bollard'])
    bollard = d / 'csv' / 'bollard.csv'
    rows = []
    for k in counts:
        names = SUBSETS[k]
        out = d / f'id{k}'
        t0 = time.perf_counter()
        rc, text = run_cli([p for p in csvs if p.stem in names], bollard, out)
        wall = time.perf_counter() - t0
        row = {'seed': seed, 'trials': k, 'start': "ship's values (the command)",
               'exit': rc, 'wall_s': round(wall, 2), 'twin': twin.describe()}
        if (out / 'params.yaml').is_file():
            ship = mt.load_ship('qiuxin_tug', out / 'params.yaml')
            pd, ok = physical(ship, [by_name[n] for n in names])
            import json
            rep = json.loads((out / 'identify.json').read_text())
            go = rep.get('go', {})
            row.update({'mass PD': pd, 'own trials bounded': ok,
                        'rel %': score(ship, tw['test_truth']),
                        'GO start': go.get('start'), 'GO costs': go.get('candidates'),
                        'identify_s': round(rep['wall_s'], 2)})
        else:
            row['error'] = text.strip().splitlines()[-1] if text.strip() else 'no params.yaml'
        rows.append(row)
        _print_row(row)
    if 12 in counts:
        b = tw['bollard']
        try:
            table = lo_go.check_bollard_table(b[:, 0], b[:, 1], 'bollard')
        except mt.errors.MmgTunerError as exc:
            rows.append({'seed': seed, 'trials': 12, 'start': 'perturbed (all)',
                         'error': str(exc)})
            return rows
        for j in range(starts):
            start = tug.with_params(perturbed(tug, np.random.default_rng([seed, 1000 + j])))
            t0 = time.perf_counter()
            try:
                res = mt.identify(start, tw['train'], bollard_pull=table)
            except mt.errors.MmgTunerError as exc:
                rows.append({'seed': seed, 'trials': 12, 'start': f'perturbed {j}',
                             'error': str(exc)})
                continue
            ship = res.identified_ship
            pd, ok = physical(ship, tw['train'])
            row = {'seed': seed, 'trials': 12, 'start': f'perturbed {j}', 'exit': 0,
                   'wall_s': round(time.perf_counter() - t0, 2), 'mass PD': pd,
                   'own trials bounded': ok, 'rel %': score(ship, tw['test_truth']),
                   'GO start': res.go.start, 'GO costs': res.go.candidates,
                   'identify_s': round(res.wall_s, 2)}
            rows.append(row)
            _print_row(row)
    return rows


def _print_row(r: dict) -> None:
    rel = r.get('rel %')
    cells = ('fail' if rel is None else ' / '.join('fail' if rel[q] is None else
                                                   f'{rel[q]:.2f}' for q in 'uvr'))
    print(f"  seed {r['seed']:>5} {r['trials']:>2} trials {r['start']:<28} "
          + (f"ERROR {r['error']}" if 'error' in r else
             f"{cells:<20} PD {r.get('mass PD')} bounded {r.get('own trials bounded')} "
             f"GO from {r.get('GO start')} {r.get('identify_s')} s"), flush=True)


def summary(rows: list[dict]) -> dict:
    """Judge the must-hold criteria over the rows."""
    ok = [r for r in rows if 'error' not in r]
    cmd12 = [r for r in ok if r['trials'] == 12 and r['start'].startswith("ship's")]
    all12 = [r for r in ok if r['trials'] == 12]
    go_never_worse = all(
        r['GO costs'] is None or r['GO costs'].get(r['GO start'], math.inf)
        <= min(r['GO costs'].values()) + 1e-15 or not r['mass PD'] for r in ok)
    out = {
        'models written': f"{sum('error' not in r for r in rows if r['start'].startswith('ship'))}"
                          f" of {sum(1 for r in rows if r['start'].startswith('ship'))} "
                          'command runs',
        'command runs refused (ERROR)': [f"seed {r['seed']} ({r['trials']}): {r['error']}"
                                         for r in rows if 'error' in r],
        'non-PD mass matrix written': sum(not r['mass PD'] for r in ok),
        'diverging on own trials written': sum(not r['own trials bounded'] for r in ok),
        '12 trials, command: beats half Table 5 (u, v, r)':
            f"{sum(beats_half(r['rel %']) for r in cmd12)} of {len(cmd12)}",
        '12 trials, every start: beats half Table 5':
            f"{sum(beats_half(r['rel %']) for r in all12)} of {len(all12)}",
        'LO -> GO never worse than GO from the ship values (GO cost)': go_never_worse,
        'identification of 12 manoeuvres, largest [s]':
            max((r['identify_s'] for r in all12), default=None),
    }
    for k in sorted({r['trials'] for r in ok}, reverse=True):
        sel = [r['rel %'] for r in ok if r['trials'] == k and r['start'].startswith("ship's")]
        for q in 'uvr':
            vals = [x[q] for x in sel if x[q] is not None]
            if vals:
                out[f'{k} trials, command: {q} % median [max]'] = (
                    f'{np.median(vals):.2f} [{np.max(vals):.2f}]')
    return out


def _seeds(text: str) -> list[int]:
    out = []
    for part in text.split(','):
        a, _, b = part.partition('-')
        out.extend(range(int(a), int(b) + 1) if b else [int(a)])
    return out


def benchmark(quick: bool, argv: list[str]) -> dict:
    """Entry point of ``python -m bench run tug_random`` (``--quick``: 3 seeds, no starts)."""
    return main((['--seeds', '0-2', '--starts', '0'] if quick else []) + argv)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    ap.add_argument('--seeds', default='1100-1119', help='e.g. 1000-1019 or 0-9 or 3,5')
    ap.add_argument('--starts', type=int, default=4,
                    help='perturbed starts per twin with 12 manoeuvres (the issue: 20)')
    ap.add_argument('--trials', default='12,6,3', help='trial counts (subsets of Table 2)')
    ap.add_argument('--data', help='keep the twins here (default: a temporary folder)')
    ap.add_argument('--drives', default=','.join(DRIVES),
                    help='azimuth drive structures drawn (comma-separated; empty: the '
                         'saturated loop alone, as seeds 1000-1019 were drawn)')
    a = ap.parse_args(argv)
    drives = tuple(x for x in a.drives.split(',') if x)
    if set(drives) - set(DRIVES):
        ap.error(f'--drives: {",".join(sorted(set(drives) - set(DRIVES)))}: use of '
                 f'{", ".join(DRIVES)}')
    tug = mt.load_ship('qiuxin_tug')
    counts = [int(x) for x in a.trials.split(',')]
    seeds = _seeds(a.seeds)
    rows: list[dict] = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(a.data) if a.data else Path(tmp)
        for s in seeds:
            try:
                rows.extend(one_twin(s, tug, a.starts, counts, folder, drives))
            except RuntimeError as exc:
                print(f'  seed {s}: {exc}')
    summ = summary(rows)
    print(f'\n{len(seeds)} twins, {time.perf_counter() - t0:.0f} s; must hold:')
    for k, v in summ.items():
        print(f'  {k}: {v}')
    return {'seeds': a.seeds, 'starts': a.starts, 'summary': summ, 'runs': rows}


if __name__ == '__main__':
    main()
