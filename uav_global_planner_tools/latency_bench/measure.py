"""The benchmark's figures: goal-to-plan latency and start-up per scene, peak memory per node.

See :mod:`uav_global_planner_tools.latency_bench` for what each figure measures. Figures only:
nothing here asserts a speed.
"""

import os
from pathlib import Path
import statistics
import tempfile
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from uav_global_planner.core.config import ALGORITHMS
from uav_global_planner.core.io.scene import find_scene, load_scene
from uav_global_planner_tools.latency_bench.session import Session

#: Goals per algorithm on the memory scene (latency there is a by-product).
MEMORY_GOALS = 2


def summary(values: List[float]) -> Dict[str, Optional[float]]:
    """median, p90 and max of ``values`` [s] in milliseconds (None when empty)."""
    if not values:
        return {'median_ms': None, 'p90_ms': None, 'max_ms': None, 'min_ms': None}
    array = np.asarray(values) * 1e3
    return {'median_ms': float(np.median(array)), 'p90_ms': float(np.percentile(array, 90)),
            'max_ms': float(np.max(array)), 'min_ms': float(np.min(array))}


def _median_ms(values: List[Optional[float]]) -> Optional[float]:
    known = [v for v in values if v is not None]
    return 1e3 * statistics.median(known) if known else None


def measure_latency(scene_name: str, goals: int, domain_id: int, log_dir: Path,
                    timeout_s: float, index: int = 0) -> Dict[str, Any]:
    """Start-up time and goal-to-plan latency of one scene (see the module documentation).

    Returns
    -------
    dict
        ``scene``, ``startup_s``, ``goals``, ``plans_received``, ``failures`` (statuses other
        than ok), ``latency`` (``median_ms``, ``p90_ms``, ``max_ms``, ``min_ms``; until the
        plan was deserialised), ``bytes_latency`` (the same until its bytes arrived),
        ``node_search_ms`` and ``node_smoothing_ms`` (medians the node reports),
        ``poses`` (median plan size), ``peak_rss_mb``, ``exit_code`` and ``by_goal``: for the
        scene's goal and the alternate goal, ``goal``, ``goals``, ``latency`` and
        ``node_plan_ms`` (median search + smoothing), since the two often differ in cost and
        the median of all goals then falls between them.
    """
    scene = load_scene(find_scene(scene_name))
    session = Session(scene, domain_id, _namespace(index), log_dir, timeout_s)
    outcomes: List[Dict[str, Any]] = []
    try:
        startup = session.start()
        for _ in range(goals):
            outcomes.append(session.send_goal())
        memory = session.node.status_kb()
    finally:
        code = session.close()
    latencies = [o['latency_s'] for o in outcomes if o['latency_s'] is not None]
    return {
        'scene': scene.name, 'startup_s': startup, 'goals': goals,
        'plans_received': len(latencies),
        'failures': sorted({o['status'] for o in outcomes if o['status'] != 'ok'}),
        'latency': summary(latencies),
        'bytes_latency': summary([o['bytes_s'] for o in outcomes if o['bytes_s'] is not None]),
        'node_search_ms': _median_ms([o['node_search_s'] for o in outcomes]),
        'node_smoothing_ms': _median_ms([o['node_smoothing_s'] for o in outcomes]),
        'poses': (int(statistics.median(o['poses'] for o in outcomes if o['poses']))
                  if latencies else None),
        'peak_rss_mb': memory.get('VmHWM', 0) / 1024.0 or None, 'exit_code': code,
        'by_goal': [_goal_figures(session.goals[kind], [o for o in outcomes if o['kind'] == kind])
                    for kind in (0, 1)],
    }


def _goal_figures(goal: np.ndarray, outcomes: List[Dict[str, Any]]) -> Dict[str, Any]:
    """Latency of the goals sent to one of the two goal positions."""
    return {'goal': [float(v) for v in goal], 'goals': len(outcomes),
            'latency': summary([o['latency_s'] for o in outcomes if o['latency_s'] is not None]),
            'node_plan_ms': _median_ms([o['node_search_s'] + o['node_smoothing_s']
                                        for o in outcomes if o['node_search_s'] is not None
                                        and o['node_smoothing_s'] is not None])}


def measure_memory(scene_name: str, domain_id: int, log_dir: Path, timeout_s: float,
                   index: int = 0) -> Dict[str, Any]:
    """Peak resident memory of the node after planning ``scene_name`` with every algorithm.

    Returns
    -------
    dict
        ``scene``, ``startup_s``, ``peak_rss_mb`` (``VmHWM`` at the end), ``rss_mb`` (``VmRSS``
        at the end), ``exit_code`` and ``algorithms``: per algorithm its ``status``, median
        ``latency_ms`` of a few goals, ``node_search_ms`` and ``peak_rss_mb`` after it.
    """
    scene = load_scene(find_scene(scene_name))
    session = Session(scene, domain_id, _namespace(index), log_dir, timeout_s)
    rows = []
    try:
        startup = session.start()
        for algorithm in ALGORITHMS:
            session.set_algorithm(algorithm)
            outcomes = [session.send_goal() for _ in range(MEMORY_GOALS)]
            rows.append({
                'algorithm': algorithm,
                'status': ','.join(sorted({o['status'] for o in outcomes})),
                'latency_ms': _median_ms([o['latency_s'] for o in outcomes]),
                'node_search_ms': _median_ms([o['node_search_s'] for o in outcomes]),
                'peak_rss_mb': session.node.status_kb().get('VmHWM', 0) / 1024.0 or None})
        memory = session.node.status_kb()
    finally:
        code = session.close()
    return {'scene': scene.name, 'startup_s': startup,
            'peak_rss_mb': memory.get('VmHWM', 0) / 1024.0 or None,
            'rss_mb': memory.get('VmRSS', 0) / 1024.0 or None, 'exit_code': code,
            'algorithms': rows}


def _namespace(index: int) -> str:
    return f'/uav_latency_bench_{os.getpid()}_{index}'


def run(scenes: Sequence[str], goals: int, memory_scene: Optional[str], domain_id: int,
        timeout_s: float) -> Dict[str, Any]:
    """Every figure: latency and start-up per scene, then the memory scene.

    Returns
    -------
    dict
        ``domain_id``, ``goals``, ``scenes`` (see :func:`measure_latency`), ``memory``
        (see :func:`measure_memory`, None when skipped), ``cpus``, ``load_average`` and
        ``load_average_after`` (1-minute load before and after), ``log_dir``.
    """
    log_dir = Path(tempfile.mkdtemp(prefix='uav_latency_bench_'))
    figures: Dict[str, Any] = {'domain_id': domain_id, 'goals': goals, 'scenes': [],
                               'memory': None, 'log_dir': str(log_dir),
                               'cpus': os.cpu_count(), 'load_average': _load_average()}
    for index, name in enumerate(scenes):
        figures['scenes'].append(measure_latency(name, goals, domain_id, log_dir, timeout_s,
                                                 index))
    if memory_scene:
        figures['memory'] = measure_memory(memory_scene, domain_id, log_dir, timeout_s,
                                           len(scenes))
    figures['load_average_after'] = _load_average()
    return figures


def _load_average() -> Optional[float]:
    """The 1-minute load average (other work on the machine skews every figure)."""
    try:
        return os.getloadavg()[0]
    except OSError:
        return None
