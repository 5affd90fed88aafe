"""
Advice: the trial that would settle what these trials cannot.

For two causes reported as indistinguishable, two rival models explain the recorded trials
about equally well. Each feasible trial of the manoeuvre repertoire (zigzags of several angles,
turning circles and pull-outs at several rpm, rpm steps up and down, a slower rudder; all
within the ship's rudder limit and steering-gear rate) is run with the first model; its
recorded commands then drive both models, and the predicted separation of their outputs is
measured against the sensor noise:

    separation = sqrt(mean_k (|dp_k| / sigma_pos)^2 + (dpsi_k / sigma_psi)^2)

(dp: position difference, dpsi: heading difference, per sample; sigma: what the tuned model
cannot explain on the recorded trials, its RMS residual, or the sensor noise of
:class:`~mmg_tuner.data.generate.SensorNoise` when larger). So a separation of 1 means the
rivals differ by as much as the model already misses; the same measure on the best recorded
trial says how much the advised one adds. Residuals along a trajectory are correlated: read
it as a ranking, not a probability. The trial with the largest separation is advised, as an
instruction a crew can follow and as a :class:`TrialSpec` that
``generate --from-advice DIR/diagnosis.json`` runs. When no trial of the repertoire separates
the rivals clearly better than the recorded ones (by SETTLES x) and by at least the error
the model already leaves (separation >= MIN_SEPARATION), the advice says so:
the two are then degenerate for every manoeuvre, and only fixing one of them from another
source separates them.

A barely identifiable effect is judged by the expected information
(:func:`advise_information`): a trial the base targets can mimic once it is tuned on settles
nothing, however far the rival fitted without it strays on it. So each trial of the
repertoire is sailed by the model linearised where the flag was raised (base optimum, every
single-parameter effect at its smallest magnitude worth finding), its Jacobian joins the tuning
trials' (Gauss-Newton information adds over trials), and the effect's standard error with the
base targets free is recomputed. Its figure, reported as the separation, is the resolution

    smallest magnitude worth finding / (2 x standard error)

which is below 1 exactly when the effect is flagged barely identifiable: a trial reaching 1
would lift the flag.

An effect whose best resolution stays below DEGENERATE_BELOW is degenerate with the base
targets for every manoeuvre of the repertoire: its advice says so and quotes the independent
measurement that settles it (the effect library's ``settle_by``). rpm_scale is the clear case:
n -> k n is reproduced exactly by 1 - w_P -> (1 - w_P) / k, 1 - t_P -> k^2 (1 - t_P) and
epsilon -> k epsilon; only the propeller side force and moment (scaling with n^2), the drift
shape of the wake and the u_R** floor differ (tested). When that measurement fixes base
coefficients (``Effect.pinned_by``; rpm_scale: R_0, t_P, w_P0 from resistance and
self-propulsion tests), the advice gives the re-run: those held at the measured values
(``--params``), the run's other targets tuned (``--targets``), and the resolution the recorded
trials (and the best trial) reach with them held, from the same linearisation.

A suspected effect (one the held-out trials hint at but disagree on; select.suspected_effects)
comes as a rival pair of kind 'suspected': the model without it against the model with it.
When no trial of the repertoire separates them by MIN_SEPARATION, its advice is the effect's
own measurement (``settle_by``, marked degenerate: no trial is sailed
for it, and the joint trial does not serve it): a rudder offset beside a wind bent to take its
share is told apart by the rudder indicator against the blade, not by a manoeuvre.

A crew sails one trial, and the diagnosis does not know which suspect is real: when two or
more things can be settled by a trial (rival pairs, and flagged effects that are not
degenerate), :func:`advise_all` puts first the one trial chosen for all of them jointly
(:func:`joint_choice`: most settled, then most information added to all; each effect judged
with the other such suspects free too, as the trial must tell them apart from each other),
then the per-pair and per-effect advice.

Every advised trial is to be sailed twice, once to each side (:func:`mirrored`; the ``pair``
spec): one goes to the tuning trials, the other is held out. The diagnosis names an effect
only on its held-out gain, so a trial that only the tuning set contains can make an effect
identifiable but never give the evidence to name it.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
import math
from types import ModuleType
from typing import Any, Callable, cast, Sequence, TYPE_CHECKING

from mmg_tuner.core.effects import EFFECTS
from mmg_tuner.core.layout import EFFECT_NEUTRAL
from mmg_tuner.core.maneuvers import steered
from mmg_tuner.core.noise import Sigmas
from mmg_tuner.core.ship import ShipConfig
from mmg_tuner.core.simulate import simulate_batch
from mmg_tuner.data.generate import SensorNoise, trial_kit
from mmg_tuner.data.trial import Trial
from mmg_tuner.errors import DiagnosisError, SimulationError
from mmg_tuner.tuning.identifiability import jacobian
from mmg_tuner.tuning.objective import Objective, TrialBatch
from mmg_tuner.tuning.parameters import ParameterSpace
import numpy as np

if TYPE_CHECKING:   # annotations only: load_advice imports it where a file is read
    from pathlib import Path

SPEC_VERSION = 1
MIN_SEPARATION = 1.0   # ... and by at least the unexplained error: below it the rivals'
#                        difference drowns in what the model misses anyway
SETTLES = 1.5   # an advised trial must separate the rivals this many times better than the
#                 best recorded one to be worth sailing
DEGENERATE_BELOW = 0.5   # an effect whose best resolution with one trial stays below this is
#   degenerate with the base targets for the repertoire: resolution grows as the square root
#   of the information, so reaching 1 would take more than 4x the best trial's information (4
#   sailings of it, each mimicked in the same way) -- no trial plan, a measurement settles it


@dataclass(frozen=True)
class TrialSpec:
    """
    A trial a crew can run (angles in degrees, as trials are specified).

    maneuver: 'zigzag', 'turning' or 'pullout'; rudder_deg: zigzag amplitude or turning /
    pull-out rudder (sign: first rudder direction, + starboard); check_deg: zigzag heading check
    angle; rpm: propeller speed [rev/min] from the start; rpm_after / step_at_s: an rpm step to
    rpm_after at step_at_s [s] (None: no step); rudder_rate_deg_s: steering-gear rate [deg/s];
    duration_s: recording length [s]; speed_ms: approach speed [m/s]; approach_s: straight run
    before the rudder is executed [s]; pullout_s: how long a pull-out holds the rudder [s].
    """

    maneuver: str
    rudder_deg: float
    rpm: float
    duration_s: float
    speed_ms: float
    rudder_rate_deg_s: float
    check_deg: float | None = None
    rpm_after: float | None = None
    step_at_s: float | None = None
    approach_s: float = 10.0
    pullout_s: float = 60.0

    def __post_init__(self) -> None:
        if self.maneuver not in ('zigzag', 'turning', 'pullout'):
            raise DiagnosisError(f'advice spec: maneuver {self.maneuver!r} must be zigzag, '
                                 'turning or pullout')
        for k in ('rudder_deg', 'rpm', 'duration_s', 'speed_ms', 'rudder_rate_deg_s',
                  'approach_s', 'pullout_s'):
            v = getattr(self, k)
            if not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise DiagnosisError(f'advice spec: {k} = {v!r} must be a finite number')
        if self.rpm <= 0 or self.duration_s <= 0 or self.speed_ms <= 0 \
                or self.rudder_rate_deg_s <= 0 or abs(self.rudder_deg) > 90:
            raise DiagnosisError(f'advice spec {self}: rpm, duration, speed and rudder rate '
                                 'must be > 0 and |rudder| <= 90 deg')
        if (self.rpm_after is None) != (self.step_at_s is None):
            raise DiagnosisError('advice spec: rpm_after and step_at_s go together')
        # (step_at_s is not None with rpm_after, as just checked)
        if self.rpm_after is not None and not (self.rpm_after > 0
                                               and 0 < cast(float, self.step_at_s)
                                               < self.duration_s):
            raise DiagnosisError(f'advice spec: rpm step to {self.rpm_after} at '
                                 f'{self.step_at_s} s must be > 0 rpm inside the trial')

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> 'TrialSpec':
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise DiagnosisError(f'advice spec: unknown field(s) {sorted(unknown)}')
        try:
            return cls(**d)
        except TypeError as exc:
            raise DiagnosisError(f'advice spec: {exc}') from None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @property
    def name(self) -> str:
        a = f'{self.rudder_deg:+g}'
        base = {'zigzag': f'zigzag{a}_{self.check_deg or abs(self.rudder_deg):g}',
                'turning': f'turning{a}', 'pullout': f'pullout{a}'}[self.maneuver]
        step = f'_to{self.rpm_after:.0f}' if self.rpm_after is not None else ''
        return f'advice_{base}_{self.rpm:.0f}rpm{step}'

    def instruction(self) -> str:
        """
        E.g.

        '20°/20° zigzag (starboard first) at 80 rpm, then step to 110 rpm at 200 s'.
        """
        side = 'starboard' if self.rudder_deg > 0 else 'port'
        a = abs(self.rudder_deg)
        if self.maneuver == 'zigzag':
            what = f'{a:g}°/{(self.check_deg or a):g}° zigzag ({side} first)'
        elif self.maneuver == 'turning':
            what = f'turning circle, {a:g}° rudder to {side}'
        else:
            what = f'pull-out: {a:g}° rudder to {side} for {self.pullout_s:.0f} s, then amidships'
        text = f'{what} at {self.rpm:.0f} rpm'
        if self.rpm_after is not None:
            text += f', then step to {self.rpm_after:.0f} rpm at {self.step_at_s:.0f} s'
        return (text + f'; approach at {self.speed_ms:.2f} m/s, rudder at '
                f'{self.rudder_rate_deg_s:.1f}°/s, record {self.duration_s:.0f} s')


@dataclass(frozen=True)
class CatalogueSpec:
    """
    A manoeuvre of the craft's own trial catalogue, by name (its actuator's ``TRIALS``).

    For a craft not steered by a screw and rudder (a twin-azimuth tug, a water-jet) the
    repertoire is what its actuator declares it sails (``catalogue(ship)``; the protocol in
    ``core/actuators/__init__.py``). catalogue: the manoeuvre's name; mirror: sailed to the
    other side (the catalogue module's optional ``mirror(ship, maneuver)``); duration_s: its
    length [s]; kind: what it is (for the instruction); mirrorable: the catalogue can mirror it
    (else its held-out twin is the same manoeuvre sailed again).
    """

    catalogue: str
    duration_s: float
    kind: str = ''
    mirror: bool = False
    mirrorable: bool = False

    @property
    def name(self) -> str:
        return f"advice_{self.catalogue}{'_mirrored' if self.mirror else ''}"

    def instruction(self) -> str:
        """E.g. 'zigzag_p20deg_5rps of the craft's trial catalogue (zigzag), record 100 s'."""
        side = ', to the other side' if self.mirror else ''
        kind = f' ({self.kind})' if self.kind else ''
        return (f"{self.catalogue} of the craft's trial catalogue{kind}{side}; record "
                f'{self.duration_s:.0f} s')

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def maneuver(self, ship: ShipConfig) -> tuple[ModuleType, Any]:
        """Return (the catalogue module, the manoeuvre to sail); DiagnosisError if absent."""
        kit = trial_kit(ship)
        found = [m for m in (kit.catalogue(ship) if kit is not None else ())
                 if m.name == self.catalogue]
        if kit is None or not found:
            raise DiagnosisError(f'advice spec: {self.catalogue!r} is no manoeuvre of the trial '
                                 f"catalogue of {ship.name}'s actuators")
        m = found[0]
        if self.mirror:
            mirror = getattr(kit, 'mirror', None)
            m = mirror(ship, m) if mirror is not None else None
            if m is None:
                raise DiagnosisError(f'advice spec: the trial catalogue of {ship.name} cannot '
                                     f'mirror {self.catalogue}')
        return kit, m


Spec = TrialSpec | CatalogueSpec
"""A trial the advice can name: a screw-and-rudder manoeuvre or a catalogue one."""


def spec_from_dict(d: dict[str, Any]) -> Spec:
    """Return the spec a diagnosis.json entry describes (either kind)."""
    if isinstance(d, dict) and 'catalogue' in d:
        known = {f.name for f in fields(CatalogueSpec)}
        if set(d) - known:
            raise DiagnosisError(f'advice spec: unknown field(s) {sorted(set(d) - known)}')
        try:
            return CatalogueSpec(**d)
        except TypeError as exc:
            raise DiagnosisError(f'advice spec: {exc}') from None
    return TrialSpec.from_dict(d)


def sail(ship: ShipConfig, spec: Spec, dt: float) -> tuple[Trial | None, str]:
    """
    Return the trial ``ship`` sails for ``spec`` without noise (None and why when it stops).

    Sampled at dt; a screw-and-rudder manoeuvre by :func:`run_spec`, a catalogue one by the
    catalogue's ``generate``.
    """
    if isinstance(spec, CatalogueSpec):
        kit, m = spec.maneuver(ship)
        try:
            truth, _ = kit.generate(ship, m, 1.0 / dt, kit.Noise(), 0)
        except SimulationError as exc:
            return None, str(exc)
        return truth, ''
    t, states, controls, why = run_spec(ship, spec, dt)
    return (None if why else Trial(t, states, controls, name=spec.name)), why


def replay_inputs(ship: ShipConfig, trial: Trial) -> np.ndarray:
    """Return the recorded inputs that drive ``ship``'s simulation of ``trial`` (T, n)."""
    return np.ascontiguousarray(trial.input_array(ship.family.inputs))


def run_spec(ship: ShipConfig, spec: TrialSpec, dt: float
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """
    Return the manoeuvre of spec by ship (all its effects acting), RK4 at <= 0.1 s.

    (t (T,), observed states (T, 6), recorded controls (T, 2) rpm and actual rudder, status (''
    when it completed, else why it stopped)).
    """
    T = int(round(spec.duration_s / dt)) + 1
    t = np.arange(T) * dt
    rpm = np.full(T, float(spec.rpm))
    if spec.rpm_after is not None:   # a spec has step_at_s with rpm_after
        rpm[t >= cast(float, spec.step_at_s)] = spec.rpm_after
    orders = np.zeros(T)
    executed = t >= spec.approach_s
    amp = math.radians(spec.rudder_deg)
    zz_amp = zz_check = 0.0
    if spec.maneuver == 'turning':
        orders[executed] = amp
    elif spec.maneuver == 'pullout':
        orders[executed & (t < spec.approach_s + spec.pullout_s)] = amp
    else:
        zz_amp = amp
        zz_check = math.radians(abs(spec.check_deg if spec.check_deg is not None
                                    else spec.rudder_deg))
        orders[executed] = amp
    substeps = max(1, int(math.ceil(dt / 0.1)))
    x0 = np.array([0.0, 0.0, 0.0, spec.speed_ms, 0.0, 0.0])
    status, k_fail, out, rudder = steered(ship, x0, rpm, orders, zz_amp, zz_check,
                                          math.radians(spec.rudder_rate_deg_s), dt, substeps,
                                          'rk4', spec.name)
    why = '' if k_fail >= T else f'stopped at t = {t[min(k_fail, T - 1)]:.1f} s (status {status})'
    return t, out, np.column_stack([rpm, rudder]), why


def trial_from_spec(truth: ShipConfig, spec: Spec, rate_hz: float = 1.0,
                    noise: Any = None, seed: int = 0,
                    name: str | None = None) -> tuple[Trial, Trial]:
    """
    (truth, measured) trial of spec sailed by ``truth`` (its hidden effects acting).

    As ``generate`` records one: command topics stamped time_offset early, sensor noise added.
    """
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise DiagnosisError(f'rate_hz = {rate_hz}: must be a finite number > 0')
    if isinstance(spec, CatalogueSpec):   # the catalogue's own noise unless one is given
        kit, m = spec.maneuver(truth)
        try:
            tr, measured = kit.generate(truth, m, rate_hz, noise or kit.Noise(), seed)
        except SimulationError as exc:
            raise DiagnosisError(f'{name or spec.name}: the advised trial stopped: {exc}') \
                from None
        note = [f'generated from advice: {spec.instruction()}']
        a, b = (Trial(x.t, x.states, name=name or spec.name, inputs=x.inputs,
                      notes=x.notes + note) for x in (tr, measured))
        return a, b
    t, states, controls, why = run_spec(truth, spec, 1.0 / rate_hz)
    name = name or spec.name
    if why:
        raise DiagnosisError(f'{name}: the advised trial {why}')
    toff = truth['time_offset']
    if toff != 0.0:  # recorded(t) = actual(t + toff), as generate_trial does
        controls = np.column_stack([np.interp(t + toff, t, controls[:, i]) for i in range(2)])
    tr = Trial(t, states, controls, name=name,
               notes=[f'generated from advice: {spec.instruction()}'])
    noise = SensorNoise() if noise is None else noise
    return tr, noise.apply(tr, np.random.default_rng(seed + 1))


def specs_from_diagnosis(doc: dict[str, Any]) -> list[Spec]:
    """
    Return the advised trials of a diagnosis.json document (its 'advice' list), each once.

    In the document's order (the joint trial first), each followed by its twin; entries marked
    'degenerate' (no trial settles them) are skipped.
    """
    if not isinstance(doc, dict) or not isinstance(doc.get('advice'), list):
        raise DiagnosisError("no 'advice' list in the diagnosis document (a diagnosis.json of "
                             'this version, written by diagnose)')
    out: list[Spec] = []
    for i, a in enumerate(doc['advice']):
        if isinstance(a, dict) and a.get('degenerate'):
            continue   # no trial settles it: its best trial is a record, not advice
        if not isinstance(a, dict) or not isinstance(a.get('spec'), dict):
            raise DiagnosisError(f'advice[{i}]: no spec')
        if a.get('version', SPEC_VERSION) != SPEC_VERSION:
            raise DiagnosisError(f"advice[{i}]: spec version {a.get('version')} is not "
                                 f'{SPEC_VERSION}')
        spec = spec_from_dict(a['spec'])
        fresh = spec not in out
        if fresh:
            out.append(spec)
        if isinstance(a.get('pair'), dict):   # its twin: one run tuned on, one held out
            held_out = spec_from_dict(a['pair'])
            # one equal to its trial (no other side) is the same manoeuvre sailed again
            if held_out not in out or (fresh and held_out == spec):
                out.append(held_out)
    return out


# ------------------------------------------------------------------------------ repertoire
def repertoire(ship: ShipConfig, rpm0: float, speed0: float, duration_s: float
               ) -> list[Spec]:
    """
    Feasible trials around the recorded operating point (rpm0, speed0).

    A craft whose actuator declares its trial catalogue (``TRIALS``) sails that catalogue
    (:class:`CatalogueSpec`); a family with neither a catalogue nor a screw and rudder has
    no repertoire (no trial is advised). Else, for a screw and rudder:

    Zigzags of 10, 20 and the largest multiple of 5 deg within the rudder limit, turning circles
    and a pull-out, at 0.8, 1 and 1.2 x rpm0, rpm steps from 0.8 to 1.2 and from 1.2 to 0.5 x
    rpm0 half-way through a zigzag, and a zigzag with the gear at half its rate. Speeds follow
    the rpm (propeller law).
    """
    kit = trial_kit(ship)
    if kit is not None:
        mirror = getattr(kit, 'mirror', None)
        return [CatalogueSpec(m.name, float(m.duration_s), str(getattr(m, 'kind', '')),
                              mirrorable=mirror is not None and mirror(ship, m) is not None)
                for m in kit.catalogue(ship)]
    if not {'rpm', 'rudder'} <= set(ship.family.inputs):
        return []
    max_deg = math.degrees(ship.max_rudder_rad)
    rate = math.degrees(ship.rudder_rate_rad_s)
    big = min(35.0, 5.0 * math.floor(max_deg / 5.0))
    out: list[Spec] = []
    for f in (0.8, 1.0, 1.2):
        rpm, u = rpm0 * f, speed0 * f
        for a in sorted({10.0, 20.0, big}):
            if a <= max_deg:
                out.append(TrialSpec('zigzag', a, rpm, duration_s, u, rate, check_deg=a))
        out.append(TrialSpec('turning', big, rpm, duration_s, u, rate))
        out.append(TrialSpec('turning', -big, rpm, duration_s, u, rate))
    out.append(TrialSpec('pullout', min(20.0, big), rpm0, duration_s, speed0, rate,
                         pullout_s=min(120.0, duration_s / 3)))
    out.append(TrialSpec('zigzag', 20.0 if big >= 20 else big, 0.8 * rpm0, duration_s,
                         0.8 * speed0, rate, check_deg=20.0 if big >= 20 else big,
                         rpm_after=1.2 * rpm0, step_at_s=round(duration_s / 2)))
    out.append(TrialSpec('zigzag', 20.0 if big >= 20 else big, rpm0, duration_s, speed0,
                         rate / 2, check_deg=20.0 if big >= 20 else big))
    # a slow-down step to 0.5 x rpm0 (a large change of the advance ratio). Starts from a
    # quarter of the speed at 1.2 x rpm0 (small advance ratio, large drift at the propeller)
    # are left out: they rank first by information, yet their misfit of the base coefficients
    # is taken up by a current or wind in the screen (benchmark: 0/3 propeller side forces)
    out.append(TrialSpec('zigzag', 20.0 if big >= 20 else big, 1.2 * rpm0, duration_s,
                         1.2 * speed0, rate, check_deg=20.0 if big >= 20 else big,
                         rpm_after=0.5 * rpm0, step_at_s=round(duration_s / 2)))
    return out


def mirrored(spec: Spec) -> Spec:
    """
    Return the advised trial's held-out twin: spec to the other side.

    The rudder to the other side; a catalogue manoeuvre mirrored when its catalogue can
    (``mirror``), else the same manoeuvre sailed again.
    """
    if isinstance(spec, CatalogueSpec):
        return replace(spec, mirror=not spec.mirror) if spec.mirrorable else spec
    return replace(spec, rudder_deg=-spec.rudder_deg)


def separation(ship: ShipConfig, params_a: np.ndarray, params_b: np.ndarray,
               spec: Spec, dt: float, sigma_pos: float, sigma_psi: float) -> float:
    """
    Return the predicted separation of two parameter vectors on spec (see the module).

    0 when the manoeuvre cannot be run, inf when one model diverges on it.
    """
    sa = replace(ship, params=np.asarray(params_a, float))
    trial, why = sail(sa, spec, dt)
    if trial is None:
        return 0.0
    return _replay_separation(ship, params_a, params_b, trial.states,
                              replay_inputs(ship, trial), dt, sigma_pos, sigma_psi)


def _replay_separation(ship: ShipConfig, params_a: np.ndarray, params_b: np.ndarray,
                       states: np.ndarray, controls: np.ndarray, dt: float, sigma_pos: float,
                       sigma_psi: float, length: int | None = None) -> float:
    T = len(states) if length is None else length
    out, _, k_fail = simulate_batch(ship.kind, np.vstack([params_a, params_b]), states[None, 0],
                                    controls[None], dt, np.array([T]), 'rk4',
                                    max(1, int(math.ceil(dt / 0.1))))
    if np.any(k_fail[:, 0] < T):
        return math.inf
    d = out[0, 0, :T] - out[1, 0, :T]
    dpsi = (d[:, 2] + math.pi) % (2 * math.pi) - math.pi
    return float(math.sqrt(np.mean((d[:, 0] ** 2 + d[:, 1] ** 2) / sigma_pos ** 2
                                   + dpsi ** 2 / sigma_psi ** 2)))


def residual_scale(ship: ShipConfig, params: np.ndarray, trials: Sequence[Trial],
                   noise: Sigmas | None = None) -> tuple[float, float]:
    """
    (sigma_pos [m], sigma_psi [rad]).

    The RMS position and heading residual of params on trials (replayed from their first sample),
    or the sensor noise when larger.
    """
    if noise is None:   # the craft's sensors (its catalogue's), else a ship's
        kit = trial_kit(ship)
        noise = kit.Noise() if kit is not None else SensorNoise()
    e_pos, e_psi = [], []
    for t in trials:
        out, _, k_fail = simulate_batch(ship.kind, np.asarray(params)[None], t.states[None, 0],
                                        replay_inputs(ship, t)[None], t.dt, None, 'rk4',
                                        max(1, int(math.ceil(t.dt / 0.1))))
        k = int(k_fail[0, 0])
        d = out[0, 0, :k] - t.states[:k]
        e_pos.append(d[:, 0] ** 2 + d[:, 1] ** 2)
        e_psi.append(((d[:, 2] + math.pi) % (2 * math.pi) - math.pi) ** 2)
    pos = math.sqrt(float(np.mean(np.concatenate(e_pos)))) if e_pos else 0.0
    psi = math.sqrt(float(np.mean(np.concatenate(e_psi)))) if e_psi else 0.0
    return (max(pos, float(getattr(noise, 'position_m', 0.0)) / ship.scale_ratio, 1e-9),
            max(psi, float(getattr(noise, 'heading_rad', 0.0)), 1e-9))


def operating_point(trials: Sequence[Trial]) -> tuple[float, float, float, float]:
    """(median rpm (NaN: none recorded), median speed [m/s], median duration [s], dt [s])."""
    rpm = float(np.median([np.median(t.inputs['rpm']) if 'rpm' in t.inputs else math.nan
                           for t in trials]))
    # the speed the ship holds (trials that start near rest would otherwise say ~0)
    u = float(np.median([np.median(t.states[:, 3]) for t in trials]))
    dur = float(np.median([t.t[-1] - t.t[0] for t in trials]))
    return rpm, max(u, 1e-3), dur, float(trials[0].dt)


def _rival_figures(ship: ShipConfig, rivals: list[dict[str, Any]], trials: Sequence[Trial],
                   sigma: tuple[float, float], specs: Sequence[Spec], dt: float
                   ) -> list[_Item]:
    """Return each rival pair's predicted separation on every spec (0: cannot be run)."""
    sig_pos, sig_psi = sigma
    out = []
    for r in rivals:
        pa, pb = np.asarray(r['params_a'], float), np.asarray(r['params_b'], float)
        seps = np.array([separation(ship, pa, pb, s, dt, sig_pos, sig_psi) for s in specs])
        seps[~np.isfinite(seps)] = 0.0   # a model diverging on it: not a trial to advise
        recorded = max((_replay_separation(ship, pa, pb, t.states, replay_inputs(ship, t), t.dt,
                                           sig_pos, sig_psi)
                        for t in trials if abs(t.dt - dt) < 1e-9),
                       default=0.0)
        out.append(_Item(r['about'], r['kind'], seps,
                         recorded if math.isfinite(recorded) else None))
    return out


def advise(ship: ShipConfig, rivals: list[dict[str, Any]], trials: Sequence[Trial],
           sigma: tuple[float, float]) -> list[dict[str, Any]]:
    """
    Return, for each rival pair, the repertoire's trial that separates them best.

    For each rival pair {'about', 'kind', 'params_a', 'params_b'} the repertoire's trial that
    separates them best, against sigma = (position [m], heading [rad]) (see
    :func:`residual_scale`): {'about', 'kind', 'instruction', 'spec', 'separation',
    'separation_recorded' (the best recorded trial's; None when a rival diverges on one),
    'settles' (whether the trial separates them SETTLES x better than the recorded ones and by
    at least MIN_SEPARATION), 'runner_up', 'version'}.
    """
    rpm0, u0, dur, dt = operating_point(trials)
    specs = repertoire(ship, rpm0, u0, dur)
    items = _rival_figures(ship, rivals, trials, sigma, specs, dt)
    return [_rival_entry(it, specs) for it in items if np.any(it.figures > 0)]


def _rival_entry(it: _Item, specs: Sequence[Spec]) -> dict[str, Any]:
    order = np.argsort(-it.figures, kind='stable')
    spec, best = specs[order[0]], float(it.figures[order[0]])
    return {'about': it.about, 'kind': it.kind, 'instruction': _twice(spec),
            'spec': spec.to_dict(), 'pair': mirrored(spec).to_dict(), 'separation': best,
            'separation_recorded': it.recorded, 'settles': _settles(best, it.recorded),
            'runner_up': specs[order[1]].instruction()
            if len(order) > 1 and it.figures[order[1]] > 0 else '',
            'version': SPEC_VERSION}


def suspect_measurement(a: dict[str, Any]) -> dict[str, Any]:
    """
    Turn a suspected effect's rival entry into the measurement that settles it.

    For a suspected effect ('about': its name, kind 'suspected') that no trial separates by
    MIN_SEPARATION (when the recorded trials already do, the trial advice stands: their
    disagreement, not the manoeuvres, kept it unnamed): the model with it and the one without
    explain every manoeuvre of the repertoire about equally (a rudder offset beside a wind
    bent to take its share: 0.75 against 0.57 recorded), so the effect's own measurement (its
    ``settle_by``) decides.
    """
    settle_by = EFFECTS[a['about']].settle_by or 'fix it from a measurement outside these trials'
    rec = a['separation_recorded']
    return {**a, 'degenerate': True, 'settle_by': settle_by, 'measure': settle_by,
            'best_trial': a['instruction'],
            'instruction': ('no trial separates the model with it from the model without it '
                            f"(the best of the repertoire: {a['separation']:.2g}, the recorded "
                            f"trials {'-' if rec is None else f'{rec:.2g}'}; 1 and "
                            f'{SETTLES:g} x the recorded needed); instead: {settle_by}')}


def _twice(spec: Spec) -> str:
    sides = '' if spec == mirrored(spec) else ', once to each side'
    return (spec.instruction() + f'; sail it twice{sides} (one run for tuning, one held out)')


def _effect_se(jac: np.ndarray, s2: float, n_base: int, j: int, width: float,
               others: Sequence[int] = (), held: Sequence[int] = ()) -> float:
    """
    Return the standard error of parameter j (own units) with the n_base first ones free.

    As tuning.identifiability.aliasing: column j regressed on the base columns (and the columns
    ``others``, also free) by least squares on the Jacobian itself (the normal equations would
    square a condition number that aliasing makes large); only the part they cannot mimic is
    evidence. ``held``: base columns held fixed (known from a measurement), left out.
    """
    y = jac[:, j]
    a = jac[:, [k for k in range(n_base) if k not in held] + [k for k in others if k != j]]
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    rr = float(np.sum((y - a @ coef) ** 2))
    return float(math.sqrt(s2 / max(rr, 1e-300)) * width)


@dataclass
class _Item:
    """One thing to settle and its figure on every spec of the repertoire (0: not run)."""

    about: str
    kind: str
    figures: np.ndarray
    recorded: float | None


@dataclass
class _Information:
    """
    The Gauss-Newton geometry of the flag, with each repertoire trial added.

    r_rec: R factor of the tuning trials' Jacobian; r_with[i]: with spec i added (None: it
    cannot be run); columns: the base targets (``base_names``), then each probed effect (col).
    """

    specs: list[Spec]
    r_rec: np.ndarray
    r_with: list[np.ndarray | None]
    s2: float
    n_base: int
    col: dict[str, int]
    width: np.ndarray
    smallest: dict[str, float]
    base_names: tuple[str, ...] = ()

    def resolution(self, r: np.ndarray | None, e: str, others: Sequence[str] = (),
                   held: Sequence[str] = ()) -> float:
        """
        Return smallest / (2 SE) of effect e with the base targets (and others) free.

        held: base targets held at known values instead (a measurement pinned them).
        """
        if r is None:
            return 0.0
        j = self.col[e]
        se = _effect_se(r, self.s2, self.n_base, j, self.width[j],
                        [self.col[o] for o in others],
                        [k for k, n in enumerate(self.base_names) if n in held])
        return self.smallest[e] / max(2 * se, 1e-300)

    def item(self, e: str, others: Sequence[str] = ()) -> _Item:
        kind = 'barely identifiable' + (' (others free)' if others else '')
        return _Item(e, kind, np.array([self.resolution(r, e, others) for r in self.r_with]),
                     self.resolution(self.r_rec, e, others))


def _information(ship: ShipConfig, base: ParameterSpace, base_theta: np.ndarray,
                 obj: Objective, effects: Sequence[str], trials: Sequence[Trial],
                 specs: Sequence[Spec] | None = None) -> _Information:
    """
    Linearise where the flag is raised and add each repertoire trial (see the module).

    specs: the repertoire at the trials' operating point unless given.
    """
    names, lo, hi, pre, value = list(base.names), list(base.lower), list(base.upper), \
        list(base.pre), list(base_theta)
    smallest = {}
    for e in effects:
        p = EFFECTS[e].params[0]
        (a, b), = EFFECTS[e].bounds(ship)
        smallest[e] = EFFECTS[e].smallest_for(ship)[0]
        names.append(p)
        lo.append(a)
        hi.append(b)
        pre.append(min(max(EFFECT_NEUTRAL[p], a), b))
        value.append(min(max(EFFECT_NEUTRAL[p] + smallest[e], a), b))
    space = ParameterSpace(tuple(names), np.array(pre), np.array(lo), np.array(hi))
    theta = np.array(value)
    integ = {0: 'euler', 1: 'rk4'}[obj.method]
    jac, s2 = jacobian(obj, space, theta, 1e-3)
    # the recorded trials' Jacobian reduced to its R factor: the same least-squares geometry
    # (information adds over trials) in as many rows as parameters
    # (numpy's stub says a QRResult for every mode; mode='r' returns the R array)
    r_rec = cast(np.ndarray, np.linalg.qr(jac, mode='r'))
    sailer = replace(ship, params=space.full_params(ship.params, theta)[0])
    rpm0, u0, dur, dt = operating_point(trials)
    specs = list(repertoire(ship, rpm0, u0, dur) if specs is None else specs)
    r_with: list[np.ndarray | None] = []
    for spec in specs:
        sailed, _ = sail(sailer, spec, dt)
        if sailed is None or not np.all(np.isfinite(sailed.states)):
            r_with.append(None)
            continue
        o = Objective(ship, TrialBatch.from_trials([sailed]), obj.weights, 0.0, integ,
                      obj.substeps)
        jc, _ = jacobian(o, space, theta, 1e-3)
        r_with.append(cast(np.ndarray, np.linalg.qr(np.vstack([r_rec, jc]), mode='r')))
    n = base.dim
    return _Information(specs, r_rec, r_with, s2, n, {e: n + k for k, e in enumerate(effects)},
                        space.upper - space.lower, smallest, tuple(base.names))


def _information_entry(info: _Information, it: _Item) -> dict[str, Any]:
    """Return the advice entry of a barely identifiable effect (degenerate ones say so)."""
    e = it.about
    k = int(np.argmax(it.figures))
    # (an information item's recorded resolution is a number, never None)
    spec, res, rec = info.specs[k], float(it.figures[k]), float(cast(float, it.recorded))
    out = {'about': e, 'kind': it.kind, 'instruction': _twice(spec), 'spec': spec.to_dict(),
           'pair': mirrored(spec).to_dict(), 'separation': res, 'separation_recorded': rec,
           'settles': _settles(res, rec), 'se_with': info.smallest[e] / (2 * res),
           'se_recorded': info.smallest[e] / (2 * rec), 'smallest': info.smallest[e],
           'runner_up': '', 'version': SPEC_VERSION}
    if res < DEGENERATE_BELOW:
        settle_by = EFFECTS[e].settle_by or 'fix it from a measurement outside these trials'
        out.update(degenerate=True, settle_by=settle_by, best_trial=out['instruction'],
                   measure=settle_by + _pinned(info, it, out))
        out['instruction'] = (f'no trial can settle it (the best of the repertoire reaches '
                              f"resolution {res:.2g} of the 1 needed); instead: {out['measure']}")
    return out


def _pinned(info: _Information, it: _Item, out: dict[str, Any]) -> str:
    """
    Add what re-running with the measured coefficients held needs and gives; return its text.

    For an effect whose measurement fixes base targets of this run (``Effect.pinned_by``):
    'pinned_by' (those targets), 'targets_pinned' (this run's targets without them, for
    ``--targets``), 'resolution_pinned' (the recorded trials' resolution with them held, same
    linearisation) and 'resolution_pinned_trial' (the best repertoire trial's, also held).
    '' (nothing added) when the measurement pins none of this run's targets.
    """
    pins = [p for p in EFFECTS[it.about].pinned_by if p in info.base_names]
    if not pins:
        return ''
    rest = [n for n in info.base_names if n not in pins]
    rec = info.resolution(info.r_rec, it.about, held=pins)
    figs = [info.resolution(r, it.about, held=pins) for r in info.r_with]
    k = int(np.argmax(figs)) if figs else -1
    best = float(figs[k]) if figs else 0.0
    out.update(pinned_by=pins, targets_pinned=rest, resolution_pinned=rec,
               resolution_pinned_trial=best)
    held = ', '.join(pins)
    text = (f'; then re-run the diagnosis with {held} held at the measured values: --params '
            f'<params.yaml with {held} under params:> --targets '
            + (' '.join(rest) if rest else '<none left: every target was pinned>')
            + f' (or, better, with each measurement and its standard error: --measured '
            f'<file with {held} under measured:>, priors that leave the trials room)')
    if rec >= MIN_SEPARATION:
        return text + (f' (with them held exactly these trials resolve it: {rec:.2g}, 1 '
                       'needed; an error in the measured values lowers it)')
    if best >= DEGENERATE_BELOW:
        return text + (f' (with them held exactly these trials resolve it to {rec:.2g} of the 1 '
                       f'needed, with {_twice(info.specs[k])}: {best:.2g})')
    return text + (f' (even with them held exactly no trial resolves it: {max(rec, best):.2g} '
                   'of the 1 needed)')


def advise_information(ship: ShipConfig, base: ParameterSpace, base_theta: np.ndarray,
                       obj: Objective, effects: Sequence[str], trials: Sequence[Trial],
                       about: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """
    Return, for each barely identifiable single-parameter effect, the trial that resolves it best.

    Linearised where :func:`~mmg_tuner.diagnosis.select.diagnose` flags it (the base optimum of
    obj's tuning trials, every probed effect of ``effects`` at its smallest magnitude worth
    finding; the same s^2): each repertoire trial, sailed by that model without noise, adds its
    Gauss-Newton information to the tuning trials'; each effect of ``about`` (default: all)
    gets its standard error with the base targets free and the resolution smallest / (2 x SE)
    (see the module). Entries as :func:`advise`, with 'separation' the resolution with the
    trial, 'separation_recorded' without it, and 'se_with' / 'se_recorded' / 'smallest' in the
    parameter's units. An effect whose best resolution stays below DEGENERATE_BELOW is marked
    'degenerate': its 'instruction' says no trial settles it and quotes the effect library's
    ``settle_by`` (also a field; 'measure' adds the re-run when the measurement pins base
    targets: 'pinned_by', 'targets_pinned', 'resolution_pinned', 'resolution_pinned_trial'); the
    best trial stays in 'spec' and 'best_trial' as a record, and ``generate --from-advice``
    skips it.
    """
    effects = [e for e in effects if len(EFFECTS[e].params) == 1]
    about = [e for e in (effects if about is None else about) if e in effects]
    if not about:
        return []
    info = _information(ship, base, base_theta, obj, effects, trials)
    return [_information_entry(info, info.item(e)) for e in about
            if np.any(info.item(e).figures > 0)]


def advise_all(ship: ShipConfig, base: ParameterSpace, base_theta: np.ndarray,
               obj: Objective, effects: Sequence[str], trials: Sequence[Trial],
               about: Sequence[str], rivals: list[dict[str, Any]],
               sigma: tuple[float, float] | None = None,
               rank: Callable[[str], float] | None = None) -> list[dict[str, Any]]:
    """
    Return one trial for the whole diagnosis, then the advice per rival pair and per effect.

    ``about``: the barely identifiable effects (probed with every single-parameter effect of
    ``effects`` at its smallest, as :func:`advise_information`); ``rivals``: the rival pairs
    (as :func:`advise`, against sigma). When two or more things are to be settled by a trial
    (rival pairs, and flagged effects that are not degenerate: see DEGENERATE_BELOW), the first
    entry ('kind': 'joint') is the one trial chosen for all of them jointly
    (:func:`joint_choice`): a crew sails one trial, and the diagnosis does not know which
    suspect is real. Per-pair entries follow, then per-effect ones ordered by ``rank`` (low
    first; default: as given).
    """
    rpm0, u0, dur, dt = operating_point(trials)
    specs = repertoire(ship, rpm0, u0, dur)
    if not specs:   # neither a screw and rudder nor a catalogue: no trial to advise
        return []
    if rivals and sigma is None:
        raise DiagnosisError('advise_all: rival pairs are judged against sigma = (position [m], '
                             'heading [rad]); pass residual_scale(...)')
    # (sigma is given with rivals, as just checked)
    pairs = _rival_figures(ship, rivals, trials, cast(tuple[float, float], sigma), specs,
                           dt) if rivals else []
    pairs = [it for it in pairs if np.any(it.figures > 0)]   # no trial of them can be run
    out = [_rival_entry(it, specs) for it in pairs]
    # a suspected effect that no trial separates from the model without it is settled by its
    # measurement, and a joint trial need not serve it
    out = [suspect_measurement(a) if a['kind'] == 'suspected' and a['separation'] < MIN_SEPARATION
           else a for a in out]
    pairs = [it for it, a in zip(pairs, out) if not a.get('degenerate')]
    probe = [e for e in effects if len(EFFECTS[e].params) == 1]
    about = [e for e in about if e in probe]
    items: list[_Item] = []
    if about:
        info = _information(ship, base, base_theta, obj, probe, trials, specs)
        alone = {e: info.item(e) for e in about}
        per = [_information_entry(info, alone[e]) for e in about
               if np.any(alone[e].figures > 0)]
        out += sorted(per, key=lambda a: rank(a['about'])) if rank else per
        settleable = [e for e in about if float(np.max(alone[e].figures)) >= DEGENERATE_BELOW]
        # each against the base and the other settleable suspects: the trial must tell them
        # apart from each other too, not only from the base coefficients
        items = [info.item(e, [o for o in settleable if o != e]) for e in settleable]
    joint = joint_choice(pairs + items, specs)
    if joint is not None:
        joint['not_settled_by_a_trial'] = {a['about']: a['measure'] for a in out
                                           if a.get('degenerate')}
        out.insert(0, joint)
    return out


def joint_choice(items: Sequence[_Item], specs: Sequence[Spec]) -> dict[str, Any] | None:
    """
    Return the one trial for all items (None: fewer than two).

    Chosen by the number of items it settles (figure >= MIN_SEPARATION and SETTLES x the
    recorded one), then by the sum over the items of log(figure with / figure recorded): the
    information it adds to all of them at once. Its 'separation' / 'separation_recorded' /
    'settles' are those of its lead item (the settled one it improves most, else the most
    improved), 'figures' lists every item's.
    """
    if len(items) < 2:
        return None

    def ratio(f: float, rec: float | None) -> float:
        if f <= 0:
            return -math.inf
        return math.log(f / rec) if rec is not None and rec > 0 else 0.0

    best, best_key = None, None
    for k, spec in enumerate(specs):
        at_k = [float(it.figures[k]) for it in items]
        if not any(f > 0 for f in at_k):
            continue
        lifts = sum(_settles(f, it.recorded) for f, it in zip(at_k, items))
        gain = sum(max(ratio(f, it.recorded), -50.0) for f, it in zip(at_k, items))
        if best_key is None or (lifts, gain) > best_key:
            best, best_key = k, (lifts, gain)
    if best is None:
        return None
    spec = specs[best]
    # (a suspected effect may also be barely identifiable: two items of one name)
    figs = {it.about + (' (suspected)' if it.kind == 'suspected' else ''):
            (float(it.figures[best]), it.recorded) for it in items}
    settled = [a for a, (f, r) in figs.items() if _settles(f, r)]
    lead = max(settled or list(figs), key=lambda a: ratio(*figs[a]))
    f, r = figs[lead]
    return {'about': ', '.join(figs), 'kind': 'joint', 'instruction': _twice(spec),
            'spec': spec.to_dict(), 'pair': mirrored(spec).to_dict(), 'separation': f,
            'separation_recorded': r, 'settles': _settles(f, r), 'lead': lead,
            'lifts': settled,
            'figures': {a: {'with': figs[a][0], 'recorded': it.recorded,
                            'settles': a in settled, 'kind': it.kind}
                        for a, it in zip(figs, items)},
            'runner_up': '', 'version': SPEC_VERSION}


def joint_text(a: dict[str, Any]) -> str:
    """
    Say what the joint trial settles, e.g.

    'settles prop_side_force; with (recorded): prop_side_force 1.3 (0.52), rudder_lag 0.8 (0.3)'.
    """
    def rec(x: float | None) -> str:
        return '-' if x is None else f'{x:.3g}'

    return ('settles ' + (', '.join(a['lifts']) or 'none of them') + '; with (recorded): '
            + ', '.join(f"{k} {v['with']:.3g} ({rec(v['recorded'])})"
                        for k, v in a['figures'].items()))


def _settles(res: float, rec: float | None) -> bool:
    """Whether a figure settles: at least 1 and SETTLES x the recorded one (if finite)."""
    return bool(res >= MIN_SEPARATION and (rec is None or res > SETTLES * rec))


def load_advice(path: str | Path) -> list[Spec]:
    """Return the advised trials of a diagnosis.json file (errors name the file)."""
    from pathlib import Path

    from mmg_tuner._limits import load_json

    p = Path(path)
    if p.is_dir():
        p = p / 'diagnosis.json'
    doc = load_json(p, 'diagnosis', error=DiagnosisError)   # size and depth limits
    try:
        specs = specs_from_diagnosis(doc)
    except DiagnosisError as exc:
        raise DiagnosisError(f'{p}: {exc}') from None
    if not specs:
        instead = '; '.join(f"{a.get('about')}: {a.get('measure') or a.get('settle_by')}"
                            for a in doc['advice']
                            if isinstance(a, dict) and a.get('degenerate'))
        raise DiagnosisError(f'{p}: the diagnosis advises no trial (' + (
            f'no trial can settle what it could not: {instead})' if instead else
            'nothing was barely identifiable or indistinguishable)'))
    return specs
