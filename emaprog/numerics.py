"""Numerical method: time steps of the models, threads of the fits. Kept apart from physical
parameters."""

from __future__ import annotations

from typing import NamedTuple

from threadpoolctl import threadpool_limits


class Numerics(NamedTuple):
    """Integration steps per controller period for each model."""

    reference_substeps: int = 100  # 1 us at 10 kHz: resolves the hysteresis ripple
    monitor_substeps: int = 4  # 25 us at 10 kHz: 25x the Reference step


DEFAULT = Numerics()


def serial_blas():
    """Context manager: BLAS on one thread for the least-squares fits.

    Their Jacobians are tall and thin (a residual of 3 x 5000 samples against 5-10
    unknowns): OpenBLAS's threads cost more than they save there (scipy's ``trf`` SVD
    of a 15 000 x 8 Jacobian measured 28 ms on two threads, 3.3 ms on one, on 2 cores),
    and numba's threads already hold the cores for the Monitor batches.
    """
    return threadpool_limits(limits=1, user_api="blas")
