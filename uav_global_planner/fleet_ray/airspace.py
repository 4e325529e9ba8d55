"""The airspace service: reservations sharded by area and time window, with version checks.

Each reservation is an accepted flight, described here by its space-time boxes (rows ``[t0, t1,
xmin, ymin, zmin, xmax, ymax, zmax]``: the flight's positions over ``[t0, t1]`` lie in the box;
:func:`~uav_global_planner.core.fleet.flight_boxes`) and a handle on the flight itself (a Ray
object reference: the service stores where the trajectory is, not the trajectory). The boxes
are filed in :class:`AirspaceShard` actors by area tile and time window (:class:`ShardLayout`),
so the load of checks and commits is spread over actors that may run on different machines.

Commits are optimistic, as in the InterUSS DSS: a planner resolves a mission against the book
as it was at some version (the number of flights committed when it looked) and records its
*footprint*, the boxes of every candidate flight it checked, inflated by the separation
envelope. :meth:`Airspace.commit` then asks every shard the footprint or the new flight touches
whether a flight committed since that version lies in the footprint. If one does, the commit is
refused (stale: the resolution might have decided otherwise) and nothing changes; if none does,
the resolution is exactly what it would have been on the latest book, and the flight is filed.
The shards involved are locked for the check-and-write (all or none: a committer that finds one
locked releases the others and tries again), so two committers never both take the same volume:
the second one sees the first one's flight and is refused.
"""

from dataclasses import dataclass
import math
import random
import threading
import time
from typing import Any, Dict, List, Optional, Sequence, Set, Tuple

import numpy as np

from uav_global_planner.core.errors import InvalidInputError
from uav_global_planner.fleet_ray.session import import_ray

ray = import_ray()

# Columns of a space-time box row.
T0, T1, XMIN, YMIN, ZMIN, XMAX, YMAX, ZMAX = range(8)

# How long a committer waits between attempts when a shard is locked by another one [s].
_RETRY_S = 0.002


def inflate(boxes: np.ndarray, horizontal_m: float, vertical_m: float) -> np.ndarray:
    """Boxes grown by the separation envelope: ``horizontal_m`` in x and y, ``vertical_m``
    in z [m]; times unchanged.

    A flight whose boxes are disjoint from another flight's inflated boxes cannot come within
    the envelope of it: at any instant the two are in boxes of the same time that are apart by
    at least the separation along x or y (so horizontally) or along z.
    """
    out = np.array(boxes, dtype=np.float64).reshape(-1, 8)
    out[:, [XMIN, YMIN]] -= horizontal_m
    out[:, [XMAX, YMAX]] += horizontal_m
    out[:, ZMIN] -= vertical_m
    out[:, ZMAX] += vertical_m
    return out


def any_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """True when a box of ``a`` and a box of ``b`` share a point (closed boxes, (n, 8) rows)."""
    if not len(a) or not len(b):
        return False
    lows = [T0, XMIN, YMIN, ZMIN]
    highs = [T1, XMAX, YMAX, ZMAX]
    # Only the rows of ``a`` that meet the hull of ``b`` can meet one of its boxes.
    near = np.all((a[:, lows] <= b[:, highs].max(axis=0))
                  & (a[:, highs] >= b[:, lows].min(axis=0)), axis=1)
    a = a[near]
    for start in range(0, len(a), 256):
        part = a[start:start + 256]
        lo = np.maximum(part[:, None, lows], b[None, :, lows])
        hi = np.minimum(part[:, None, highs], b[None, :, highs])
        if np.any(np.all(lo <= hi, axis=2)):
            return True
    return False


@dataclass(frozen=True)
class ShardLayout:
    """How the airspace is cut into shards.

    The map's horizontal bounds are cut into ``tiles`` x ``tiles`` areas and time into windows
    of ``window_s`` seconds; the cell of area ``a`` (``tx * tiles + ty``) and window ``w`` (the
    batch clock's ``floor(t / window_s)``) belongs to shard ``(a + w) mod shards``, so every
    shard holds some area in every window and the load moves round the shards as time goes.

    Attributes
    ----------
    xy_min, xy_max : tuple of float
        Horizontal bounds of the map [m]; boxes beyond them go to the border tiles.
    tiles : int
        Tiles per axis, >= 1.
    window_s : float
        Length of a time window [s], > 0.
    shards : int
        Number of shard actors, >= 1.
    """

    xy_min: Tuple[float, float]
    xy_max: Tuple[float, float]
    tiles: int = 2
    window_s: float = 600.0
    shards: int = 4

    def __post_init__(self) -> None:
        if self.tiles < 1 or self.shards < 1:
            raise InvalidInputError(f'shard layout: tiles and shards must be >= 1, got '
                                    f'{self.tiles} and {self.shards}')
        if not (math.isfinite(self.window_s) and self.window_s > 0.0):
            raise InvalidInputError(f'shard layout: window_s must be > 0 s, got {self.window_s}')
        if not all(hi > lo for lo, hi in zip(self.xy_min, self.xy_max)):
            raise InvalidInputError('shard layout: xy_max must exceed xy_min')

    @property
    def count(self) -> int:
        """Number of shards."""
        return self.shards

    def shards_of(self, boxes: np.ndarray) -> List[int]:
        """Ids of the shards any of ``boxes`` touches, sorted."""
        rows = np.asarray(boxes, dtype=np.float64).reshape(-1, 8)
        if not len(rows):
            return []
        origin = np.asarray(self.xy_min, dtype=np.float64)
        size = (np.asarray(self.xy_max, dtype=np.float64) - origin) / self.tiles
        lo = np.clip(np.floor((rows[:, [XMIN, YMIN]] - origin) / size), 0, self.tiles - 1)
        hi = np.clip(np.floor((rows[:, [XMAX, YMAX]] - origin) / size), 0, self.tiles - 1)
        first = np.floor(rows[:, T0] / self.window_s)
        # The shard of a cell repeats every ``shards`` windows.
        last = np.minimum(np.floor(rows[:, T1] / self.window_s), first + self.shards - 1)
        ranges = np.unique(np.column_stack([lo, hi, first, last]).astype(np.int64), axis=0)
        found: Set[int] = set()
        for x0, y0, x1, y1, w0, w1 in ranges.tolist():
            for tx in range(x0, x1 + 1):
                for ty in range(y0, y1 + 1):
                    for window in range(w0, w1 + 1):
                        found.add((tx * self.tiles + ty + window) % self.shards)
        return sorted(found)


class AirspaceShard:
    """One shard of the airspace: the boxes of the flights it holds and who holds its lock.

    Run as a Ray actor (:func:`make_shards`); its methods run one at a time.

    Parameters
    ----------
    shard_id : int
    """

    def __init__(self, shard_id: int) -> None:
        self.shard_id = shard_id
        #: Flights filed here: (sequence number, boxes (n, 8), handle), in commit order.
        self._entries: List[Tuple[int, np.ndarray, Any]] = []
        self._version = 0
        self._holder: Optional[str] = None
        self._busy_s = 0.0

    def version(self) -> int:
        """Commits filed in this shard so far."""
        return self._version

    def busy_s(self) -> float:
        """Time spent in checks and commits [s] (this actor's share of the serial work)."""
        return self._busy_s

    def prepare(self, token: str, footprint: np.ndarray, seen: int) -> Optional[List[int]]:
        """Lock the shard for ``token`` and list the flights committed at sequence ``seen`` or
        later whose boxes meet ``footprint`` (sorted); None when another token holds the lock.
        """
        started = time.perf_counter()
        if self._holder is not None and self._holder != token:
            return None
        self._holder = token
        stale = sorted(seq for seq, boxes, _ in self._entries
                       if seq >= seen and any_overlap(footprint, boxes))
        self._busy_s += time.perf_counter() - started
        return stale

    def write(self, token: str, seq: int, boxes: Optional[np.ndarray], handle: Any) -> int:
        """File a flight (``boxes`` None: nothing to file) and release the lock; the new
        version.

        Raises
        ------
        RuntimeError
            When ``token`` does not hold the lock.
        """
        started = time.perf_counter()
        if self._holder != token:
            raise RuntimeError(f'shard {self.shard_id}: write without the lock')
        if boxes is not None:
            self._entries.append((seq, np.asarray(boxes), handle))
            self._version += 1
        self._holder = None
        self._busy_s += time.perf_counter() - started
        return self._version

    def release(self, token: str) -> None:
        """Give the lock up (a refused commit)."""
        if self._holder == token:
            self._holder = None

    def flights_since(self, seen: int) -> List[Tuple[int, Any]]:
        """(sequence number, handle) of the flights committed at ``seen`` or later."""
        return [(seq, handle) for seq, _, handle in self._entries if seq >= seen]


@dataclass(frozen=True)
class CommitOutcome:
    """What :meth:`Airspace.commit` did.

    Attributes
    ----------
    committed : bool
        True when the flight was filed (or, for a rejected mission, the footprint was clear).
    stale : tuple of int
        Sequence numbers of flights committed since the resolution's version that meet its
        footprint (empty when committed).
    shards : tuple of int
        Shards the commit locked.
    """

    committed: bool
    stale: Tuple[int, ...]
    shards: Tuple[int, ...]


class Airspace:
    """Client of the shard actors; picklable, so any task or actor can commit through it.

    Parameters
    ----------
    layout : ShardLayout
    shards : sequence of actor handles
        One :class:`AirspaceShard` actor per shard id.
    """

    def __init__(self, layout: ShardLayout, shards: Sequence[Any]) -> None:
        if len(shards) != layout.count:
            raise InvalidInputError(f'{layout.count} shards expected, got {len(shards)}')
        self.layout = layout
        self.shards = list(shards)
        self._counter = 0
        self._lock = threading.Lock()
        self._pending: List[Any] = []

    def __getstate__(self) -> Dict[str, Any]:
        return {'layout': self.layout, 'shards': self.shards}

    def __setstate__(self, state: Dict[str, Any]) -> None:
        self.__init__(state['layout'], state['shards'])  # type: ignore[misc]

    def _token(self) -> str:
        with self._lock:
            self._counter += 1
            return f'{id(self):x}-{threading.get_ident():x}-{self._counter}'

    def commit(self, seq: int, footprint: np.ndarray, seen: int,
               boxes: Optional[np.ndarray], handle: Any = None,
               timeout_s: float = 60.0, wait: bool = True) -> CommitOutcome:
        """Check a resolution against the flights committed since it looked, and file its
        flight when none of them meets its footprint.

        Parameters
        ----------
        seq : int
            The flight's sequence number (the book version it is added at).
        footprint : numpy.ndarray, shape (n, 8)
            Inflated boxes of every candidate flight the resolution checked.
        seen : int
            The book version the resolution was made against.
        boxes : numpy.ndarray, shape (m, 8), or None
            The accepted flight's boxes; None for a rejected mission (only checked).
        handle : Any
            What to file with the boxes (the flight's object reference).
        timeout_s : float
            How long to wait for shards locked by other committers [s].
        wait : bool
            Wait until the shards have filed the flight. Without waiting, the filing is sent
            and the outcome returned at once: a shard runs one caller's requests in the order
            sent, so this caller's next commit sees the flight; :meth:`settle` waits for it.

        Returns
        -------
        CommitOutcome
        """
        footprint = np.asarray(footprint, dtype=np.float64).reshape(-1, 8)
        own = (np.empty((0, 8)) if boxes is None
               else np.asarray(boxes, dtype=np.float64).reshape(-1, 8))
        involved = sorted(set(self.layout.shards_of(footprint)) | set(self.layout.shards_of(own)))
        writes = set(self.layout.shards_of(own)) if boxes is not None else set()
        token = self._token()
        deadline = time.monotonic() + timeout_s
        while True:
            # All shards at once: a locked shard answers None at once instead of waiting, so
            # asking in parallel cannot deadlock; a commit that meets one backs off entirely.
            answers = ray.get([self.shards[shard_id].prepare.remote(token, footprint, seen)
                               for shard_id in involved])
            held = [shard_id for shard_id, answer in zip(involved, answers)
                    if answer is not None]
            busy = len(held) < len(involved)
            stale = sorted({seq for answer in answers if answer for seq in answer})
            if busy or stale:
                ray.get([self.shards[shard_id].release.remote(token) for shard_id in held])
                if not busy:
                    return CommitOutcome(False, tuple(stale), tuple(involved))
                if time.monotonic() > deadline:
                    raise TimeoutError(f'airspace shards {involved} stayed locked for '
                                       f'{timeout_s:g} s')
                # Back off for a random while, so two committers do not meet again.
                time.sleep(_RETRY_S * (1.0 + random.random()))
                continue
            filed = [self.shards[shard_id].write.remote(
                token, seq, own if shard_id in writes else None, handle) for shard_id in held]
            if wait:
                ray.get(filed)
            else:
                self._pending.extend(filed)
            return CommitOutcome(True, (), tuple(involved))

    def settle(self) -> None:
        """Wait for the filings sent by commits that did not wait (raises what they raised)."""
        pending, self._pending = self._pending, []
        ray.get(pending)

    def flights_since(self, seen: int) -> List[Tuple[int, Any]]:
        """(sequence number, handle) of every flight committed at ``seen`` or later, in
        sequence order (a flight filed in several shards is listed once)."""
        found: Dict[int, Any] = {}
        for entries in ray.get([shard.flights_since.remote(seen) for shard in self.shards]):
            for seq, handle in entries:
                found.setdefault(seq, handle)
        return sorted(found.items(), key=lambda item: item[0])

    def busy_s(self) -> List[float]:
        """Time each shard spent checking and filing [s]."""
        return list(ray.get([shard.busy_s.remote() for shard in self.shards]))


def make_airspace(layout: ShardLayout) -> Airspace:
    """Start one shard actor per shard of ``layout`` (each needs no CPU of its own)."""
    remote = ray.remote(num_cpus=0)(AirspaceShard)
    return Airspace(layout, [remote.remote(number) for number in range(layout.count)])
