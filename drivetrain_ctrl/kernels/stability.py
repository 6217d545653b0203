"""The largest stable step of a mode: ``STABILITY_FACTOR / rho(J)`` from the mode's Jacobian.

The spectral radius ``rho`` is bounded from above by :func:`_spectral_radius_bound` (Gelfand's
formula on the balanced Jacobian); the simulator first uses a cruder, cheaper lower bound of the
step (:func:`stable_step_lazy`) and the tight one only where it can matter
(:func:`stable_step_exact`), both cached per mode and table region.
"""

from __future__ import annotations

import numpy as np

from ._jit import jit, jit_inline, jit_nonrt
from .physics import jacobians

#: |lambda| h allowed per step for the mode's fastest eigenvalue (with |lambda| from
#: :func:`_spectral_radius_bound`), so that a loose tolerance cannot let a stiff mode grow
#: numerically and trigger spurious stick/slip events. Dormand-Prince 5(4)'s stability region
#: reaches about 3.3 on the negative real axis, so for well-damped modes this is inside it with a
#: margin. Near the imaginary axis the region is narrower: along the ray of the lightly damped
#: gear-mesh eigenvalue (damping ratio about 0.03) it ends near 2.2, on the axis itself near 1.0
#: (``python benchmarks/step_limits.py`` prints both). For such a mode this bound is only a
#: ceiling; the error control keeps the steps inside the region (the local error estimate grows
#: with the numerically amplified mode), and the steps there sit below the bound (the script
#: prints the distribution of h / bound).
STABILITY_FACTOR = 2.5


@jit_nonrt
def _mode_key(fm, reg):
    key = np.int64(7)
    for f in range(fm.shape[0]):
        key = key * np.int64(1000003) + np.int64(fm[f] + 1)
    for k in range(reg.shape[0]):
        key = key * np.int64(1000003) + np.int64(reg[k] + 1)
    return key


@jit
def _balance(J):
    """``S^-1 J S`` for a diagonal ``S`` of powers of 2 that balances row and column norms
    (EISPACK ``balanc`` without permutations): similar to ``J``, exactly so in floating point."""
    n = J.shape[0]
    A = J.copy()
    for _sweep in range(50):
        done = True
        for i in range(n):
            c = 0.0
            r = 0.0
            for j in range(n):
                if j != i:
                    c += abs(A[j, i])
                    r += abs(A[i, j])
            if c == 0.0 or r == 0.0:
                continue
            g = r / 2.0
            f = 1.0
            sm = c + r
            while c < g:
                f *= 2.0
                c *= 4.0
            g = r * 2.0
            while c >= g:
                f /= 2.0
                c /= 4.0
            if (c + r) / f < 0.95 * sm:
                done = False
                for j in range(n):
                    A[i, j] /= f
                    A[j, i] *= f
        if done:
            break
    return A


@jit
def _inf_norm(A):
    """Max row sum of ``|A|`` (the operator norm induced by the max norm)."""
    nrm = 0.0
    for i in range(A.shape[0]):
        r = 0.0
        for j in range(A.shape[1]):
            r += abs(A[i, j])
        if r > nrm:
            nrm = r
    return nrm


#: squarings in :func:`_spectral_radius_bound`: ``||A^1024||^(1/1024)``, within 3 % of the
#: spectral radius on the drivetrain's mode Jacobians (``tests/unit/test_kernel_numerics.py``)
GELFAND_SQUARINGS = 10


@jit
def _spectral_radius_bound(J):
    """An upper bound of the spectral radius of ``J``, tight to a few per cent: Gelfand's
    ``rho(A) <= ||A^m||^(1/m)`` for every induced norm, with ``A`` the balanced ``J`` and
    ``m = 2^GELFAND_SQUARINGS`` (repeated squaring, normalised after each product so that nothing
    overflows; the logarithms of the norms are accumulated). Ten small matrix products in place
    of LAPACK's eigenvalue routine, which it replaces: the bound only sets the largest stable
    step, where a bound from above is what is needed (``tests/unit/test_kernel_numerics.py``
    checks both sides)."""
    A = _balance(J)
    nrm = _inf_norm(A)
    if nrm == 0.0:
        return 0.0
    B = A / nrm
    lg = np.log(nrm)
    for _k in range(GELFAND_SQUARINGS):
        B = B @ B
        nb = _inf_norm(B)
        if nb == 0.0:  # nilpotent: spectral radius 0
            return 0.0
        lg = 2.0 * lg + np.log(nb)
        B /= nb
    return np.exp(lg / 2.0**GELFAND_SQUARINGS)


@jit
def _rho_step(J):
    """``STABILITY_FACTOR / rho`` with ``rho`` :func:`_spectral_radius_bound` (``inf`` for 0),
    with a margin for round-off in the products."""
    rho = _spectral_radius_bound(J)
    return STABILITY_FACTOR / (rho * (1.0 + 1e-9)) if rho > 0.0 else np.inf


@jit
def stable_step_lazy(D, y, u, fm, reg, P, nx, key, jcache, lcache):
    """Largest step [s] that keeps the mode's fastest eigenvalue in the stability region,
    ``STABILITY_FACTOR / max |lambda(J)|`` (J at the first entry of the mode; cached per mode and
    table region), without the tight bound of the spectral radius until it can matter.

    Returns ``(h, exact)``: the tight step bound (``STABILITY_FACTOR / rho`` with ``rho`` from
    :func:`_spectral_radius_bound`, at most ~1 % above the spectral radius) if it is known for the
    mode (``exact``), else a cruder lower bound of it, ``STABILITY_FACTOR / ||S^-1 J S||``
    (balanced norm; J kept in ``jcache``). A step not longer than the crude bound is not limited
    by the tight one either, so :func:`stable_step_exact` is only called for longer steps, and
    modes that only see short steps (chatter after events) never need it. The caller
    (:func:`_stab_lookup`) has looked ``key`` up in both caches: this is the miss path. ``jcache``
    keeps the balanced J (similar to J: the same spectral radius)."""
    J, _B = jacobians(D, y[:nx], u, fm, reg, P, False)
    A = _balance(J)
    nrm = _inf_norm(A)
    # margin for round-off in the norm's sums (~1e-15)
    h_lo = STABILITY_FACTOR / (nrm * (1.0 + 1e-9)) if nrm > 0.0 else np.inf
    jcache[key] = A
    lcache[key] = h_lo
    return h_lo, False


@jit
def stable_step_exact(fm, reg, hcache, jcache):
    """The tight bound of :func:`stable_step_lazy` for a mode it has seen (:func:`_rho_step`)."""
    key = _mode_key(fm, reg)
    if key in hcache:
        return hcache[key]
    h = _rho_step(jcache[key])
    hcache[key] = h
    return h


@jit_inline
def _stab_lookup(D, y, u, fm, reg, P, nx, hcache, jcache, lcache):
    """The mode's step bound ``(h, exact)`` from the caches (see :func:`stable_step_lazy`, called
    only for a new mode)."""
    key = _mode_key(fm, reg)
    if key in hcache:
        return hcache[key], True
    if key in lcache:
        return lcache[key], False
    return stable_step_lazy(D, y, u, fm, reg, P, nx, key, jcache, lcache)
