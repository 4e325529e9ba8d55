"""Arc lengths of cubic pieces by the Gauss-Legendre rule, in one compiled loop.

Every arc length of the project's curves (the verification samples' labels, the output samples,
the evaluator's inverse) is :meth:`~uav_global_planner.core.path.clearance.Pieces.speed_integral`,
which calls :func:`speed_integral` here: a fine grid's curve has tens of thousands of
verification intervals, and the array form of the rule gathers each piece's coefficients once
per Gauss node. The same source is the pure-Python fallback without numba (slow, same bits).
"""

import math

import numpy as np

from uav_global_planner.core.jit import njit


@njit
def _integrate(coef, piece, tau0, tau1, nodes, weights, out):  # pragma: no cover - compiled
    for i in range(piece.shape[0]):
        p = piece[i]
        half = 0.5 * (tau1[i] - tau0[i])
        mid = 0.5 * (tau1[i] + tau0[i])
        total = 0.0
        for k in range(nodes.shape[0]):
            x = mid + half * nodes[k]
            squared = 0.0
            for axis in range(3):
                d = (3.0 * coef[0, p, axis] * x + 2.0 * coef[1, p, axis]) * x + coef[2, p, axis]
                squared += d * d
            total += math.sqrt(squared) * weights[k]
        out[i] = half * total


def speed_integral(coef: np.ndarray, piece: np.ndarray, tau0: np.ndarray, tau1: np.ndarray,
                   nodes: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Arc length from ``tau0`` to ``tau1`` on each piece [m].

    Parameters
    ----------
    coef : numpy.ndarray, shape (4, P, 3)
        Cubic coefficients, highest power first [m / unit^k].
    piece : numpy.ndarray of int, shape (M,)
    tau0, tau1 : numpy.ndarray, shape (M,)
        Local parameters on each piece [parameter units].
    nodes, weights : numpy.ndarray
        The Gauss-Legendre rule on [-1, 1].
    """
    out = np.empty(len(piece))
    _integrate(coef, np.asarray(piece, dtype=np.int64),
               np.ascontiguousarray(tau0, dtype=np.float64),
               np.ascontiguousarray(tau1, dtype=np.float64), nodes, weights, out)
    return out
