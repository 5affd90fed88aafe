"""
Geodetic (WGS84 latitude, longitude, ellipsoidal height) <-> a local tangent plane.

A thin wrapper over pymap3d (a maintained, pure-Python geodesy library) so that the rest of the
package never does ellipsoid maths by hand. The local frame is ENU at a datum: x east,
y north, z up [m] -- the ROS ``map`` frame of REP-103/105 (see doc/conventions.md).

Examples
--------
>>> d = Datum(35.5, 139.8, 0.0)
>>> e, n, u = geodetic_to_enu(lat, lon, alt, d)          # numpy arrays, metres
>>> lat2, lon2, alt2 = enu_to_geodetic(e, n, u, d)       # back, degrees and metres

"""
from __future__ import annotations

from dataclasses import dataclass
import math

from mmg_tuner.errors import ConfigError, TrialDataError
import numpy as np
import numpy.typing as npt
import pymap3d

WGS84 = pymap3d.Ellipsoid.from_name('wgs84')
ALT_MAX_M = 1.0e5  # |altitude| beyond 100 km is no ship's GNSS fix


@dataclass(frozen=True)
class Datum:
    """
    Origin of a local ENU frame.

    WGS84 latitude and longitude [deg] and ellipsoidal height [m] (what sensor_msgs/NavSatFix
    carries). Refused when not finite or out of range.
    """

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0

    def __post_init__(self) -> None:
        for name, v, lim in (('lat_deg', self.lat_deg, 90.0), ('lon_deg', self.lon_deg, 180.0),
                             ('alt_m', self.alt_m, ALT_MAX_M)):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
                raise ConfigError(f'datum {name} = {v!r} must be a number')
            if not (math.isfinite(v) and abs(v) <= lim):
                raise ConfigError(f'datum {name} = {v!r} is outside [{-lim:g}, {lim:g}]')


def datum_from_fixes(lat_deg: npt.ArrayLike, lon_deg: npt.ArrayLike, alt_m: npt.ArrayLike,
                     source: str = 'fixes') -> Datum:
    """
    Return the first fix whose three values are finite, as a datum (a recording's default origin).

    Source names the topic or file for the error when there is none.
    """
    lat, lon, alt = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (lat_deg, lon_deg, alt_m))
    ok = np.flatnonzero(np.isfinite(lat) & np.isfinite(lon) & np.isfinite(alt))
    if ok.size == 0:
        raise TrialDataError(f'{source}: no fix with finite latitude, longitude and altitude')
    i = ok[0]
    return Datum(float(lat[i]), float(lon[i]), float(alt[i]))


def _check_latlon(lat: np.ndarray, lon: np.ndarray) -> None:
    # NaN passes (a missing fix stays missing); a finite value out of range is corrupt data
    with np.errstate(invalid='ignore'):
        bad = (np.abs(lat) > 90.0) | (np.abs(lon) > 360.0)
    if np.any(bad):
        i = int(np.flatnonzero(bad.ravel())[0])
        raise TrialDataError(f'latitude {lat.ravel()[i]:g} / longitude {lon.ravel()[i]:g} deg '
                             f'(sample {i}) is outside [-90, 90] / [-360, 360]')


def geodetic_to_enu(lat_deg: npt.ArrayLike, lon_deg: npt.ArrayLike, alt_m: npt.ArrayLike,
                    datum: Datum
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    East, north, up [m] of WGS84 points about ``datum``.

    Vectorised (numpy broadcasting), NaN in gives NaN out. Returns float arrays of the broadcast
    shape (0-d for scalars).
    """
    lat, lon, alt = np.broadcast_arrays(*(np.asarray(a, dtype=float)
                                          for a in (lat_deg, lon_deg, alt_m)))
    _check_latlon(lat, lon)
    e, n, u = pymap3d.geodetic2enu(lat, lon, alt, datum.lat_deg, datum.lon_deg, datum.alt_m,
                                   ell=WGS84, deg=True)
    return np.asarray(e, dtype=float), np.asarray(n, dtype=float), np.asarray(u, dtype=float)


def enu_to_geodetic(e_m: npt.ArrayLike, n_m: npt.ArrayLike, u_m: npt.ArrayLike, datum: Datum
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    WGS84 latitude, longitude [deg] and ellipsoidal height [m] of ENU points about ``datum``.

    Vectorised like :func:`geodetic_to_enu`, whose inverse it is.
    """
    e, n, u = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (e_m, n_m, u_m)))
    lat, lon, alt = pymap3d.enu2geodetic(e, n, u, datum.lat_deg, datum.lon_deg, datum.alt_m,
                                         ell=WGS84, deg=True)
    lon = (np.asarray(lon, dtype=float) + 180.0) % 360.0 - 180.0  # one branch: [-180, 180)
    return np.asarray(lat, dtype=float), lon, np.asarray(alt, dtype=float)
