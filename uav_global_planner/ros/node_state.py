"""Records of the planner node's parts, passed between its threads (executor, intake, worker).

Each record says which part's lock guards it. :class:`Snapshot` is what one plan uses, copied
from the planning inputs under their lock when the plan begins.
"""

from collections import deque
from dataclasses import dataclass, field
from typing import Any, Deque, Optional, Tuple

import numpy as np

from uav_global_planner.core.map.airspace import Airspace
from uav_global_planner.core.map.live_map import LiveMap
from uav_global_planner.core.result import PlanResult
from uav_global_planner.ros.parameters import NodeSettings
from uav_global_planner.ros.start_source import StartSource


@dataclass(frozen=True, eq=False)
class Goal:
    """A goal accepted from ``goal_pose``.

    Attributes
    ----------
    position : numpy.ndarray, shape (3,)
        [m] in the planning frame.
    orientation : numpy.ndarray, shape (4,)
        Unit quaternion (x, y, z, w), kept for the last pose of the plan.
    serial : int
        Increases with every accepted goal.
    """

    position: np.ndarray
    orientation: np.ndarray
    serial: int


@dataclass(frozen=True, eq=False)
class Snapshot:
    """Everything one plan uses, copied from the planning inputs when the plan begins.

    ``obstacles`` and ``obstacles_version`` are those of ``map``, the consistent map (obstacles
    and inflated grid) the plan runs on.
    """

    settings: NodeSettings
    settings_changed: bool
    obstacles: Any
    obstacles_changed: bool
    obstacles_version: int
    obstacles_stamp_ns: int
    goal: Optional[Goal]
    goal_changed: bool
    start: np.ndarray
    start_source: StartSource
    map: Optional[LiveMap] = None
    replan_reason: Optional[str] = None


@dataclass
class SourceState:
    """What one map source has delivered (guarded by the map intake's lock).

    Attributes
    ----------
    received : int
        Messages that arrived (clouds the intake had no time for included).
    accepted, refused, superseded : int
        Messages taken into the map, refused (with ``last_refusal``), or dropped unread for a
        newer cloud.
    refused_last : bool
        The newest message was refused: the map holds older data of this source (or none).
    last_refusal : str
    last_stamp_ns : int
        Header stamp of the newest accepted message.
    """

    received: int = 0
    accepted: int = 0
    refused: int = 0
    superseded: int = 0
    refused_last: bool = False
    last_refusal: str = ''
    last_stamp_ns: int = 0

    @property
    def delivered(self) -> bool:
        return self.accepted > 0

    def summary(self) -> str:
        if not self.delivered and not self.refused:
            return 'nothing received'
        text = f'{self.accepted} accepted'
        if self.refused:
            text += f', {self.refused} refused'
        if self.superseded:
            text += f', {self.superseded} superseded by newer'
        return text


@dataclass
class InForce:
    """The plan latched on ``plan`` (guarded by the plan in force's release lock).

    ``stamp_ns`` is the plan's time 0 (its header stamp). A plan that takes over in the future
    keeps the plan it replaces as ``previous``: until its stamp the vehicle still flies that
    one (:meth:`flown_at`).
    """

    result: PlanResult
    frame_id: str
    stamp_ns: int
    start_source: StartSource
    checked_version: int
    goal_serial: Optional[int] = None     # None: a Nav2 request's plan
    previous: Optional['InForce'] = None

    def flown_at(self, at_ns: int) -> 'InForce':
        """The plan the vehicle flies at ``at_ns`` [ns]: this one from its stamp on, before
        that the one it replaces."""
        plan = self
        while plan.previous is not None and at_ns < plan.stamp_ns:
            plan = plan.previous
        return plan


@dataclass
class Inbox:
    """Map messages waiting for the intake (guarded by the intake's condition)."""

    markers: Deque[Tuple[bytes, int]] = field(default_factory=deque)
    cloud: Optional[Tuple[bytes, int]] = None
    reconfigure: bool = False
    # The frame changed since the intake last ran: drop the markers and cloud even if it has
    # changed back meanwhile (they were stamped in a frame that was left).
    frame_reset: bool = False
    # A geofence read from new parameters, for the next map, and its serial number.
    airspace: Optional[Airspace] = None
    airspace_serial: int = 0
    stopping: bool = False
