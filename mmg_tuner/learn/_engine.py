"""
The differentiable simulation and the optimiser (JAX, equinox, optax; imported lazily).

The physics is the compiled numba kernel itself, called on the whole batch as an XLA FFI
handler (``_bridge.ffi_handler``; ``jax.pure_callback`` where XLA refuses it), with a custom
VJP whose backward multiplies by the kernel's state Jacobian (forward differences in float64,
computed in the same call as the forward). The network,
the features, the kinematics and the integrator steps are JAX, so the gradient of the
simulation-based loss flows through every step of the simulated window.
"""
from __future__ import annotations

from dataclasses import dataclass
import logging
import threading
from typing import Any, Callable, cast, Mapping, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.typing import ArrayLike
from mmg_tuner.core.correction import FEATURE_PARAMS
from mmg_tuner.core.dynamics import family_tag
from mmg_tuner.core.layout import PARAM_INDEX
from mmg_tuner.learn._bridge import (batch_derivative, batch_param_jacobian, FD_REL_STEP,
                                     ffi_handler, param_steps)
import numpy as np
import optax

logger = logging.getLogger(__name__)

# the physics runs in float64 (before any array); (jax's config.update has no annotations)
jax.config.update('jax_enable_x64', True)  # type: ignore[no-untyped-call]

_Vc = PARAM_INDEX['current_speed']
_dirc = PARAM_INDEX['current_dir']
_ax = PARAM_INDEX['antenna_x']
_ay = PARAM_INDEX['antenna_y']
_NOT_FREE = {PARAM_INDEX[n] for n in FEATURE_PARAMS}   # the features read them

# a batch of windows simulated: (model, x0, hist, inp, act, wind) -> (observed, residual)
Simulate = Callable[['MLP | Joint', ArrayLike, ArrayLike, ArrayLike, ArrayLike, ArrayLike],
                    tuple[jax.Array, jax.Array]]
# a batch's losses of a model: (model, batch, window weights) -> ...
DataLoss = Callable[['MLP | Joint', Mapping[str, ArrayLike], ArrayLike],
                    tuple[jax.Array, jax.Array, jax.Array]]
Total = Callable[['MLP | Joint', Mapping[str, ArrayLike], ArrayLike],
                 tuple[jax.Array, jax.Array]]


_FFI_TARGETS: dict[int, bool] = {}
_FFI_LOCK = threading.Lock()   # one registration per family, whichever thread asks first
AGREE_RTOL = 1e-12
"""The self-test's tolerance on F: a misread struct gives gross errors, while the kernel
compiled twice (fast-math) may differ by an ulp. On J, forward differences amplify an ulp by
1 / FD_REL_STEP: it is held to AGREE_RTOL / FD_REL_STEP of each row's scale."""


def _ffi_target(kind: int, p: np.ndarray) -> str | None:
    """
    Register family ``kind``'s XLA FFI handler once; return its target name, or None.

    None when XLA refuses it (a C API version it does not speak) or when a call on a few rows
    differs from the kernel's: the caller falls back to ``jax.pure_callback``.
    """
    name = f'mmg_tuner_physics_{kind}'
    with _FFI_LOCK:
        if kind not in _FFI_TARGETS:
            ok = False
            try:
                address: int = getattr(ffi_handler(kind), 'address')
                capsule = jax.ffi.pycapsule(address)  # type: ignore[no-untyped-call]
                jax.ffi.register_ffi_target(name, capsule, platform='cpu')
                ok = _ffi_agrees(kind, name, p)
            except Exception as exc:   # noqa: BLE001 -- any refusal means: use the callback
                logger.warning('the physics runs through jax.pure_callback (slower): its XLA '
                               'FFI handler was refused: %s', exc)
            _FFI_TARGETS[kind] = ok
        return name if _FFI_TARGETS[kind] else None


def _ffi_call(name: str, s: jax.Array, act: jax.Array, wind: jax.Array, p: jax.Array,
              with_jac: bool, free: tuple[jax.Array, jax.Array] | None = None) -> Any:
    """Call the handler: F, with_jac: and J, free (slots, steps): and Jp (..., 6, k)."""
    shapes = [s.shape] + ([s.shape + (6,)] if with_jac else [])
    extra: list[jax.Array] = []
    if free is not None:
        shapes.append(s.shape + (free[0].shape[0],))
        extra = list(free)
    out = [jax.ShapeDtypeStruct(x, jnp.float64)  # type: ignore[no-untyped-call]
           for x in shapes]
    # float64 only: the handler reads the buffers' bytes as doubles
    args = [jnp.asarray(x, dtype=jnp.float64) for x in (s, act, wind, p, *extra)]
    return jax.ffi.ffi_call(name, out, vmap_method='broadcast_all')(*args)


def _ffi_agrees(kind: int, name: str, p: np.ndarray) -> bool:
    """Return whether the FFI handler gives the kernel's F and J (parameters p) on test rows."""
    tag = family_tag(kind)
    rng = np.random.default_rng(0)
    from mmg_tuner.core.models import family_of_code
    n_out = len(family_of_code(kind).outputs)
    S = np.zeros((3, 6))
    S[:, 2:] = rng.uniform([-3.0, 0.1, -0.1, -0.05], [3.0, 1.0, 0.1, 0.05], (3, 4))
    A = rng.uniform(0.0, 1.0, (3, n_out))
    Wd = np.column_stack([rng.uniform(0.0, 3.0, 3), rng.uniform(-3.0, 3.0, 3)])
    F, J = np.empty((3, 6)), np.empty((3, 6, 6))
    batch_derivative(tag, p, S, A, Wd, F, J, True)
    got = _ffi_call(name, jnp.asarray(S), jnp.asarray(A), jnp.asarray(Wd), jnp.asarray(p), True)
    rows = np.all(np.isfinite(F), axis=1) & np.all(np.isfinite(J), axis=(1, 2))
    scale = np.maximum(1.0, np.abs(F).max(axis=1))[rows, None]
    tol_j = AGREE_RTOL / FD_REL_STEP * scale[..., None]
    same = bool(rows.any()) and \
        bool(np.all(np.abs(np.asarray(got[0])[rows] - F[rows]) <= AGREE_RTOL * scale)) and \
        bool(np.all(np.abs(np.asarray(got[1])[rows] - J[rows]) <= tol_j))
    if not same:
        logger.warning('the physics runs through jax.pure_callback (slower): its XLA FFI '
                       'handler disagreed with the kernel on a test batch')
    return same


def physics_fn(kind: int, p: np.ndarray, ffi: bool = True,
               free: Sequence[int] | np.ndarray = (), steps: Sequence[float] | np.ndarray = ()
               ) -> Callable[..., jax.Array]:
    """
    Return ds/dt (B, 6) of the family as a differentiable JAX function of the states (B, 6).

    f(s, act, wind) -> (B, 6); with ``free`` parameter slots (k,): f(s, act, wind, theta),
    theta (k,) their values (replacing p's), differentiable too (forward differences with
    ``steps`` (k,): the training of the network and the coefficients together).
    Actuators (B, n_outputs) and wind (B, 2) are data (zero cotangent); ``kind``: the family
    code. ffi: call the kernel as an XLA FFI handler (``_bridge.ffi_handler``) when XLA takes
    it; False (or refused): through ``jax.pure_callback``, the same kernel with Python between
    (the reference the tests compare against).
    """
    p = np.ascontiguousarray(p, dtype=float)
    tag = family_tag(kind)
    target = _ffi_target(kind, p) if ffi else None
    p_jax = jnp.asarray(p)
    idx = np.asarray(free, dtype=np.int64)
    hp = np.asarray(steps, dtype=float)
    k = idx.shape[0]
    if hp.shape != (k,) or (k and not np.all(hp > 0)):
        raise ValueError(f'physics_fn: {k} free slots need {k} positive steps, got {hp}')
    free_jax = (jnp.asarray(idx, dtype=jnp.float64), jnp.asarray(hp))

    def host(s: np.ndarray, act: np.ndarray, wind: np.ndarray, theta: np.ndarray,
             with_jac: bool) -> np.ndarray | tuple[np.ndarray, ...]:
        s = np.ascontiguousarray(s, dtype=float)
        act = np.ascontiguousarray(act, dtype=float)
        wind = np.ascontiguousarray(wind, dtype=float)
        q = p.copy()
        q[idx] = theta
        B = s.shape[0]
        F = np.empty((B, 6))
        J = np.empty((B, 6, 6))
        batch_derivative(tag, q, s, act, wind, F, J, with_jac)
        if not with_jac:
            return F
        Jp = np.empty((B, 6, k))
        if k:
            batch_param_jacobian(tag, q, s, act, wind, F, idx, hp, Jp)
        return F, J, Jp

    # (jax's ShapeDtypeStruct.__init__ has no annotations)
    def shape(*dims: int) -> jax.ShapeDtypeStruct:
        return jax.ShapeDtypeStruct(dims, jnp.float64)  # type: ignore[no-untyped-call]

    def full(theta: jax.Array) -> jax.Array:
        return p_jax.at[idx].set(theta) if k else p_jax

    @jax.custom_vjp
    def f(s: jax.Array, act: jax.Array, wind: jax.Array, theta: jax.Array) -> jax.Array:
        if target is not None:
            out: jax.Array = _ffi_call(target, s, act, wind, full(theta), False)[0]
            return out
        out = jax.pure_callback(lambda a, b, c, t: host(a, b, c, t, False), shape(*s.shape),
                                s, act, wind, theta, vmap_method='sequential')
        return out

    def fwd(s: jax.Array, act: jax.Array, wind: jax.Array, theta: jax.Array
            ) -> tuple[jax.Array, tuple[jax.Array, jax.Array, jax.Array, jax.Array]]:
        if target is not None:
            got = _ffi_call(target, s, act, wind, full(theta), True, free_jax if k else None)
            F, J = got[0], got[1]
            Jp = got[2] if k else jnp.zeros(s.shape + (0,))
        else:
            F, J, Jp = jax.pure_callback(
                lambda a, b, c, t: host(a, b, c, t, True),
                (shape(*s.shape), shape(*s.shape, 6), shape(*s.shape, k)), s, act, wind, theta,
                vmap_method='sequential')
        return F, (J, Jp, act, wind)

    def bwd(res: tuple[jax.Array, jax.Array, jax.Array, jax.Array], g: jax.Array
            ) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
        J, Jp, act, wind = res
        return (jnp.einsum('bi,bij->bj', g, J), jnp.zeros_like(act), jnp.zeros_like(wind),
                jnp.einsum('bi,bik->k', g, Jp))

    f.defvjp(fwd, bwd)
    if k:
        return f
    none = jnp.zeros(0)
    return lambda s, act, wind: f(s, act, wind, none)


class MLP(eqx.Module):
    """
    The network: tanh hidden layers, linear output.

    The last layer starts at zero, so the hybrid starts as its physics part.
    """

    layers: list[eqx.nn.Linear]

    def __init__(self, sizes: Sequence[int], key: jax.Array) -> None:
        keys = jax.random.split(key, len(sizes) - 1)
        layers = [eqx.nn.Linear(i, o, key=k, dtype=jnp.float64)
                  for i, o, k in zip(sizes[:-1], sizes[1:], keys)]
        last = layers[-1]
        # (a Linear has its bias: use_bias is True by default)
        layers[-1] = eqx.tree_at(lambda m: (m.weight, m.bias), last,
                                 (jnp.zeros_like(last.weight),
                                  jnp.zeros_like(cast(jax.Array, last.bias))))
        self.layers = layers

    def __call__(self, x: jax.Array) -> jax.Array:
        for layer in self.layers[:-1]:
            x = jnp.tanh(layer(x))
        return self.layers[-1](x)

    @classmethod
    def of(cls, weights: Sequence[np.ndarray], biases: Sequence[np.ndarray]) -> MLP:
        """Return the network with these weights ((out, in) each) and biases: a warm start."""
        sizes = [np.shape(weights[0])[1], *(np.shape(w)[0] for w in weights)]
        net = cls(sizes, jax.random.PRNGKey(0))
        out: MLP = eqx.tree_at(lambda m: [x for la in m.layers for x in (la.weight, la.bias)],
                               net, [jnp.asarray(x, dtype=jnp.float64)
                                     for w, b in zip(weights, biases) for x in (w, b)])
        return out

    def export(self) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        return (tuple(np.asarray(la.weight, dtype=float) for la in self.layers),
                tuple(np.asarray(la.bias, dtype=float) for la in self.layers))


@dataclass(frozen=True)
class Coefficients:
    """
    Physics coefficients trained with the network: slots, start, box, steps and prior.

    theta = start + width z, z trained from 0 (``Joint.z``) and projected back into the box
    after every step (:meth:`project`: a clip inside the loss would zero the gradient at an
    edge and keep the coefficient there for good); the prior
    adds weight x sum(((theta - centre) / width)^2) to the loss (weight in loss units);
    steps: the forward-difference steps of the parameter Jacobian.
    """

    slots: np.ndarray     # (k,) int, never the wind's, the current's or the antenna's
    start: np.ndarray     # (k,) the values training starts from (the tuned ones)
    lower: np.ndarray
    upper: np.ndarray
    centre: np.ndarray    # (k,) the prior's centre (the published values)
    weight: float         # the prior's weight [loss units]

    @property
    def width(self) -> np.ndarray:
        w: np.ndarray = self.upper - self.lower
        return w

    @property
    def steps(self) -> np.ndarray:
        return param_steps(self.start, self.lower, self.upper)

    def values(self, z: jax.Array) -> jax.Array:
        """Return theta (k,) of the trained offsets z (k,)."""
        return jnp.asarray(self.start) + jnp.asarray(self.width) * z

    def project(self, z: jax.Array) -> jax.Array:
        """Return z moved into the box (each theta within [lower, upper])."""
        w = self.width
        return jnp.clip(z, jnp.asarray((self.lower - self.start) / w),
                        jnp.asarray((self.upper - self.start) / w))

    def penalty(self, z: jax.Array) -> jax.Array:
        d = (self.values(z) - jnp.asarray(self.centre)) / jnp.asarray(self.width)
        return self.weight * jnp.sum(d * d)


class Joint(eqx.Module):
    """The network and the physics coefficients' offsets z, trained together."""

    net: MLP
    z: jax.Array


def make_simulator(kind: int, p: np.ndarray, physics: bool, rk4: bool, dt: float,
                   x_mean: np.ndarray, x_std: np.ndarray, y_scale: np.ndarray,
                   coefficients: Coefficients | None = None,
                   physics_input: bool = False) -> Simulate:
    """
    Return simulate(model, x0, hist, inp, act, wind) -> (observed, residual).

    Observed (B, H, 6) and residual (B, H, 3) for a batch of windows, mirroring
    ``learn.residual.simulate_hybrid_one`` (one step per sample, the residual held over it).
    With ``coefficients`` the model is a :class:`Joint` (the network and the coefficients);
    physics_input: each row ends with the physics' accelerations at the sample (the first
    stage's, computed once for both).
    """
    free = coefficients
    if free is not None and (not physics or set(free.slots.tolist()) & _NOT_FREE):
        raise ValueError('free coefficients need the physics, and never the wind, current or '
                         'antenna slots (the features read them)')
    phys = physics_fn(kind, p) if free is None else \
        physics_fn(kind, p, True, free.slots, free.steps)
    Vc, dirc, ax, ay = (float(p[_Vc]), float(p[_dirc]), float(p[_ax]), float(p[_ay]))
    mean = jnp.asarray(x_mean)
    std = jnp.asarray(x_std)
    yscale = jnp.asarray(y_scale)

    def features(s: jax.Array, inp: jax.Array, wind: jax.Array) -> jax.Array:
        psi, u, v = s[:, 2], s[:, 3], s[:, 4]
        ug, vg = u, v
        if Vc != 0.0:
            ug = u + Vc * jnp.cos(dirc - psi)
            vg = v + Vc * jnp.sin(dirc - psi)
        rel = wind[:, 1] - psi
        wu = -wind[:, 0] * jnp.cos(rel) - ug
        wv = -wind[:, 0] * jnp.sin(rel) - vg
        return jnp.concatenate([s[:, 3:6], inp, wu[:, None], wv[:, None]], axis=1)

    def phys_at(s: jax.Array, act: jax.Array, wind: jax.Array,
                theta: jax.Array | None) -> jax.Array:
        return phys(s, act, wind) if theta is None else phys(s, act, wind, theta)

    def deriv(s: jax.Array, act: jax.Array, wind: jax.Array, a: jax.Array,
              theta: jax.Array | None, f: jax.Array | None = None) -> jax.Array:
        if physics:
            f = phys_at(s, act, wind, theta) if f is None else f
            return f + jnp.concatenate([jnp.zeros_like(s[:, :3]), a], axis=1)
        psi, u, v, r = s[:, 2], s[:, 3], s[:, 4], s[:, 5]
        c, sn = jnp.cos(psi), jnp.sin(psi)
        dx = u * c - v * sn
        dy = u * sn + v * c
        if Vc != 0.0:
            dx = dx + Vc * np.cos(dirc)
            dy = dy + Vc * np.sin(dirc)
        return jnp.concatenate([dx[:, None], dy[:, None], r[:, None], a], axis=1)

    def observe(s: jax.Array) -> jax.Array:
        psi = s[:, 2]
        c, sn = jnp.cos(psi), jnp.sin(psi)
        o = s
        if ax != 0.0 or ay != 0.0:
            o = o.at[:, 0].add(ax * c - ay * sn).at[:, 1].add(ax * sn + ay * c)
        if Vc != 0.0:
            o = o.at[:, 3].add(Vc * jnp.cos(dirc - psi)).at[:, 4].add(Vc * jnp.sin(dirc - psi))
        return o

    def simulate(model: MLP | Joint, x0: ArrayLike, hist: ArrayLike, inp: ArrayLike,
                 act: ArrayLike, wind: ArrayLike) -> tuple[jax.Array, jax.Array]:
        theta = None
        if isinstance(model, Joint):
            assert free is not None
            theta = free.values(model.z)
            model = model.net
        net = jax.vmap(model)

        def step(carry: tuple[jax.Array, jax.Array], xs: tuple[jax.Array, jax.Array, jax.Array]
                 ) -> tuple[tuple[jax.Array, jax.Array], tuple[jax.Array, jax.Array]]:
            s, ring = carry
            inp_k, act_k, wind_k = xs
            row = features(s, inp_k, wind_k)
            f0 = None
            if physics_input:
                f0 = phys_at(s, act_k, wind_k, theta)
                row = jnp.concatenate([row, f0[:, 3:6]], axis=1)
            full = jnp.concatenate([ring, row[:, None, :]], axis=1)
            z = ((full - mean) / std).reshape(full.shape[0], -1)
            a = net(z) * yscale
            k1 = deriv(s, act_k, wind_k, a, theta, f0)
            if rk4:
                k2 = deriv(s + 0.5 * dt * k1, act_k, wind_k, a, theta)
                k3 = deriv(s + 0.5 * dt * k2, act_k, wind_k, a, theta)
                k4 = deriv(s + dt * k3, act_k, wind_k, a, theta)
                s = s + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
            else:
                s = s + dt * k1
            return (s, full[:, 1:]), (observe(s), a)

        xs = (jnp.swapaxes(inp, 0, 1), jnp.swapaxes(act, 0, 1), jnp.swapaxes(wind, 0, 1))
        # (the batch's arrays are jax Arrays inside the trace)
        _, (obs, res) = jax.lax.scan(step, cast(tuple[jax.Array, jax.Array], (x0, hist)), xs)
        return jnp.swapaxes(obs, 0, 1), jnp.swapaxes(res, 0, 1)

    return simulate


def make_loss(simulate: Simulate, sigma: np.ndarray, y_scale: np.ndarray, l2: float,
              physics: bool, coefficients: Coefficients | None = None
              ) -> tuple[DataLoss, Total]:
    """
    Return the batch losses data_loss(model, b, w) and total(model, b, w).

    The data loss is the mean over windows, steps and the six states of
    ((simulated - measured) / sigma)^2 (Wakita et al. 2022's simulation-based loss, heading
    wrapped), each window weighted by w; the total adds l2 x the mean squared residual in
    y_scale units, weighted alike (hybrid: keeps it small where the physics is right) or x the
    mean squared weight (pure network); with ``coefficients`` (a :class:`Joint` model) also
    their prior's penalty.
    """
    inv = jnp.asarray(1.0 / np.asarray(sigma))
    inv_y2 = jnp.asarray(1.0 / np.asarray(y_scale) ** 2)

    def data_loss(model: MLP | Joint, b: Mapping[str, ArrayLike], w: ArrayLike
                  ) -> tuple[jax.Array, jax.Array, jax.Array]:
        obs, res = simulate(model, b['x0'], b['hist'], b['inp'], b['act'], b['wind'])
        e = obs - b['target']
        e = e.at[:, :, 2].set((e[:, :, 2] + jnp.pi) % (2 * jnp.pi) - jnp.pi)
        per = jnp.mean((e * inv) ** 2, axis=(1, 2))
        return jnp.sum(per * w) / jnp.sum(w), res, per

    def total(model: MLP | Joint, b: Mapping[str, ArrayLike], w: ArrayLike
              ) -> tuple[jax.Array, jax.Array]:
        d, res, _ = data_loss(model, b, w)
        if physics:   # weighted as the data loss: a window weighing more is held closer
            per = jnp.mean(res ** 2, axis=1) @ inv_y2 / 3.0
            reg: jax.Array | float = jnp.sum(per * w) / jnp.sum(w)
        else:
            assert isinstance(model, MLP)
            leaves = [la.weight for la in model.layers]
            reg = sum(jnp.sum(x ** 2) for x in leaves) / sum(x.size for x in leaves)
        out = d + l2 * reg
        if isinstance(model, Joint):
            assert coefficients is not None
            out = out + coefficients.penalty(model.z)
        return out, d

    return data_loss, total


def optimiser(learning_rate: float) -> Any:   # an optax GradientTransformation (no stubs)
    return optax.chain(optax.clip_by_global_norm(1.0), optax.adam(learning_rate))
