"""The ROS-free planning core: grid, inflation, search, smoothing, timing and the facade.

Nothing here imports rclpy or message types, so the core runs and is tested without ROS.

The public API, importable from this package::

    from uav_global_planner.core import Planner, PlannerConfig, load_scene

    scene = load_scene(find_scene('paper_medium'))
    result = Planner(scene.config, scene.obstacles).plan(scene.start, scene.goal)

- the facade: :class:`Planner`, :class:`PlannerConfig`, :class:`PlanResult`, :class:`PlanStatus`;
- scenes: :func:`load_scene`, :func:`find_scene`, :class:`Scene`;
- shapes (ENU, metres, in the planning frame): :class:`Sphere`, :class:`Box`, :class:`PointSet`,
  :class:`HeightField`, :class:`ObstacleSet`;
- errors: :class:`PlanningError` and its kinds (:class:`InvalidInputError`, ...).

Each name is imported when first used (PEP 562), so importing one module of the core (the grid,
the settings) does not load the planner and its compiled kernels.
"""

import importlib
from typing import Any, Dict, List, TYPE_CHECKING

if TYPE_CHECKING:  # the names as the type checker sees them
    from uav_global_planner.core.config import PlannerConfig as PlannerConfig
    from uav_global_planner.core.errors import (GoalOccupiedError as GoalOccupiedError,
                                                GoalOutsideMapError as GoalOutsideMapError,
                                                InvalidInputError as InvalidInputError,
                                                MissingDependencyError as MissingDependencyError,
                                                NoValidPathError as NoValidPathError,
                                                PlanningCancelledError as PlanningCancelledError,
                                                PlanningError as PlanningError,
                                                PlanningTimeoutError as PlanningTimeoutError,
                                                StartOccupiedError as StartOccupiedError,
                                                StartOutsideMapError as StartOutsideMapError)
    from uav_global_planner.core.io.scene import (find_scene as find_scene,
                                                  load_scene as load_scene, Scene as Scene)
    from uav_global_planner.core.map.obstacles import (Box as Box, ObstacleSet as ObstacleSet,
                                                       PointSet as PointSet, Sphere as Sphere)
    from uav_global_planner.core.map.terrain import HeightField as HeightField
    from uav_global_planner.core.planner import Planner as Planner
    from uav_global_planner.core.result import PlanResult as PlanResult
    from uav_global_planner.core.status import PlanStatus as PlanStatus

#: Public name -> the module of the core that defines it.
_PUBLIC: Dict[str, str] = {
    'Planner': 'planner', 'PlannerConfig': 'config', 'PlanResult': 'result',
    'PlanStatus': 'status', 'load_scene': 'io.scene', 'find_scene': 'io.scene',
    'Scene': 'io.scene',
    'Sphere': 'map.obstacles', 'Box': 'map.obstacles', 'PointSet': 'map.obstacles',
    'ObstacleSet': 'map.obstacles', 'HeightField': 'map.terrain',
    'PlanningError': 'errors', 'InvalidInputError': 'errors',
    'MissingDependencyError': 'errors', 'StartOutsideMapError': 'errors',
    'GoalOutsideMapError': 'errors', 'StartOccupiedError': 'errors',
    'GoalOccupiedError': 'errors', 'NoValidPathError': 'errors',
    'PlanningTimeoutError': 'errors', 'PlanningCancelledError': 'errors',
}

__all__ = ['Box', 'find_scene', 'GoalOccupiedError', 'GoalOutsideMapError', 'HeightField',
           'InvalidInputError', 'load_scene', 'MissingDependencyError', 'NoValidPathError',
           'ObstacleSet', 'Planner', 'PlannerConfig', 'PlanningCancelledError', 'PlanningError',
           'PlanningTimeoutError', 'PlanResult', 'PlanStatus', 'PointSet', 'Scene', 'Sphere',
           'StartOccupiedError', 'StartOutsideMapError']


def __getattr__(name: str) -> Any:
    """The public name ``name``, imported from its module on first use."""
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(f'{__name__}.{module}'), name)
    globals()[name] = value
    return value


def __dir__() -> List[str]:
    return sorted(set(globals()) | set(__all__))
