"""diagnosis.json, diagnosis.md and the plots a naval architect would look at."""
from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np

from mmg_tuner.core.effects import EFFECTS, describe_values
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis.residuals import residual_series, simulate_trials, summarize
from mmg_tuner.diagnosis.select import Diagnosis


def to_dict(d: Diagnosis, residuals_base: dict, residuals_final: dict) -> dict:
    causes = []
    for c in d.causes:
        cc = dict(c)
        cc['summary'] = describe_values(EFFECTS[c['effect']], c['parameters'], c['uncertainty'])
        causes.append(cc)
    return {'causes': causes, 'baseline': d.baseline, 'final': d.final,
            'candidates': [[asdict(c) for c in r] for r in d.rounds],
            'residuals': {'base_model': residuals_base, 'final_model': residuals_final},
            'barely_identifiable': d.aliased, 'params': d.params, 'wall_s': d.wall_s}


def markdown(doc: dict, ship: ShipConfig) -> str:
    b, f = doc['baseline'], doc['final']
    lines = [f'# Diagnosis: {ship.name}', '']
    if doc['causes']:
        lines.append('**What was wrong, and why:**')
        lines.append('')
        for c in doc['causes']:
            lines.append(f"- **{c['effect']}** — {c['summary']}. Held-out gain "
                         f"{100 * c['heldout_gain']:.1f} % ± {100 * c['heldout_gain_se']:.1f} "
                         f"(jackknife over test trials). {c['description'].capitalize()}."
                         + (f" These trials cannot tell it apart from "
                            f"{', '.join(c['indistinguishable_from'])} (held-out gains within "
                            "their combined uncertainty)." if c.get('indistinguishable_from')
                            else ''))
    else:
        lines.append('**No effect in the library explains the errors significantly.** The '
                     'tuned base model is the best description of these trials.')
    lines += ['', '| held-out J (test trials) | value |', '|---|---|',
              f"| base model, tuned | {b['J_test']:.4g} |",
              f"| final model | {f['J_test']:.4g} |",
              f"| gain | {100 * f['heldout_gain_total']:.1f} % |", '',
              '## Candidates', '', '| round | effect | held-out gain | ± | named | note |',
              '|---|---|---|---|---|---|']
    for i, r in enumerate(doc['candidates'], 1):
        for c in r:
            note = ', '.join(f'{p} on its bound' for p in c.get('on_bound', []))
            lines.append(f"| {i} | {c['effect']} | {100 * c['gain']:.1f} % | "
                         f"{100 * c['gain_se']:.1f} | {'yes' if c['accepted'] else ''} | "
                         f"{note} |")
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
                         f"{100 * a['r2']:.2f} % | {', '.join(a['mimicked_by'])} |")
    lines += ['', '## Residuals of the tuned base model (test trials)', '',
              '| trial | position rms [m] | psi rms [deg] | u rms [m/s] | v rms [m/s] | '
              'r rms [deg/s] |', '|---|---|---|---|---|---|']
    for n, t in doc['residuals']['base_model']['per_trial'].items():
        lines.append(f"| {n} | {t['position_rms_m']:.2f} | {t['psi']['rms']:.2f} | "
                     f"{t['u']['rms']:.3f} | {t['v']['rms']:.3f} | {t['r']['rms']:.3f} |")
    lines += ['', 'Correlation of velocity residuals (base model) with:', '',
              '| regressor | u | v | r |', '|---|---|---|---|']
    for k, c in doc['residuals']['base_model']['correlation'].items():
        lines.append(f"| {k} | {c['u']:+.2f} | {c['v']:+.2f} | {c['r']:+.2f} |")
    lines += ['', '## What remains', '']
    for n, t in doc['residuals']['final_model']['per_trial'].items():
        lines.append(f"- {n}: position rms {t['position_rms_m']:.2f} m, heading rms "
                     f"{t['psi']['rms']:.2f} deg")
    lines.append('')
    lines.append('The remaining error is what no effect in the library explains: sensor noise, '
                 'the start-state estimate, and the difference between the sampled commands and '
                 'what acted between samples.')
    return '\n'.join(lines) + '\n'


def residuals_for(ship: ShipConfig, params: dict[str, float], trials: list[Trial],
                  integrator: str) -> tuple[dict, list[np.ndarray]]:
    p = ship.with_params(params).params
    sims = simulate_trials(ship, p, trials, integrator)
    return summarize(trials, sims), sims


def plot_residuals(out: Path, trials: list[Trial], sims_base: list[np.ndarray],
                   sims_final: list[np.ndarray]) -> list[Path]:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    paths = []
    fig, axes = plt.subplots(4, 1, figsize=(10, 9), sharex=True)
    for tr, sb in zip(trials, sims_base):
        e = residual_series(tr, sb)
        t = tr.t - tr.t[0]
        axes[0].plot(t, np.hypot(e[:, 0], e[:, 1]), lw=1, label=tr.name)
        axes[1].plot(t, np.degrees(e[:, 2]), lw=1)
        axes[2].plot(t, e[:, 4], lw=1)
        axes[3].plot(t, np.degrees(e[:, 5]), lw=1)
    for a, lab in zip(axes, ('position error [m]', 'heading error [deg]', 'v error [m/s]',
                             'r error [deg/s]')):
        a.set_ylabel(lab, fontsize=8)
        a.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    axes[0].set_title('Residuals of the tuned base model (simulated - recorded)')
    axes[-1].set_xlabel('t [s]')
    fig.tight_layout()
    paths.append(out / 'residuals_time.png')
    fig.savefig(paths[-1], dpi=90)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for label, sims, c in (('base model', sims_base, 'tab:orange'),
                           ('final model', sims_final, 'tab:blue')):
        hdg, ev, er = [], [], []
        for tr, s in zip(trials, sims):
            e = residual_series(tr, s)
            hdg.append(np.degrees(tr['psi']) % 360)
            ev.append(e[:, 4])
            er.append(np.degrees(e[:, 5]))
        axes[0].scatter(np.concatenate(hdg), np.concatenate(ev), s=2, c=c, label=label)
        axes[1].scatter(np.concatenate(hdg), np.concatenate(er), s=2, c=c, label=label)
    axes[0].set_ylabel('v error [m/s]')
    axes[1].set_ylabel('r error [deg/s]')
    for a in axes:
        a.set_xlabel('heading [deg]')
        a.grid(alpha=0.3)
        a.legend(fontsize=7)
    fig.suptitle('Residuals vs heading (a current or wind shows as a sinusoid)')
    fig.tight_layout()
    paths.append(out / 'residuals_vs_heading.png')
    fig.savefig(paths[-1], dpi=90)
    plt.close(fig)
    return paths

