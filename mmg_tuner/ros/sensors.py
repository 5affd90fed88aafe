"""
Simulated GNSS (sensor_msgs/NavSatFix) and IMU (sensor_msgs/Imu) of the simulated ship.

Sampled on *simulated* time at their own rates: the node steps the simulation exactly to each
sample's time (:meth:`SimulatedSensors.steps_to_next`), so stamps and values do not depend on
the wall clock or the real-time factor. Noise is Gaussian, seeded (``noise_seed``): a run is
reproducible. Nothing here runs when both rates are 0 (the default).
"""
from __future__ import annotations

from typing import Any, Callable, Mapping, TYPE_CHECKING

from mmg_tuner.core.geodesy import Datum, enu_to_geodetic
from mmg_tuner.ros.conversions import imu_from_state, navsat_fix
import numpy as np

if TYPE_CHECKING:   # annotations only
    from mmg_tuner.core.stepper import ShipSimulator

_NEVER = 1 << 62


class _Channel:
    """
    One sensor's schedule.

    Sample k at simulated time k / rate, rounded to the nearest step of dt (the exact rate holds on
    average); at most one sample per step.
    """

    def __init__(self, rate_hz: float, dt: float, publish: Callable[[Any], None]) -> None:
        self.rate_hz = rate_hz
        self.publish = publish
        self.restart(0, dt)

    def restart(self, step: int, dt: float) -> None:
        self.dt = dt
        self.origin = step  # simulation step of sample 0
        self.k = 0
        self.next_step = step

    def advance(self) -> None:
        self.k += 1
        self.next_step = max(self.next_step + 1,
                             self.origin + int(round(self.k / (self.rate_hz * self.dt))))


class SimulatedSensors:
    """
    The node's sensor channels; ``sample_due`` publishes the samples due at the current step.

    params: the node's parameter dict (read at each sample, so noise and datum changes apply
    to the next sample); publishers: 'gnss' and 'imu' -> publish callables or None (off).
    """

    def __init__(self, params: dict[str, Any], dt: float,
                 publishers: Mapping[str, Callable[[Any], None] | None], frame_id: str) -> None:
        self.p = params
        self.frame_id = frame_id
        self.rng = np.random.default_rng(params['noise_seed'])
        self.datum = datum_from_params(params)
        self._fix = None
        self._imu = None
        self._prev_imu: tuple[float, float, float] | None = None  # t, u, v at the last sample
        self.channels: dict[str, _Channel] = {}
        for name, rate_key in (('gnss', 'gnss_rate_hz'), ('imu', 'imu_rate_hz')):
            pub = publishers.get(name)
            if pub is not None and params[rate_key] > 0:
                self.channels[name] = _Channel(params[rate_key], dt, pub)
        self.active = bool(self.channels)

    def reseed(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def restart(self, step: int, dt: float) -> None:
        """Note the simulation restarted (reset, new ship or dt): samples from ``step`` on."""
        self._prev_imu = None
        for ch in self.channels.values():
            ch.restart(step, dt)

    def steps_to_next(self, step: int) -> int:
        """Step from ``step`` to the next sample (at least 1)."""
        nxt = min((ch.next_step for ch in self.channels.values()), default=_NEVER)
        return max(1, nxt - step)

    def sample_due(self, sim: ShipSimulator, stamp0: float) -> None:
        """
        Publish every sample due at the simulator's current step.

        (message stamp: stamp0 + simulated time [s]).
        """
        step = sim.steps
        state = None
        for name, ch in self.channels.items():
            if ch.next_step <= step:
                if state is None:
                    state = sim.observed()
                t = stamp0 + sim.t
                ch.publish(self._gnss(state, t) if name == 'gnss' else self._imu_msg(state, t))
                ch.advance()

    def _gnss(self, state: np.ndarray, t: float) -> Any:   # a NavSatFix (messages are Any)
        p = self.p
        sh, sv = p['gnss_noise_m'], p['gnss_alt_noise_m']
        dn, de, du = self.rng.standard_normal(3)
        # map ENU: east = model y, north = model x (the observed antenna position)
        lat, lon, alt = enu_to_geodetic(float(state[1]) + sh * de, float(state[0]) + sh * dn,
                                        sv * du, self.datum)
        self._fix = navsat_fix(float(lat), float(lon), float(alt), t, self.frame_id, sh, sv,
                               self._fix)
        return self._fix

    def _imu_msg(self, state: np.ndarray, t: float) -> Any:   # an Imu
        p = self.p
        s_yaw, s_gyro, s_acc = p['imu_yaw_noise_rad'], p['imu_gyro_noise_rad_s'], \
            p['imu_accel_noise_m_s2']
        n_yaw, n_gyro, n_ax, n_ay = self.rng.standard_normal(4)
        u, v, r = float(state[3]), float(state[4]), float(state[5])
        accel = None
        if self._prev_imu is not None and t > self._prev_imu[0]:
            # mean specific force over the last sample interval (what an integrating IMU
            # reports): body-frame rate of change of the velocity plus the rotation term,
            # MMG axes (x forward, y starboard): a_x = du/dt - v r, a_y = dv/dt + u r
            t0, u0, v0 = self._prev_imu
            h = t - t0
            um, vm = 0.5 * (u + u0), 0.5 * (v + v0)
            ax = (u - u0) / h - vm * r
            ay = (v - v0) / h + um * r
            accel = (ax + s_acc * n_ax, -ay + s_acc * n_ay)  # FLU: y to port
        self._prev_imu = (t, u, v)
        self._imu = imu_from_state(state, accel, t, self.frame_id, s_yaw * n_yaw,
                                   s_gyro * n_gyro, (s_yaw, s_gyro, s_acc), self._imu)
        return self._imu


def datum_from_params(p: Mapping[str, Any]) -> Datum:
    """Return the GNSS datum of the node's parameters (a ConfigError names the bad one)."""
    return Datum(p['datum_lat_deg'], p['datum_lon_deg'], p['datum_alt_m'])
