"""
Compiled helpers of the training: the physics over a batch with its state Jacobian.

The differentiable simulation calls the *same* compiled ``core.dynamics.derivative`` as every
other simulation (one source of the force equations): :func:`batch_derivative` evaluates it
for a batch of states, and its Jacobian with respect to the state by forward differences in
float64 (the families have branches and table look-ups; a finite difference of the compiled
kernel needs no second implementation). JAX sees it through a custom VJP
(``_engine.physics_fn``), calling it as an XLA FFI handler (:func:`ffi_handler`, a numba
``cfunc`` of the C API in ``jaxlib/include/xla/ffi/api/c_api.h``): no Python between the
compiled steps; a forward call on 64 rows (Esso Osaka) takes 15 us where
``jax.pure_callback``'s round trip through Python took 82. NumPy and numba only.
"""
from __future__ import annotations

from typing import Any, TYPE_CHECKING

from llvmlite import ir  # type: ignore[import-untyped]
from mmg_tuner.core.correction import window_residual
from mmg_tuner.core.dynamics import act_tuple, derivative
from mmg_tuner.core.layout import PARAM_INDEX
from numba import cfunc, njit, types
from numba.core.extending import intrinsic
from numba.np.numpy_support import carray
import numpy as np

if TYPE_CHECKING:  # annotations only: numba never evaluates them
    from mmg_tuner.core._jit import FloatArray, IntArray
    import numpy.typing as npt

_Vw = PARAM_INDEX['wind_speed']
_dirw = PARAM_INDEX['wind_dir']
FD_REL_STEP = 1.5e-8
"""Forward-difference step, relative to max(1, |state|): about sqrt(machine epsilon), so
truncation and rounding are both ~1e-8 of the derivative's scale, far below what a stochastic
optimiser's gradient needs; central differences (1e-10) cost twice the kernel calls, and the
Jacobian was most of a hybrid training's time (133 against 74 us a 64-row batch, Esso Osaka)."""


def param_steps(start: npt.ArrayLike, lower: npt.ArrayLike, upper: npt.ArrayLike) -> np.ndarray:
    """Return the parameter Jacobian's steps: FD_REL_STEP x max(box width, |value|)."""
    width = np.asarray(upper, dtype=float) - np.asarray(lower, dtype=float)
    h: np.ndarray = FD_REL_STEP * np.maximum(width, np.abs(np.asarray(start, dtype=float)))
    return h


@njit(cache=True, inline='always')
def _load_row(kind: tuple[int, ...], p: FloatArray, S: FloatArray, A: FloatArray,
              Wd: FloatArray, b: int, s: FloatArray) -> tuple[float, ...]:
    """Load row b: its wind into p's wind slots, its state into s; return its actuators."""
    p[_Vw] = Wd[b, 0]
    p[_dirw] = Wd[b, 1]
    for i in range(6):
        s[i] = S[b, i]
    return act_tuple(kind, A, b)


@njit(cache=True)
def batch_derivative(kind: tuple[int, ...], p_in: FloatArray, S: FloatArray, A: FloatArray,
                     Wd: FloatArray, F: FloatArray, J: FloatArray, with_jac: bool) -> None:
    """
    Fill ds/dt F (B, 6) of the family for states, actuator tuples and winds.

    ``kind``: the family's tag; S (B, 6) states, A (B, n_outputs) actuator tuples, Wd (B, 2)
    winds.

    Wd holds (wind_speed [m/s], wind_dir [rad]) per row (the measured wind of the sample, or
    the ship's parameters). with_jac: also J (B, 6, 6) = dF/dS by forward differences (x, y
    do not enter the dynamics: their columns are exactly 0).
    """
    p = p_in.copy()
    s = np.empty(6)
    out = np.empty(6)
    fp = np.empty(6)
    for b in range(S.shape[0]):
        act = _load_row(kind, p, S, A, Wd, b, s)
        derivative(kind, p, s, act, out)
        for i in range(6):
            F[b, i] = out[i]
        if not with_jac:
            continue
        for i in range(6):
            J[b, i, 0] = 0.0
            J[b, i, 1] = 0.0
        for j in range(2, 6):
            h = FD_REL_STEP * max(1.0, abs(S[b, j]))
            s[j] = S[b, j] + h
            derivative(kind, p, s, act, fp)
            s[j] = S[b, j]
            for i in range(6):
                J[b, i, j] = (fp[i] - out[i]) / h


@njit(cache=True)
def batch_param_jacobian(kind: tuple[int, ...], p_in: FloatArray, S: FloatArray,
                         A: FloatArray, Wd: FloatArray, F: FloatArray, idx: IntArray,
                         hp: FloatArray, Jp: FloatArray) -> None:
    """
    Fill Jp (B, 6, k) = dF/dp[idx] by forward differences (steps hp (k,)) at F's rows.

    F: :func:`batch_derivative`'s output for the same rows and parameters (the base point);
    idx: the parameter slots (never the wind's, which each row sets). For the training of a
    network and the physics' coefficients together (``_engine.physics_fn(free=...)``).
    """
    p = p_in.copy()
    s = np.empty(6)
    fp = np.empty(6)
    for b in range(S.shape[0]):
        act = _load_row(kind, p, S, A, Wd, b, s)
        for k in range(idx.shape[0]):
            j = idx[k]
            p[j] = p_in[j] + hp[k]
            derivative(kind, p, s, act, fp)
            p[j] = p_in[j]
            for i in range(6):
                Jp[b, i, k] = (fp[i] - F[b, i]) / hp[k]


@njit(cache=True)
def teacher_residuals(rows: FloatArray, window: int, sizes: IntArray, flat: FloatArray,
                      x_mean: FloatArray, x_std: FloatArray, y_scale: FloatArray,
                      out: FloatArray) -> None:
    """
    Fill out (T, 3) with the residual on a measured history.

    At each sample the window of measured rows (padded with the first at the start), as a
    one-step prediction sees it.
    """
    T = rows.shape[0]
    nf = rows.shape[1]
    ring = np.empty((window, nf))
    z = np.empty(window * nf)
    nb = 0
    for i in range(sizes.shape[0]):
        nb = max(nb, sizes[i])
    buf_a = np.empty(nb)
    buf_b = np.empty(nb)
    for k in range(T):
        for i in range(window):
            kk = k - (window - 1) + i
            if kk < 0:
                kk = 0
            for f in range(nf):
                ring[i, f] = rows[kk, f]
        a0, a1, a2 = window_residual(ring, window, sizes, flat, x_mean, x_std, y_scale, z,
                                     buf_a, buf_b)
        out[k, 0] = a0
        out[k, 1] = a1
        out[k, 2] = a2


# ----------------------------------------------------------------------------- XLA FFI handler
FFI_API_VERSION = (0, 3)
"""The XLA FFI C API version the handler's struct offsets follow (``XLA_FFI_API_MAJOR``,
``_MINOR`` of jaxlib 0.10's c_api.h). XLA asks a handler its version when it is registered
and refuses a major version it does not speak: a changed layout fails there, loudly, and the
training falls back to ``jax.pure_callback`` (``_engine.physics_fn``)."""
_METADATA_EXTENSION = 1      # XLA_FFI_Extension_Metadata
_EXECUTE = 3                 # XLA_FFI_ExecutionStage_EXECUTE


def _ptr_typer(typingctx, addr):  # type: ignore[no-untyped-def]  # numba's intrinsic protocol
    def codegen(context, builder, signature, args):  # type: ignore[no-untyped-def]
        return builder.inttoptr(args[0], ir.IntType(8).as_pointer())
    return types.voidptr(types.int64), codegen


_ptr: Any = intrinsic(_ptr_typer)
"""An address (int64) as a pointer (compiled only): the C structs hold addresses."""


_HANDLERS: dict[int, object] = {}


@njit(cache=True)
def _rows(buf: IntArray) -> int:
    """Return the elements of an XLA_FFI_Buffer (as 8-byte words) over its last axis: rows."""
    dims = carray(_ptr(buf[5]), (buf[4],), dtype=np.int64)
    n = 1
    for i in range(buf[4] - 1):
        n *= dims[i]
    return n


@njit(cache=True)
def _last(buf: IntArray) -> int:
    """Return the length of an XLA_FFI_Buffer's last axis."""
    return int(carray(_ptr(buf[5]), (buf[4],), dtype=np.int64)[buf[4] - 1])


def ffi_handler(kind: int) -> object:
    """
    Return the XLA FFI handler (a numba cfunc) of family code ``kind``'s physics.

    Arguments (XLA buffers, float64 only: the caller casts, the handler reads bytes): the
    states S (..., 6), actuator tuples A (..., n), winds Wd (..., 2) (:func:`batch_derivative`)
    and the parameter vector (read from the buffer at every call); results: F (..., 6), and
    with a second result the state Jacobian J (..., 6, 6). With two more arguments, the free
    parameters' slots (k,) and their difference steps (k,) (both float64), and a third result:
    the parameter Jacobian Jp (..., 6, k) (:func:`batch_param_jacobian`). Every leading axis
    is one batch of rows. Compiled once per family and process (about a second). The struct
    offsets are those of ``FFI_API_VERSION`` on a 64-bit platform (every field 8 bytes, enums
    padded).
    """
    if kind in _HANDLERS:
        return _HANDLERS[kind]
    from mmg_tuner.core.dynamics import family_tag
    tag = family_tag(kind)
    major, minor = FFI_API_VERSION

    @cfunc(types.voidptr(types.voidptr), cache=True, error_model='numpy')
    def handler(frame):  # type: ignore[no-untyped-def]  # a numba cfunc
        # XLA_FFI_CallFrame as 8-byte words: 1 extension_start, 9 args.args, 12 rets.size,
        # 14 rets.rets; the stage is a 4-byte enum at byte 32 (its padding is not ours to read)
        cf = carray(frame, (15,), dtype=np.int64)   # 7 args.size
        if cf[1] != 0 and carray(_ptr(cf[1] + 8), (1,), dtype=np.int32)[0] == \
                _METADATA_EXTENSION:   # XLA asks the handler's metadata (at registration)
            md = _ptr(carray(_ptr(cf[1]), (4,), dtype=np.int64)[3])
            words = carray(md, (3,), dtype=np.int64)   # XLA_FFI_Metadata: api_version at 8
            words[1] = 24       # XLA_FFI_Api_Version's struct_size
            words[2] = 0        # its extension_start
            half = carray(md, (9,), dtype=np.int32)
            half[6] = major
            half[7] = minor
            half[8] = 0         # traits (at byte 32)
            return _ptr(0)
        if carray(frame, (9,), dtype=np.int32)[8] != _EXECUTE:
            return _ptr(0)
        args = carray(_ptr(cf[9]), (cf[7],), dtype=np.int64)
        rets = carray(_ptr(cf[14]), (cf[12],), dtype=np.int64)
        # XLA_FFI_Buffer as words: 3 data, 4 rank, 5 dims
        bs = carray(_ptr(args[0]), (6,), dtype=np.int64)
        B = _rows(bs)
        S = carray(_ptr(bs[3]), (B, 6), dtype=np.float64)
        ba = carray(_ptr(args[1]), (6,), dtype=np.int64)
        A = carray(_ptr(ba[3]), (B, _last(ba)), dtype=np.float64)
        bw = carray(_ptr(args[2]), (6,), dtype=np.int64)
        Wd = carray(_ptr(bw[3]), (B, 2), dtype=np.float64)
        # the parameters: one vector, or one per leading index under jax.vmap ('broadcast_all'
        # gives every argument the same leading axes), each for B / groups rows
        bp = carray(_ptr(args[3]), (6,), dtype=np.int64)
        n_p = _last(bp)
        groups = _rows(bp)
        P = carray(_ptr(bp[3]), (groups, n_p), dtype=np.float64)
        bf = carray(_ptr(rets[0]), (6,), dtype=np.int64)
        F = carray(_ptr(bf[3]), (B, 6), dtype=np.float64)
        m = B // groups
        J = np.empty((1, 6, 6))
        if cf[12] > 1:
            bj = carray(_ptr(rets[1]), (6,), dtype=np.int64)
            J = carray(_ptr(bj[3]), (B, 6, 6), dtype=np.float64)
        n_free = 0
        idx = np.empty(0, dtype=np.int64)
        hp = np.empty(0)
        Jp = np.empty((1, 6, 1))
        if cf[12] > 2 and cf[7] > 5:   # the free parameters' Jacobian (the same for each group)
            bi = carray(_ptr(args[4]), (6,), dtype=np.int64)
            n_free = _last(bi)
            idx = carray(_ptr(bi[3]), (n_free,), dtype=np.float64).astype(np.int64)
            bh = carray(_ptr(args[5]), (6,), dtype=np.int64)
            hp = carray(_ptr(bh[3]), (n_free,), dtype=np.float64)
            bq = carray(_ptr(rets[2]), (6,), dtype=np.int64)
            Jp = carray(_ptr(bq[3]), (B, 6, n_free), dtype=np.float64)
            Jp[:] = np.nan
        # NaN first: a kernel that raised (nothing can be raised through XLA from here) leaves
        # NaN, which the training skips as a diverging window, never stale memory
        F[:] = np.nan
        J[:] = np.nan
        for g in range(groups):   # under jax.vmap: one parameter row per group of rows
            lo, hi = g * m, (g + 1) * m
            if groups == 1:   # whole arrays (no slicing)
                batch_derivative(tag, P[0], S, A, Wd, F, J, cf[12] > 1)
            else:
                batch_derivative(tag, P[g], S[lo:hi], A[lo:hi], Wd[lo:hi], F[lo:hi],
                                 J[lo:hi] if cf[12] > 1 else J, cf[12] > 1)
            if n_free > 0:
                batch_param_jacobian(tag, P[g], S[lo:hi], A[lo:hi], Wd[lo:hi], F[lo:hi], idx,
                                     hp, Jp[lo:hi])
        return _ptr(0)

    _HANDLERS[kind] = handler
    return handler
