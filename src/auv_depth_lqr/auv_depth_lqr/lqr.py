"""Discrete LQR design from a continuous cost, and controllability tests.

The depth loop is designed on a continuous linear model ``x_dot = A x + B u`` (from the
linearisation of the vehicle model about a trim point) and runs as a sampled controller with
zero-order hold. :func:`lqrd` computes the discrete gain that minimises the *continuous*
quadratic cost, exactly as MATLAB's ``lqrd``: the cost is integrated over one sample period
with the input held constant, which yields the discrete weights ``Qd``, ``Rd`` and a cross
term ``Nd`` (Van Loan's block-matrix exponential; Franklin, Powell & Workman, *Digital Control
of Dynamic Systems*, 3rd ed., section 9.4.4), then the discrete Riccati equation with its
cross term is solved with :func:`scipy.linalg.solve_discrete_are` (what
:func:`control.dlqr` calls without slycot; importing python-control for it cost the depth
pilot 2.2 s of CPU at start, and the tests compare the gains with it).

Sign convention (MATLAB's and python-control's): the optimal input is ``u = -K x``.

This module is pure: no ROS import, no global state.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from auv_depth_lqr.errors import DesignError, NotControllableError

__all__ = [
    'Controllability',
    'LqrdResult',
    'as_matrix',
    'check_controllable',
    'controllability',
    'input_rate_system',
    'lqrd',
    'uncontrollable_modes',
]

Matrix = NDArray[np.float64]


class Controllability(NamedTuple):
    """Rank and conditioning of the controllability matrix ``[B, AB, ..., A^(n-1) B]``."""

    rank: int
    """Numerical rank (SVD, NumPy's default tolerance)."""
    condition: float
    """2-norm condition number (largest over smallest singular value); ``inf`` if singular."""


class LqrdResult(NamedTuple):
    """Discrete LQR designed from a continuous cost (see :func:`lqrd`).

    ``x`` has ``n`` states and ``u`` has ``m`` inputs.
    """

    K: Matrix
    """Gain (m, n) of the sampled state feedback ``u[k] = -K x[k]``."""
    S: Matrix
    """Solution (n, n) of the discrete algebraic Riccati equation."""
    E: NDArray[np.complex128]
    """Closed-loop eigenvalues (n,) of ``Phi - Gamma K`` (z-plane)."""
    Phi: Matrix
    """Zero-order-hold state transition (n, n): ``expm(A Ts)``."""
    Gamma: Matrix
    """Zero-order-hold input matrix (n, m): ``int_0^Ts expm(A t) dt B``."""
    Qd: Matrix
    """Discrete state weight (n, n)."""
    Rd: Matrix
    """Discrete input weight (m, m)."""
    Nd: Matrix
    """Discrete cross weight (n, m)."""


def as_matrix(
    name: str, value: ArrayLike, shape: tuple[int | None, int | None], expected: str
) -> Matrix:
    """Return ``value`` as a finite 2-D float array of ``shape`` (``None``: any size).

    A scalar is accepted where a (1, 1) matrix fits and a 1-D array for a single column.
    ``expected`` spells the expected shape for the error message, e.g. ``'(n, m) = (5, m)'``.
    """
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DesignError(f'{name} must be a numeric matrix, got {value!r}') from None
    if arr.ndim == 0 and all(s in (1, None) for s in shape):
        arr = arr.reshape(1, 1)
    if arr.ndim == 1 and shape[1] in (1, None) and shape[0] in (arr.size, None):
        arr = arr.reshape(-1, 1)
    if arr.ndim != 2 or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        raise DesignError(f'{name} must have shape {expected}, got shape {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise DesignError(f'{name} has non-finite entries: {arr.tolist()}')
    return arr


def _system(A: ArrayLike, B: ArrayLike) -> tuple[Matrix, Matrix]:
    """Check and return (A, B): A square (n, n), B (n, m)."""
    a = as_matrix('A', A, (None, None), '(n, n)')
    n = a.shape[0]
    if a.shape != (n, n) or n == 0:
        raise DesignError(f'A must be square and non-empty, got shape {a.shape}')
    b = as_matrix('B', B, (n, None), f'(n, m) with n = {n}')
    if b.shape[1] == 0:
        raise DesignError(f'B must have at least one column, got shape {b.shape}')
    return a, b


def _symmetric(name: str, M: Matrix, definite: bool) -> Matrix:
    """Check that ``M`` is symmetric and positive semi-definite (``definite``: definite)."""
    scale = max(1.0, float(np.max(np.abs(M))))
    if not np.allclose(M, M.T, rtol=0.0, atol=1e-10 * scale):
        raise DesignError(f'{name} must be symmetric, got {M.tolist()}')
    sym = 0.5 * (M + M.T)
    lowest = float(np.min(np.linalg.eigvalsh(sym)))
    if definite and lowest <= 0.0:
        raise DesignError(
            f'{name} must be positive definite, its smallest eigenvalue is {lowest:.6g}')
    if not definite and lowest < -1e-12 * scale:
        raise DesignError(
            f'{name} must be positive semi-definite, its smallest eigenvalue is {lowest:.6g}')
    return sym


def controllability(A: ArrayLike, B: ArrayLike) -> Controllability:
    """Rank and condition number of the controllability matrix of ``x_dot = A x + B u``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix (continuous or discrete; the test is the same).
    B : array_like, shape (n, m)
        Input matrix.

    Returns
    -------
    Controllability
        ``(rank, condition)`` of ``C_o = [B, AB, ..., A^(n-1) B]``. A rank of ``n`` means
        controllable; a large condition number means some modes are barely reachable (the
        rank then depends on the scaling of the states, check with :func:`check_controllable`).
    """
    a, b = _system(A, B)
    n = a.shape[0]
    blocks = [b]
    for _ in range(n - 1):
        blocks.append(a @ blocks[-1])
    co = np.hstack(blocks)
    sv = np.linalg.svd(co, compute_uv=False)
    rank = int(np.linalg.matrix_rank(co))
    condition = float(sv[0] / sv[n - 1]) if sv[n - 1] > 0.0 else math.inf
    return Controllability(rank, condition)


def uncontrollable_modes(
    A: ArrayLike, B: ArrayLike, rtol: float = 1e-9
) -> NDArray[np.complex128]:
    """Eigenvalues of A that the input cannot move (Popov-Belevitch-Hautus test).

    An eigenvalue ``lam`` of A is uncontrollable when ``[lam I - A, B]`` loses rank, i.e. when
    its smallest singular value is below ``rtol * max(1, ||[A, B]||_2)``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix.
    B : array_like, shape (n, m)
        Input matrix.
    rtol : float
        Relative tolerance of the rank test (dimensionless).

    Returns
    -------
    ndarray of complex, shape (k,)
        The uncontrollable eigenvalues (``k = 0`` for a controllable pair).
    """
    a, b = _system(A, B)
    n = a.shape[0]
    tol = rtol * max(1.0, float(np.linalg.norm(np.hstack([a, b]), 2)))
    modes = []
    for lam in np.linalg.eigvals(a):
        pbh = np.hstack([lam * np.eye(n) - a, b.astype(complex)])
        if np.linalg.svd(pbh, compute_uv=False)[n - 1] <= tol:
            modes.append(lam)
    return np.array(modes, dtype=complex)


def _format_eig(lam: complex) -> str:
    """An eigenvalue as ``-2`` or ``-0.5+1.2j`` (6 significant digits)."""
    if abs(lam.imag) <= 1e-12 * max(1.0, abs(lam)):
        return f'{lam.real:.6g}'
    return f'{lam.real:.6g}{lam.imag:+.6g}j'


def check_controllable(A: ArrayLike, B: ArrayLike, rtol: float = 1e-9) -> Controllability:
    """Raise :class:`NotControllableError` unless ``(A, B)`` is controllable.

    The pair is declared uncontrollable when the controllability matrix is rank deficient or
    the PBH test (:func:`uncontrollable_modes`) finds an eigenvalue the input cannot move.

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix.
    B : array_like, shape (n, m)
        Input matrix.
    rtol : float
        Relative tolerance of the PBH rank test.

    Returns
    -------
    Controllability
        Rank and condition number, for reporting.

    Raises
    ------
    NotControllableError
        With the rank of the controllability matrix and the uncontrollable eigenvalues.
    """
    ctrb = controllability(A, B)
    modes = uncontrollable_modes(A, B, rtol=rtol)
    n = np.shape(A)[0]
    if ctrb.rank < n or modes.size > 0:
        listed = ', '.join(_format_eig(complex(lam)) for lam in modes) or 'none found by PBH'
        raise NotControllableError(
            f'(A, B) is not controllable: the controllability matrix has rank {ctrb.rank} '
            f'of {n}; uncontrollable mode(s) at eigenvalue(s) {listed}')
    return ctrb


def input_rate_system(A: ArrayLike, B: ArrayLike) -> tuple[Matrix, Matrix]:
    """The plant with its input as a state and the input's rate as the new input.

    ``x_dot = A x + B u`` becomes ``x_a_dot = A_a x_a + B_a r`` with ``x_a = (x, u)`` and
    ``r = u_dot``::

        A_a = [[A, B],     B_a = [[0],
               [0, 0]],           [I]]

    A gain designed on it (:func:`lqrd`) feeds the input's rate back on the state and on the
    input itself, so a weight on ``r`` prices the actuator's rate, and a weight on ``u`` (a
    diagonal entry of the augmented state weight) its angle.

    Parameters
    ----------
    A : array_like, shape (n, n)
        The plant's continuous state matrix [1/s].
    B : array_like, shape (n, m)
        The plant's continuous input matrix [state unit / (input unit s)].

    Returns
    -------
    tuple of ndarray
        ``A_a`` (n + m, n + m) [1/s] and ``B_a`` (n + m, m) [1 for the input rows].

    Raises
    ------
    DesignError
        On a wrong shape or non-finite entries.
    """
    a, b = _system(A, B)
    n, m = b.shape
    a_aug = np.zeros((n + m, n + m))
    a_aug[:n, :n], a_aug[:n, n:] = a, b
    b_aug = np.zeros((n + m, m))
    b_aug[n:, :] = np.eye(m)
    return a_aug, b_aug


def lqrd(
    A: ArrayLike,
    B: ArrayLike,
    Q: ArrayLike,
    R: ArrayLike,
    Ts: float,
    N: ArrayLike | None = None,
) -> LqrdResult:
    r"""Discrete LQR gain minimising a continuous cost, sampled with zero-order hold.

    For the continuous plant ``x_dot = A x + B u`` driven by a piecewise-constant input
    ``u(t) = u[k]`` on ``[k Ts, (k+1) Ts)``, the continuous cost

    .. math:: J = \int_0^\infty (x'Qx + u'Ru + 2x'Nu)\, dt

    equals the discrete cost ``sum_k (x'Qd x + u'Rd u + 2 x'Nd u)`` with

    .. math::
        \begin{bmatrix} Q_d & N_d \\ N_d' & R_d \end{bmatrix}
        = \int_0^{T_s} e^{F' t} \begin{bmatrix} Q & N \\ N' & R \end{bmatrix} e^{F t}\, dt,
        \qquad F = \begin{bmatrix} A & B \\ 0 & 0 \end{bmatrix},

    computed by Van Loan's method from one matrix exponential,
    ``expm([[-F', W], [0, F]] Ts) = [[., G12], [0, G22]]`` and ``int = G22' G12``
    (Franklin, Powell & Workman, section 9.4.4; the same construction as MATLAB's ``lqrd``).
    The weights are scaled to unit norm inside the exponential, so very large or very small
    weights (e.g. ``R = 1e9``) do not degrade its accuracy; the scale is restored afterwards.
    The gain then comes from the stabilising solution ``S`` of the discrete algebraic Riccati
    equation on ``(Phi, Gamma, Qd, Rd, Nd)`` (:func:`scipy.linalg.solve_discrete_are`):
    ``K = (Rd + Gamma' S Gamma)^-1 (Gamma' S Phi + Nd')``, as :func:`control.dlqr` gives it.

    Parameters
    ----------
    A : array_like, shape (n, n)
        Continuous state matrix [1/s].
    B : array_like, shape (n, m)
        Continuous input matrix [state unit / (input unit s)].
    Q : array_like, shape (n, n)
        State weight, symmetric positive semi-definite [1 / (state unit^2 s)].
    R : array_like, shape (m, m) or scalar when m == 1
        Input weight, symmetric positive definite [1 / (input unit^2 s)].
    Ts : float
        Sample period [s], finite and positive.
    N : array_like, shape (n, m), optional
        Cross weight; zero if omitted.

    Returns
    -------
    LqrdResult
        ``K, S, E, Phi, Gamma, Qd, Rd, Nd``; the control law is ``u[k] = -K x[k]``.

    Raises
    ------
    DesignError
        On a wrong shape (the message names the matrix and the expected shape), non-finite
        entries, Q not symmetric PSD, R not symmetric PD, a bad ``Ts``, or when the discrete
        Riccati equation has no stabilising solution (e.g. an unstabilisable pair).

    Examples
    --------
    Scalar integrator ``x_dot = u`` with ``q = r = 1``: as ``Ts -> 0`` the gain tends to the
    continuous ``sqrt(q / r) = 1``.

    >>> round(float(lqrd([[0.0]], [[1.0]], [[1.0]], [[1.0]], 1e-4).K[0, 0]), 3)
    1.0
    """
    a, b = _system(A, B)
    n, m = b.shape
    q = _symmetric('Q', as_matrix('Q', Q, (n, n), f'(n, n) = ({n}, {n})'), definite=False)
    r = _symmetric('R', as_matrix('R', R, (m, m), f'(m, m) = ({m}, {m})'), definite=True)
    nn = np.zeros((n, m)) if N is None else as_matrix('N', N, (n, m), f'(n, m) = ({n}, {m})')
    try:
        ts = float(Ts)
    except (TypeError, ValueError):
        raise DesignError(f'Ts must be a number of seconds, got {Ts!r}') from None
    if not (math.isfinite(ts) and ts > 0.0):
        raise DesignError(f'Ts must be finite and > 0 s, got {Ts!r}')

    weight = np.block([[q, nn], [nn.T, r]])
    scale = float(np.max(np.abs(weight)))
    if scale == 0.0:  # R is positive definite, so this cannot happen; kept for clarity
        raise DesignError('the cost weights are all zero')
    k = n + m
    F = np.zeros((k, k))
    F[:n, :n] = a
    F[:n, n:] = b
    vanloan = np.zeros((2 * k, 2 * k))
    vanloan[:k, :k] = -F.T
    vanloan[:k, k:] = weight / scale
    vanloan[k:, k:] = F
    G = scipy.linalg.expm(vanloan * ts)
    G12 = G[:k, k:]
    G22 = G[k:, k:]
    W = G22.T @ G12 * scale
    W = 0.5 * (W + W.T)
    Qd, Nd, Rd = W[:n, :n], W[:n, n:], W[n:, n:]
    Phi, Gamma = G22[:n, :n], G22[:n, n:]

    try:
        S = scipy.linalg.solve_discrete_are(Phi, Gamma, Qd, Rd, s=Nd)
        K = np.linalg.solve(Rd + Gamma.T @ S @ Gamma, Gamma.T @ S @ Phi + Nd.T)
        E = np.linalg.eigvals(Phi - Gamma @ K)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        raise DesignError(
            f'no stabilising discrete LQR solution for this (A, B, Q, R, Ts={ts:g} s): '
            f'{exc}') from None
    if not (np.all(np.isfinite(K)) and np.all(np.abs(E) < 1.0)):
        raise DesignError(f'no stabilising discrete LQR solution for this (A, B, Q, R, '
                          f'Ts={ts:g} s): closed-loop eigenvalues {np.abs(E).max():.6g} in '
                          'modulus')
    return LqrdResult(
        K=np.asarray(K, dtype=float), S=np.asarray(S, dtype=float),
        E=np.asarray(E, dtype=complex), Phi=Phi, Gamma=Gamma, Qd=Qd, Rd=Rd, Nd=Nd)
