"""
Reader for the SIMMAN 2008 / MARIN free-running ``.dat`` files (KVLCC2, full scale).

Format (see data/kvlcc2_simman2008_marin/README.md): 2 title lines, a blank line, then 11
tab-separated columns: time [s], x0, y0 [m], phi [deg], psi [deg], u, v [m/s EARTH-fixed],
p, r [deg/s], delta [deg, + to PORT], rev [rpm]. Only 3 significant digits: time is rebuilt as
index x 0.13533 s, the model's 0.02 s sample scaled to full scale.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, TYPE_CHECKING

from mmg_tuner.core import frames
from mmg_tuner.data.files import check_regular_file
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import TrialDataError
import numpy as np

if TYPE_CHECKING:   # annotations only: the comparison imports the simulation when it runs
    from mmg_tuner.core.ship import ShipConfig

MAX_DAT_BYTES = 256 << 20  # the SIMMAN files are ~200 kB each
MARIN_DT_S = 0.13533  # 0.02 s model scale x sqrt(45.714)


def read_marin_dat(path: str | Path) -> Trial:
    """
    Read one MARIN .dat file into a full-scale Trial in the MMG frame.

    (rudder sign flipped, earth-fixed velocities turned into body velocities).
    """
    path = Path(path)
    check_regular_file(path, 'MARIN .dat file', MAX_DAT_BYTES)
    try:
        a = np.loadtxt(path, skiprows=3, ndmin=2)
    except (OSError, ValueError) as exc:
        raise TrialDataError(f'{path}: not a MARIN .dat file ({exc})') from None
    if a.shape[1] != 11 or a.shape[0] < 2:
        raise TrialDataError(f'{path}: expected 11 columns and at least 2 rows, got {a.shape}')
    t = np.arange(a.shape[0]) * MARIN_DT_S
    psi = frames.unwrap(np.radians(a[:, 4]))
    ue, ve = a[:, 5], a[:, 6]
    c, s = np.cos(psi), np.sin(psi)
    states = np.column_stack([a[:, 1], a[:, 2], psi, ue * c + ve * s, -ue * s + ve * c,
                              np.radians(a[:, 8])])
    controls = np.column_stack([a[:, 10], -np.radians(a[:, 9])])
    return Trial(t, states, controls, name=path.stem, source=str(path),
                 notes=['MARIN .dat: time rebuilt as index x 0.13533 s; rudder sign flipped to '
                        'MMG (+ starboard); earth-fixed u, v rotated into the body frame'])


MARIN_FILES = {
    'turn_port_35': 'MARIN_FREE_KVLCC2_tc_35_m.dat',
    'turn_starboard_35': 'MARIN_FREE_KVLCC2_tc_-35_m.dat',
    'zigzag_10_port_first': 'MARIN_FREE_KVLCC2_zz_10_m.dat',
    'zigzag_10_starboard_first': 'MARIN_FREE_KVLCC2_zz_-10_m.dat',
    'zigzag_20_port_first': 'MARIN_FREE_KVLCC2_zz_20_m.dat',
    'zigzag_20_starboard_first': 'MARIN_FREE_KVLCC2_zz_-20_m.dat',
}


def marin_data_dir() -> Path:
    """Return the MARIN KVLCC2 data shipped in the repository (data/kvlcc2_simman2008_marin)."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        cand = parent / 'data' / 'kvlcc2_simman2008_marin'
        if cand.is_dir():
            return cand
        cand = parent / 'share' / 'mmg_tuner' / 'data' / 'kvlcc2_simman2008_marin'
        if cand.is_dir():
            return cand
    raise TrialDataError('MARIN KVLCC2 data not found (data/kvlcc2_simman2008_marin)')


def compare_with_marin(ship: ShipConfig, rpm_mode: str = 'hold_speed',
                       data_dir: Path | None = None, dt: float = 0.05) -> list[dict[str, Any]]:
    """
    Simulate each MARIN manoeuvre and put its indices beside the measured ones.

    Simulate each MARIN manoeuvre with the ship (model scale) and put its indices beside the
    measured ones. rpm_mode: 'hold_speed' (the rpm holding the recorded approach speed) or
    'recorded' (the recorded rpm, Froude-scaled). Lengths in L_pp, angles in degrees.
    """
    from mmg_tuner.core import indices as ix
    from mmg_tuner.core import maneuvers as mv
    from mmg_tuner.core.simulate import self_propulsion_rpm

    data_dir = marin_data_dir() if data_dir is None else Path(data_dir)
    L = ship.L_pp
    rows: list[dict[str, Any]] = []
    for key, fname in MARIN_FILES.items():
        trial = read_marin_dat(data_dir / fname).froude_scaled(ship.scale_ratio)
        ke = ix.execution_index(trial['rudder'])
        u0 = float(trial['u'][ke])
        rec_rpm = float(trial['rpm'].mean())
        rpm = self_propulsion_rpm(ship, u0) if rpm_mode == 'hold_speed' else rec_rpm
        first = trial['rudder'][ke:ke + 2000]
        moved = first - first[0]
        sign = 1.0 if moved[np.argmax(np.abs(moved) > math.radians(1.0))] > 0 else -1.0
        # nominal 10, 20 or 35 deg from the first rudder order once the gear has reached it
        amp = sign * round(math.degrees(float(np.percentile(np.abs(first), 90))) / 5.0) * 5.0
        row: dict[str, Any] = {'manoeuvre': key, 'file': fname, 'approach_speed_ms': u0,
                               'rpm': rpm, 'recorded_rpm': rec_rpm}
        if key.startswith('turn'):
            meas = ix.turning_indices(trial['x'], trial['y'], trial['psi'], ke)
            spec = mv.ManeuverSpec('turning', rudder_deg=amp, rpm=rpm, speed_ms=u0,
                                   duration_s=300.0, dt=dt)
            sim = mv.run(ship, spec)
            si = ix.turning_indices(sim['x'], sim['y'], sim['psi'])
            row.update({'measured': meas.in_lengths(L), 'simulated': si.in_lengths(L)})
        else:
            check = math.radians(abs(amp))
            zmeas = ix.zigzag_indices(trial['psi'], trial['rudder'], check, ke)
            spec = mv.ManeuverSpec('zigzag', rudder_deg=amp, rpm=rpm, speed_ms=u0,
                                   duration_s=200.0, dt=dt)
            sim = mv.run(ship, spec)
            zsim = ix.zigzag_indices(sim['psi'], sim['rudder'], check)
            row.update({'measured': {'overshoot_1_deg': zmeas.first_overshoot_deg,
                                     'overshoot_2_deg': zmeas.second_overshoot_deg},
                        'simulated': {'overshoot_1_deg': zsim.first_overshoot_deg,
                                      'overshoot_2_deg': zsim.second_overshoot_deg}})
        rows.append(row)
    return rows
