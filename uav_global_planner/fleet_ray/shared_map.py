"""The map a fleet is planned on, built once and shared read-only by every planner.

The driver inflates the scene's obstacles once (the planning grid's blocked mask, and the
conservative mask a plan falls back to when smoothing fails) and puts the result into Ray's
object store with one ``ray.put``. Planner actors on the same machine then read the masks'
numpy arrays zero-copy from shared memory (Ray hands them out as read-only views); an actor on
another machine gets one copy per node, transferred once. The obstacles themselves travel as
their shapes (a few kB for a city of boxes); each actor rebuilds its distance index from them.
"""

from dataclasses import dataclass
from typing import Optional, Tuple

from uav_global_planner.core.config import PlannerConfig
from uav_global_planner.core.io.scene import Scene
from uav_global_planner.core.map.inflation import blocked_mask, Mask
from uav_global_planner.core.map.obstacles import Obstacle, ObstacleSet
from uav_global_planner.core.map.unknown_space import UnknownSpace
from uav_global_planner.core.planner import fallback_margin, Planner


@dataclass(frozen=True, eq=False)
class SharedMap:
    """Everything a planner needs to plan on a scene's map, without building its grid.

    Attributes
    ----------
    config : PlannerConfig
        The scene's settings (bounds, delta, gamma, limits).
    shapes : tuple of Obstacle
        The obstacles, in the scene's order (ENU map frame, [m]).
    unknown : UnknownSpace or None
        The scene's unknown space.
    blocked : numpy.ndarray of bool or SparseMask
        The planning grid's mask for ``config`` (read-only).
    fallback : numpy.ndarray of bool or SparseMask, or None
        The mask at gamma + delta * sqrt(3) / 2; None when not built (a plan that needs it then
        builds it on its actor).
    grid_key : tuple
        :meth:`PlannerConfig.grid_key` the masks belong to.
    """

    config: PlannerConfig
    shapes: Tuple[Obstacle, ...]
    unknown: Optional[UnknownSpace]
    blocked: Mask
    fallback: Optional[Mask]
    grid_key: tuple

    @property
    def nbytes(self) -> int:
        """Bytes of the masks' arrays, what the object store holds for them."""
        return sum(_mask_bytes(mask) for mask in (self.blocked, self.fallback))


def build_shared_map(scene: Scene, with_fallback: bool = True) -> SharedMap:
    """Inflate the scene's map once.

    Parameters
    ----------
    scene : Scene
        With its ground (:func:`~uav_global_planner.core.io.scene.with_ground`) already applied.
    with_fallback : bool
        Also build the conservative mask (about half the time of the first).

    Returns
    -------
    SharedMap
    """
    planner = Planner(scene.config, scene.obstacles, unknown=scene.unknown)
    blocked = planner.blocked
    fallback = (blocked_mask(planner.grid, planner.obstacles, fallback_margin(scene.config))
                if with_fallback else None)
    return SharedMap(config=scene.config, shapes=tuple(scene.obstacles.items),
                     unknown=scene.unknown, blocked=blocked, fallback=fallback,
                     grid_key=scene.config.grid_key())


def planner_from_map(shared: SharedMap) -> Planner:
    """A planner on the shared masks: no grid is built, the masks are read in place.

    When the masks cannot be used (unknown space counted as obstacles, which the shared mask
    does not hold) the planner builds its own grid at its first plan, with the same result.
    """
    obstacles = ObstacleSet(shared.shapes)
    planner = Planner(shared.config, obstacles, unknown=shared.unknown)
    planner.set_map(obstacles, shared.blocked, shared.grid_key, shared.fallback)
    return planner


def _mask_bytes(mask: Optional[Mask]) -> int:
    if mask is None:
        return 0
    table = getattr(mask, 'table', None)
    if table is not None:
        return int(table.nbytes + getattr(mask, 'pool').nbytes)
    return int(getattr(mask, 'nbytes', 0))
