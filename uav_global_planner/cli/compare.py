"""The paper's comparison (Tables 1 and 2): every algorithm on one scene."""

from dataclasses import dataclass
import statistics
from typing import Dict, List, Sequence

from uav_global_planner.core.config import ALGORITHMS
from uav_global_planner.core.io.scene import Scene
from uav_global_planner.core.planner import Planner
from uav_global_planner.core.result import PlanResult


@dataclass(frozen=True)
class ComparisonRow:
    """One algorithm's figures on one scene.

    Attributes
    ----------
    algorithm : str
    result : PlanResult
        The last of the repeated runs (all runs give the same path).
    median_time_s : float
        Median search time over the runs (eq. 14) [s].
    runs : int
    relative_cost : float
        Path length over the optimum (the shortest length among optimal algorithms) [-].
    """

    algorithm: str
    result: PlanResult
    median_time_s: float
    runs: int
    relative_cost: float


def compare_algorithms(scene: Scene, algorithms: Sequence[str] = ALGORITHMS,
                       repeats: int = 5) -> List[ComparisonRow]:
    """Plan the scene with each algorithm ``repeats`` times and collect the figures.

    The grid is built once and shared, so the times are search times only.
    """
    planner = Planner(scene.config, scene.obstacles, unknown=scene.unknown)
    results: Dict[str, PlanResult] = {}
    times: Dict[str, float] = {}
    for algorithm in algorithms:
        planner.plan(scene.start, scene.goal, algorithm, via=scene.via)  # warm: compile, grid
        runs = [planner.plan(scene.start, scene.goal, algorithm, via=scene.via)
                for _ in range(repeats)]
        results[algorithm] = runs[-1]
        times[algorithm] = statistics.median(r.planning_time_s for r in runs)
    optimal = [r.path_length_m for name, r in results.items()
               if r.ok and name not in ('adaptive', 'weighted')]
    optimum = min(optimal) if optimal else float('nan')
    return [ComparisonRow(name, results[name], times[name], repeats,
                          results[name].path_length_m / optimum)
            for name in algorithms]
