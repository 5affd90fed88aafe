"""diagnosis.json, diagnosis.md and the plots a naval architect would look at (returned as
text and PNG bytes; the caller writes them)."""
from __future__ import annotations

from dataclasses import asdict

import numpy as np

from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.diagnosis.residuals import residual_series, simulate_trials, summarize
from mmg_tuner.diagnosis.select import Diagnosis
from mmg_tuner.tuning.report import display_name, fmt_J, fmt_gain, png_bytes, unique_names


def to_dict(d: Diagnosis, residuals_base: dict, residuals_final: dict) -> dict:
    causes = [c.to_dict() for c in d.causes]
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
              f"| base model, tuned | {fmt_J(b['J_test'])} |",
              f"| final model | {fmt_J(f['J_test'])} |",
              f"| gain | {fmt_gain(b['J_test'], f['J_test'])} |", '',
              '## Candidates', '', '| round | effect | held-out gain | ± | named | note |',
              '|---|---|---|---|---|---|']
    for i, r in enumerate(doc['candidates'], 1):
        for c in r:
            note = ', '.join(f'{p} on its bound' for p in c.get('on_bound', []))
            lines.append(f"| {i} | {c['effect']} | {_pct(c['gain'])} | "
                         f"{_pct(c['gain_se'])} | {'yes' if c['accepted'] else ''} | "
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
                         f"{_pct(a['r2'])} | {', '.join(a['mimicked_by'])} |")
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
    return '\n'.join(lines) + '\n'


def _pct(x: float) -> str:
    return f'{100 * x:.1f} %' if np.isfinite(x) else ('inf' if x > 0 else '—')


def residuals_for(ship: ShipConfig, params: dict[str, float], trials: list[Trial],
                  integrator: str) -> tuple[dict, list[np.ndarray]]:
    p = ship.with_params(params).params
    sims = simulate_trials(ship, p, trials, integrator)
    return summarize(trials, sims), sims


def plot_residuals(trials: list[Trial], sims_base: list[np.ndarray],
                   sims_final: list[np.ndarray]) -> dict[str, bytes]:
    """Residuals over time and against heading; {file name: PNG bytes}."""
    from matplotlib.figure import Figure

    images = {}
    fig = Figure(figsize=(10, 9))
    axes = fig.subplots(4, 1, sharex=True)
    for tr, label, sb in zip(trials, unique_names(trials), sims_base):
        e = residual_series(tr, sb)
        t = tr.t - tr.t[0]
        axes[0].plot(t, np.hypot(e[:, 0], e[:, 1]), lw=1, label=label)
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
    images['residuals_time.png'] = png_bytes(fig)

    fig = Figure(figsize=(11, 4))
    axes = fig.subplots(1, 2)
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
    images['residuals_vs_heading.png'] = png_bytes(fig)
    return images
