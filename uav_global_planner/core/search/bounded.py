"""Certified bounded-suboptimal search on the 26-connected grid (algorithm ``bounded``).

The path returned costs at most ``w`` times the optimum of the grid (``w >= 1``, the setting
``bound``), and the search proves it for each query with a lower bound ``L`` on the optimum:
the result carries ``L`` and the path's cost ``U`` with ``U <= w * L``.

Scheme (an anytime search certified by a lower bound)
-----------------------------------------------------
1. *Upper bound.* The ``adaptive`` search of :mod:`.grid_search` (a greedy best-first search,
   about a thousand expansions) finds a path of cost ``U``.
2. *Trivial lower bound.* Every path from ``s`` to ``t`` costs at least the obstacle-free
   octile distance ``L0 = delta * oct(t - s)``. If ``U <= w * L0`` the path is returned.
3. *Corridor.* An optimal path on a coarse, optimistic grid (:mod:`.coarse_guide`) picks the
   way around the obstacles; an optimal A* confined to the fine nodes near it gives a path of
   cost ``U'``, kept when below ``U``. If ``U' <= w * L0`` it is returned.
4. *Lower-bound search.* An optimal A* over the whole grid (octile heuristic, consistent;
   closed nodes are never reopened) pops nodes in nondecreasing ``f = g + h``. When it pops a
   node with ``f >= U' / w`` it stops: ``L = f`` and the corridor path is returned. When it
   pops the goal first, its own path is optimal (``L = U``) and returned.

*Proof sketch.* With a consistent heuristic, whenever A* pops a node of key ``f``, some node
of an optimal path lies on the open list with its optimal ``g`` (the first node of that path
not yet closed; its predecessor was closed with its optimal cost), so its key is at most the
optimum ``C*``; the popped key is the smallest, hence ``f <= C*`` (Hart, Nilsson and Raphael
1968, lemma 1 and its corollary). So ``L = f`` is a lower bound, and ``U' <= w * L <= w * C*``.
``L0`` is the heuristic of the start, a lower bound by admissibility. Step costs and the
heuristic are the same floating-point expressions as in :mod:`.grid_search`; the lower bound
is reduced by a relative ``1e-9`` so rounding cannot break the inequality.

Cost modes: the proof needs the length cost. With climb or descent weights other than 1, or
with a charge for unknown space, the search is ``weighted`` A* with ``w`` (same guarantee,
Likhachev et al. 2003; its lower bound is reported as ``U / w``).

Memory: the kernel's per-node arrays (cost 8 bytes, parent 1, mark 4, corridor stamp 4) are
lazily committed zero pages, kept for the last grid shape searched and reused without
clearing (:class:`~.bounded_kernel.Memory`), so only the pages the phases touch cost memory.
A query whose start is its goal (what :meth:`~uav_global_planner.core.planner.Planner.warm_up`
sends) also runs every phase once on a tiny grid, so the compiled kernels are loaded before
the first real query.
"""

from dataclasses import dataclass
import math
import time
from typing import Callable, List, Optional, Tuple, Union

import numpy as np

from uav_global_planner.core.errors import NoValidPathError
from uav_global_planner.core.map.sparse_grid import SparseMask
from uav_global_planner.core.search.bounded_kernel import (CERTIFIED, FOUND, memory_for,
                                                           octile, Phase, ROUNDING)
from uav_global_planner.core.search.coarse_guide import coarse_corridor
from uav_global_planner.core.search.grid_search import SearchResult, SearchWorkspace
from uav_global_planner.core.settings import check_setting

#: Default certified bound w: the path costs at most w times the optimum.
DEFAULT_BOUND = 1.05

#: Reach of the corridor around the coarse path [coarse cells] (Chebyshev).
CORRIDOR_REACH = 1

#: Weight of the heuristic of the corridor search: it only proposes a path.
CORRIDOR_WEIGHT = 1.0


@dataclass(frozen=True, eq=False)
class BoundedResult(SearchResult):
    """A :class:`~.grid_search.SearchResult` with its certificate.

    Attributes
    ----------
    lower_bound_m : float
        Proven lower bound L on the optimal cost [m]; ``cost_m <= bound * lower_bound_m``.
    bound : float
        The bound w asked for [-].
    phase : str
        What certified the path: ``octile distance``, ``corridor``, ``lower-bound search``,
        ``optimal`` (the lower-bound search reached the goal) or ``weighted`` (cost modes).
    """

    lower_bound_m: float = 0.0
    bound: float = DEFAULT_BOUND
    phase: str = ''

    @property
    def certified_ratio(self) -> float:
        """``cost_m / lower_bound_m``: the proven bound of this path (<= :attr:`bound`)."""
        if self.lower_bound_m <= 0.0:
            return 1.0 if self.cost_m <= 0.0 else math.inf
        return self.cost_m / self.lower_bound_m


def octile_lower_bound(start, goal, resolution: float) -> float:
    """Obstacle-free 26-connected distance between two nodes [m]: a lower bound of any path."""
    d = np.abs(np.asarray(goal, dtype=np.int64) - np.asarray(start, dtype=np.int64))
    return float(resolution * octile(int(d[0]), int(d[1]), int(d[2])))


def _flat(index, shape) -> int:
    i, j, k = (int(v) for v in index)
    return (i * shape[1] + j) * shape[2] + k


def bounded_search(workspace: SearchWorkspace, start_index, goal_index, resolution: float,
                   adaptive_threshold: float, bound: float = DEFAULT_BOUND,
                   max_expansions: int = 0, *, climb_weight: float = 1.0,
                   descent_weight: float = 1.0, checkpoint: Optional[Callable[[], None]] = None,
                   unknown: Optional[Union[np.ndarray, SparseMask]] = None,
                   unknown_cost: float = 0.0, corridor: bool = True) -> BoundedResult:
    """Find a path costing at most ``bound`` times the optimum, with its proof (module notes).

    Parameters
    ----------
    workspace : SearchWorkspace
        The grid (its mask, dense or block-sparse) and the memory of the first search.
    start_index, goal_index : array_like of int, shape (3,)
        Node indices (i, j, k).
    resolution : float
        Node spacing delta [m].
    adaptive_threshold : float
        eta [m] of the first (adaptive) search.
    bound : float
        w >= 1 (the setting ``bound``): the path costs at most w times the optimum.
    max_expansions : int
        Budget of expanded nodes over all phases; 0 means unlimited.
    climb_weight, descent_weight, unknown, unknown_cost
        Cost modes as for :meth:`SearchWorkspace.search`; with any of them in force the search
        is ``weighted`` A* with weight ``bound`` (module notes).
    checkpoint : callable, optional
        Called every 20000 expansions; what it raises stops the search.
    corridor : bool
        Run phase 3 (the coarse corridor); False skips it.

    Returns
    -------
    BoundedResult
        ``cost_m <= bound * lower_bound_m <= bound * optimum``.

    Raises
    ------
    InvalidInputError
        A bound below 1, not finite or above 10, and what :meth:`SearchWorkspace.search`
        refuses.
    StartOccupiedError, GoalOccupiedError, NoValidPathError, PlanningTimeoutError
        As :meth:`SearchWorkspace.search`.
    """
    w = check_setting('bound', bound)
    began = time.perf_counter()
    climb = check_setting('climb_weight', climb_weight)
    descent = check_setting('descent_weight', descent_weight)
    charged = unknown is not None and check_setting('unknown_cost', unknown_cost) > 0.0
    if climb != 1.0 or descent != 1.0 or charged:
        found = workspace.search(start_index, goal_index, 'weighted', resolution,
                                 adaptive_threshold, max_expansions, weight=w,
                                 climb_weight=climb_weight, descent_weight=descent_weight,
                                 checkpoint=checkpoint, unknown=unknown,
                                 unknown_cost=unknown_cost)
        return _result(found.path_indices, found.cost_m, found.expanded_nodes, began,
                       found.cost_m / w, w, 'weighted')
    first = workspace.search(start_index, goal_index, 'adaptive', resolution,
                             adaptive_threshold, max_expansions, checkpoint=checkpoint)
    spent = first.expanded_nodes
    if len(first.path_indices) == 1:
        _warm_up()
    lower = octile_lower_bound(first.path_indices[0], first.path_indices[-1], resolution)
    best_path, best_cost = first.path_indices, first.cost_m
    if best_cost <= w * lower * (1.0 - ROUNDING):
        return _result(best_path, best_cost, spent, began, lower, w, 'octile distance')
    blocked = workspace.blocked
    shape: Tuple[int, int, int] = tuple(int(n) for n in blocked.shape)  # type: ignore
    start = _flat(best_path[0], shape)
    goal = _flat(best_path[-1], shape)
    with memory_for(shape) as memory:
        if corridor:
            stamp = memory.new_stamp()
            phase = Phase(blocked, start, goal, memory, stamp)
            if coarse_corridor(phase.masks, shape, start, goal, memory.corridor,
                               CORRIDOR_REACH, stamp=stamp):
                status = phase.run(math.inf, max_expansions, checkpoint, spent,
                                   CORRIDOR_WEIGHT)
                spent += phase.pops
                if status == FOUND and float(phase.g[goal]) * resolution < best_cost:
                    best_path, best_cost = phase.path(goal), float(phase.g[goal]) * resolution
            if best_cost <= w * lower * (1.0 - ROUNDING):
                return _result(best_path, best_cost, spent, began, lower, w, 'corridor')
        search = Phase(blocked, start, goal, memory)
        threshold = best_cost / (w * resolution) * (1.0 + ROUNDING)
        status = search.run(threshold, max_expansions, checkpoint, spent)
        spent += search.pops
        if status == FOUND:
            cost = float(search.g[goal]) * resolution
            return _result(search.path(goal), cost, spent, began, cost, w, 'optimal')
        if status == CERTIFIED:
            lower = max(lower, float(search.bounds[1]) * resolution)
            return _result(best_path, best_cost, spent, began, lower, w, 'lower-bound search')
    # The adaptive search reached the goal, so the full search cannot exhaust the grid.
    raise NoValidPathError('the lower-bound search exhausted the grid without reaching the '
                           'goal the first search reached', expanded_nodes=spent)


_WARM: List[bool] = []


def _warm_up() -> None:
    """Run every phase once on a tiny grid (loads or compiles the kernels), once a process."""
    if _WARM:
        return
    _WARM.append(True)
    blocked = np.zeros((6, 6, 6), dtype=np.bool_)
    blocked[2:4, :5, :] = True
    workspace = SearchWorkspace(blocked)
    bounded_search(workspace, (0, 0, 0), (5, 0, 0), 1.0, 0.0, 1.0)


def _result(path: np.ndarray, cost: float, expanded: int, began: float, lower: float,
            bound: float, phase: str) -> BoundedResult:
    return BoundedResult(path_indices=np.asarray(path, dtype=np.int64), cost_m=float(cost),
                         expanded_nodes=int(expanded),
                         search_time_s=time.perf_counter() - began,
                         lower_bound_m=float(lower), bound=float(bound), phase=phase)
