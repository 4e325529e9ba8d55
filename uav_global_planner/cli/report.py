"""Turning planner results into JSON-ready dictionaries and text tables."""

import math
from typing import Any, Dict, Iterable, List, Optional, Sequence, TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # the types only: the command line imports the planner once it plans
    from uav_global_planner.core.io.mapfiles import MapReport
    from uav_global_planner.core.result import PlanResult
    from uav_global_planner.core.search.start_admission import Admission


def finite_or_none(value: float) -> Any:
    """``value`` as a float, or None where it is NaN or infinite (JSON has no NaN)."""
    number = float(value)
    return number if math.isfinite(number) else None


def _points(array: np.ndarray) -> List[List[float]]:
    return [[round(float(c), 6) for c in row] for row in np.asarray(array).reshape(-1, 3)]


def result_to_dict(result: 'PlanResult') -> Dict[str, Any]:
    """Every field of a plan result as plain JSON types, lengths in m and times in s."""
    energy = result.energy
    return {
        'status': result.status.value,
        'message': result.message,
        'algorithm': result.algorithm,
        'start': [finite_or_none(v) for v in result.start],
        'goal': [finite_or_none(v) for v in result.goal],
        'path': _points(result.path),
        'path_length_m': finite_or_none(result.path_length_m),
        'expanded_nodes': int(result.expanded_nodes),
        'planning_time_s': finite_or_none(result.planning_time_s),
        'grid_build_time_s': finite_or_none(result.grid_build_time_s),
        'resolution': finite_or_none(result.resolution),
        'safety_margin': finite_or_none(result.safety_margin),
        'adaptive_threshold': finite_or_none(result.adaptive_threshold),
        'shortcut_path': _points(result.shortcut_path),
        'shortcut_length_m': finite_or_none(result.shortcut_length_m),
        'smoothed_path': _points(result.smoothed_path),
        'smoothed_length_m': finite_or_none(result.smoothed_length_m),
        'min_clearance_m': finite_or_none(result.min_clearance_m),
        'min_clearance_point': [finite_or_none(v) for v in result.min_clearance_point],
        'repaired_stretches': [
            {'start_m': s.start_m, 'end_m': s.end_m, 'method': s.method.value,
             'clearance_before_m': finite_or_none(s.clearance_before_m)}
            for s in result.repaired_stretches],
        'duration_s': finite_or_none(result.duration_s),
        'smoothing_time_s': finite_or_none(result.smoothing_time_s),
        'total_time_s': finite_or_none(result.total_time_s),
        'via': _points(result.via),
        'legs': [{'leg': leg.index, 'path_length_m': finite_or_none(leg.path_length_m),
                  'smoothed_length_m': finite_or_none(leg.smoothed_length_m),
                  'duration_s': finite_or_none(leg.duration_s),
                  'expanded_nodes': int(leg.expanded_nodes)} for leg in result.legs],
        'failed_leg': int(result.failed_leg),
        'cost': finite_or_none(result.cost),
        'flight_time_s': finite_or_none(energy.flight_time_s if energy else math.nan),
        'energy_wh': finite_or_none(energy.energy_wh if energy else math.nan),
        'climb_energy_wh': finite_or_none(energy.climb_energy_j / 3600.0 if energy
                                          else math.nan),
        'planning_margin': finite_or_none(result.planning_margin),
        'unknown_length_m': finite_or_none(result.unknown_length_m),
        'flight': flight_to_dict(result),
    }


#: Sample step of the peaks a summary reports [s]: a measurement (the limits hold between
#: samples by construction, core.path.timing); 10 ms over a flight of minutes costs the
#: command line a tenth of a second or more, and 50 ms finds the same peaks on town400.
PEAKS_STEP_S = 0.05


def flight_to_dict(result: 'PlanResult') -> Optional[Dict[str, Any]]:
    """Flight time and the peaks the timed reference reaches (every :data:`PEAKS_STEP_S`), or
    None."""
    trajectory = result.trajectory
    if trajectory is None:
        return None
    peaks = trajectory.peaks(PEAKS_STEP_S)
    return {'flight_time_s': finite_or_none(trajectory.duration_s),
            'peak_speed_horizontal': peaks.speed_horizontal,
            'peak_speed_vertical': peaks.speed_vertical,
            'peak_accel_horizontal': peaks.accel_horizontal,
            'peak_accel_vertical': peaks.accel_vertical,
            'peak_jerk': peaks.jerk, 'peak_tilt_deg': peaks.tilt_deg,
            'peak_thrust_to_weight': peaks.thrust_to_weight,
            'peak_yaw_rate': peaks.yaw_rate, 'peaks_step_s': peaks.step_s,
            'start_velocity': [float(v) for v in result.start_velocity],
            'start_acceleration': [float(v) for v in result.start_acceleration],
            'handover_velocity_error': finite_or_none(result.handover_velocity_error),
            'handover_accel_error': finite_or_none(result.handover_accel_error)}


def format_table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A plain-text table with right-aligned columns."""
    widths = [max(len(str(cell)) for cell in column) for column in zip(headers, *rows)]
    lines = ['  '.join(str(h).rjust(w) for h, w in zip(headers, widths)),
             '  '.join('-' * w for w in widths)]
    lines += ['  '.join(str(c).rjust(w) for c, w in zip(row, widths)) for row in rows]
    return '\n'.join(lines)


def format_summary(result: 'PlanResult') -> str:
    """A short human-readable account of one plan."""
    lines = [f'status: {result.status.value} ({result.message})',
             f'algorithm: {result.algorithm}']
    if result.ok:
        lines += [
            f'raw path: {len(result.path)} nodes, {result.path_length_m:.3f} m, '
            f'{result.expanded_nodes} nodes expanded in {result.planning_time_s * 1e3:.2f} ms',
            f'shortcut: {len(result.shortcut_path)} waypoints, {result.shortcut_length_m:.3f} m',
            f'smoothed: {result.smoothed_length_m:.3f} m, min clearance '
            f'{result.min_clearance_m:.3f} m (gamma {result.safety_margin} m), '
            f'{len(result.repaired_stretches)} repaired stretch(es), '
            f'{result.unknown_length_m:.3f} m in unknown space',
            f'trajectory: {result.duration_s:.2f} s; grid build {result.grid_build_time_s:.3f} s, '
            f'smoothing + timing {result.smoothing_time_s * 1e3:.2f} ms',
        ]
        flight = flight_to_dict(result)
        if flight is not None:
            lines.append(
                f"limits reached: speed {flight['peak_speed_horizontal']:.2f} / "
                f"{flight['peak_speed_vertical']:.2f} m/s (h/v), acceleration "
                f"{flight['peak_accel_horizontal']:.2f} / {flight['peak_accel_vertical']:.2f} "
                f"m/s^2, jerk {flight['peak_jerk']:.2f} m/s^3, tilt "
                f"{flight['peak_tilt_deg']:.1f} deg, thrust/weight "
                f"{flight['peak_thrust_to_weight']:.2f}")
    return '\n'.join(lines)


def map_report_lines(reports: Iterable['MapReport']) -> List[str]:
    """One ``map file ...`` line per map file read: points read, dropped (and why), kept,
    extent [m] and resolution."""
    return [f'map file {report.summary()}' for report in reports]


def admission_to_dict(admissions: Iterable['Admission']) -> Dict[str, Any]:
    """``start_adjusted``, ``start_note`` ('' when not moved) and ``requested_start`` [m], the
    goal's alike: what admission did to the points asked for."""
    output: Dict[str, Any] = {}
    for admission in admissions:
        values = admission.values()
        values[f'requested_{admission.which}'] = [
            finite_or_none(v) for v in admission.requested]
        output.update(values)
    return output


def admission_lines(admissions: Iterable['Admission']) -> List[str]:
    """One ``start adjusted: ...`` (``goal adjusted: ...``) line per moved point."""
    return [f'{admission.which} adjusted: {admission.note}' for admission in admissions
            if admission.adjusted]
