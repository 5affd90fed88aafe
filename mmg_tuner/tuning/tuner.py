"""
CMA-ES with IPOP restarts and checkpoints, around the ask/tell state machine of ``cmaes``.

CMA-ES with IPOP restarts around the ask/tell state machine of ``cmaes`` (the caller owns the loop,
as in cmaes' own examples), with checkpoints so a run can be interrupted and resumed.

Paper setting (Suyama et al. 2023, section 4): population 12, doubled at each restart up to
128; the search runs in the unit box of :class:`ParameterSpace`.

The restarts stop early once one of them has found nothing better: a whole run, from its own
random start and with twice the population, that ends within ``RESTART_GAIN`` of the best J
found before it reached the same minimum (or one the data cannot tell from it), and IPOP has
its answer. A restart exists to escape a local minimum, and another basin differs in J by far
more. On the paper's problem (``python -m bench run bench_tune``) the first two runs end within
0.001 % of each other and the three larger populations then buy 0.05 % of J (no better on the
test trials) for 84 % of the evaluations; on seeds 6-8 the early stop ends within 0.005 % of
the full sequence's J with the same test J, at 4-7 times fewer evaluations.
``restart_gain = 0`` runs to the largest population, as the paper does.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import io
import json
import math
from pathlib import Path
import time
from typing import Any, Callable

from cmaes import CMA
from mmg_tuner._atomic import write_atomic
from mmg_tuner._limits import clip, json_loads, read_npz
from mmg_tuner.errors import OutputError, TuningError
from mmg_tuner.tuning.objective import Objective, Prior
from mmg_tuner.tuning.parameters import ParameterSpace
import numpy as np

RESTART_GAIN = 1e-3
"""A restart that lowers the best J by less than this fraction ends the search (module doc)."""

# version 2: a .npz of plain arrays and a JSON string (version 1 was a pickle, which runs code
# when loaded: never read, see refuse_pickle)
CHECKPOINT_VERSION = 2
CHECKPOINT_FORMAT = 'mmg_tuner tuning checkpoint'
_ZIP_MAGIC = b'PK\x03\x04'      # every .npz is a zip archive
_CMA = 'cma.'                    # prefix of the optimizer's attributes among the arrays
_KINDS = ('array', 'numpy', 'bool', 'int', 'float')
_STATE_INTS = ('seed', 'restart', 'popsize', 'evaluations', 'flat_gens')
_STATE_FLOATS = ('best_J', 'wall_s', 'last_best_run')
_MEMBERS = frozenset(_STATE_INTS + _STATE_FLOATS + (
    'best_z', 'history_counts', 'history_best', 'meta', 'rng.keys', 'rng.pos_has_gauss',
    'rng.gauss'))


def _is_member(name: str) -> bool:
    """Whether ``name`` is an array a tuning checkpoint has (see ``Tuner._encode``)."""
    return name in _MEMBERS or (name.startswith(_CMA) and name[len(_CMA):].isidentifier())


def refuse_pickle(path: Path | str, head: bytes, error: type[Exception]) -> None:
    """
    Raise ``error`` when a checkpoint's first bytes say it is a pickle.

    Checkpoints of older versions were pickles: unpickling runs whatever code the file holds,
    and a folder may come from someone else, so they are refused unread (whatever their name).
    """
    if head[:1] == b'\x80':    # the opcode every pickle of protocol 2 or later starts with
        raise error(f'{path}: a checkpoint in the old pickle format (an older mmg_tuner wrote '
                    'it, or someone else did); it is never loaded, because unpickling a file '
                    'runs whatever code it holds: re-run without --resume, into a new output '
                    'folder')


@dataclass
class Progress:
    restart: int
    popsize: int
    generation: int
    evaluations: int
    best_J: float


@dataclass
class TuningResult:
    theta: np.ndarray            # best tuned values, in space.names order
    J: float                     # objective at theta (tuning trials)
    evaluations: int
    restarts: int
    wall_s: float
    history: list[tuple[int, int, float]] = field(default_factory=list)  # (evals, restart, best)
    interrupted: bool = False


@dataclass
class _State:
    """Everything needed to resume: written to the checkpoint every generation (as data)."""

    version: int
    fingerprint: str
    seed: int
    restart: int
    popsize: int
    optimizer: CMA
    best_z: np.ndarray
    best_J: float
    evaluations: int
    wall_s: float
    flat_gens: int = 0
    last_best_run: float = math.inf
    history: list[tuple[int, int, float]] = field(default_factory=list)
    done: bool = False


def _rounded(a: np.ndarray | None) -> list[float] | None:
    return None if a is None else np.round(np.asarray(a, dtype=float), 12).tolist()


def _prior_key(prior: Prior | None) -> tuple[list[float] | None, list[float] | None,
                                             list[float] | None, float] | None:
    """Return what identifies a prior in a checkpoint's fingerprint (None: no prior)."""
    if prior is None:
        return None
    return (_rounded(prior.indices), _rounded(prior.centre), _rounded(prior.scale),
            round(float(prior.weight), 12))


class Tuner:
    """
    Minimise an :class:`Objective` over a :class:`ParameterSpace`.

    Examples
    --------
    >>> tuner = Tuner(space, objective, seed=0)
    >>> result = tuner.run()
    >>> tuned = space.full_params(ship.params, result.theta)[0]

    """

    def __init__(self, space: ParameterSpace, objective: Objective, *, popsize: int = 12,
                 max_popsize: int = 128, max_evaluations: int = 200_000, sigma0: float = 0.25,
                 seed: int = 0, checkpoint: str | Path | None = None, rtol: float = 1e-9,
                 x0: np.ndarray | None = None, restart_gain: float = RESTART_GAIN):
        self.space = space
        self.objective = objective
        self.popsize0 = popsize
        self.max_popsize = max_popsize
        self.max_evaluations = max_evaluations
        self.sigma0 = sigma0
        self.seed = seed
        self.checkpoint = Path(checkpoint) if checkpoint else None
        self.rtol = rtol
        self.restart_gain = restart_gain
        self.x0 = None if x0 is None else np.asarray(x0, dtype=float)  # warm start (values)
        self._base = objective.ship.params

    def fingerprint(self) -> str:
        b = self.objective.batch
        return repr((self.space.names, self.space.lower.round(12).tolist(),
                     self.space.upper.round(12).tolist(), b.names, b.meas.shape,
                     float(np.round(b.meas.sum(), 6)), self.objective.weights.tolist(),
                     self.objective.shoot_every, self.popsize0, self.max_popsize,
                     _rounded(getattr(self.objective, 'trial_weights', None)),
                     _prior_key(getattr(self.objective, 'prior', None))))

    def _new_optimizer(self, restart: int, popsize: int, rng: np.random.Generator) -> CMA:
        d = self.space.dim
        mean = np.full(d, 0.5) if restart == 0 else rng.uniform(0.1, 0.9, d)
        if restart == 0:  # start from the pre-determined values (or the warm start)
            start = self.space.pre if self.x0 is None else self.x0
            mean = np.clip(self.space.to_unit(start), 0.0, 1.0)
        return CMA(mean=mean, sigma=self.sigma0, bounds=np.tile([0.0, 1.0], (d, 1)),
                   population_size=popsize, seed=self.seed + 7919 * restart)

    def evaluate_unit(self, Z: np.ndarray) -> np.ndarray:
        return self.objective(self.space.full_params(self._base, self.space.from_unit(Z)))

    def run(self, resume: bool = False, progress: Callable[[Progress], None] | None = None
            ) -> TuningResult:
        state = self._load() if resume else None
        if state is None:
            pre_J = float(self.evaluate_unit(self.space.to_unit(self.space.pre)[None])[0])
            start = self.space.pre if self.x0 is None else self.x0
            if self.x0 is not None:
                pre_J = float(self.evaluate_unit(self.space.to_unit(start)[None])[0])
            state = _State(CHECKPOINT_VERSION, self.fingerprint(), self.seed, 0, self.popsize0,
                           self._new_optimizer(0, self.popsize0, np.random.default_rng(self.seed)),
                           self.space.to_unit(start), pre_J, 1, 0.0)
        t_start = time.perf_counter() - state.wall_s
        interrupted = False
        # the state after the last whole generation: Ctrl-C can land inside one (evaluations
        # counted, the optimizer not yet told), and resuming from that half would not continue
        # as the uninterrupted run does (no checkpoint: nothing to resume, no snapshots)
        keep = self.checkpoint is not None
        whole = self._encode(state) if keep else None
        try:
            while not state.done:
                self._generation(state)
                state.wall_s = time.perf_counter() - t_start
                whole = self._encode(state) if keep else None
                if progress:
                    progress(Progress(state.restart, state.popsize, state.optimizer.generation,
                                      state.evaluations, state.best_J))
                self._save(state, whole)
        except KeyboardInterrupt:
            interrupted = True
            if whole is not None:
                state = self._decode(whole, self.checkpoint)
            state.wall_s = time.perf_counter() - t_start
            self._save(state)
        return TuningResult(self.space.from_unit(state.best_z), state.best_J, state.evaluations,
                            state.restart, state.wall_s, list(state.history), interrupted)

    def _generation(self, state: _State) -> None:
        opt = state.optimizer
        # reseed per generation: a resumed run continues exactly as an uninterrupted one
        opt.reseed_rng((self.seed * 1_000_003 + state.restart * 10_007 + opt.generation)
                       % (2**32 - 1))
        Z = np.array([opt.ask() for _ in range(opt.population_size)])
        J = self.evaluate_unit(Z)
        state.evaluations += len(Z)
        opt.tell(list(zip(Z, J)))
        k = int(np.argmin(J))
        if J[k] < state.best_J:
            state.best_J, state.best_z = float(J[k]), Z[k].copy()
        state.history.append((state.evaluations, state.restart, state.best_J))
        gen_best = float(J[k])
        # converged when the generation's best stops improving relative to the run's best
        if gen_best < state.last_best_run * (1 - self.rtol):
            state.last_best_run = gen_best
            state.flat_gens = 0
        else:
            state.flat_gens += 1
        patience = 10 + math.ceil(30 * self.space.dim / opt.population_size)
        run_over = opt.should_stop() or state.flat_gens > patience
        if state.evaluations >= self.max_evaluations:
            state.done = True
        elif run_over:
            if state.popsize >= self.max_popsize:
                state.done = True  # the largest population has converged too
                return
            if state.restart > 0 and self.restart_gain > 0:
                before = min((b for _, r, b in state.history if r < state.restart),
                             default=math.inf)
                if state.best_J > before * (1.0 - self.restart_gain):
                    state.done = True  # a whole restart found nothing better (module doc)
                    return
            state.restart += 1
            state.popsize = min(2 * state.popsize, self.max_popsize)
            rng = np.random.default_rng(self.seed + 104729 * state.restart)
            state.optimizer = self._new_optimizer(state.restart, state.popsize, rng)
            state.flat_gens = 0
            state.last_best_run = math.inf

    def _save(self, state: _State, blob: bytes | None = None) -> None:
        if self.checkpoint is not None:
            try:
                write_atomic(self.checkpoint, self._encode(state) if blob is None else blob)
            except OSError as exc:
                raise OutputError(f'writing the checkpoint {self.checkpoint} failed '
                                  f'({exc.strerror or exc}); the run stopped there') from None

    def _load(self) -> _State | None:
        if self.checkpoint is None or not self.checkpoint.is_file():
            raise TuningError(f'no checkpoint to resume at {self.checkpoint}')
        try:
            blob = self.checkpoint.read_bytes()
        except OSError as exc:
            raise TuningError(f'{self.checkpoint}: unreadable checkpoint '
                              f'({exc.strerror or exc})') from None
        return self._decode(blob, self.checkpoint)

    # ------------------------------------------------------------------ checkpoint format
    def _encode(self, state: _State) -> bytes:
        """
        Return the state as a ``.npz`` (bytes): plain arrays and a JSON string, nothing pickled.

        The optimizer is stored attribute by attribute, whole (the covariance in full, the
        random generator's state as its key array), so a resumed run continues to the last digit.
        """
        arrays: dict[str, np.ndarray] = {}
        kinds: dict[str, str] = {}
        for name, v in vars(state.optimizer).items():
            if name == '_rng':
                continue
            kinds[name] = _kind(v)
            if v is not None:
                arrays[_CMA + name] = np.asarray(v)
        alg, keys, pos, has_gauss, gauss = state.optimizer._rng.get_state()
        arrays['rng.keys'] = np.asarray(keys, dtype=np.uint32)
        arrays['rng.pos_has_gauss'] = np.array([pos, has_gauss], dtype=np.int64)
        arrays['rng.gauss'] = np.array(gauss, dtype=float)
        for k in _STATE_INTS:
            arrays[k] = np.array(getattr(state, k), dtype=np.int64)
        for k in _STATE_FLOATS:
            arrays[k] = np.array(getattr(state, k), dtype=float)
        arrays['best_z'] = np.asarray(state.best_z, dtype=float)
        h = np.array(state.history, dtype=float).reshape(-1, 3)
        arrays['history_counts'] = h[:, :2].astype(np.int64)
        arrays['history_best'] = h[:, 2].copy()
        arrays['meta'] = np.array(json.dumps({
            'format': CHECKPOINT_FORMAT, 'version': state.version, 'ship': self._ship_name(),
            'fingerprint': state.fingerprint, 'done': bool(state.done), 'rng': alg,
            'cma': kinds}))
        buf = io.BytesIO()
        np.savez(buf, **arrays)  # type: ignore[arg-type]  # stub: a key may be allow_pickle
        return buf.getvalue()

    def _decode(self, blob: bytes, path: Path | None) -> _State:
        """Read what :meth:`_encode` wrote; every check names the file (TuningError)."""
        src = path or 'the checkpoint'
        refuse_pickle(src, blob[:4], TuningError)
        if blob[:4] != _ZIP_MAGIC:   # checked before any parsing: only a zip reaches np.load
            raise TuningError(f'{src}: not a tuning checkpoint (.npz of mmg_tuner): re-run '
                              'without --resume, into a new output folder')
        try:   # only the checkpoint's members, each checked from its header (_limits.py)
            a = read_npz(blob, src, 'tuning checkpoint', members=_is_member, error=TuningError)
            meta = json_loads(str(a['meta']), src, error=TuningError, what="member 'meta'",
                              limit=1 << 20)
        except (TuningError, KeyError) as exc:
            raise TuningError(f'{src}: unreadable checkpoint, damaged or incomplete '
                              f'({str(exc).removeprefix(f"{src}: ")}); re-run without '
                              '--resume') from None
        if not isinstance(meta, dict) or meta.get('format') != CHECKPOINT_FORMAT:
            raise TuningError(f'{src}: not a tuning checkpoint of mmg_tuner')
        if meta.get('version') != CHECKPOINT_VERSION:
            raise TuningError(f"{src}: checkpoint version {meta.get('version')}, this mmg_tuner "
                              f'reads version {CHECKPOINT_VERSION}; re-run without --resume')
        if meta.get('ship') != self._ship_name():
            raise TuningError(f"{src}: the checkpoint is of ship {meta.get('ship')!r}, this run "
                              f'tunes {self._ship_name()!r}; re-run without --resume')
        if meta.get('fingerprint') != self.fingerprint():
            raise TuningError(f'{src}: checkpoint belongs to another problem '
                              '(trials, targets, bounds, weights, pieces, balance or prior '
                              'differ, or an older mmg_tuner wrote it) and cannot be resumed: '
                              'start a new run in a new output folder')
        try:
            return self._state_from(a, meta, src)
        except KeyError as exc:
            raise TuningError(f'{src}: checkpoint incomplete, array {exc} missing; re-run '
                              'without --resume') from None
        except (TypeError, ValueError, OverflowError) as exc:   # e.g. a scalar of shape (2,)
            raise TuningError(f'{src}: damaged checkpoint ({clip(exc)}); re-run without '
                              '--resume') from None

    def _state_from(self, a: dict[str, np.ndarray], meta: dict[str, Any], src: Path | str
                    ) -> _State:
        """Rebuild the state from checked arrays; shapes compared with what this run expects."""
        def bad(what: str) -> TuningError:
            return TuningError(f'{src}: damaged checkpoint ({what}); re-run without --resume')

        d = self.space.dim
        ints = {k: int(a[k]) for k in _STATE_INTS}
        floats = {k: float(a[k]) for k in _STATE_FLOATS}
        if a['best_z'].shape != (d,):
            raise bad(f"best_z has shape {a['best_z'].shape}, expected ({d},)")
        if ints['popsize'] < 2:
            raise bad(f"popsize {ints['popsize']}")
        # a fresh optimizer of the stored size gives every attribute's expected type and shape
        opt = CMA(mean=np.full(d, 0.5), sigma=self.sigma0, bounds=np.tile([0.0, 1.0], (d, 1)),
                  population_size=ints['popsize'], seed=0)
        kinds = meta.get('cma')
        expected = {k: _kind(v) for k, v in vars(opt).items() if k != '_rng'}
        if not isinstance(kinds, dict) or set(kinds) != set(expected):
            raise bad('the optimizer attributes differ from those of the installed cmaes; '
                      'another cmaes version wrote it')
        for name, kind in kinds.items():
            ref = getattr(opt, name)
            if kind == 'none':
                if expected[name] != 'none':   # only a cache (the eigen decomposition) may be
                    raise bad(f'{name} is missing')
                setattr(opt, name, None)
                continue
            v = a[_CMA + name]
            # a scalar may change type as the run goes (float -> numpy.float64): both scalars
            if kind not in _KINDS or (kind == 'array') != (expected[name] == 'array') \
                    and expected[name] != 'none':
                raise bad(f'{name} is {kind}, expected {expected[name]}')
            want = ref.shape if isinstance(ref, np.ndarray) else None if kind == 'array' else ()
            if want is not None and v.shape != want:
                raise bad(f'{name} has shape {v.shape}, expected {want}')
            if v.dtype.kind not in 'biuf':
                raise bad(f'{name} has dtype {v.dtype}')
            setattr(opt, name, _value(v, kind))
        keys, pos = a['rng.keys'], a['rng.pos_has_gauss']
        if keys.shape != (624,) or pos.shape != (2,):
            raise bad('random generator state')
        opt._rng.set_state((str(meta.get('rng')), keys, int(pos[0]), int(pos[1]),
                            float(a['rng.gauss'])))
        counts, best = a['history_counts'], a['history_best']
        if counts.ndim != 2 or counts.shape[1:] != (2,) or best.shape != (len(counts),):
            raise bad('history')
        history = [(int(e), int(r), float(b)) for (e, r), b in zip(counts, best)]
        return _State(CHECKPOINT_VERSION, meta['fingerprint'], ints['seed'], ints['restart'],
                      ints['popsize'], opt, a['best_z'].astype(float), floats['best_J'],
                      ints['evaluations'], floats['wall_s'], ints['flat_gens'],
                      floats['last_best_run'], history, bool(meta.get('done')))

    def _ship_name(self) -> str:
        return str(getattr(self.objective.ship, 'name', ''))


def _kind(v: object) -> str:
    """How an optimizer attribute is stored and rebuilt (its exact Python / numpy type)."""
    if v is None:
        return 'none'
    if isinstance(v, np.ndarray):
        return 'array'
    if isinstance(v, np.generic):   # before float: np.float64 is a float too
        return 'numpy'
    if isinstance(v, bool):         # before int: bool is an int too
        return 'bool'
    if isinstance(v, int):
        return 'int'
    if isinstance(v, float):
        return 'float'
    raise TuningError(f'cannot checkpoint an optimizer attribute of type {type(v).__name__} '
                      '(an unsupported cmaes version)')


def _value(v: np.ndarray, kind: str) -> object:
    """Inverse of storing with :func:`_kind`: the same type and the same bits."""
    if kind == 'array':
        return v.copy()
    if kind == 'numpy':
        return v[()]
    return {'bool': bool, 'int': int, 'float': float}[kind](v[()])
