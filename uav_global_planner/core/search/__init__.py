"""The search over the grid: ``grid_search`` (Dijkstra, A* with the octile, adaptive (eq. 12)
and weighted heuristics) and ``start_admission`` (is a start or goal admissible, and the
nearest free node when it is not).
"""
