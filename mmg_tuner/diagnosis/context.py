"""
Where the data was taken, and which effects are physically possible there.

A diagnosis names the effect that best explains held-out trials; but an effect that cannot
exist where the trials were run (a wind indoors, a current in a towing tank, a GNSS antenna
offset when the positions are already those of a reference point) fits only because it mimics
something the model lacks. Such effects are still screened and fitted, never named: the report
lists them as "would fit, but impossible here" with their gain, as evidence of a structural gap.

The setting comes from, in this order: the caller (``DiagnoseConfig.setting``, ``diagnose
--setting``), the ship YAML's optional ``setting:`` key, and what the trials' readers recorded
(MARIN's .dat files are towing-tank runs with positions of a reference point; FRT-DS-ESSO
pond runs carry midship positions). Unknown parts stay 'unknown' and forbid nothing.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import DiagnosisError

# sea: open water (wind, current, waves); pond: outdoor still water (wind; a wind-driven drift
# is possible, so current is not ruled out); basin: indoor manoeuvring basin; tank: indoor
# towing tank (still air, still water)
VENUES = ('sea', 'pond', 'basin', 'tank', 'unknown')
# antenna: positions recorded at a GNSS antenna (wherever it sits); reference: positions of the
# ship's reference point (midship, CoG or a tracking target moved there by the data provider)
POSITIONS = ('antenna', 'reference', 'unknown')


@dataclass(frozen=True)
class Setting:
    """
    Where and how the trials were recorded.

    venue: one of VENUES; position: one of POSITIONS; scale: 'model' or 'full' (from the ship's
    scale_ratio: a model has scale_ratio > 1); source: who declared it (for the report).
    """

    venue: str = 'unknown'
    position: str = 'unknown'
    scale: str = 'full'
    source: str = 'default'

    def __post_init__(self) -> None:
        if self.venue not in VENUES:
            raise DiagnosisError(f'setting venue {self.venue!r}: must be one of {list(VENUES)}')
        if self.position not in POSITIONS:
            raise DiagnosisError(f'setting position {self.position!r}: must be one of '
                                 f'{list(POSITIONS)}')
        if self.scale not in ('model', 'full'):
            raise DiagnosisError(f"setting scale {self.scale!r}: must be 'model' or 'full'")

    @classmethod
    def parse(cls, value: object, source: str = 'given') -> 'Setting | None':
        """
        Return a Setting from a Setting, None, a string or a mapping.

        A Setting from a Setting, None, 'tank' / 'tank,reference' / 'sea,antenna', or a mapping
        {venue:, position:} (the ship YAML's ``setting:`` key).
        """
        if value is None or isinstance(value, Setting):
            return value
        if isinstance(value, str):
            parts = [p.strip() for p in value.split(',') if p.strip()]
            kw: dict[str, str] = {}
            for p in parts:
                if p in VENUES:
                    kw['venue'] = p
                elif p in POSITIONS:
                    kw['position'] = p
                else:
                    raise DiagnosisError(
                        f'setting {value!r}: {p!r} is neither a venue {list(VENUES)} nor a '
                        f'position {list(POSITIONS)} (e.g. "tank,reference")')
            return cls(**kw, source=source)
        if isinstance(value, Mapping):
            extra = set(value) - {'venue', 'position'}
            if extra:
                raise DiagnosisError(f'setting {dict(value)!r}: unknown key(s) {sorted(extra)}; '
                                     'use venue and position')
            return cls(str(value.get('venue', 'unknown')), str(value.get('position', 'unknown')),
                       source=source)
        raise DiagnosisError(f'setting {value!r}: give a venue name such as "tank" or '
                             '"sea,antenna", or a mapping with venue and position')

    def describe(self) -> str:
        where = {'sea': 'at sea', 'pond': 'in an outdoor pond', 'basin': 'in an indoor basin',
                 'tank': 'in a towing tank', 'unknown': 'in an undeclared setting'}[self.venue]
        pos = {'antenna': 'positions at a GNSS antenna',
               'reference': "positions of the ship's reference point",
               'unknown': 'position reference undeclared'}[self.position]
        return f'{self.scale}-scale trials {where}, {pos} (declared by {self.source})'


def _from_trials(trials: Sequence[Trial]) -> dict[str, str]:
    """Return what the readers recorded about where the trials come from."""
    if trials and all(any(n.startswith('MARIN .dat') for n in t.notes) for t in trials):
        return {'venue': 'tank', 'position': 'reference'}
    if trials and all(any('FRT-DS-ESSO' in n for n in t.notes) for t in trials):
        return {'venue': 'pond', 'position': 'reference'}
    return {}


def resolve(ship: ShipConfig, trials: Sequence[Trial], given: object = None) -> Setting:
    """
    Return the setting of a diagnosis.

    The caller's, else the ship YAML's ``setting:``, else what the trials' readers recorded; each
    part (venue, position) filled from the next source when the earlier one leaves it unknown. The
    scale always follows ship.scale_ratio.
    """
    scale = 'model' if ship.scale_ratio > 1.0 else 'full'
    s = Setting.parse(given, 'the caller') or Setting(source='default')
    yaml_s = Setting.parse(ship.extra.get('setting'), f'{ship.source or ship.name} (setting:)') \
        if ship.extra.get('setting') is not None else None
    read = _from_trials(trials)
    venue, position, src = s.venue, s.position, [s.source] if s.source != 'default' else []
    for other, name in ((yaml_s, yaml_s.source if yaml_s else ''),
                        (Setting(**read, source='the trial files') if read else None,
                         'the trial files')):
        if other is None:
            continue
        used = False
        if venue == 'unknown' and other.venue != 'unknown':
            venue, used = other.venue, True
        if position == 'unknown' and other.position != 'unknown':
            position, used = other.position, True
        if used:
            src.append(name)
    return replace(s, venue=venue, position=position, scale=scale,
                   source=' and '.join(src) or 'default')


def impossible_effects(setting: Setting) -> dict[str, str]:
    """
    {effect name: why it cannot exist in this setting}.

    Measured signals follow the same rule as the effect they measure.
    """
    out = {}
    if setting.venue in ('tank', 'basin'):
        out['wind'] = f'no wind indoors ({setting.venue})'
        out['current'] = f'still water in a {setting.venue}: no current'
    if setting.position == 'reference':
        out['antenna_offset'] = ("positions are already those of the ship's reference point, "
                                 'not of an antenna')
    return out
