"""
Say when the model structure, not the named effects, is the likely cause of an error.

The effects search can only name what the library holds. When the model lacks a force or
moment (a port/starboard asymmetry the standard MMG regression cannot produce, a stall, a
shallow-water change), effects that break the same symmetry fit instead, and they show it:
they are impossible where the trials were recorded, or their estimates sit on or near the edge
of their box, and the base coefficients pile up on their bounds. This module collects that
evidence and measures what the model cannot produce:

* **port/starboard asymmetry**: per trial, the yaw-rate (and sway) error averaged over the
  manoeuvre, model minus recorded, in % of the recorded mean |r| over all trials, regressed
  on the side of the first rudder (s = +1 starboard, -1 port): ``e_k = a + b s_k``. A model
  that errs symmetrically (a rudder too weak) errs with the side (b); a recorded ship that
  turns more readily to one side than the model errs the same way on both sides (a, a bias
  in the body frame). ``a`` is significant when it exceeds twice its standard error over
  the trials and a material size (2 % of |r|; 5 % when two trials leave no standard error).
* **learnable structure** (when a residual network was trained, see
  :func:`with_learnable`): the share of the remaining held-out error it removes.

Verdict ``structure``: implausible effects (impossible here, significant but pinned on a
bound, or named with an estimate within 10 % of its box's edge) while a large error remains
(the final model keeps >= 30 % of the base held-out error, or a systematic error is measured),
or base coefficients on their bounds together with a measured systematic error, or together
with named causes that leave >= 30 % of the base error, above the noise (they explain too
little to be believed: a hull 29 % stronger was named a wind that left 65 %). Verdict
``unexplained``: a systematic error no effect explains, without implausible effects. A final
held-out error above NOISE_RATIO noise floors (diagnosis/noise.py: what sensor noise alone
leaves) is a systematic error. Otherwise ``none``, "no sign of a structural gap" -- said only
when what remains is noise; when the noise could not be estimated it says so instead.

One verdict (:func:`one_verdict`, the default ``verdict='rules'`` of the diagnosis): when
the verdict is ``structure``, no fitted effect is named as a CAUSE in the same report; they
are listed as mimicking the gap. A measured signal (the recorded wind driving the model) and a
cause a measurement sized fit nothing, so they cannot mimic: they stay causes beside it. With
``verdict='evidence'`` (diagnosis/decide.py) the structure verdict describes only what the
named causes leave and never withdraws a cause.
"""
from __future__ import annotations

import math
from typing import Any, cast, Mapping, Sequence, TYPE_CHECKING

from mmg_tuner.core.effects import EFFECTS
from mmg_tuner.core.layout import EFFECT_NEUTRAL, STATE_NAMES
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis.noise import describe as describe_noise
from mmg_tuner.diagnosis.residuals import simulate_trials
from mmg_tuner.diagnosis.settings import MEASURED
from mmg_tuner.tuning.parameters import ParameterSpace
from mmg_tuner.tuning.report import unique_names
import numpy as np

if TYPE_CHECKING:   # annotations only
    from mmg_tuner.diagnosis.results import Cause

NEAR_BOUND = 0.10          # an effect estimate this close to its box's edge (fraction of width)
REMAINING_LARGE = 0.30     # final / base held-out J at or above this: a large error remains
ASYM_MATERIAL = 0.02       # smallest side-independent yaw-rate error worth reporting (of |r|)
ASYM_MATERIAL_NO_SE = 0.05  # the same when only two trials give no standard error
MIN_RUDDER_RAD = math.radians(5.0)   # a trial needs a rudder this large to have a side
_PERIODIC = {'current_dir', 'wind_dir'}
_R, _V = STATE_NAMES.index('r'), STATE_NAMES.index('v')


def side_of(trial: Trial) -> int:
    """
    Return the side of a trial's manoeuvre: +1 starboard, -1 port, 0 none.

    The sign of the first rudder beyond half the largest; 0 when the rudder never exceeds
    5 deg, or the trial has no rudder.
    """
    if 'rudder' not in trial.inputs:   # no rudder (a twin-azimuth tug): no side is known
        return 0
    d = np.asarray(trial['rudder'], float)
    big = float(np.nanmax(np.abs(d))) if d.size else 0.0
    if not big >= MIN_RUDDER_RAD:
        return 0
    k = int(np.argmax(np.abs(d) >= 0.5 * big))
    return 1 if d[k] > 0 else -1


def asymmetry(trials: Sequence[Trial], sims: Sequence[np.ndarray]) -> dict[str, Any] | None:
    """
    Regress each trial's mean yaw-rate and sway error on its side (see the module docstring).

    Returns None when the trials do not cover both sides (or a simulation failed); else a dict
    with per-trial rows, the side-independent part ``a`` and the side-flipping part ``b`` of
    the yaw-rate error (fractions of the recorded mean |r|), ``a_se`` (None with two trials),
    the same for sway (``v_a``, in % of the recorded mean |v|), ``significant`` and ``text``.
    """
    rows: list[dict[str, Any]] = []
    r_scale, v_scale = [], []
    for tr, name, sim in zip(trials, unique_names(trials), sims):
        side = side_of(tr)
        if side == 0 or sim is None or not np.all(np.isfinite(sim)):
            continue
        k0 = int(np.argmax(np.abs(tr['rudder']) >= MIN_RUDDER_RAD))
        e = sim[k0:] - tr.states[k0:]
        rows.append({'trial': name, 'side': 'starboard' if side > 0 else 'port', 's': side,
                     'e_r': float(np.mean(e[:, _R])), 'e_v': float(np.mean(e[:, _V]))})
        r_scale.append(np.abs(tr.states[k0:, _R]))
        v_scale.append(np.abs(tr.states[k0:, _V]))
    sides = {r['s'] for r in rows}
    if sides != {-1, 1}:
        return None
    r_ref = float(np.mean(np.concatenate(r_scale)))
    v_ref = float(np.mean(np.concatenate(v_scale)))
    if not (r_ref > 0 and v_ref > 0):
        return None
    s = np.array([r['s'] for r in rows], float)
    out: dict[str, Any] = {'trials': rows, 'r_ref_rad_s': r_ref, 'v_ref_m_s': v_ref}
    for key, ref in (('r', r_ref), ('v', v_ref)):
        y = np.array([r[f'e_{key}'] for r in rows]) / ref
        a, b, se = _side_fit(s, y)
        out[f'{key}_a'], out[f'{key}_b'], out[f'{key}_a_se'] = a, b, se
        for r, yi in zip(rows, y):
            r[f'e_{key}_rel'] = float(yi)
    a, se = out['r_a'], out['r_a_se']
    material = ASYM_MATERIAL if se is not None else ASYM_MATERIAL_NO_SE
    out['significant'] = bool(abs(a) >= material and (se is None or abs(a) > 2 * se))
    n_s, n_p = int(np.sum(s > 0)), int(np.sum(s < 0))
    pm = '' if se is None else f' ± {100 * se:.1f}'
    way = 'port' if a > 0 else 'starboard'   # r > 0 is starboard yaw (MMG sign)
    out['text'] = (
        f'yaw-rate error (model - recorded, mean over each manoeuvre, % of the recorded mean '
        f'|r|) over {n_s} starboard-first and {n_p} port-first trial(s): side-independent part '
        f'{100 * a:+.1f}{pm} %, part that flips with the side {100 * out["r_b"]:+.1f} %'
        + (f'; on both sides the recorded ship yaws further to {way} than the model: a '
           'port/starboard asymmetry the model does not produce' if out['significant']
           else '; no material asymmetry'))
    return out


def _side_fit(s: np.ndarray, y: np.ndarray) -> tuple[float, float, float | None]:
    """Least squares y = a + b s; the standard error of a (None without a spare trial)."""
    X = np.column_stack([np.ones_like(s), s])
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    n = len(y)
    if n <= 2:
        return float(coef[0]), float(coef[1]), None
    res = y - X @ coef
    sigma2 = float(res @ res) / (n - 2)
    cov = sigma2 * np.linalg.inv(X.T @ X)
    return float(coef[0]), float(coef[1]), float(math.sqrt(max(cov[0, 0], 0.0)))


def _near_edge(ship: ShipConfig, effect: str, values: Mapping[str, float]) -> list[str]:
    """
    List a named effect's parameters within NEAR_BOUND of an edge of their box.

    An edge equal to the neutral value does not count (there the effect merely vanishes).
    """
    e = EFFECTS.get(effect)
    if e is None:
        return []
    out = []
    for p, (lo, hi) in zip(e.params, e.bounds(ship)):
        if p in _PERIODIC or p not in values:
            continue
        v, w = float(values[p]), NEAR_BOUND * (hi - lo)
        if (v - lo < w and lo != EFFECT_NEUTRAL[p]) or (hi - v < w and hi != EFFECT_NEUTRAL[p]):
            out.append(p)
    return out


def evidence(doc: Mapping[str, Any], ship: ShipConfig, targets: Sequence[str] | None = None,
             a_r: float | None = None) -> tuple[list[str], list[str]]:
    """
    Implausible effects (strong evidence) and base coefficients on their bounds (weak).

    ``doc``: diagnosis.json's content (causes, candidates, would_fit_but_impossible,
    baseline). Candidates count from the last round only (the earlier ones may have bent to
    mimic a cause named later). Returns (strong, weak) lists of sentences.
    """
    strong, weak = [], []
    for x in doc.get('would_fit_but_impossible') or []:
        strong.append(f"{x['effect']} would fit (held-out gain {100 * x['gain']:.0f} %) but "
                      f"is impossible here ({x['reason']})")
    # only the last round's candidates: they were judged against the model with every cause
    # named before them; a candidate that bent on its bound in an earlier round (a yaw moment
    # bias pinned while the current was not yet named) mimicked a cause found later
    for rnd in (doc.get('candidates') or [])[-1:]:
        for c in rnd:
            if c.get('significant') and c.get('on_bound') and not c.get('impossible'):
                strong.append(f"{c['effect']} fits (held-out gain {100 * c['gain']:.0f} %) only "
                              f"with {', '.join(c['on_bound'])} on its bound")
        for c in rnd:
            if c.get('significant') and not c.get('impossible') and not c.get('on_bound') \
                    and (c.get('implausible') or c.get('inconsistent')):
                strong.append(f"{c['effect']} fits (held-out gain {100 * c['gain']:.0f} %) but "
                              + ('is implausible: ' + c['implausible'] if c.get('implausible')
                                 else 'is inconsistent: ' + c['inconsistent']))
    for c in doc.get('causes') or []:
        near = _near_edge(ship, c['effect'], c.get('parameters') or {})
        if near:
            strong.append(f"{c['effect']} was named with {', '.join(near)} within "
                          f'{100 * NEAR_BOUND:.0f} % of the edge of its box')
    params = (doc.get('baseline') or {}).get('params') or {}
    if params:
        space = ParameterSpace.around(ship, tuple(targets) if targets else None, a_r)
        theta = np.array([params.get(n, p) for n, p in zip(space.names, space.pre)])
        pinned = space.on_bound(theta)
        if pinned:
            weak.append(f"base coefficients on a bound of their box: {', '.join(pinned)} "
                        '(they bend to absorb something the model lacks)')
    return strong, weak


def assess(doc: Mapping[str, Any], ship: ShipConfig, trials: Sequence[Trial],
           final_params: np.ndarray, integrator: str = 'rk4', *,
           targets: Sequence[str] | None = None, a_r: float | None = None,
           learnable: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """
    Give the structure verdict of a diagnosis (see the module docstring).

    ``doc``: diagnosis.json's content; ``trials``: every trial (tuning and held out) as the
    final model sees them; ``final_params``: the final model's full parameter vector;
    ``learnable``: the residual network's measurement (``share``, ``share_se``,
    ``significant``), if one was trained. Returns structure.json-like content: ``verdict``,
    ``summary``, ``evidence``, ``asymmetry``, ``remaining``, ``learnable``.
    """
    strong, weak = evidence(doc, ship, targets, a_r)
    sims = simulate_trials(ship, final_params, list(trials), integrator) if trials else []
    asym = asymmetry(list(trials), sims) if trials else None
    return verdict(doc, strong, weak, asym, learnable)


def verdict(doc: Mapping[str, Any], strong: list[str], weak: list[str],
            asym: dict[str, Any] | None, learnable: Mapping[str, Any] | None = None
            ) -> dict[str, Any]:
    """Weigh the evidence: 'structure', 'unexplained' or 'none' (see the module docstring)."""
    b, f = doc.get('baseline') or {}, doc.get('final') or {}
    Jb, Jf = b.get('J_test'), f.get('J_test')
    remaining = (float(Jf) / float(Jb) if Jb and Jf is not None and math.isfinite(Jb)
                 and math.isfinite(Jf) and Jb > 0 else None)
    systematic = []
    is_noise, noise_text = describe_noise(float(Jf) if Jf is not None else math.nan,
                                          doc.get('noise'))
    if asym and asym['significant']:
        systematic.append('a port/starboard asymmetry: ' + asym['text'])
    if learnable and learnable.get('significant'):
        systematic.append('learnable structure: a residual network removes '
                          f"{100 * learnable['share']:.0f} % ± "
                          f"{100 * learnable['share_se']:.0f} of the remaining held-out error")
    # an error above the noise is systematic, but says nothing of its kind: with implausible
    # effects it makes the structure verdict, alone 'unexplained'; beside coefficients on
    # their bounds (common on real data) it is not the measured asymmetry or learnable
    # structure that blames the structure
    measured = list(systematic)
    if is_noise is False:
        systematic.append('an error above the noise: ' + noise_text)
    # large: the named causes left much of the base error, or a measured systematic error
    # (an error merely above the noise after causes that explained 98 % of it is no reason
    # to call those causes mimics: it makes the verdict 'unexplained')
    large = (remaining is not None and remaining >= REMAINING_LARGE) or bool(measured)
    # named causes that leave most of a base error far above the noise while the base
    # coefficients pile up on their bounds explain too little to be believed: every hull force
    # 29 % larger (no effect describes it) was named a 5.4 m/s wind that left 65 % of the
    # error, 3.9 x what noise leaves, with 8 of 12 coefficients on a bound
    doubtful = bool(doc.get('causes')) and remaining is not None \
        and remaining >= REMAINING_LARGE and is_noise is False
    left = ('what remains' if remaining is None else
            f"{100 * remaining:.0f} % of the base model's held-out error remains")
    if strong and large or weak and (measured or doubtful):
        v = 'structure'
        summary = (f'{left}, STRUCTURAL (a force or moment the model lacks, beside any named '
                   'cause): '
                   + '; '.join((strong or weak)[:2])
                   + ('' if not systematic else '; measured: ' + systematic[0].split(':')[0])
                   + (f' ({noise_text})' if is_noise is False else ''))
    elif systematic:
        v = 'unexplained'
        summary = (f'{left}, systematic, and no effect in the library explains it: '
                   + systematic[0].split(':')[0]
                   + (f' ({noise_text})' if is_noise is False else ''))
    elif is_noise:
        v = 'none'
        summary = 'no sign of a structural gap: ' + noise_text
    else:
        v = 'none'
        summary = 'no evidence of a structural gap, but ' + noise_text
    evidence = {'implausible_effects': strong, 'bounded_coefficients': weak,
                'systematic': systematic}
    return {'verdict': v, 'summary': summary, 'evidence': evidence,
            'remaining_fraction': remaining, 'asymmetry': asym,
            'learnable': dict(learnable) if learnable else None, 'noise': noise_text,
            'remaining_is_noise': is_noise}


def one_verdict(causes: list[Cause], st: dict[str, Any], J_base: float | None = None,
                noise: dict[str, Any] | None = None) -> tuple[list[Cause], list[Cause]]:
    """
    Return (causes, mimicking): every fitted cause moves to mimicking when structure wins.

    ``causes``: the search's named causes; ``st``: the structure verdict (:func:`verdict`),
    updated in place. A report never names a CAUSE in the same breath as "the model
    structure is the likely cause": if the structure check wins, the effects are listed as
    mimicking it (a cause a measurement sized stays: it mimics nothing). What remains after the
    named causes is then the base model's error
    (``J_base``, held out): the noise statement is made of it (``noise``: the floor).
    """
    # a cause sized by a measurement (Cause.measured) or a measured signal driving the model
    # (the recorded wind: nothing fitted) is a fact, not a fit that could bend to mimic a gap
    def fact(c: Cause) -> bool:
        return bool(getattr(c, 'measured', '')) or getattr(c, 'effect', None) in MEASURED

    kept = [c for c in causes if fact(c)]
    fitted = [c for c in causes if not fact(c)]
    if st.get('verdict') != 'structure' or not fitted:
        return list(causes), []
    if J_base is not None:
        is_noise, text = describe_noise(float(J_base), noise)
        st['remaining_is_noise'] = is_noise
        st['noise'] = text + ' (after the named causes: none; the tuned base model)'
    return kept, fitted


def markdown_lines(doc: Mapping[str, Any]) -> list[str]:
    """Return the report's structure section from diagnosis.json's ``structure`` ([] if none)."""
    st = doc.get('structure')
    if not st:
        return []
    head = {'structure': '**Likely cause: the model structure.**',
            'unexplained': '**Unexplained systematic error.**',
            'none': 'No structural gap shown.'}[st['verdict']]
    lines = ['', '## Model structure', '', f"{head} {st['summary'][0].upper()}"
             f"{st['summary'][1:]}."]
    ev = st['evidence']
    items = ev['implausible_effects'] + ev['bounded_coefficients']
    if items:
        lines += ['', 'Evidence that the effects only mimic a gap:', '']
        lines += [f'- {x}' for x in items]
    if doc.get('mimicking'):
        lines += ['', 'Effects kept in the fitted model but not named (their value follows the '
                  'manoeuvre, or they add nothing beside the causes):', '']
        lines += [f"- {c['effect']}: {c['summary']} (held-out gain "
                  f"{100 * c['heldout_gain']:.0f} %)" for c in doc['mimicking']]
    if st.get('remaining_fraction') is not None:
        lines += ['', f"The final model keeps {100 * st['remaining_fraction']:.0f} % of the "
                  "base model's held-out error."]
    a = st.get('asymmetry')
    if a:
        lines += ['', f"Port/starboard: {a['text']}.", '',
                  '| trial | first rudder | yaw-rate error [% of mean abs r] | '
                  'sway error [% of mean abs v] |', '|---|---|---|---|']
        for r in a['trials']:
            lines.append(f"| {r['trial']} | {r['side']} | {100 * r['e_r_rel']:+.1f} | "
                         f"{100 * r['e_v_rel']:+.1f} |")
    lr = st.get('learnable')
    if lr and lr.get('line'):
        lines += ['', lr['line']]
    rs = st.get('residual')
    if rs and rs.get('why'):
        lines += ['', f"Residual network (--residual {rs['mode']}): {rs['why']}."]
    return lines


# ------------------------------------------------------------------ learnable structure
LEARNABLE_MIN = 0.10       # a held-out gain below this is not "learnable structure"
REGIMES = ('speed', 'drift angle', 'rudder', 'propeller load')


def regime_values(trial: Trial, states: np.ndarray) -> dict[str, np.ndarray]:
    """
    Per-sample regime coordinates of a trial.

    speed |U| [m/s], drift angle |beta| = |atan2(-v, u)| [deg] and, for a trial with a
    rudder and rpm, |rudder| [deg] and the propeller load n / |u| [rev/min per m/s] (high
    when the propeller works hard for the speed: accelerating, stopping, slow), from the
    recorded states and inputs.
    """
    u, v = states[:, 3], states[:, 4]
    out = {'speed': np.hypot(u, v), 'drift angle': np.degrees(np.abs(np.arctan2(-v, u)))}
    if 'rudder' in trial.inputs:   # a screw and rudder's (another craft: speed and drift)
        out['rudder'] = np.degrees(np.abs(trial['rudder']))
    if 'rpm' in trial.inputs:
        out['propeller load'] = np.abs(trial['rpm']) / np.maximum(np.abs(u), 0.05 * max(
            float(np.max(np.abs(u))), 1e-6))
    return out


def learnable(ship: ShipConfig, tune_trials: Sequence[Trial], test_trials: Sequence[Trial],
              options: Mapping[str, Any] | None = None, integrator: str = 'rk4',
              restart_every_s: float = 100.0) -> dict[str, Any]:
    """
    Train a residual network on the final model and measure what it learns on held-out trials.

    ``ship``: the final model (tuned, with the named effects); the network trains on
    ``tune_trials`` (early stopping on the last quarter of each) and is scored on
    ``test_trials`` with the evaluate machinery (eq. 26 index, restarts every
    ``restart_every_s``): ``share`` = 1 - sum of the hybrid's squared standardised errors /
    the final model's, with its jackknife standard error over the test trials; where it lives
    (per-state gains; the regime bins where the error falls most; where the network acts).
    Raises MissingDependencyError (saying how to install JAX) when it is missing.
    """
    from mmg_tuner.diagnosis.stats import jackknife_se
    from mmg_tuner.learn import ResidualConfig, train_residual
    from mmg_tuner.learn.model import Model
    from mmg_tuner.learn.residual import simulate_segments
    from mmg_tuner.tuning.evaluate import INDEX_STATES, errors, evaluate, pooled_sigma

    opts = {'integrator': integrator if integrator in ('euler', 'rk4') else 'rk4',
            **dict(options or {}), 'physics': True}
    fit = train_residual(ship, list(tune_trials), config=ResidualConfig(**opts))
    hybrid = Model(ship, fit.net)
    sig = pooled_sigma(test_trials)
    base = evaluate(ship, test_trials, restart_every_s, 'rk4', sigma=sig)
    hyb = evaluate(hybrid, test_trials, restart_every_s, 'rk4', sigma=sig)
    names = list(base.trials)
    # (an index is cast to float where it was just checked not None)
    J_b = np.array([np.inf if base.trials[n].index is None
                    else cast(float, base.trials[n].index) * len(t)
                    for n, t in zip(names, test_trials)])
    J_h = np.array([np.inf if hyb.trials[n].index is None
                    else cast(float, hyb.trials[n].index) * len(t)
                    for n, t in zip(names, test_trials)])
    ok = bool(np.all(np.isfinite(J_b)) and np.all(np.isfinite(J_h)))
    share = float(1 - J_h.sum() / J_b.sum()) if ok and J_b.sum() > 0 else None
    se = jackknife_se(J_b, J_h) if ok else None
    significant = bool(share is not None and share > LEARNABLE_MIN and se is not None
                       and share > 2 * se)
    # where: per state, and per regime bin (tertiles over the test samples)
    eb_parts: list[np.ndarray] = []
    eh_parts: list[np.ndarray] = []
    reg_parts: dict[str, list[np.ndarray]] = {}
    res_parts: list[np.ndarray] = []
    for tr, n in zip(test_trials, names):
        eb_parts.append(errors(base.trials[n].predicted, tr.states))
        eh_parts.append(errors(hyb.trials[n].predicted, tr.states))
        for k, x in regime_values(tr, tr.states).items():
            reg_parts.setdefault(k, []).append(x)
        res_parts.append(simulate_segments(ship, fit.net, tr, 'rk4', restart_every_s)[1])
    eb, eh = np.concatenate(eb_parts), np.concatenate(eh_parts)
    res = np.concatenate(res_parts)
    reg = {k: np.concatenate(v) for k, v in reg_parts.items()}
    col = {n: STATE_NAMES.index(n) for n in INDEX_STATES}
    fin = np.all(np.isfinite(eb), axis=1) & np.all(np.isfinite(eh), axis=1)
    per_state = {}
    for n in INDEX_STATES:
        a = float(np.sum(eb[fin, col[n]] ** 2))
        per_state[n] = None if not a > 0 else float(1 - np.sum(eh[fin, col[n]] ** 2) / a)
    zb = sum((eb[:, col[n]] / sig[n]) ** 2 for n in INDEX_STATES)
    zh = sum((eh[:, col[n]] / sig[n]) ** 2 for n in INDEX_STATES)
    drop = np.where(fin, zb - zh, 0.0)
    total = float(drop.sum())
    regimes = {}
    for k, x in reg.items():
        edges = np.quantile(x[fin], [0, 1 / 3, 2 / 3, 1]) if fin.any() else np.zeros(4)
        bins = []
        for i in range(3):
            m = fin & (x >= edges[i]) & ((x <= edges[i + 1]) if i == 2 else (x < edges[i + 1]))
            bins.append({'low': float(edges[i]), 'high': float(edges[i + 1]),
                         'samples': int(m.sum()),
                         'share_of_gain': float(drop[m].sum() / total) if total > 0 else None,
                         'residual_rms': [float(np.sqrt(np.nanmean(res[m, j] ** 2)))
                                          if m.any() else None for j in range(3)]})
        regimes[k] = bins
    where = _where_text(per_state, regimes) if significant else ''
    pm = '—' if se is None else f'{100 * se:.0f}'
    line = ('unexplained but learnable structure: '
            + ('— (a model diverged on a held-out trial)' if share is None else
               f'{100 * share:.0f} % ± {pm} of the remaining held-out error')
            + (f'; {where}' if where else ('' if significant else ' (not significant)')))
    return {'share': share, 'share_se': se, 'significant': significant, 'line': line,
            'per_state_gain': per_state, 'regimes': regimes, 'where': where,
            'residual_share_of_acceleration': float(fit.share), 'val_gain': fit.val_gain,
            'seconds': float(fit.seconds), 'epochs': int(fit.epochs), 'seed': int(fit.seed),
            'notes': list(fit.notes), '_plot': (reg, res, fin)}


def _where_text(per_state: Mapping[str, Any], regimes: Mapping[str, Any]) -> str:
    """
    Say where the learnable structure lives, e.g.

    'mostly in r and v ...; at high drift angle'.

    The states with the largest gains and the regime bin holding the largest share of the gain.
    """
    st = sorted(((g, n) for n, g in per_state.items() if g is not None), reverse=True)[:2]
    parts = ['mostly in ' + ' and '.join(f'{n} ({100 * g:.0f} % of its error)'
                                         for g, n in st if g > 0)] if st and st[0][0] > 0 else []
    best = None
    for k, bins in regimes.items():
        for i, b in enumerate(bins):
            s = b['share_of_gain']
            if s is not None and (best is None or s > best[0]):
                best = (s, k, i, b)
    if best is not None and best[0] > 0.45:   # a third of the samples holding most of it
        s, k, i, b = best
        parts.append(f"at {('low', 'medium', 'high')[i]} {k} ({b['low']:.3g}-{b['high']:.3g}: "
                     f'{100 * s:.0f} % of the gain in a third of the samples)')
    return '; '.join(parts)


def plot_learnable(doc: Mapping[str, Any]) -> dict[str, bytes]:
    """Plot the network's accelerations against each regime (learnable_structure.png)."""
    from matplotlib.figure import Figure

    from mmg_tuner.tuning.report import png_bytes
    reg, res, fin = doc['_plot']
    fig = Figure(figsize=(12, 8))
    regimes = [k for k in REGIMES if k in reg]   # a craft without a rudder: speed and drift
    axes = fig.subplots(3, len(regimes), sharex='col', squeeze=False)
    for j, (label, unit) in enumerate((('du', 'm/s^2'), ('dv', 'm/s^2'), ('dr', 'rad/s^2'))):
        for i, k in enumerate(regimes):
            ax = axes[j, i]
            m = fin & np.isfinite(res[:, j])
            ax.scatter(reg[k][m], res[m, j], s=2, alpha=0.4)
            ax.grid(alpha=0.3)
            if i == 0:
                ax.set_ylabel(f'{label} [{unit}]')
            if j == 2:
                ax.set_xlabel(k)
    fig.suptitle('What the residual network adds on the held-out trials (' + doc['line'] + ')',
                 fontsize=9)
    fig.tight_layout()
    return {'learnable_structure.png': png_bytes(fig)}
