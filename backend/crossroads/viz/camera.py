"""Where the 3D view's camera goes in each mode: free orbit (the user's), following the ego from
behind, or looking down on the whole junction. Pure geometry, so tested without a browser."""

from __future__ import annotations

import math

CAMERA_MODES: dict[str, str] = {"free orbit": "orbit", "follow the ego": "follow", "top-down": "top"}
FOLLOW_BACK_M = 14.0  # [m] the follow camera sits this far behind the ego
FOLLOW_UP_M = 7.0  # [m] and this high
FOLLOW_AHEAD_M = 8.0  # [m] looking at a point this far ahead of it
TOP_HEIGHT_FACTOR = 1.1  # the top-down camera's height over the scene's larger side


def camera_pose(mode: str, ego_xy: tuple[float, float], heading_rad: float, scene_size_m: float
                ) -> tuple[tuple[float, float, float], tuple[float, float, float]] | None:
    """(position, look-at) of the camera in ``mode`` for the ego at ``ego_xy`` (scene frame)
    heading ``heading_rad``; None for ``orbit`` (the user moves the camera)."""
    x, y = ego_xy
    if mode == "follow":
        c, s = math.cos(heading_rad), math.sin(heading_rad)
        return ((x - FOLLOW_BACK_M * c, y - FOLLOW_BACK_M * s, FOLLOW_UP_M),
                (x + FOLLOW_AHEAD_M * c, y + FOLLOW_AHEAD_M * s, 0.0))
    if mode == "top":
        # straight down is degenerate with +z up: a hair south of the vertical, north at the top
        height = max(scene_size_m, 20.0) * TOP_HEIGHT_FACTOR
        return ((0.0, -0.01 * height, height), (0.0, 0.0, 0.0))
    if mode == "orbit":
        return None
    raise ValueError(f"camera mode must be one of {', '.join(CAMERA_MODES.values())}, got {mode!r}")
