"""A fleet's missions planned and deconflicted on Ray (the optional extra ``fleet``).

The only package that imports ``ray``; it uses :mod:`uav_global_planner.core.fleet` and never
the other way round. Public API (imported on first use, so an airspace shard's process loads
only its own module):

- :func:`plan_fleet_ray` (:mod:`.runner`): a batch planned by planner actors on a map shared
  through the object store, committed in the fleet order through a sharded airspace; the same
  :class:`~uav_global_planner.core.fleet.FleetResult` as the serial
  :func:`~uav_global_planner.core.fleet.run_fleet` for any number of workers.
- :func:`ray_session` (:mod:`.session`): an embedded local Ray, or a cluster by address.
- :class:`Airspace`, :class:`ShardLayout`, :func:`make_airspace` (:mod:`.airspace`): the
  reservations by area and time window, with version-checked commits.

Importing them imports Ray: a missing Ray is a
:class:`~uav_global_planner.core.errors.MissingDependencyError` naming the pip package.
"""

from importlib import import_module
from typing import Any

_EXPORTS = {
    'plan_fleet_ray': 'runner', 'FleetRun': 'runner', 'RunStats': 'runner',
    'default_layout': 'runner',
    'ray_session': 'session', 'SessionInfo': 'session',
    'Airspace': 'airspace', 'CommitOutcome': 'airspace', 'ShardLayout': 'airspace',
    'make_airspace': 'airspace',
    'build_shared_map': 'shared_map', 'SharedMap': 'shared_map',
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    """The public names, each imported from its module on first use."""
    if name not in _EXPORTS:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    return getattr(import_module(f'{__name__}.{_EXPORTS[name]}'), name)
