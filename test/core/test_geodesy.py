"""core/geodesy.py: WGS84 <-> local ENU about a datum (pymap3d underneath), no ROS."""
import math

from mmg_tuner.core.geodesy import Datum, datum_from_fixes, enu_to_geodetic, geodetic_to_enu
from mmg_tuner.errors import ConfigError, TrialDataError
import numpy as np
import pytest


def test_geodesy_round_trip_and_scale():
    d = Datum(35.5, 139.8, 10.0)
    e = np.array([0.0, 1000.0, -2500.0, 40_000.0, np.nan])
    n = np.array([0.0, 2000.0, 300.0, -70_000.0, 1.0])
    u = np.array([0.0, 0.0, 5.0, 0.0, 0.0])
    lat, lon, alt = enu_to_geodetic(e, n, u, d)
    assert lat.shape == lon.shape == alt.shape == (5,)
    assert lat[0] == pytest.approx(35.5) and lon[0] == pytest.approx(139.8)
    assert alt[0] == pytest.approx(10.0)
    assert np.isnan(lat[4]) and np.isnan(lon[4])  # a missing point stays missing
    e2, n2, u2 = geodetic_to_enu(lat, lon, alt, d)
    np.testing.assert_allclose(e2[:4], e[:4], atol=1e-6)
    np.testing.assert_allclose(n2[:4], n[:4], atol=1e-6)
    np.testing.assert_allclose(u2[:4], u[:4], atol=1e-6)
    # north is +latitude, east is +longitude; a degree of latitude is ~110.9 km here (WGS84
    # meridian arc at 35.5 deg), a degree of longitude ~90.8 km: not a sphere, not swapped
    e1, n1, _ = geodetic_to_enu(36.5, 139.8, 10.0, d)
    assert abs(float(e1)) < 1e-3 and float(n1) == pytest.approx(110_955, rel=2e-3)
    e1, n1, _ = geodetic_to_enu(35.5, 140.8, 10.0, d)
    assert float(e1) == pytest.approx(90_770, rel=2e-3) and abs(float(n1)) < 1_000


def test_geodesy_refuses_what_is_no_position():
    for bad in ((91.0, 0.0, 0.0), (0.0, 181.0, 0.0), (math.nan, 0.0, 0.0), (0.0, 0.0, 1e9)):
        with pytest.raises(ConfigError, match='datum'):
            Datum(*bad)
    with pytest.raises(TrialDataError, match='latitude 95'):
        geodetic_to_enu(np.array([35.0, 95.0]), np.array([139.0, 139.0]), 0.0,
                        Datum(35.0, 139.0))
    assert datum_from_fixes([np.nan, 35.2, 35.3], [139.0, 139.1, 139.2], [0, 3.0, 4.0]) == \
        Datum(35.2, 139.1, 3.0)
    with pytest.raises(TrialDataError, match='/fix'):
        datum_from_fixes([np.nan], [1.0], [0.0], source='/fix')
