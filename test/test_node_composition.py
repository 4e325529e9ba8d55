"""The planner node is composed of parts: each owns its state, its lock and its ROS entities.

In-process (no DDS traffic): the node object is inspected. It holds parts and read-only values
only; no lock, container or mutable record is held by two parts (a part reaches another's state
through that part's methods); each part's lock is named in its class docstring; each topic of
the node is created by the part that owns it.
"""

from collections import deque
import dataclasses
import threading
from typing import Any, Dict, Iterator, List, Set, Tuple

import pytest
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node

from ros_harness import in_process_planner
from uav_global_planner.core.io.mapfiles import MapPoints
from uav_global_planner.core.map.live_map import LiveMapBuilder
from uav_global_planner.core.planner import Planner
from uav_global_planner.ros.mission_service import MissionExportService
from uav_global_planner.ros.nav2_interfaces import PlannerInterfaces
from uav_global_planner.ros.node_diagnostics import NodeDiagnostics
from uav_global_planner.ros.node_in_force import PlanInForce
from uav_global_planner.ros.node_inputs import CommandInputs
from uav_global_planner.ros.node_intake import MapIntake
from uav_global_planner.ros.node_plan_inputs import PlanningInputs
from uav_global_planner.ros.node_reconfigure import NodeParameters
from uav_global_planner.ros.node_status import NodeStatus
from uav_global_planner.ros.node_worker import PlanningWorker
from uav_global_planner.ros.planner_node import PlannerNode

#: The parts of the node.
PARTS = (PlanningInputs, NodeDiagnostics, PlanInForce, MapIntake, PlanningWorker,
         CommandInputs, NodeStatus, NodeParameters, PlannerInterfaces, MissionExportService)

_LOCK_TYPES = (type(threading.Lock()), type(threading.RLock()), threading.Condition)

#: Which part creates each topic of the node (relative names as the parts give them).
TOPIC_OWNERS = {
    'plan': PlanInForce, 'unsmoothed_plan': PlanInForce, 'trajectory': PlanInForce,
    '/diagnostics': NodeDiagnostics, 'planner_markers': NodeStatus,
    'obstacles': MapIntake, 'obstacle_cloud': MapIntake,
    'goal_pose': CommandInputs, 'odom': CommandInputs, 'start_pose': CommandInputs,
}


@pytest.fixture(scope='module')
def planner() -> Iterator[PlannerNode]:
    with in_process_planner() as node:
        yield node


def _parts(planner: PlannerNode) -> Dict[str, Any]:
    return {name: value for name, value in vars(planner).items() if isinstance(value, PARTS)}


def _is_state(value: Any) -> bool:
    """A value that holds mutable state: a lock, a container, a mutable record, the planner
    or the map builder."""
    if isinstance(value, _LOCK_TYPES + (dict, list, set, deque, Planner, LiveMapBuilder)):
        return True
    return (dataclasses.is_dataclass(value) and not isinstance(value, type)
            and not type(value).__dataclass_params__.frozen)  # type: ignore[union-attr]


def test_the_node_holds_parts_and_read_only_values_only(planner: PlannerNode) -> None:
    parts = _parts(planner)
    assert {type(part) for part in parts.values()} == set(PARTS), parts
    others = {name: value for name, value in vars(planner).items() if name not in parts}
    for name, value in others.items():
        assert isinstance(value, (Node, RcutilsLogger, MapPoints, type(None))), (name, value)
        assert not _is_state(value), name


def test_no_state_is_held_by_two_parts(planner: PlannerNode) -> None:
    holders: Dict[int, List[Tuple[str, str]]] = {}
    for part_name, part in _parts(planner).items():
        for attribute, value in vars(part).items():
            if _is_state(value):
                holders.setdefault(id(value), []).append((part_name, attribute))
    shared = [names for names in holders.values() if len(names) > 1]
    assert not shared, f'state held by more than one part: {shared}'


def test_each_part_owns_at_most_one_lock_and_its_docstring_names_it(
        planner: PlannerNode) -> None:
    seen: Set[int] = set()
    for part_name, part in _parts(planner).items():
        locks = [(attribute, value) for attribute, value in vars(part).items()
                 if isinstance(value, _LOCK_TYPES)]
        assert len(locks) <= 1, (part_name, locks)
        for attribute, lock in locks:
            assert id(lock) not in seen, (part_name, attribute)
            seen.add(id(lock))
            if type(part).__module__.startswith('uav_global_planner.ros.node_'):
                assert f'``{attribute}``' in (type(part).__doc__ or ''), (
                    f"{type(part).__name__}'s docstring does not say what {attribute} guards")
    # The plan in force, the planning inputs, the intake and the diagnostics publisher have
    # locks of their own.
    owners = {type(part) for part in _parts(planner).values()
              if any(isinstance(value, _LOCK_TYPES) for value in vars(part).values())}
    assert {PlanInForce, PlanningInputs, MapIntake, NodeDiagnostics} <= owners, owners


def test_each_topic_is_created_by_the_part_that_owns_it(planner: PlannerNode) -> None:
    entities = {id(entity): entity for entity in
                list(planner.node.publishers) + list(planner.node.subscriptions)}
    found: Dict[str, type] = {}
    for part in _parts(planner).values():
        for value in vars(part).values():
            entity = entities.get(id(value))
            if entity is not None:
                name = entity.topic_name
                short = name if name == '/diagnostics' else name.rsplit('/', 1)[-1]
                assert short not in found, f'{short} is held by two parts'
                found[short] = type(part)
    assert {name: found.get(name) for name in TOPIC_OWNERS} == TOPIC_OWNERS
