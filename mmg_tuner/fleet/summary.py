"""
The fleet summary: fleet.json, fleet.md and fleet.png in OUT/.

Which ships have which causes, the held-out gains of the tuned and of the diagnosed models,
the ships whose model drifts over time (``trend_parameter`` fitted per trial date; a rising
resistance R_0 is hull fouling), and every failure with its stage and reason. Ships skipped
as up to date are summarised from their records, so the summary always covers the fleet.
"""
from __future__ import annotations

import math
from typing import Any, cast, TYPE_CHECKING

from mmg_tuner._outdir import OutputDir
from mmg_tuner.fleet.manifest import Manifest
from mmg_tuner.tuning.report import json_text, png_bytes

if TYPE_CHECKING:   # annotations only: graph imports this module when it writes
    from mmg_tuner.fleet.graph import FleetResult


def _pct(x: float | None) -> str:
    return '—' if x is None or not math.isfinite(x) else f'{100 * x:.1f} %'


def fleet_doc(manifest: Manifest, result: FleetResult) -> dict[str, Any]:
    ships: dict[str, dict[str, Any]] = {}
    causes: dict[str, list[str]] = {}
    drifting: list[str] = []
    failed: dict[str, str] = {}
    for job in manifest.ships:
        o = result.ships.get(job.name)
        if o is None:
            continue
        rec = o.record
        entry = {'status': o.status, 'ship': job.ship, 'finished': rec.finished,
                 'wall_s': rec.wall_s}
        if rec.status == 'failed':
            failure = cast('dict[str, str]', rec.failure)   # (a failed record has its failure)
            entry['failure'] = {k: failure[k] for k in ('stage', 'reason')}
            failed[job.name] = f"{failure['stage']}: {failure['reason']}"
        else:
            s = rec.summary or {}
            tu, dg, tr = s.get('tune'), s.get('diagnose'), s.get('trend')
            entry['heldout_gain'] = {'tune': tu and tu.get('heldout_gain'),
                                     'diagnose': dg and dg.get('heldout_gain')}
            entry['causes'] = [c['summary'] for c in dg['causes']] + [
                f"undecided: one of {u['summary']} or {', '.join(u['indistinguishable_from'])}"
                for u in dg.get('undecided', [])] if dg else None
            for c in (dg or {}).get('causes', []):
                causes.setdefault(c['effect'], []).append(job.name)
            if tr:
                entry['trend'] = tr
                if tr['drifts']:
                    drifting.append(job.name)
        ships[job.name] = entry
    counts = {k: sum(1 for e in ships.values() if e['status'] == k)
              for k in ('done', 'skipped', 'failed')}
    return {'ships': ships, 'causes': causes, 'drifting': drifting, 'failed': failed,
            'counts': counts, 'wall_s': result.wall_s}


def markdown(doc: dict[str, Any]) -> str:
    c = doc['counts']
    lines = ['# Fleet summary', '',
             f"{len(doc['ships'])} ship(s): {c['done']} run, {c['skipped']} up to date "
             f"(skipped), {c['failed']} failed; {doc['wall_s']:.0f} s.", '',
             '| ship | status | causes | held-out gain, tuned | held-out gain, diagnosed | '
             'over time |', '|---|---|---|---|---|---|']
    for name, e in doc['ships'].items():
        if e['status'] == 'failed' or 'failure' in e:
            lines.append(f"| {name} | failed | {e['failure']['stage']}: "
                         f"{e['failure']['reason'].replace('|', '/')} | | | |")
            continue
        g = e.get('heldout_gain', {})
        causes = e.get('causes')
        tr = e.get('trend')
        trend = '' if not tr else (
            f"{tr['parameter']} {tr['direction']} {100 * tr['relative_change']:+.1f} % over "
            f"{len(tr['groups'])} dates" + (' **drifts**' if tr['drifts'] else ''))
        lines.append(f"| {name} | {e['status']} | "
                     f"{'; '.join(causes) if causes else ('none' if causes == [] else '—')} | "
                     f"{_pct(g.get('tune'))} | {_pct(g.get('diagnose'))} | {trend} |")
    lines += ['', '## Causes', '']
    lines += [f'- **{eff}**: {", ".join(names)}' for eff, names in sorted(doc['causes'].items())]
    if not doc['causes']:
        lines.append('- none named')
    if doc['drifting']:
        lines += ['', '## Models that drift over time', '']
        for n in doc['drifting']:
            tr = doc['ships'][n]['trend']
            lines.append(f"- {n}: {tr['parameter']} " + ', '.join(
                f"{g['date']} {g['value']:.4g}" for g in tr['groups']))
    if doc['failed']:
        lines += ['', '## Failures', '']
        lines += [f'- {n}: {r}' for n, r in doc['failed'].items()]
    lines += ['', 'Per ship: OUT/<ship>/tune/ (as `tune` writes it), OUT/<ship>/diagnose/ (as '
              '`diagnose` writes it), evaluation.json, fleet_ship.json.', '']
    return '\n'.join(lines)


def figure(doc: dict[str, Any]) -> bytes:
    """
    Draw the fleet figure: causes, held-out gains and drift per date.

    Causes per ship (left), held-out gains (middle), the drift parameter per date (right, when
    trials carry dates).
    """
    from matplotlib.figure import Figure
    names = list(doc['ships'])
    effects = sorted(doc['causes'])
    trends = {n: e['trend'] for n, e in doc['ships'].items() if e.get('trend')}
    ncol = 3 if trends else 2
    h = max(3.0, 0.35 * len(names) + 1.5)
    fig = Figure(figsize=(5 * ncol, h), layout='constrained')
    ax = fig.add_subplot(1, ncol, 1)
    y = range(len(names))
    for j, eff in enumerate(effects):
        ys = [i for i, n in enumerate(names) if n in doc['causes'][eff]]
        ax.scatter([j] * len(ys), ys, s=80, marker='s')
    for i, n in enumerate(names):
        if doc['ships'][n]['status'] == 'failed':
            ax.text(0, i, 'failed', color='red', va='center')
    ax.set_yticks(list(y), names)
    ax.set_xticks(range(len(effects)), effects, rotation=30, ha='right')
    ax.set_xlim(-0.5, max(len(effects), 1) - 0.5)
    ax.set_ylim(len(names) - 0.5, -0.5)
    ax.set_xlabel('effect named by diagnose')
    ax.set_title('named causes (a square: named for that ship)')
    ax = fig.add_subplot(1, ncol, 2)
    for k, (key, label) in enumerate((('tune', 'tuned'), ('diagnose', 'diagnosed'))):
        vals: list[Any] = [(doc['ships'][n].get('heldout_gain') or {}).get(key) for n in names]
        vals = [100 * v if v is not None and math.isfinite(v) else 0.0 for v in vals]
        ax.barh([i + 0.2 * (2 * k - 1) for i in y], vals, height=0.4, label=label)
    ax.set_yticks(list(y), names)
    ax.set_ylim(len(names) - 0.5, -0.5)
    ax.set_xlabel('held-out gain [%, + = J on held-out trials lower than before]')
    ax.axvline(0, color='k', lw=0.5)
    ax.legend(loc='lower right')
    ax.set_title('held-out gains (tuned vs pre-determined; diagnosed vs tuned)')
    if trends:
        import datetime as _dt
        ax = fig.add_subplot(1, ncol, 3)
        for n, tr in trends.items():
            d = [_dt.date.fromisoformat(g['date']) for g in tr['groups']]
            # (matplotlib plots dates through its units registry; its stubs take numbers)
            ax.plot(d, [g['value'] for g in tr['groups']], 'o-',  # type: ignore[arg-type]
                    label=n + (' (drifts)' if tr['drifts'] else ''))
        ax.set_ylabel(', '.join(sorted({tr['parameter'] for tr in trends.values()}))
                      + ' (fitted, model units)')
        ax.set_xlabel('trial date')
        ax.set_title('fitted per trial date')
        ax.legend()
        fig.autofmt_xdate()
    return png_bytes(fig)


def write_summary(od: OutputDir, manifest: Manifest, result: FleetResult) -> dict[str, Any]:
    """fleet.md, fleet.png, and fleet.json last."""
    doc = fleet_doc(manifest, result)
    od.write_text('fleet.md', markdown(doc))
    od.write_bytes('fleet.png', figure(doc))
    od.write_text('fleet.json', json_text(doc))
    return doc
