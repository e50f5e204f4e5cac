"""Shortest paths on the navigable grid: A*, its Dijkstra reference, line-of-sight shortcutting, episode sampling."""
