"""``diagnostic_msgs/DiagnosticArray`` messages of the planner's events, and reading them back."""

from typing import Dict, Iterable, Mapping, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
import numpy as np
from std_msgs.msg import Header

from uav_global_planner.core.result import PlanResult
from uav_global_planner.core.status import NAV2_CODE_BY_STATUS
from uav_global_planner.ros.conversions.stamps import time_from_ns
from uav_global_planner.ros.start_source import StartSource


def format_value(value) -> str:
    """Diagnostics text of a value: floats with 4 decimals, arrays as [x, y, z]."""
    if isinstance(value, (bool, np.bool_)):
        return 'true' if value else 'false'
    if isinstance(value, (float, np.floating)):
        return f'{float(value):.4f}'
    if isinstance(value, np.ndarray):
        return '[' + ', '.join(f'{float(v):.4f}' for v in value.ravel()) + ']'
    return str(value)


def diagnostic_array(stamp_ns: int, name: str, hardware_id: str, level: bytes, message: str,
                     values: Mapping[str, object]) -> DiagnosticArray:
    """A ``DiagnosticArray`` with a single status.

    Parameters
    ----------
    level : bytes
        ``DiagnosticStatus.OK``, ``WARN`` or ``ERROR``.
    values : mapping
        Key values, formatted with :func:`format_value`.
    """
    status = DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id)
    status.values = [KeyValue(key=str(k), value=format_value(v)) for k, v in values.items()]
    msg = DiagnosticArray()
    msg.header = Header(stamp=time_from_ns(stamp_ns))
    msg.status = [status]
    return msg


def plan_diagnostic_values(result: PlanResult, start_source: StartSource,
                           extra: Optional[Mapping[str, object]] = None) -> Dict[str, object]:
    """Key values of one plan attempt: outcome, Nav2 code, timing, lengths, delta/gamma/eta."""
    values: Dict[str, object] = {
        'event': 'plan',
        'status': result.status.value,
        'status_code': NAV2_CODE_BY_STATUS[result.status],
        'algorithm': result.algorithm,
        'planning_time_s': result.planning_time_s,
        'grid_build_time_s': result.grid_build_time_s,
        'smoothing_time_s': result.smoothing_time_s,
        'expanded_nodes': result.expanded_nodes,
        'path_length_m': result.path_length_m,
        'smoothed_length_m': result.smoothed_length_m,
        'path_cost': result.cost,
        'duration_s': result.duration_s,
        'energy_wh': result.energy.energy_wh if result.energy is not None else float('nan'),
        'min_clearance_m': result.min_clearance_m,
        'unknown_length_m': result.unknown_length_m,
        'resolution_m': result.resolution,
        'safety_margin_m': result.safety_margin,
        'adaptive_threshold_m': result.adaptive_threshold,
        'start_source': start_source,
        'start': result.start,
        'goal': result.goal,
    }
    values.update(extra or {})
    return values


def diagnostic_values(msg: DiagnosticArray) -> Iterable[Tuple[DiagnosticStatus, Dict[str, str]]]:
    """(status, {key: value}) of each status in a ``DiagnosticArray`` (for readers and tests)."""
    return [(status, {kv.key: kv.value for kv in status.values}) for status in msg.status]
