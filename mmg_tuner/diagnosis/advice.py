"""
Advice: the trial that would settle what these trials cannot.

For two causes reported as indistinguishable, two rival models explain the recorded trials
about equally well. Each feasible trial of the manoeuvre repertoire (zigzags of several angles,
turning circles and pull-outs at several rpm, rpm steps up and down, a slower rudder; all
within the ship's rudder limit and steering-gear rate) is run with the first model; its
recorded commands then drive both models, and the predicted separation of their outputs is
measured against the sensor noise:

    separation = sqrt(mean_k (|dp_k| / sigma_pos)^2 + (dpsi_k / sigma_psi)^2)

(dp: position difference, dpsi: heading difference, per sample; sigma: what the tuned model
cannot explain on the recorded trials, its RMS residual, or the sensor noise of
:class:`~mmg_tuner.data.generate.SensorNoise` when larger). So a separation of 1 means the
rivals differ by as much as the model already misses; the same measure on the best recorded
trial says how much the advised one adds. Residuals along a trajectory are correlated: read
it as a ranking, not a probability. The trial with the largest separation is advised, as an
instruction a crew can follow and as a :class:`TrialSpec` that
``generate --from-advice DIR/diagnosis.json`` runs. When no trial of the repertoire separates
the rivals clearly better than the recorded ones (by SETTLES x) and by at least the error
the model already leaves (separation >= MIN_SEPARATION), the advice says so:
the two are then degenerate for every manoeuvre, and only fixing one of them from another
source separates them.

A barely identifiable effect is judged by the expected information
(:func:`advise_information`): a trial the base targets can mimic once it is tuned on settles
nothing, however far the rival fitted without it strays on it. So each trial of the
repertoire is sailed by the model linearised where the flag was raised (base optimum, every
single-parameter effect at its smallest magnitude worth finding), its Jacobian joins the tuning
trials' (Gauss-Newton information adds over trials), and the effect's standard error with the
base targets free is recomputed. Its figure, reported as the separation, is the resolution

    smallest magnitude worth finding / (2 x standard error)

which is below 1 exactly when the effect is flagged barely identifiable: a trial reaching 1
would lift the flag.

Every advised trial is to be sailed twice, once to each side (:func:`mirrored`; the ``pair``
spec): one goes to the tuning trials, the other is held out. The diagnosis names an effect
only on its held-out gain, so a trial that only the tuning set contains can make an effect
identifiable but never give the evidence to name it.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
import math
from typing import Sequence

from mmg_tuner.core.effects import EFFECTS
from mmg_tuner.core.layout import EFFECT_NEUTRAL
from mmg_tuner.core.mmg import run_maneuver
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import integrator_code, simulate_batch
from mmg_tuner.data.generate import SensorNoise
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import DiagnosisError
from mmg_tuner.tuning.identifiability import jacobian
from mmg_tuner.tuning.objective import Objective, TrialBatch
from mmg_tuner.tuning.parameters import ParameterSpace
import numpy as np

SPEC_VERSION = 1
MIN_SEPARATION = 1.0   # ... and by at least the unexplained error: below it the rivals'
#                        difference drowns in what the model misses anyway
SETTLES = 1.5   # an advised trial must separate the rivals this many times better than the
#                 best recorded one to be worth sailing


@dataclass(frozen=True)
class TrialSpec:
    """
    A trial a crew can run (angles in degrees, as trials are specified).

    maneuver: 'zigzag', 'turning' or 'pullout'; rudder_deg: zigzag amplitude or turning /
    pull-out rudder (sign: first rudder direction, + starboard); check_deg: zigzag heading check
    angle; rpm: propeller speed [rev/min] from the start; rpm_after / step_at_s: an rpm step to
    rpm_after at step_at_s [s] (None: no step); rudder_rate_deg_s: steering-gear rate [deg/s];
    duration_s: recording length [s]; speed_ms: approach speed [m/s]; approach_s: straight run
    before the rudder is executed [s]; pullout_s: how long a pull-out holds the rudder [s].
    """

    maneuver: str
    rudder_deg: float
    rpm: float
    duration_s: float
    speed_ms: float
    rudder_rate_deg_s: float
    check_deg: float | None = None
    rpm_after: float | None = None
    step_at_s: float | None = None
    approach_s: float = 10.0
    pullout_s: float = 60.0

    def __post_init__(self) -> None:
        if self.maneuver not in ('zigzag', 'turning', 'pullout'):
            raise DiagnosisError(f'advice spec: maneuver {self.maneuver!r} must be zigzag, '
                                 'turning or pullout')
        for k in ('rudder_deg', 'rpm', 'duration_s', 'speed_ms', 'rudder_rate_deg_s',
                  'approach_s', 'pullout_s'):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise DiagnosisError(f'advice spec: {k} = {v!r} must be a finite number')
        if self.rpm <= 0 or self.duration_s <= 0 or self.speed_ms <= 0 \
                or self.rudder_rate_deg_s <= 0 or abs(self.rudder_deg) > 90:
            raise DiagnosisError(f'advice spec {self}: rpm, duration, speed and rudder rate '
                                 'must be > 0 and |rudder| <= 90 deg')
        if (self.rpm_after is None) != (self.step_at_s is None):
            raise DiagnosisError('advice spec: rpm_after and step_at_s go together')
        if self.rpm_after is not None and not (self.rpm_after > 0
                                               and 0 < self.step_at_s < self.duration_s):
            raise DiagnosisError(f'advice spec: rpm step to {self.rpm_after} at '
                                 f'{self.step_at_s} s must be > 0 rpm inside the trial')

    @classmethod
    def from_dict(cls, d: dict) -> 'TrialSpec':
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise DiagnosisError(f'advice spec: unknown field(s) {sorted(unknown)}')
        try:
            return cls(**d)
        except TypeError as exc:
            raise DiagnosisError(f'advice spec: {exc}') from None

    def to_dict(self) -> dict:
        return asdict(self)

    @property
    def name(self) -> str:
        a = f'{self.rudder_deg:+g}'
        base = {'zigzag': f'zigzag{a}_{self.check_deg or abs(self.rudder_deg):g}',
                'turning': f'turning{a}', 'pullout': f'pullout{a}'}[self.maneuver]
        step = f'_to{self.rpm_after:.0f}' if self.rpm_after is not None else ''
        return f'advice_{base}_{self.rpm:.0f}rpm{step}'

    def instruction(self) -> str:
        """
        E.g.

        '20°/20° zigzag (starboard first) at 80 rpm, then step to 110 rpm at 200 s'.
        """
        side = 'starboard' if self.rudder_deg > 0 else 'port'
        a = abs(self.rudder_deg)
        if self.maneuver == 'zigzag':
            what = f'{a:g}°/{(self.check_deg or a):g}° zigzag ({side} first)'
        elif self.maneuver == 'turning':
            what = f'turning circle, {a:g}° rudder to {side}'
        else:
            what = f'pull-out: {a:g}° rudder to {side} for {self.pullout_s:.0f} s, then amidships'
        text = f'{what} at {self.rpm:.0f} rpm'
        if self.rpm_after is not None:
            text += f', then step to {self.rpm_after:.0f} rpm at {self.step_at_s:.0f} s'
        return (text + f'; approach at {self.speed_ms:.2f} m/s, rudder at '
                f'{self.rudder_rate_deg_s:.1f}°/s, record {self.duration_s:.0f} s')


def run_spec(ship: ShipConfig, spec: TrialSpec, dt: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """
    Return the manoeuvre of spec by ship (all its effects acting), RK4 at <= 0.1 s.

    (t (T,), observed states (T, 6), recorded controls (T, 2) rpm and actual rudder, status (''
    when it completed, else why it stopped)).
    """
    T = int(round(spec.duration_s / dt)) + 1
    t = np.arange(T) * dt
    rpm = np.full(T, float(spec.rpm))
    if spec.rpm_after is not None:
        rpm[t >= spec.step_at_s] = spec.rpm_after
    orders = np.zeros(T)
    executed = t >= spec.approach_s
    amp = math.radians(spec.rudder_deg)
    zz_amp = zz_check = 0.0
    if spec.maneuver == 'turning':
        orders[executed] = amp
    elif spec.maneuver == 'pullout':
        orders[executed & (t < spec.approach_s + spec.pullout_s)] = amp
    else:
        zz_amp = amp
        zz_check = math.radians(abs(spec.check_deg if spec.check_deg is not None
                                    else spec.rudder_deg))
        orders[executed] = amp
    substeps = max(1, int(math.ceil(dt / 0.1)))
    out = np.empty((T, 6))
    rudder = np.empty(T)
    x0 = np.array([0.0, 0.0, 0.0, spec.speed_ms, 0.0, 0.0])
    status, k_fail = run_maneuver(ship.kind, ship.params, x0, rpm, orders, zz_amp, zz_check,
                                  math.radians(spec.rudder_rate_deg_s), T, float(dt), substeps,
                                  integrator_code('rk4'), out, rudder)
    why = '' if k_fail >= T else f'stopped at t = {t[min(k_fail, T - 1)]:.1f} s (status {status})'
    return t, out, np.column_stack([rpm, rudder]), why


def trial_from_spec(truth: ShipConfig, spec: TrialSpec, rate_hz: float = 1.0,
                    noise: SensorNoise | None = None, seed: int = 0,
                    name: str | None = None) -> tuple[Trial, Trial]:
    """
    (truth, measured) trial of spec sailed by ``truth`` (its hidden effects acting).

    As ``generate`` records one: command topics stamped time_offset early, sensor noise added.
    """
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise DiagnosisError(f'rate_hz = {rate_hz}: must be a finite number > 0')
    t, states, controls, why = run_spec(truth, spec, 1.0 / rate_hz)
    name = name or spec.name
    if why:
        raise DiagnosisError(f'{name}: the advised trial {why}')
    toff = truth['time_offset']
    if toff != 0.0:  # recorded(t) = actual(t + toff), as generate_trial does
        controls = np.column_stack([np.interp(t + toff, t, controls[:, i]) for i in range(2)])
    tr = Trial(t, states, controls, name=name,
               notes=[f'generated from advice: {spec.instruction()}'])
    noise = SensorNoise() if noise is None else noise
    return tr, noise.apply(tr, np.random.default_rng(seed + 1))


def specs_from_diagnosis(doc: dict) -> list[TrialSpec]:
    """Return the advised trials of a diagnosis.json document (its 'advice' list), each once."""
    if not isinstance(doc, dict) or not isinstance(doc.get('advice'), list):
        raise DiagnosisError("no 'advice' list in the diagnosis document (a diagnosis.json of "
                             'this version, written by diagnose)')
    out: list[TrialSpec] = []
    for i, a in enumerate(doc['advice']):
        if not isinstance(a, dict) or not isinstance(a.get('spec'), dict):
            raise DiagnosisError(f'advice[{i}]: no spec')
        if a.get('version', SPEC_VERSION) != SPEC_VERSION:
            raise DiagnosisError(f"advice[{i}]: spec version {a.get('version')} is not "
                                 f'{SPEC_VERSION}')
        pair = [a['spec']] + ([a['pair']] if isinstance(a.get('pair'), dict) else [])
        for d in pair:   # the advised trial, then its mirror (one tuned on, one held out)
            s = TrialSpec.from_dict(d)
            if s not in out:
                out.append(s)
    return out


# ------------------------------------------------------------------------------ repertoire
def repertoire(ship: ShipConfig, rpm0: float, speed0: float, duration_s: float
               ) -> list[TrialSpec]:
    """
    Feasible trials around the recorded operating point (rpm0, speed0).

    Zigzags of 10, 20 and the largest multiple of 5 deg within the rudder limit, turning circles
    and a pull-out, at 0.8, 1 and 1.2 x rpm0, rpm steps from 0.8 to 1.2 and from 1.2 to 0.5 x
    rpm0 half-way through a zigzag, and a zigzag with the gear at half its rate. Speeds follow
    the rpm (propeller law).
    """
    max_deg = math.degrees(ship.max_rudder_rad)
    rate = math.degrees(ship.rudder_rate_rad_s)
    big = min(35.0, 5.0 * math.floor(max_deg / 5.0))
    out = []
    for f in (0.8, 1.0, 1.2):
        rpm, u = rpm0 * f, speed0 * f
        for a in sorted({10.0, 20.0, big}):
            if a <= max_deg:
                out.append(TrialSpec('zigzag', a, rpm, duration_s, u, rate, check_deg=a))
        out.append(TrialSpec('turning', big, rpm, duration_s, u, rate))
        out.append(TrialSpec('turning', -big, rpm, duration_s, u, rate))
    out.append(TrialSpec('pullout', min(20.0, big), rpm0, duration_s, speed0, rate,
                         pullout_s=min(120.0, duration_s / 3)))
    out.append(TrialSpec('zigzag', 20.0 if big >= 20 else big, 0.8 * rpm0, duration_s,
                         0.8 * speed0, rate, check_deg=20.0 if big >= 20 else big,
                         rpm_after=1.2 * rpm0, step_at_s=round(duration_s / 2)))
    out.append(TrialSpec('zigzag', 20.0 if big >= 20 else big, rpm0, duration_s, speed0,
                         rate / 2, check_deg=20.0 if big >= 20 else big))
    # a slow-down step to 0.5 x rpm0 (a large change of the advance ratio). Starts from a
    # quarter of the speed at 1.2 x rpm0 (small advance ratio, large drift at the propeller)
    # are left out: they rank first by information, yet their misfit of the base coefficients
    # is taken up by a current or wind in the screen (benchmark: 0/3 propeller side forces)
    out.append(TrialSpec('zigzag', 20.0 if big >= 20 else big, 1.2 * rpm0, duration_s,
                         1.2 * speed0, rate, check_deg=20.0 if big >= 20 else big,
                         rpm_after=0.5 * rpm0, step_at_s=round(duration_s / 2)))
    return out


def mirrored(spec: TrialSpec) -> TrialSpec:
    """Return spec with the rudder to the other side (the advised trial's held-out twin)."""
    return replace(spec, rudder_deg=-spec.rudder_deg)


def separation(ship: ShipConfig, params_a: np.ndarray, params_b: np.ndarray,
               spec: TrialSpec, dt: float, sigma_pos: float, sigma_psi: float) -> float:
    """
    Return the predicted separation of two parameter vectors on spec (see the module).

    0 when the manoeuvre cannot be run, inf when one model diverges on it.
    """
    sa = replace(ship, params=np.asarray(params_a, float))
    t, states, controls, why = run_spec(sa, spec, dt)
    if why:
        return 0.0
    return _replay_separation(ship, params_a, params_b, states, controls, dt, sigma_pos,
                              sigma_psi)


def _replay_separation(ship, params_a, params_b, states, controls, dt, sigma_pos, sigma_psi,
                       length: int | None = None) -> float:
    T = len(states) if length is None else length
    out, _, k_fail = simulate_batch(ship.kind, np.vstack([params_a, params_b]), states[None, 0],
                                    controls[None], dt, np.array([T]), 'rk4',
                                    max(1, int(math.ceil(dt / 0.1))))
    if np.any(k_fail[:, 0] < T):
        return math.inf
    d = out[0, 0, :T] - out[1, 0, :T]
    dpsi = (d[:, 2] + math.pi) % (2 * math.pi) - math.pi
    return float(math.sqrt(np.mean((d[:, 0] ** 2 + d[:, 1] ** 2) / sigma_pos ** 2
                                   + dpsi ** 2 / sigma_psi ** 2)))


def residual_scale(ship: ShipConfig, params: np.ndarray, trials: Sequence[Trial],
                   noise: SensorNoise | None = None) -> tuple[float, float]:
    """
    (sigma_pos [m], sigma_psi [rad]).

    The RMS position and heading residual of params on trials (replayed from their first sample),
    or the sensor noise when larger.
    """
    noise = SensorNoise() if noise is None else noise
    e_pos, e_psi = [], []
    for t in trials:
        out, _, k_fail = simulate_batch(ship.kind, np.asarray(params)[None], t.states[None, 0],
                                        t.controls[None], t.dt, None, 'rk4',
                                        max(1, int(math.ceil(t.dt / 0.1))))
        k = int(k_fail[0, 0])
        d = out[0, 0, :k] - t.states[:k]
        e_pos.append(d[:, 0] ** 2 + d[:, 1] ** 2)
        e_psi.append(((d[:, 2] + math.pi) % (2 * math.pi) - math.pi) ** 2)
    pos = math.sqrt(float(np.mean(np.concatenate(e_pos)))) if e_pos else 0.0
    psi = math.sqrt(float(np.mean(np.concatenate(e_psi)))) if e_psi else 0.0
    return (max(pos, noise.position_m / ship.scale_ratio, 1e-9),
            max(psi, noise.heading_rad, 1e-9))


def operating_point(trials: Sequence[Trial]) -> tuple[float, float, float, float]:
    """(median rpm, median speed [m/s], median duration [s], dt [s]) of trials."""
    rpm = float(np.median([np.median(t.controls[:, 0]) for t in trials]))
    # the speed the ship holds (trials that start near rest would otherwise say ~0)
    u = float(np.median([np.median(t.states[:, 3]) for t in trials]))
    dur = float(np.median([t.t[-1] - t.t[0] for t in trials]))
    return rpm, max(u, 1e-3), dur, float(trials[0].dt)


def advise(ship: ShipConfig, rivals: list[dict], trials: Sequence[Trial],
           sigma: tuple[float, float]) -> list[dict]:
    """
    Return, for each rival pair, the repertoire's trial that separates them best.

    For each rival pair {'about', 'kind', 'params_a', 'params_b'} the repertoire's trial that
    separates them best, against sigma = (position [m], heading [rad]) (see

    :func:`residual_scale`): {'about', 'kind', 'instruction', 'spec', 'separation',
    'separation_recorded' (the best recorded trial's), 'settles' (whether the trial separates
    them SETTLES x better than the recorded ones and by at least MIN_SEPARATION), 'runner_up',
    'version'}.
    """
    rpm0, u0, dur, dt = operating_point(trials)
    sig_pos, sig_psi = sigma
    specs = repertoire(ship, rpm0, u0, dur)
    out = []
    for r in rivals:
        pa, pb = np.asarray(r['params_a'], float), np.asarray(r['params_b'], float)
        seps = [separation(ship, pa, pb, s, dt, sig_pos, sig_psi) for s in specs]
        finite = [(x, s) for x, s in zip(seps, specs) if math.isfinite(x) and x > 0]
        if not finite:
            continue
        finite.sort(key=lambda x: -x[0])
        best, spec = finite[0]
        recorded = max((_replay_separation(ship, pa, pb, t.states, t.controls, t.dt, sig_pos,
                                           sig_psi) for t in trials if abs(t.dt - dt) < 1e-9),
                       default=0.0)
        better = not math.isfinite(recorded) or best > SETTLES * recorded
        settles = best >= MIN_SEPARATION and better
        out.append({'about': r['about'], 'kind': r['kind'], 'instruction': _twice(spec),
                    'spec': spec.to_dict(), 'pair': mirrored(spec).to_dict(),
                    'separation': best,
                    'separation_recorded': recorded if math.isfinite(recorded) else None,
                    'settles': bool(settles),
                    'runner_up': finite[1][1].instruction() if len(finite) > 1 else '',
                    'version': SPEC_VERSION})
    return out


def _twice(spec: TrialSpec) -> str:
    return (spec.instruction() + '; sail it twice, once to each side (one run for tuning, one '
            'held out)')


def _effect_se(jac: np.ndarray, s2: float, n_base: int, j: int, width: float) -> float:
    """
    Return the standard error of parameter j (own units) with the n_base first ones free.

    As tuning.identifiability.aliasing: column j regressed on the base columns by least squares
    on the Jacobian itself (the normal equations would square a condition number that aliasing
    makes large); only the part they cannot mimic is evidence.
    """
    y, a = jac[:, j], jac[:, :n_base]
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    rr = float(np.sum((y - a @ coef) ** 2))
    return float(math.sqrt(s2 / max(rr, 1e-300)) * width)


def advise_information(ship: ShipConfig, base: ParameterSpace, base_theta: np.ndarray,
                       obj: Objective, effects: Sequence[str], trials: Sequence[Trial],
                       about: Sequence[str] | None = None) -> list[dict]:
    """
    Return, for each barely identifiable single-parameter effect, the trial that resolves it best.

    Linearised where :func:`~mmg_tuner.diagnosis.select.diagnose` flags it (the base optimum of
    obj's tuning trials, every probed effect of ``effects`` at its smallest magnitude worth
    finding; the same s^2): each repertoire trial, sailed by that model without noise, adds its
    Gauss-Newton information to the tuning trials'; each effect of ``about`` (default: all)
    gets its standard error with the base targets free and the resolution smallest / (2 x SE)
    (see the module). Entries as :func:`advise`, with 'separation' the resolution with the
    trial, 'separation_recorded' without it, and 'se_with' / 'se_recorded' / 'smallest' in the
    parameter's units.
    """
    effects = [e for e in effects if len(EFFECTS[e].params) == 1]
    about = [e for e in (effects if about is None else about) if e in effects]
    if not about:
        return []
    names, lo, hi, pre, value = list(base.names), list(base.lower), list(base.upper), \
        list(base.pre), list(base_theta)
    smallest = {}
    for e in effects:
        p = EFFECTS[e].params[0]
        (a, b), = EFFECTS[e].bounds(ship)
        smallest[e] = EFFECTS[e].smallest_for(ship)[0]
        names.append(p)
        lo.append(a)
        hi.append(b)
        pre.append(min(max(EFFECT_NEUTRAL[p], a), b))
        value.append(min(max(EFFECT_NEUTRAL[p] + smallest[e], a), b))
    space = ParameterSpace(tuple(names), np.array(pre), np.array(lo), np.array(hi))
    theta = np.array(value)
    width = space.upper - space.lower
    integ = {0: 'euler', 1: 'rk4'}[obj.method]
    jac, s2 = jacobian(obj, space, theta, 1e-3)
    # the recorded trials' Jacobian reduced to its R factor: the same least-squares geometry
    # (information adds over trials) in as many rows as parameters
    r_rec = np.linalg.qr(jac, mode='r')
    sailer = replace(ship, params=space.full_params(ship.params, theta)[0])
    rpm0, u0, dur, dt = operating_point(trials)
    n = base.dim
    col = {e: n + k for k, e in enumerate(effects)}
    rec = {e: smallest[e] / max(2 * _effect_se(r_rec, s2, n, col[e], width[col[e]]), 1e-300)
           for e in about}
    best: dict[str, tuple[float, TrialSpec | None]] = {e: (0.0, None) for e in about}
    for spec in repertoire(ship, rpm0, u0, dur):
        t, states, controls, why = run_spec(sailer, spec, dt)
        if why or not np.all(np.isfinite(states)):
            continue
        o = Objective(ship, TrialBatch.from_trials([Trial(t, states, controls, name=spec.name)]),
                      obj.weights, 0.0, integ, obj.substeps)
        jc, _ = jacobian(o, space, theta, 1e-3)
        both = np.vstack([r_rec, jc])
        res = {e: smallest[e] / max(2 * _effect_se(both, s2, n, col[e], width[col[e]]), 1e-300)
               for e in about}
        for e in about:
            if res[e] > best[e][0]:
                best[e] = (res[e], spec)

    def entry(e: str, res: float, spec: TrialSpec, kind: str) -> dict:
        return {'about': e, 'kind': kind, 'instruction': _twice(spec), 'spec': spec.to_dict(),
                'pair': mirrored(spec).to_dict(), 'separation': res,
                'separation_recorded': rec[e], 'settles': _settles(res, rec[e]),
                'se_with': smallest[e] / (2 * res), 'se_recorded': smallest[e] / (2 * rec[e]),
                'smallest': smallest[e], 'runner_up': '', 'version': SPEC_VERSION}

    return [entry(e, best[e][0], best[e][1], 'barely identifiable') for e in about
            if best[e][1] is not None]


def _settles(res: float, rec: float) -> bool:
    return bool(res >= MIN_SEPARATION and res > SETTLES * rec)


def load_advice(path) -> list[TrialSpec]:
    """Return the advised trials of a diagnosis.json file (errors name the file)."""
    import json
    from pathlib import Path

    p = Path(path)
    if p.is_dir():
        p = p / 'diagnosis.json'
    try:
        doc = json.loads(p.read_text())
    except OSError as exc:
        raise DiagnosisError(f'{p}: cannot read the diagnosis ({exc.strerror or exc})') from None
    except ValueError as exc:
        raise DiagnosisError(f'{p}: not JSON ({exc})') from None
    try:
        specs = specs_from_diagnosis(doc)
    except DiagnosisError as exc:
        raise DiagnosisError(f'{p}: {exc}') from None
    if not specs:
        raise DiagnosisError(f'{p}: the diagnosis advises no trial (nothing was barely '
                             'identifiable or indistinguishable)')
    return specs
