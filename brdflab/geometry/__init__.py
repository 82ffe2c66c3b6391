"""Directions, half/difference angles, geodesic grids and sampling warps."""
