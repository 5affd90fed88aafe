"""
CMA-ES with IPOP restarts and checkpoints, around the ask/tell state machine of ``cmaes``.

CMA-ES with IPOP restarts around the ask/tell state machine of ``cmaes`` (the caller owns the loop,
as in cmaes' own examples), with checkpoints so a run can be interrupted and resumed.

Paper setting (Suyama et al. 2023, section 4): population 12, doubled at each restart up to
128; the search runs in the unit box of :class:`ParameterSpace`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path
import pickle
import time
from typing import Callable

from cmaes import CMA
from mmg_tuner._atomic import write_atomic
from mmg_tuner.errors import OutputError, TuningError
from mmg_tuner.tuning.objective import Objective
from mmg_tuner.tuning.parameters import ParameterSpace
import numpy as np

CHECKPOINT_VERSION = 1


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
    """Everything needed to resume: pickled to the checkpoint every generation."""

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
    history: list = field(default_factory=list)
    done: bool = False


def _rounded(a: np.ndarray | None) -> list | None:
    return None if a is None else np.round(np.asarray(a, dtype=float), 12).tolist()


def _prior_key(prior) -> tuple | None:
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
                 x0: np.ndarray | None = None):
        self.space = space
        self.objective = objective
        self.popsize0 = popsize
        self.max_popsize = max_popsize
        self.max_evaluations = max_evaluations
        self.sigma0 = sigma0
        self.seed = seed
        self.checkpoint = Path(checkpoint) if checkpoint else None
        self.rtol = rtol
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
        whole = pickle.dumps(state) if keep else None
        try:
            while not state.done:
                self._generation(state)
                state.wall_s = time.perf_counter() - t_start
                whole = pickle.dumps(state) if keep else None
                if progress:
                    progress(Progress(state.restart, state.popsize, state.optimizer.generation,
                                      state.evaluations, state.best_J))
                self._save(state, whole)
        except KeyboardInterrupt:
            interrupted = True
            if whole is not None:
                state = pickle.loads(whole)
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
            state.restart += 1
            state.popsize = min(2 * state.popsize, self.max_popsize)
            rng = np.random.default_rng(self.seed + 104729 * state.restart)
            state.optimizer = self._new_optimizer(state.restart, state.popsize, rng)
            state.flat_gens = 0
            state.last_best_run = math.inf

    def _save(self, state: _State, blob: bytes | None = None) -> None:
        if self.checkpoint is not None:
            try:
                write_atomic(self.checkpoint, pickle.dumps(state) if blob is None else blob)
            except OSError as exc:
                raise OutputError(f'writing the checkpoint {self.checkpoint} failed '
                                  f'({exc.strerror or exc}); the run stopped there') from None

    def _load(self) -> _State | None:
        if self.checkpoint is None or not self.checkpoint.is_file():
            raise TuningError(f'no checkpoint to resume at {self.checkpoint}')
        try:
            state = pickle.loads(self.checkpoint.read_bytes())
        except Exception as exc:  # a truncated or foreign file
            raise TuningError(f'{self.checkpoint}: unreadable checkpoint ({exc})') from None
        if not isinstance(state, _State) or state.version != CHECKPOINT_VERSION:
            raise TuningError(f'{self.checkpoint}: not a checkpoint of this version')
        if state.fingerprint != self.fingerprint():
            raise TuningError(f'{self.checkpoint}: checkpoint belongs to another problem '
                              '(trials, targets, bounds, weights, pieces, balance or prior '
                              'differ, or an older mmg_tuner wrote it) and cannot be resumed: '
                              'start a new run in a new output folder')
        return state
