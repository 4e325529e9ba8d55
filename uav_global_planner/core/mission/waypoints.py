"""The waypoint search: certified waypoints chosen among points of the plan.

Choosing the waypoints
----------------------
Candidates are points of the plan in force: samples of the smoothed curve (every ``delta / 2``
of arc length) and the raw grid path's nodes, ordered by their position along the curve. The
plan keeps only ``gamma`` and a turn cuts inside its corner, so copies of the candidates near
obstacles are pushed up the distance gradient to ``m`` and to ``m + R/4, R/2, R`` (in an alley
too narrow for that, to its middle). From each waypoint the search takes the farthest candidate
whose leg, turn region and leg length pass, and backtracks a few waypoints when it gets stuck.
Where the straight legs are visible along the route in order (what usually holds), this gives
the fewest waypoints among the candidates. Via-points are never skipped. When no certified
mission exists (a passage narrower than about ``2 m`` plus the turns' room, the goal closer than
``m`` to an obstacle, a blocked climb or end action) :class:`UncertifiableMissionError` says
where.
"""

from dataclasses import dataclass
import math
from typing import Iterator, List, Optional, Tuple

import numpy as np

from uav_global_planner.core.map.obstacles import ObstacleSet
from uav_global_planner.core.mission.certify import (certify_triangle, TURN_CELL_INRADIUS,
                                                     turn_triangle, unit_vector)
from uav_global_planner.core.path.clearance import certify_segments

#: Candidates ahead of a waypoint that are all checked at once; beyond, a gallop and bisection.
_FULL_SCAN = 256
#: Budget of the waypoint search, in leg or turn certifications.
_SEARCH_BUDGET = 20000
#: Alternatives tried after a waypoint, and how many waypoints the search may take back.
_OPTIONS_PER_WAYPOINT = 16
_BACKTRACK_WAYPOINTS = 4
_PUSH_ITERATIONS = 40
#: Extra clearance of the pushed-off candidate copies, in acceptance radii.
_OFFSET_LAYERS = (0.0, 0.25, 0.5, 1.0)


@dataclass
class WaypointNode:
    """A waypoint of the search: its position [m] and where it stands among the candidates."""

    position: np.ndarray
    before: Optional[np.ndarray]     # incoming leg start: the node is a turn when set
    candidate: int                   # candidate index, -1 for the first node
    progress: float


class WaypointSearch:
    """Depth-first farthest-first search of certified waypoints over the candidates."""

    def __init__(self, obstacles: ObstacleSet, candidates: np.ndarray, progress: np.ndarray,
                 mandatory: np.ndarray, margin: float, resolution: float, radius: float,
                 after_goal: Optional[np.ndarray]) -> None:
        self.obstacles = obstacles
        self.candidates = candidates
        self.progress = progress
        self.mandatory = mandatory          # sorted candidate indices that cannot be skipped
        self.margin = margin
        self.leg_margin = margin + TURN_CELL_INRADIUS
        self.resolution = resolution
        self.radius = radius
        self.goal = len(candidates) - 1
        self.after_goal = after_goal        # first point flown after the goal (a turn), or None
        self.budget = _SEARCH_BUDGET
        self.farthest = 0.0

    def _spend(self, amount: int = 1) -> None:
        self.budget -= amount
        if self.budget < 0:
            raise SearchExhausted()

    def _legs_clear(self, origin: np.ndarray, indices: np.ndarray) -> np.ndarray:
        # Legs keep a turn cell's inradius more than the turns, so that the turn triangles'
        # sides, which lie on the legs, need no second certificate.
        self._spend()
        ends = self.candidates[indices]
        starts = np.broadcast_to(origin, ends.shape)
        return certify_segments(self.obstacles, starts, ends, self.leg_margin,
                                self.resolution).clear

    def _window(self, node: WaypointNode) -> Tuple[int, int]:
        lo = int(np.searchsorted(self.progress, node.progress, side='right'))
        lo = max(lo, node.candidate + 1)
        ahead = self.mandatory[self.mandatory >= lo]
        hi = int(ahead[0]) if len(ahead) else self.goal
        return lo, hi

    def _clear_batches(self, node: WaypointNode) -> Iterator[np.ndarray]:
        """Candidates with a certified leg from ``node``, farthest first, in batches (lazily)."""
        lo, hi = self._window(node)
        if lo > hi:
            return
        if hi - lo + 1 <= _FULL_SCAN:
            indices = np.arange(lo, hi + 1)
            yield indices[self._legs_clear(node.position, indices)][::-1]
            return
        # Gallop outwards, then bisect between the farthest clear and the next blocked one.
        offsets = np.unique(np.r_[(2 ** np.arange(int(math.log2(hi - lo)) + 1)) - 1, hi - lo])
        tested = lo + offsets
        clear = self._legs_clear(node.position, tested)
        known = dict(zip(tested.tolist(), clear.tolist()))
        clear_tested = tested[clear]
        below = hi
        if len(clear_tested):
            best = int(clear_tested[-1])
            later = tested[tested > best]
            blocked = int(later[0]) if len(later) else None
            while blocked is not None and blocked - best > 1:
                mid = (best + blocked) // 2
                ok = bool(self._legs_clear(node.position, np.array([mid]))[0])
                known[mid] = ok
                best, blocked = (mid, blocked) if ok else (best, mid)
            yield np.array([best])
            below = best - 1
        # Everything else below, in descending batches.
        while below >= lo:
            batch = np.arange(max(lo, below - _FULL_SCAN + 1), below + 1)[::-1]
            todo = np.array([j for j in batch.tolist() if j not in known], dtype=np.int64)
            if len(todo):
                for j, ok in zip(todo.tolist(), self._legs_clear(node.position, todo).tolist()):
                    known[j] = ok
            yield np.array([j for j in batch.tolist() if known[j]], dtype=np.int64)
            below = int(batch[-1]) - 1

    def _options(self, node: WaypointNode) -> Iterator[int]:
        """Next waypoints from ``node`` that pass every check, farthest first (lazily)."""
        radius = self.radius
        for batch in self._clear_batches(node):
            if not len(batch):
                continue
            targets = self.candidates[batch]
            lengths = np.linalg.norm(targets - node.position, axis=1)
            final = batch == self.goal
            turns = int(node.before is not None) + (~final | (self.after_goal is not None))
            keep = lengths >= radius * np.maximum(turns, 1)
            if node.before is not None and np.any(keep):
                # The cut A -> B first, for the whole batch: most turns that fail, fail there,
                # and one segment is far cheaper than the subdivided triangle.
                self._spend()
                a = node.position + radius * unit_vector(node.before - node.position)
                b = node.position + radius * (targets[keep] - node.position) / lengths[keep, None]
                cut = certify_segments(self.obstacles, np.broadcast_to(a, b.shape), b,
                                       self.margin, self.resolution).clear
                keep[np.flatnonzero(keep)[~cut]] = False
            for j in batch[keep].tolist():
                target = self.candidates[j]
                if node.before is not None and not self._turn_clear(
                        node.before, node.position, target, radius):
                    continue
                if j == self.goal and self.after_goal is not None:
                    after = self.after_goal
                    r = min(radius, float(np.linalg.norm(after - target)))
                    if not self._turn_clear(node.position, target, after, r):
                        continue
                yield j

    def _turn_clear(self, before: np.ndarray, corner: np.ndarray, after: np.ndarray,
                    radius: float) -> bool:
        self._spend()
        a, p, b = turn_triangle(before, corner, after, radius)
        return certify_triangle(self.obstacles, a, p, b, self.margin, self.resolution,
                                known_sides=self.leg_margin)[0]

    def run(self, first: WaypointNode) -> List[WaypointNode]:
        """Depth-first search from ``first`` to the goal; backtracks at most a few waypoints."""
        chain = [first]
        stack = [self._options(first)]
        tried = [0]
        deepest = 0
        while stack:
            self.farthest = max(self.farthest, chain[-1].progress)
            if chain[-1].candidate == self.goal:
                return chain
            choice = next(stack[-1], None) if tried[-1] < _OPTIONS_PER_WAYPOINT else None
            if choice is None:
                if len(chain) <= deepest - _BACKTRACK_WAYPOINTS:
                    break
                stack.pop()
                chain.pop()
                tried.pop()
                continue
            tried[-1] += 1
            node = WaypointNode(self.candidates[choice], chain[-1].position, choice,
                                float(self.progress[choice]))
            chain.append(node)
            stack.append(self._options(node))
            tried.append(0)
            deepest = max(deepest, len(chain))
        raise SearchExhausted()


class SearchExhausted(Exception):
    """The search spent its budget or backtracked as far as it may without reaching the goal."""


def _push_off(points: np.ndarray, obstacles: ObstacleSet, target: float, max_shift: float,
              lo: np.ndarray, hi: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Move points closer than ``target`` to an obstacle up the distance gradient.

    Damped steps (a fraction of the missing clearance, at most ``max_step``) climb away from the
    nearest obstacle and, between two obstacles, settle on the ridge midway instead of bouncing
    between them: where ``target`` is out of reach (an alley narrower than twice it), the point
    ends near the middle, the best place there is. Returns the moved points (at most
    ``max_shift`` from where they started) and their clearances [m].
    """
    moved = points.copy()
    # Distances capped a little above the target: exact where it matters, and a capped query
    # reads only the obstacles near the point.
    cap = target + 1.0
    dist = obstacles.distance(moved, cap)
    todo = np.flatnonzero(dist < target)
    h = 1e-4
    max_step = max(max_shift / 4.0, 1e-3)
    for _ in range(_PUSH_ITERATIONS):
        if not len(todo):
            break
        p = moved[todo]
        grad = np.zeros_like(p)
        for axis in range(3):
            offset = np.zeros(3)
            offset[axis] = h
            ahead = obstacles.distance(p + offset, cap)
            grad[:, axis] = (ahead - obstacles.distance(p - offset, cap)) / (2.0 * h)
        norm = np.linalg.norm(grad, axis=1)
        usable = norm > 1e-6
        gap = target - obstacles.distance(p, cap)
        length = np.minimum(0.6 * gap + 2e-3, max_step)
        shift = np.where(usable[:, None],
                         grad * (length / np.where(usable, norm, 1.0))[:, None], 0.0)
        moved[todo] = np.clip(p + shift, lo, hi)
        far = np.linalg.norm(moved[todo] - points[todo], axis=1) > max_shift
        todo = todo[(obstacles.distance(moved[todo], cap) < target) & usable & ~far]
    far = np.linalg.norm(moved - points, axis=1) > max_shift
    moved[far] = points[far]
    return moved, obstacles.distance(moved, cap)


def offset_layers(points: np.ndarray, progress: np.ndarray, fixed: np.ndarray,
                  obstacles: ObstacleSet, margin: float, radius: float, shift: float,
                  lo: np.ndarray, hi: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Keep the candidates that keep ``margin``, and add pushed-off copies near obstacles.

    A turn cuts inside its corner by up to about ``R``, so waypoints near an obstacle need more
    room than a leg does: for each of :data:`_OFFSET_LAYERS` a copy of every candidate below
    ``margin + f R`` is pushed towards that clearance (by at most ``shift + f R``; in a passage
    too narrow for it, to the passage's middle) and kept if it keeps ``margin``. Copies sort
    just before their original, so the search tries the original first.
    """
    dist = obstacles.distance(points, margin + radius + 1.0)
    keep = fixed | (dist >= margin)
    out = [(points[keep], progress[keep], fixed[keep], np.zeros(int(keep.sum())))]
    for rank, fraction in enumerate(_OFFSET_LAYERS, start=1):
        target = margin + fraction * radius
        select = ~fixed & (dist < target)
        if not np.any(select):
            continue
        moved, clearance = _push_off(points[select], obstacles, target,
                                     shift + fraction * radius, lo, hi)
        # Also those that stopped short of the target on a ridge: the middle of a narrow alley.
        ok = (clearance >= margin) & (np.linalg.norm(moved - points[select], axis=1) > 1e-3)
        count = int(ok.sum())
        out.append((moved[ok], progress[select][ok], np.zeros(count, dtype=bool),
                    np.full(count, float(rank))))
    points, progress, fixed, ranks = (np.concatenate(column) for column in zip(*out))
    order = np.lexsort((-ranks, progress))
    return points[order], progress[order], fixed[order]


def candidate_points(smoothed: np.ndarray, raw: np.ndarray, via: np.ndarray, spacing: float
                     ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Candidate points, their progress along the curve (sample index) and the fixed ones."""
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(smoothed, axis=0), axis=1))]
    marks = np.floor(arc / spacing)
    keep = np.r_[True, marks[1:] != marks[:-1]]
    keep[-1] = True
    from scipy.spatial import cKDTree  # a slow import, for missions only
    tree = cKDTree(smoothed)
    point_parts: List[np.ndarray] = [smoothed[keep]]
    progress_parts: List[np.ndarray] = [np.flatnonzero(keep).astype(np.float64)]
    fixed_parts: List[np.ndarray] = [np.zeros(int(keep.sum()), dtype=bool)]
    fixed_parts[0][[0, -1]] = True
    last = len(smoothed) - 1
    if len(raw):
        nearest = np.asarray(tree.query(raw)[1])
        inner = (nearest > 0) & (nearest < last)
        point_parts.append(raw[inner])
        # Just after the curve sample they are nearest to, so the sample comes first.
        progress_parts.append(nearest[inner] + 0.25)
        fixed_parts.append(np.zeros(int(inner.sum()), dtype=bool))
    if len(via):
        nearest = np.asarray(tree.query(via)[1])
        point_parts.append(via)
        progress_parts.append(nearest.astype(np.float64) + 0.5)
        fixed_parts.append(np.ones(len(via), dtype=bool))
    points = np.concatenate(point_parts)
    progress = np.concatenate(progress_parts)
    fixed = np.concatenate(fixed_parts)
    # The start and the goal stay first and last.
    progress[0], progress[int(keep.sum()) - 1] = -1.0, last + 1.0
    order = np.argsort(progress, kind='stable')
    return points[order], progress[order], fixed[order]
