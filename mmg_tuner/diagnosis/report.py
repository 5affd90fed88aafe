"""
Write diagnosis.json, diagnosis.md and the plots a naval architect would look at.

diagnosis.json, diagnosis.md and the plots a naval architect would look at (returned as text and
PNG bytes; the caller writes them).
"""
from __future__ import annotations

from dataclasses import asdict
import math
from typing import Any, Callable

from mmg_tuner.core.actuators import commanded_channels
from mmg_tuner.core.channels import TABLE as CHANNELS
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis.advice import joint_text
from mmg_tuner.diagnosis.residuals import residual_series, simulate_trials, summarize
from mmg_tuner.diagnosis.results import Diagnosis
from mmg_tuner.diagnosis.structure import markdown_lines as structure_lines
from mmg_tuner.tuning.plots import INPUT_AXES, png_bytes
from mmg_tuner.tuning.report import display_name, fmt_gain, fmt_J, unique_names
import numpy as np


def to_dict(d: Diagnosis, residuals_base: dict[str, Any], residuals_final: dict[str, Any]
            ) -> dict[str, Any]:
    causes = [c.to_dict() for c in d.causes]
    return {'causes': causes, 'baseline': d.baseline, 'final': d.final,
            'candidates': [[asdict(c) for c in r] for r in d.rounds],
            'residuals': {'base_model': residuals_base, 'final_model': residuals_final},
            'barely_identifiable': d.aliased, 'params': d.params, 'wall_s': d.wall_s}


def markdown(doc: dict[str, Any], ship: ShipConfig) -> str:
    b, f = doc['baseline'], doc['final']
    lines = [f'# Diagnosis: {ship.name}', '']
    if doc.get('setting'):
        lines += [f"Setting: {doc['setting']['description']}." + (
            ' Impossible here: ' + '; '.join(
                f'{e} ({w})' for e, w in doc.get('impossible_here', {}).items()) + '.'
            if doc.get('impossible_here') else ''), '']
    if doc['causes']:
        lines.append('**What was wrong, and why:**')
        lines.append('')
        for c in doc['causes']:
            lines.append(f"- **{c['effect']}** — {c['summary']}"
                         + (f" (measured: {c['measured']}; held at that value, not fitted)"
                            if c.get('measured') else '') + '. Held-out gain '
                         f"{_pct(c['heldout_gain'])} ± {_pct(c['heldout_gain_se'])} "
                         '(jackknife over test trials)'
                         + (f"; it explains {_pct(c['share'])} of the base model's held-out "
                            'error' if c.get('share') is not None else '')
                         + f". {c['description'].capitalize()}."
                         + (f' These trials cannot tell it apart from '
                            f"{', '.join(c['indistinguishable_from'])} (held-out gains within "
                            'their combined uncertainty).' if c.get('indistinguishable_from')
                            else ''))
    elif doc.get('mimicking'):
        lines.append('**No cause is named:** the effects that fit take a different value on '
                     'each trial, add nothing beside the others, or a change of the hull '
                     'explains the trials better (see "Evidence per effect" '
                     'and "Model structure").')
    elif doc.get('undecided'):
        lines.append('**No cause is named alone:** these trials cannot tell the effects below '
                     'from their rivals.')
    else:
        lines.append('**No effect in the library explains the errors significantly.** The '
                     'tuned base model is the best description of these trials.')
    lines += _listed(
        doc.get('undecided'),
        '**Undecided: one of a set.** Each fits the trials, and is in the fitted model, but a '
        'rival explains them about as well (held-out gains within their combined uncertainty), '
        'so neither is named. "The trial that would settle it" below says what would tell them '
        'apart:',
        lambda c: (f"one of **{c['effect']}** ({c['summary']}, held-out gain "
                   f"{_pct(c['heldout_gain'])} ± {_pct(c['heldout_gain_se'])}) or "
                   f"{', '.join(c['indistinguishable_from'])}"))
    lines += _listed(
        doc.get('suspected'),
        '**Suspected, not named.** The trials hint at these (a held-out gain above the least a '
        'cause needs, with a reduction that counts as evidence), but the held-out trials '
        'disagree on them (one made worse, or the gain within its standard error). "The trial '
        'that would settle it" below says what would:',
        lambda x: (f"{x['effect']}: {x['summary']}, held-out gain {_pct(x['gain'])} ± "
                   f"{_pct(x['gain_se'])} (round {x['round']}"
                   + (f", beside {', '.join(x['beside'])}" if x.get('beside') else '') + ')'))
    lines += _listed(
        doc.get('would_fit_but_impossible'),
        '**Would fit, but impossible here.** These effects explain the held-out trials '
        'significantly, yet cannot exist where they were recorded. A good fit by an impossible '
        'effect is evidence of a structural gap of the model (a force or moment it lacks, which '
        'the effect mimics), not of that effect:',
        lambda x: (f"{x['effect']}: held-out gain {_pct(x['gain'])} ± {_pct(x['gain_se'])} "
                   f"(round {x['round']}) — {x['reason']}"))
    lines += ['', '| held-out J (test trials) | value |', '|---|---|',
              f'| base model, tuned | {_J(b)} |',
              f'| final model | {_J(f)} |',
              f"| gain | {fmt_gain(b['J_test'], f['J_test'])} |"]
    for m in doc.get('measured_signals') or []:
        lines += ['', f"## Measured signal: {m['signal'].replace('_', ' ')} (round {m['round']})",
                  '', '| model | held-out J |', '|---|---|',
                  f"| without it | {_fmt_J(m['J_test_without'])} |",
                  f"| with it | {_fmt_J(m['J_test_with'])} |",
                  f"| held-out gain | {_pct(m['heldout_gain'])} ± {_pct(m['heldout_gain_se'])} "
                  f"({'named' if m['named'] else 'not named: ' + (m['note'] or '—')}) |"]
    lines += _decision_lines(doc)   # diagnosis/decide.py: why each fitted effect is named or not
    lines += structure_lines(doc)   # diagnosis/structure.py: is the model structure to blame?
    lines += ['', '## Candidates', '', '| round | effect | held-out gain | ± | named | note |',
              '|---|---|---|---|---|---|']
    for i, r in enumerate(doc['candidates'], 1):
        for c in r:
            note = [f'{p} on its bound' for p in c.get('on_bound', [])]
            if c.get('impossible'):
                note.append(('would fit, but ' if c.get('significant') else '')
                            + 'impossible here: ' + c['impossible'])
            if c.get('diverged'):
                note.append(c['diverged'])
            if c.get('implausible'):
                note.append('implausible: ' + c['implausible'])
            if c.get('inconsistent'):
                note.append('inconsistent: ' + c['inconsistent'])
            gain = _pct(c['gain']) if np.isfinite(c['gain'] if c['gain'] is not None
                                                  else np.nan) else 'diverged'
            lines.append(f"| {i} | {c['effect']} | {gain} | "
                         f"{_pct(c['gain_se'])} | {'yes' if c['accepted'] else ''} | "
                         f"{'; '.join(note)} |")
    if doc.get('barely_identifiable'):
        lines += ['', '## Effects these trials can barely see', '',
                  'With the base targets tuned, these effects have a standard error over half '
                  'the smallest magnitude worth finding: the tuned coefficients reproduce most '
                  'of their signature, so they may go unnamed even if present. Trials that '
                  'separate them (other speeds, rpm changes, more samples) or fewer base '
                  'targets would.', '',
                  '| effect | standard error | smallest worth finding | share mimicked | '
                  'mimicked by |', '|---|---|---|---|---|']
        for n, a in doc['barely_identifiable'].items():
            lines.append(f"| {n} | {a['se']:.3g} | {a['smallest']:.3g} | "
                         f"{_pct(a['r2'])} | {', '.join(a['mimicked_by'])} |")
    if doc.get('advice'):
        lines += ['', '## The trial that would settle it', '',
                  'From the feasible trials (zigzags, turning circles, pull-outs at several rpm, '
                  'rpm steps up and down, a slower rudder; within the rudder limit and gear '
                  'rate): for a pair of causes these trials cannot tell apart, the one whose '
                  'predicted outputs differ most between the rival models, against the '
                  'unexplained error (separation); for an effect they barely see, the one that '
                  'adds most information: its smallest magnitude worth finding over twice its '
                  'standard error with the base targets free (resolution; 1 lifts the flag). '
                  'Rankings, not probabilities (residuals along a trajectory are correlated). '
                  'Sail each twice, once to each side: tune on one run, hold the other out '
                  '(an effect is named on its held-out gain). '
                  '`generate --from-advice diagnosis.json` runs both (the trial to sail '
                  'first, then the others; never those no trial can settle). An effect no '
                  'trial can settle names the measurement that would; when that measurement '
                  'fixes base coefficients, its advice gives the re-run (`--params` with them, '
                  '`--targets` without them) and the resolution these trials reach then.', '']
        joint = [a for a in doc['advice'] if a.get('kind') == 'joint']
        for a in joint:   # one trial for all the suspects: which one is real is unknown
            lines += [f"**Sail first** (one trial for all of {a['about']}, chosen by how many "
                      'it settles, then by the information it adds to all of them; each '
                      'judged with the others free): ' + a['instruction'] + '. It '
                      + joint_text(a) + '.'
                      + ('' if a.get('lifts') else ' No single trial settles them all apart '
                         'here; this one adds the most information to all of them, and each '
                         "effect's own trial below may settle it alone."), '']
            lines += [f'- {e}: no trial can settle it against the base coefficients; '
                      f'instead: {m}' for e, m in a.get('not_settled_by_a_trial', {}).items()]
            lines += [''] if a.get('not_settled_by_a_trial') else []
        lines += ['| about | trial | separation / resolution | recorded trials |',
                  '|---|---|---|---|']
        for a in doc['advice']:
            rec = a.get('separation_recorded')
            lines.append(f"| {a['about']} ({a['kind']}) | {a['instruction']}"
                         + ('' if a.get('settles', True) or a.get('degenerate')
                            or a.get('kind') == 'joint' else
                            ' — *no trial of the repertoire reaches 1 and clearly beats the '
                            'recorded ones: degenerate for these manoeuvres*')
                         + f" | {a['separation']:.3g} | "
                         + f"{'—' if rec is None else f'{rec:.3g}'} |")
    lines += ['', '## Residuals of the tuned base model (test trials)', '',
              '| trial | position rms [m] | psi rms [deg] | u rms [m/s] | v rms [m/s] | '
              'r rms [deg/s] |', '|---|---|---|---|---|---|']
    for n, t in doc['residuals']['base_model']['per_trial'].items():
        if 'psi' not in t:  # the simulation failed at once
            lines.append(f'| {display_name(n)} | diverged | | | | |')
            continue
        lines.append(f"| {display_name(n)} | {t['position_rms_m']:.2f} | {t['psi']['rms']:.2f} | "
                     f"{t['u']['rms']:.3f} | {t['v']['rms']:.3f} | {t['r']['rms']:.3f} |")
    lines += ['', 'Correlation of velocity residuals (base model) with:', '',
              '| regressor | u | v | r |', '|---|---|---|---|']
    for k, c in doc['residuals']['base_model']['correlation'].items():
        lines.append(f"| {k} | {c['u']:+.2f} | {c['v']:+.2f} | {c['r']:+.2f} |")
    lines += ['', '## What remains', '']
    for n, t in doc['residuals']['final_model']['per_trial'].items():
        if 'psi' not in t:
            lines.append(f'- {display_name(n)}: the simulation diverged at once')
            continue
        lines.append(f"- {display_name(n)}: position rms {t['position_rms_m']:.2f} m, heading "
                     f"rms {t['psi']['rms']:.2f} deg")
    lines.append('')
    lines.append('The remaining error is what no effect in the library explains: sensor noise, '
                 'the start-state estimate, and the difference between the sampled commands and '
                 'what acted between samples.')
    if doc.get('timings_s'):
        lines += ['', 'Time per stage: ' + ', '.join(f'{k} {v:.1f} s'
                                                     for k, v in doc['timings_s'].items())
                  + f" (total {doc.get('wall_s', 0.0):.0f} s)."]
    return '\n'.join(lines) + '\n'


def _listed(items: list[dict[str, Any]] | None, header: str,
            line: Callable[[dict[str, Any]], str]) -> list[str]:
    """
    Return a headed list of effects the diagnosis did not name, or [] when there are none.

    One layout for the undecided, the suspected and the impossible ones: a blank line, the
    header paragraph, a blank line and a ``- `` line per effect.
    """
    if not items:
        return []
    return ['', header, '', *(f'- {line(x)}' for x in items)]


def _decision_lines(doc: dict[str, Any]) -> list[str]:
    """Return the verdict's evidence per fitted effect (diagnosis.json's ``decision``)."""
    rows = doc.get('decision') or []
    if not rows:
        return []
    out = ['', '## Evidence per effect', '',
           'Each effect of the fitted model: the held-out error lost without it (fraction of '
           "the base model's, jackknife error over held-out trials), the factor by which the "
           'held-out trials lose without it (geometric mean, with its standard error), its '
           'share of what the model explains, and how much its value fitted on each trial '
           'alone scatters (fraction of its size; a physical effect has one value). Named: a '
           'factor above two standard errors from 1, a scatter of at most 0.5, and no evidence '
           "against it: verdict 'hull' when the hull's linear derivatives re-tuned without it "
           'explain the trials better and it adds nothing beside them.', '',
           '| effect | contribution | ± | factor | ± | share | scatter | trials | verdict | '
           'why |', '|---|---|---|---|---|---|---|---|---|---|']
    for e in rows:
        disp = '-' if e.get('dispersion') is None else f"{e['dispersion']:.2f}"
        out.append(f"| {e['effect']} | {_pct(e['contribution'])} | {_pct(e['contribution_se'])}"
                   f" | {_factor(e['log_ratio'])} | {_factor(e['log_ratio_se'])} | "
                   f"{_pct(e['share'])} | {disp} | {e['trials_used']} | {e['verdict']} | "
                   f"{e['why']} |")
    return out


def _factor(log_x: float | None) -> str:
    return '-' if log_x is None or not math.isfinite(log_x) else f'{math.exp(log_x):.2f}'


def _pct(x: float | None) -> str:
    """Return a fraction as a percentage; never 'nan %' (None and NaN: '—')."""
    if x is None or not np.isfinite(x):
        return 'inf' if x is not None and x > 0 else '—'
    return f'{100 * x:.1f} %'


def _J(m: dict[str, Any]) -> str:
    """Return a model's held-out J, or where it diverged."""
    return m['diverged'] if m.get('diverged') else _fmt_J(m['J_test'])


def _fmt_J(x: float | None) -> str:
    """J for text; never 'nan'."""
    return '—' if x is None or np.isnan(x) else fmt_J(x)


def residuals_for(ship: ShipConfig, params: dict[str, float], trials: list[Trial],
                  integrator: str) -> tuple[dict[str, Any], list[np.ndarray]]:
    p = ship.with_params(params).params
    sims = simulate_trials(ship, p, trials, integrator)
    return summarize(trials, sims), sims


def plot_residuals(trials: list[Trial], sims_base: list[np.ndarray],
                   sims_final: list[np.ndarray]) -> dict[str, bytes]:
    """Residuals over time (with the rudder beside them) and against heading; {name: PNG}."""
    from matplotlib.figure import Figure

    images = {}
    fig = Figure(figsize=(10, 10.5), layout='constrained')
    axes = fig.subplots(5, 1, sharex=True)
    # the steering input beside the residuals: the rudder, or a craft's first measured angle
    # (a tug's port azimuth)
    steer = 'rudder' if 'rudder' in trials[0].inputs else next(
        (c for c in trials[0].inputs if c in CHANNELS and CHANNELS[c].unit == 'rad'
         and c not in commanded_channels()), None)
    steer_label = (INPUT_AXES['rudder'] if steer == 'rudder' else '' if steer is None else
                   f'{steer} [deg,\n{CHANNELS[steer].description.split(", ")[-1]}]')
    for tr, label, sb in zip(trials, unique_names(trials), sims_base):
        e = residual_series(tr, sb)
        t = tr.t - tr.t[0]
        line, = axes[0].plot(t, np.hypot(e[:, 0], e[:, 1]), lw=1, label=label)
        axes[1].plot(t, np.degrees(e[:, 2]), lw=1)
        axes[2].plot(t, e[:, 4], lw=1)
        axes[3].plot(t, np.degrees(e[:, 5]), lw=1)
        if steer in tr.inputs:
            axes[4].plot(t, np.degrees(tr[steer]), lw=1, color=line.get_color())
    for a, lab in zip(axes, ('position error [m,\ndistance sim. to rec.]',
                             'heading error [deg,\n+ sim. more clockwise]',
                             'v error [m/s,\n+ sim. more to starboard]',
                             'r error [deg/s,\n+ sim. turns more to stbd]',
                             'recorded ' + steer_label)):
        a.set_ylabel(lab, fontsize=8)
        a.grid(alpha=0.3)
    axes[0].legend(fontsize=7, title='held-out trial', title_fontsize=7)
    axes[0].set_title('Residuals of the tuned base model on the held-out trials '
                      '(simulated - recorded)')
    axes[-1].set_xlabel('t [s from the trial start]')
    images['residuals_time.png'] = png_bytes(fig)

    fig = Figure(figsize=(11, 4.2), layout='constrained')
    axes = fig.subplots(1, 2)
    for label, sims, c in (('base model (tuned)', sims_base, 'tab:orange'),
                           ('final model (with the named effects)', sims_final, 'tab:blue')):
        hdg, ev, er = [], [], []
        for tr, s in zip(trials, sims):
            e = residual_series(tr, s)
            hdg.append(np.degrees(tr['psi']) % 360)
            ev.append(e[:, 4])
            er.append(np.degrees(e[:, 5]))
        axes[0].scatter(np.concatenate(hdg), np.concatenate(ev), s=2, c=c, label=label)
        axes[1].scatter(np.concatenate(hdg), np.concatenate(er), s=2, c=c, label=label)
    axes[0].set_ylabel('v error [m/s, simulated - recorded, + to starboard]', fontsize=8)
    axes[1].set_ylabel('r error [deg/s, simulated - recorded, + to starboard]', fontsize=8)
    for a in axes:
        a.set_xlabel('recorded heading psi [deg, clockwise from north]')
        a.set_xticks(range(0, 361, 45))
        a.grid(alpha=0.3)
        a.legend(fontsize=7, markerscale=4)
    fig.suptitle('Residuals vs heading on the held-out trials (a current or wind shows as a '
                 'sinusoid)')
    images['residuals_vs_heading.png'] = png_bytes(fig)
    return images
