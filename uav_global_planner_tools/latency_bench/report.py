"""Tables of the ROS benchmark's figures (the JSON document of ``--json``)."""

from typing import Any, Dict, Optional

from uav_global_planner.cli.report import format_table


def _ms(value: Optional[float], spec: str = '.1f') -> str:
    return '-' if value is None else format(value, spec)


def format_ros_report(figures: Dict[str, Any]) -> str:
    """Tables of the ROS-side figures: the document of :func:`~uav_global_planner_tools.
    latency_bench.measure.run` (``--json``), as text."""
    load = figures.get('load_average')
    after = figures.get('load_average_after')
    lines = ['ROS: goal published -> plan received over DDS (localhost, domain '
             f"{figures['domain_id']}), {figures['goals']} goals per scene alternating between "
             f"two goals; {figures.get('cpus') or '?'} CPUs, load average "
             f"{_ms(load, '.2f')} before, {_ms(after, '.2f')} after"]
    rows = []
    for s in figures['scenes']:
        latency = s['latency']
        received = s.get('bytes_latency') or {}
        rows.append([s['scene'], f"{s['startup_s']:.2f}", _ms(latency['median_ms']),
                     _ms(latency['p90_ms']), _ms(latency['max_ms']),
                     _ms(received.get('median_ms')),
                     f"{_ms(s['node_search_ms'], '.2f')} + {_ms(s['node_smoothing_ms'])}",
                     str(s['poses'] or '-'), f"{s['plans_received']}/{s['goals']}",
                     _ms(s['peak_rss_mb'], '.0f')])
    if rows:
        lines.append(format_table(
            ['scene', 'start-up [s]', 'median [ms]', 'p90 [ms]', 'max [ms]',
             'bytes in, median [ms]', 'node search + smoothing [ms]', 'poses', 'plans',
             'peak RSS [MB]'], rows))
    for s in figures['scenes']:
        parts = [f"goal {[round(v, 2) for v in g['goal']]}: median "
                 f"{_ms(g['latency']['median_ms'])} ms (node plan {_ms(g['node_plan_ms'])} ms)"
                 for g in s.get('by_goal', ())]
        if parts:
            lines.append(f"  {s['scene']} per goal: " + '; '.join(parts))
    memory = figures.get('memory')
    if memory:
        lines.append('')
        lines.append(f"{memory['scene']}: node peak RSS (VmHWM) "
                     f"{_ms(memory['peak_rss_mb'], '.0f')} MB after planning with every "
                     f"algorithm (VmRSS then {_ms(memory['rss_mb'], '.0f')} MB), start-up "
                     f"{memory['startup_s']:.2f} s")
        lines.append(format_table(
            ['algorithm', 'status', 'latency [ms]', 'node search [ms]', 'VmHWM after [MB]'],
            [[r['algorithm'], r['status'], _ms(r['latency_ms']), _ms(r['node_search_ms']),
              _ms(r['peak_rss_mb'], '.0f')] for r in memory['algorithms']]))
    return '\n'.join(lines)
