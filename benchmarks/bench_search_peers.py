"""Prints our grid search against OMPL's BIT* and dijkstra3d on one scene family, interleaved.

Run inside the project's environment (the peers are the optional extra ``peers``: ``pip install
ompl==2.0.1 dijkstra3d==1.15.2``; without them their rows say ``absent``)::

    source scripts/venv.sh && python benchmarks/bench_search_peers.py \
        [--sizes 6M,20M,100M,1G] [--repeats N] [--peers ompl,dijkstra3d] [--json out.json]

The scenes are ``uav_global_planner_tools.search_scenes``: the 20 x 20 x 15 m workspace with the
60 spheres of ``dense60_fine`` and 20 boxes, 48 % of the nodes blocked at gamma 0.2 m, a 27.1 m
diagonal from start to goal, at 6 M, 20 M, 100 M and 1 G nodes. Every method searches the
planner's own blocked mask, in one process; each repetition runs every method once, in turn,
and the table shows medians.

Methods:

- ours: every name of ``uav_global_planner.core.config.ALGORITHMS`` at run time, on one
  :class:`SearchWorkspace` (as the planner keeps one), search time only: through
  ``SearchWorkspace.search``, or ``<name>_search`` of ``core.search.<name>`` for an algorithm
  with a module of its own (``bounded``). An algorithm with a proven cost bound (``weighted``:
  w; another: a ``bound`` on its result or in ``grid_search.ALGORITHM_BOUNDS``) shows the
  bound beside its measured cost ratio to the ``octile`` optimum, and the ratio the query
  proved when its result carries one (``certified_ratio``).
- BIT* (OMPL): a 3D RealVectorStateSpace over the grid's nodes, a state valid when its nearest
  node is free (the same mask, a Python callback), motions checked every delta, path length
  the objective with a cost threshold of 1.05 times the grid optimum: the time from setup to
  the first solution within 5 % of the grid optimum. Its paths are straight segments, so they
  may be shorter than any grid path.
- dijkstra3d: a float32 field, 1 on free nodes and infinity on blocked ones (4 bytes a node,
  built untimed). Its edge from A to B costs the field at B: with ``anisotropy=(1, 1, 1)`` times
  the step length, which is our cost (its cost ratio shows the same optimum), and plain it
  counts steps
  (each of the 26 moves costs 1, so its path is optimal in steps, longer in metres).
  ``compass=True`` is its A* (chessboard heuristic).
- whole plan: ``Planner.plan`` end to end with ``adaptive`` on the built grid (endpoint
  checks, search, smoothing with its clearance certificate, timing), and the search's share.

The OMPL bindings report their objects as leaked when the interpreter shuts down; that report,
after every figure, is kept off stderr.

Slow methods stop at a grid size (``NODE_CAPS``); a method also stops repeating at a size once
it spent ``--budget`` seconds there. Figures only: nothing here asserts a speed.
"""

import argparse
import atexit
from functools import partial
import gc
import importlib
import inspect
import json
import math
import os
from pathlib import Path
import platform
import statistics
import sys
import time
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

import numpy as np

from uav_global_planner.core import config as core_config, PlanningError, PlanStatus
from uav_global_planner.core.search import grid_search
from uav_global_planner.core.search.grid_search import SearchWorkspace
from uav_global_planner_tools.search_scenes import (blocked_fraction, parse_sizes, scene_obstacles,
                                                    search_scene, SearchScene, SIZES)

#: Largest grid [nodes] a method runs on; methods not named run at every size.
NODE_CAPS: Dict[str, float] = {
    'dijkstra': 25e6, 'astar': 150e6, 'dijkstra3d A*': 150e6, 'dijkstra3d Dijkstra': 25e6,
    'dijkstra3d A*, steps': 150e6, 'dijkstra3d Dijkstra, steps': 25e6}
#: BIT* gives up after this long [s] (the run then counts as not reaching 5 %).
BIT_TIME_LIMIT = 30.0
#: Cost threshold of BIT*: this times the grid optimum.
BIT_COST_FACTOR = 1.05
#: A certified algorithm: proven cost bound at most this.
CERTIFIED_BOUND = 1.05
PEERS = ('ompl', 'dijkstra3d')


class Run:
    """One timed repetition: time [s], path cost [m] (NaN without a path), and notes."""

    def __init__(self, time_s: float, cost_m: float = math.nan, expanded: int = -1,
                 bound: Optional[float] = None, solved: bool = True,
                 extra: Optional[Dict[str, float]] = None) -> None:
        self.time_s, self.cost_m, self.expanded = time_s, cost_m, expanded
        self.bound, self.solved, self.extra = bound, solved, extra or {}


def proven_bound(name: str, result: Any, weight: float) -> Optional[float]:
    """The proven cost bound (factor on the optimum) of an algorithm, None when it has none."""
    for attribute in ('bound', 'cost_bound', 'suboptimality_bound', 'proven_bound'):
        value = getattr(result, attribute, None)
        if isinstance(value, (int, float)) and math.isfinite(value):
            return float(value)
    bounds = getattr(grid_search, 'ALGORITHM_BOUNDS', None)
    if isinstance(bounds, dict) and isinstance(bounds.get(name), (int, float)):
        return float(bounds[name])
    return weight if name == 'weighted' else None


def search_function(name: str) -> Optional[Callable[..., Any]]:
    """How the core searches with ``name``: ``SearchWorkspace.search`` when it takes the name,
    else ``<name>_search`` of the module ``uav_global_planner.core.search.<name>`` (called with
    the workspace first, as the planner calls ``bounded_search``); None when neither exists."""
    if name in getattr(grid_search, 'ALGORITHM_CODES', {}):
        return None
    try:
        module = importlib.import_module(f'uav_global_planner.core.search.{name}')
    except ImportError:
        return None
    function = getattr(module, f'{name}_search', None)
    return function if callable(function) else None


def ours(workspace: SearchWorkspace, scene: SearchScene, start, goal,
         name: str) -> Callable[[], Run]:
    """One search of algorithm ``name`` on the shared workspace, search time only.

    The settings' ``search_weight`` and ``bound`` are passed on where the search takes them.
    """
    config = scene.config
    function = search_function(name)
    target = workspace.search if function is None else function
    parameters = inspect.signature(target).parameters
    settings = (('weight', 'search_weight'), ('bound', 'bound'))
    options = {key: getattr(config, field) for key, field in settings
               if key in parameters and hasattr(config, field)}
    arguments = () if function is None else (workspace,)

    def run() -> Run:
        if function is None:
            result = workspace.search(start, goal, name, config.resolution,
                                      config.adaptive_threshold, **options)
        else:
            result = function(*arguments, start, goal, config.resolution,
                              config.adaptive_threshold, **options)
        # A per-query certificate (cost over a proven lower bound), when the result has one.
        proven = getattr(result, 'certified_ratio', None)
        return Run(result.search_time_s, result.cost_m, result.expanded_nodes,
                   proven_bound(name, result, config.search_weight),
                   extra={} if proven is None else {'proven_ratio': float(proven)})
    return run


def whole_plan(planner, scene: SearchScene) -> Callable[[], Run]:
    """``Planner.plan`` end to end with ``adaptive``: the search, and the rest (endpoint checks,
    smoothing with its clearance certificate, timing)."""
    def run() -> Run:
        result = planner.plan(scene.start, scene.goal, 'adaptive')
        if result.status != PlanStatus.OK:
            return Run(result.total_time_s, solved=False)
        return Run(result.total_time_s, result.cost, result.expanded_nodes,
                   extra={'search_s': result.planning_time_s,
                          'outside_search_s': result.total_time_s - result.planning_time_s,
                          'smoothing_s': result.smoothing_time_s})
    return run


def bit_star(dense: np.ndarray, scene: SearchScene, start, goal,
             optimum_m: float) -> Callable[[], Run]:
    """BIT* to the first path within 5 % of ``optimum_m``; validity = the node lookup."""
    import ompl.base as ob  # type: ignore[import-untyped, import-not-found, unused-ignore]
    import ompl.geometric as og  # type: ignore[import-untyped, import-not-found, unused-ignore]
    delta = scene.config.resolution
    low = np.asarray(scene.config.bounds_min, dtype=np.float64)
    nx, ny, nz = dense.shape
    high = low + (np.asarray(dense.shape) - 1) * delta
    space = ob.RealVectorStateSpace(3)
    bounds = ob.RealVectorBounds(3)
    for axis in range(3):
        bounds.setLow(axis, float(low[axis]))
        bounds.setHigh(axis, float(high[axis]))
    space.setBounds(bounds)
    info = ob.SpaceInformation(space)
    flat = dense.reshape(-1).data  # a memoryview: indexing gives a Python bool
    x0, y0, z0 = (float(v) for v in low)
    inverse = 1.0 / delta
    checks = [0]

    def valid(state) -> bool:
        checks[0] += 1
        i = int((state[0] - x0) * inverse + 0.5)
        j = int((state[1] - y0) * inverse + 0.5)
        k = int((state[2] - z0) * inverse + 0.5)
        return not flat[(min(i, nx - 1) * ny + min(j, ny - 1)) * nz + min(k, nz - 1)]

    info.setStateValidityChecker(valid)
    # Motions are checked every delta: the fraction is of the space's longest extent.
    info.setStateValidityCheckingResolution(delta / space.getMaximumExtent())
    info.setup()
    ends = [low + np.asarray(node, dtype=np.float64) * delta for node in (start, goal)]
    threshold = BIT_COST_FACTOR * optimum_m

    def run() -> Run:
        problem = ob.ProblemDefinition(info)
        a, b = space.allocState(), space.allocState()
        for axis in range(3):
            a[axis], b[axis] = float(ends[0][axis]), float(ends[1][axis])
        problem.setStartAndGoalStates(a, b)
        objective = ob.PathLengthOptimizationObjective(info)
        objective.setCostThreshold(ob.Cost(threshold))
        problem.setOptimizationObjective(objective)
        planner = og.BITstar(info)
        planner.setProblemDefinition(problem)
        checks[0] = 0
        started = time.perf_counter()
        planner.setup()
        planner.solve(BIT_TIME_LIMIT)
        elapsed = time.perf_counter() - started
        cost = planner.bestCost().value() if problem.hasExactSolution() else math.nan
        solved = math.isfinite(cost) and cost <= threshold
        return Run(elapsed if solved else math.inf, cost, solved=solved,
                   extra={'validity_checks': float(checks[0])})
    return run


def dijkstra3d_run(field: np.ndarray, start, goal, delta: float, compass: bool,
                   lengths: bool) -> Callable[[], Run]:
    """dijkstra3d on ``field``: edge costs of step lengths (``lengths``) or of steps."""
    import dijkstra3d  # type: ignore[import-untyped, import-not-found, unused-ignore]
    options: Dict[str, Any] = {'anisotropy': (1.0, 1.0, 1.0)} if lengths else {}

    def run() -> Run:
        started = time.perf_counter()
        path = dijkstra3d.dijkstra(field, start, goal, connectivity=26, compass=compass,
                                   **options)
        elapsed = time.perf_counter() - started
        steps = np.diff(np.asarray(path, dtype=np.float64).reshape(-1, 3), axis=0)
        return Run(elapsed, float(np.linalg.norm(steps, axis=1).sum()) * delta,
                   extra={'nodes_on_path': float(len(path))})
    return run


def available_peers(wanted: List[str]) -> Dict[str, str]:
    """Each peer -> 'ok', 'absent' (with its message printed) or 'not run'."""
    state = {}
    for peer in PEERS:
        if peer not in wanted:
            state[peer] = 'not run'
            continue
        try:
            if peer == 'ompl':
                importlib.import_module('ompl.base')
                importlib.import_module('ompl.geometric')
                ou = importlib.import_module('ompl.util')
                ou.setLogLevel(ou.LOG_WARN)
                ou.RNG.setSeed(2026)
            else:
                importlib.import_module('dijkstra3d')
            state[peer] = 'ok'
        except ImportError as error:
            state[peer] = 'absent'
            print(f'{peer} is absent ({error}); its rows say "absent". Install the optional '
                  'extra peers: pip install ompl==2.0.1 dijkstra3d==1.15.2')
    if state['ompl'] == 'ok':
        # The OMPL bindings report their own objects as leaked while the interpreter shuts
        # down (after every figure is printed): keep that report off the output.
        atexit.register(lambda: (sys.stdout.flush(), sys.stderr.flush(),
                                 os.dup2(os.open(os.devnull, os.O_WRONLY), 2)))
    return state


def measure_size(size: Union[str, float], obstacles, args,
                 peers: Dict[str, str]) -> Dict[str, Any]:
    """Every method at one size, interleaved; medians and costs."""
    scene = search_scene(size, obstacles)
    figures: Dict[str, Any] = {'size': scene.size, 'shape': list(scene.shape),
                               'nodes': scene.nodes, 'delta_m': scene.config.resolution,
                               'load_before': list(os.getloadavg())}
    planner = scene.planner()
    started = time.perf_counter()
    blocked = planner.blocked
    figures['grid_build_s'] = time.perf_counter() - started
    figures['blocked_fraction'] = blocked_fraction(blocked)
    figures['layout'] = 'dense' if isinstance(blocked, np.ndarray) else 'block-sparse'
    grid = planner.grid
    start = tuple(int(v) for v in grid.world_to_index(scene.start))
    goal = tuple(int(v) for v in grid.world_to_index(scene.goal))
    workspace = SearchWorkspace(blocked)
    # Kernel load and the first touches of the workspace; then the reference optimum.
    workspace.search(start, start, 'octile', scene.config.resolution, 1.5)
    reference = workspace.search(start, goal, 'octile', scene.config.resolution,
                                 scene.config.adaptive_threshold)
    optimum = reference.cost_m
    figures['optimum_m'] = optimum
    print(f'\n{scene.size}: {" x ".join(map(str, scene.shape))} = '
          f'{scene.nodes / 1e6:,.2f} M nodes, delta {scene.config.resolution:.5g} m, '
          f'{figures["layout"]}, {figures["blocked_fraction"]:.1%} blocked, grid build '
          f'{figures["grid_build_s"]:.2f} s, octile optimum {optimum:.3f} m', flush=True)

    methods: Dict[str, Callable[[], Run]] = {}
    skipped: Dict[str, str] = {}

    def add(name: str, make: Callable[[], Callable[[], Run]], peer: str = '',
            warm: bool = False) -> None:
        if peer and peers[peer] != 'ok':
            skipped[name] = peers[peer]
        elif scene.nodes > NODE_CAPS.get(name, math.inf) and not args.no_caps:
            skipped[name] = f'> {NODE_CAPS[name] / 1e6:g} M nodes'
        else:
            method = make()
            if warm:  # a first, untimed run: kernels compile or load, pages are touched
                try:
                    method()
                except PlanningError as error:
                    skipped[name] = f'refused: {error}'
                    return
            methods[name] = method

    codes = getattr(grid_search, 'ALGORITHM_CODES', {})
    for name in core_config.ALGORITHMS:
        # The workspace's algorithms load their kernel (A*'s, or Dial's for dijkstra) in an
        # untimed query from the start to itself; an algorithm with a kernel of its own gets an
        # untimed first run.
        if name in codes:
            workspace.search(start, start, name, scene.config.resolution,
                             scene.config.adaptive_threshold)
        add(name, partial(ours, workspace, scene, start, goal, name), warm=name not in codes)
    add('whole plan, adaptive', partial(whole_plan, planner, scene))
    # The peers read a dense copy of the mask (1 byte a node).
    dense = np.zeros((0, 0, 0), dtype=bool)
    if 'ok' in peers.values():
        dense = blocked if isinstance(blocked, np.ndarray) else blocked.to_dense()
    add('BIT* (OMPL)', partial(bit_star, dense, scene, start, goal, optimum), 'ompl')
    field = np.zeros((0, 0, 0), dtype=np.float32)
    largest = max(cap for name, cap in NODE_CAPS.items() if name.startswith('dijkstra3d'))
    if peers['dijkstra3d'] == 'ok' and (args.no_caps or scene.nodes <= largest):
        field = np.where(dense, np.float32(np.inf), np.float32(1.0))
    for compass, label in ((True, 'A*'), (False, 'Dijkstra')):
        for lengths, suffix in ((True, ''), (False, ', steps')):
            add(f'dijkstra3d {label}{suffix}',
                partial(dijkstra3d_run, field, start, goal, scene.config.resolution, compass,
                        lengths), 'dijkstra3d')
    # The first plan builds nothing (the grid is built) but loads the smoothing kernels.
    planner.plan(scene.start, scene.goal, 'adaptive')

    runs: Dict[str, List[Run]] = {name: [] for name in methods}
    for repeat in range(args.repeats):
        for name, method in methods.items():
            spent = sum(r.time_s for r in runs[name] if math.isfinite(r.time_s))
            if repeat and (spent > args.budget or not runs[name][-1].solved):
                continue
            gc.collect()
            runs[name].append(method())
    figures['load_after'] = list(os.getloadavg())
    figures['methods'] = {name: summary(runs[name], optimum) for name in methods}
    figures['skipped'] = skipped
    for name, text in skipped.items():
        figures['methods'][name] = {'skipped': text}
    return figures


def summary(runs: List[Run], optimum: float) -> Dict[str, Any]:
    """Median time and the cost figures of a method's runs."""
    times = [r.time_s for r in runs]
    ratios = [r.cost_m / optimum for r in runs if math.isfinite(r.cost_m)]
    out: Dict[str, Any] = {'runs': len(runs), 'median_s': statistics.median(times),
                           'min_s': min(times), 'solved': sum(r.solved for r in runs)}
    if ratios:
        out['cost_ratio_min'], out['cost_ratio_max'] = min(ratios), max(ratios)
    if runs[0].expanded >= 0:
        out['expanded'] = runs[0].expanded
    if runs[0].bound is not None:
        out['bound'] = runs[0].bound
    for key in runs[0].extra:
        out[key] = statistics.median(r.extra.get(key, math.nan) for r in runs)
    return out


def _time(seconds: float) -> str:
    if not math.isfinite(seconds):
        return f'> {BIT_TIME_LIMIT:g} s'
    return f'{seconds * 1e3:.3g} ms' if seconds < 1.0 else f'{seconds:.3g} s'


def cell(figure: Optional[Dict[str, Any]]) -> str:
    """One table cell: median time, cost against the optimum, bound."""
    if figure is None:
        return ''
    if 'skipped' in figure:
        return figure['skipped']
    text = _time(figure['median_s'])
    if 'cost_ratio_min' in figure:
        low, high = (100.0 * (figure[k] - 1.0) for k in ('cost_ratio_min', 'cost_ratio_max'))
        low, high = (0.0 if abs(v) < 0.005 else v for v in (low, high))
        spread = f'{low:+.2f} %' if abs(high - low) < 0.005 else f'{low:+.2f} to {high:+.2f} %'
        text += f', cost {spread}'
    if 'bound' in figure:
        text += f', bound {figure["bound"]:g}'
    if 'proven_ratio' in figure:
        text += f' (proven {figure["proven_ratio"]:.4g})'
    if 'search_s' in figure:
        text += (f' (search {figure["search_s"] / figure["median_s"]:.0%}, outside the search '
                 f'{figure["outside_search_s"] * 1e3:.3g} ms)')
    return text + f' [{figure["runs"]}]'


def certified(methods: Dict[str, Dict[str, Any]]) -> Optional[Tuple[str, Dict[str, Any]]]:
    """The fastest of our algorithms with a proven bound <= 1.05."""
    best = [(f['median_s'], name) for name, f in methods.items()
            if f.get('bound') is not None and f['bound'] <= CERTIFIED_BOUND + 1e-12]
    return (min(best)[1], methods[min(best)[1]]) if best else None


def targets(sizes: Dict[str, Dict[str, Any]]) -> List[Dict[str, Any]]:
    """The project's targets with the measured ratios (None: not measured)."""
    rows = []

    def ratio(size: str, numerator: Callable, denominator: Callable) -> Optional[float]:
        methods = sizes[size]['methods'] if size in sizes else {}
        top, bottom = numerator(methods), denominator(methods)
        if top is None or bottom is None or not math.isfinite(bottom) or bottom <= 0.0:
            return None
        return top / bottom

    def median(name: str) -> Callable:
        return lambda m: m.get(name, {}).get('median_s')

    def cert(m) -> Optional[float]:
        found = certified(m)
        return None if found is None else found[1]['median_s']

    def one(m) -> float:
        return 1.0

    for label, top, bottom, goal, only in (
            ('certified (bound <= 1.05) / BIT* to 5 %', cert, median('BIT* (OMPL)'), 1.0, None),
            ('certified at 1 G [s]', cert, one, 1.0, '1G'),
            ('octile at 1 G [s]', median('octile'), one, 5.0, '1G'),
            ('dijkstra / dijkstra3d Dijkstra (same costs)', median('dijkstra'),
             median('dijkstra3d Dijkstra'), 1.0, None),
            ('whole plan, adaptive, at 1 G [s]', median('whole plan, adaptive'), one, 0.15,
             '1G')):
        values = {size: ratio(size, top, bottom) for size in sizes if only in (None, size)}
        rows.append({'target': label, 'goal': goal, 'values': values})
    return rows


def machine() -> Dict[str, Any]:
    """CPU, cores, memory and Python of this machine."""
    model = platform.processor() or 'unknown'
    try:
        with open('/proc/cpuinfo') as handle:
            model = next(line.split(':', 1)[1].strip() for line in handle
                         if line.startswith('model name'))
        with open('/proc/meminfo') as handle:
            memory_gb = int(handle.readline().split()[1]) / 1024 ** 2
    except (OSError, StopIteration):
        memory_gb = math.nan
    return {'cpu': model, 'cores': os.cpu_count(), 'memory_gb': round(memory_gb, 1),
            'python': platform.python_version(), 'platform': platform.platform()}


def print_tables(sizes: Dict[str, Dict[str, Any]], rows: List[Dict[str, Any]]) -> None:
    """The table of medians and the target table, in Markdown."""
    labels = list(sizes)
    names: List[str] = []
    for figures in sizes.values():
        names += [name for name in figures['methods'] if name not in names]
    print('\nmedian time, cost against the octile optimum [repetitions]\n')
    print('| method | ' + ' | '.join(labels) + ' |')
    print('|---|' + '---|' * len(labels))
    for name in names:
        print(f'| {name} | '
              + ' | '.join(cell(sizes[s]['methods'].get(name)) for s in labels) + ' |')
    picks = []
    for size in labels:
        found = certified(sizes[size]['methods'])
        picks.append(found[0] if found else '–')
    print('| certified (bound <= 1.05): fastest | ' + ' | '.join(picks) + ' |')
    print('\ntargets (ratio or seconds; goal: at most; the 1 G rows need --sizes 1G)\n')
    print('| target | goal | ' + ' | '.join(labels) + ' |')
    print('|---|---|' + '---|' * len(labels))
    for row in rows:
        values = []
        for size in labels:
            value = row['values'].get(size, math.nan)
            if value is None:
                values.append('not measured')
            elif math.isnan(value):
                values.append('')
            else:
                values.append(f'{value:.3g} ({"met" if value <= row["goal"] else "short"})')
        print(f'| {row["target"]} | {row["goal"]:g} | ' + ' | '.join(values) + ' |')


def write_json(path: Path, info: Dict[str, Any], peers: Dict[str, str],
               sizes: Dict[str, Dict[str, Any]], rows: Optional[List[Dict[str, Any]]] = None
               ) -> None:
    """Every figure so far as JSON."""
    document = {'machine': info, 'peers': peers, 'sizes': sizes, 'targets': rows or []}
    path.write_text(json.dumps(document, indent=1, default=float) + '\n', encoding='utf-8')


def main(argv: Optional[List[str]] = None) -> int:
    """Measure the sizes asked for and print the tables; 0 when every size ran."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--sizes', default=','.join(SIZES),
                        help=f'comma-separated sizes ({", ".join(SIZES)}) or deltas in metres')
    parser.add_argument('--repeats', type=int, default=7, help='repetitions per method')
    parser.add_argument('--budget', type=float, default=30.0,
                        help='stop repeating a method at a size after this much time [s]')
    parser.add_argument('--peers', default=','.join(PEERS),
                        help='peers to run: ompl, dijkstra3d (comma-separated; "" for none)')
    parser.add_argument('--no-caps', action='store_true',
                        help='run the slow methods at every size (see NODE_CAPS)')
    parser.add_argument('--json', type=Path, help='also write every figure to this file')
    args = parser.parse_args(argv)
    try:
        chosen = parse_sizes(args.sizes)
    except ValueError as error:
        parser.error(f'--sizes: {error}')
    if args.repeats < 1:
        parser.error(f'--repeats: must be >= 1, got {args.repeats}')
    wanted = [p.strip() for p in args.peers.split(',') if p.strip()]
    unknown = sorted(set(wanted) - set(PEERS))
    if unknown:
        parser.error(f'--peers: unknown {", ".join(unknown)} (known: {", ".join(PEERS)})')
    info = machine()
    print(f'machine: {info["cpu"]}, {info["cores"]} cores, {info["memory_gb"]} GB, '
          f'Python {info["python"]}; load average {os.getloadavg()[0]:.2f}; '
          f'algorithms {", ".join(core_config.ALGORITHMS)}')
    peers = available_peers(wanted)
    obstacles = scene_obstacles()
    sizes: Dict[str, Dict[str, Any]] = {}
    for size in chosen:
        figures = measure_size(size, obstacles, args, peers)
        sizes[figures['size']] = figures
        for name, figure in figures['methods'].items():
            print(f'  {name}: {cell(figure)}')
        load = figures['load_after']
        print(f'  done at load average {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f}',
              flush=True)
        if args.json:  # written after every size, so a long run keeps what it measured
            write_json(args.json, info, peers, sizes)
    rows = targets(sizes)
    print_tables(sizes, rows)
    print(f'\nload average (1/5/15 min) at the end: '
          f'{" / ".join(f"{v:.2f}" for v in os.getloadavg())}; peers: '
          + ', '.join(f'{k} {v}' for k, v in peers.items()))
    if args.json:
        write_json(args.json, info, peers, sizes, rows)
    return 0


if __name__ == '__main__':
    sys.exit(main())
