"""Camera motion: keys held and mouse drags, turned into a new Camera.

Motion integrates how long each key was held, not how many frames were drawn:
a CPU that needs two seconds per frame moves the camera as far, for the same
key press, as a GPU that draws a hundred frames meanwhile.

Directions follow the camera's own convention (camera.py): right is
cross(forward, up), the direction of increasing pixel x; the camera's `up` is
kept as the world's up, so turning never rolls the view.
"""

from __future__ import annotations

import math

import numpy as np

from ..camera import Camera

TURN_DEG_PER_S = 90.0  # arrow keys
DRAG_DEG_PER_PIXEL = 0.25  # mouse look
MAX_ELEVATION_DEG = 85.0  # never look straight up or down: the view would have no "right"
MIN_SPEED = 0.1  # scene units per second, for a scene with nothing in it

_MOVES = {"forward": (1, 0), "back": (-1, 0), "right": (0, 1), "left": (0, -1)}
_TURNS = {"turn_right": (1, 0), "turn_left": (-1, 0), "look_up": (0, 1), "look_down": (0, -1)}


def axes(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit forward, right and (world) up vectors of a camera, in float64."""
    forward = np.subtract(camera.look_at, camera.position)
    forward /= np.linalg.norm(forward)
    up = np.array(camera.up, dtype=np.float64)
    up /= np.linalg.norm(up)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    return forward, right, up


def moved(camera: Camera, forward: float, right: float) -> Camera:
    """The camera carried `forward` units along its view and `right` units to
    its right; it keeps looking the same way."""
    f, r, _ = axes(camera)
    delta = f * forward + r * right
    return Camera(
        position=tuple(np.add(camera.position, delta)),
        look_at=tuple(np.add(camera.look_at, delta)),
        up=camera.up,
        fov_deg=camera.fov_deg,
    )


def turned(camera: Camera, yaw_deg: float, pitch_deg: float) -> Camera:
    """The camera turned yaw_deg to the right (about the world up) and pitch_deg
    upwards, its elevation kept within +-MAX_ELEVATION_DEG."""
    f, r, up = axes(camera)
    elevation = math.degrees(math.asin(max(-1.0, min(1.0, float(f @ up)))))
    elevation = max(-MAX_ELEVATION_DEG, min(MAX_ELEVATION_DEG, elevation + pitch_deg))
    level = f - (f @ up) * up  # forward, flattened onto the ground plane
    level /= np.linalg.norm(level)
    yaw = math.radians(yaw_deg)
    level = math.cos(yaw) * level + math.sin(yaw) * r
    e = math.radians(elevation)
    direction = math.cos(e) * level + math.sin(e) * up
    distance = float(np.linalg.norm(np.subtract(camera.look_at, camera.position)))
    return Camera(
        position=camera.position,
        look_at=tuple(np.add(camera.position, direction * distance)),
        up=camera.up,
        fov_deg=camera.fov_deg,
    )


def travel_speed(centers: np.ndarray, camera: Camera) -> float:
    """Scene units per second for WASD: half the median distance from the camera
    to the spheres, so that crossing any scene, whatever its scale, takes a few
    seconds."""
    if len(centers) == 0:
        return 1.0
    distance = float(np.median(np.linalg.norm(np.asarray(centers, np.float64) - camera.position, axis=1)))
    return max(distance / 2.0, MIN_SPEED)


class HeldKeys:
    """How long each motion key was held since the last take()."""

    def __init__(self):
        self._down_since: dict[str, float] = {}
        self._held_s: dict[str, float] = {}

    def press(self, action: str, now: float) -> None:
        # Key repeat, or a press whose release we missed: the first press counts.
        self._down_since.setdefault(action, now)

    def release(self, action: str, now: float) -> None:
        since = self._down_since.pop(action, None)
        if since is not None:
            self._held_s[action] = self._held_s.get(action, 0.0) + max(0.0, now - since)

    def release_all(self, now: float) -> None:
        for action in list(self._down_since):
            self.release(action, now)

    def take(self, now: float) -> dict[str, float]:
        """Seconds held per action since the last take (keys still down count up to now)."""
        held = dict(self._held_s)
        self._held_s.clear()
        for action, since in self._down_since.items():
            held[action] = held.get(action, 0.0) + max(0.0, now - since)
            self._down_since[action] = now
        return held

    @property
    def down(self) -> bool:
        return bool(self._down_since)


class Motion:
    """Keys held and mouse drags since the last frame, applied to a camera when
    the next frame is traced."""

    def __init__(self, speed: float):
        self.speed = speed
        self.keys = HeldKeys()
        self._drag_deg = [0.0, 0.0]  # yaw (right), pitch (up)

    def drag(self, dx: float, dy: float) -> None:
        """Mouse look: the pointer moved (dx, dy) logical pixels with the button
        down; right turns right, up (negative dy) looks up."""
        self._drag_deg[0] += dx * DRAG_DEG_PER_PIXEL
        self._drag_deg[1] -= dy * DRAG_DEG_PER_PIXEL

    def clear(self, now: float) -> None:
        """Forget everything pending (the view was reset)."""
        self.keys.take(now)
        self._drag_deg = [0.0, 0.0]

    def apply(self, camera: Camera, now: float) -> Camera:
        """The camera after everything since the last apply(). With nothing to
        do it is the same object, bit for bit the view it was."""
        held = self.keys.take(now)
        forward = sum(held.get(a, 0.0) * f for a, (f, _) in _MOVES.items()) * self.speed
        right = sum(held.get(a, 0.0) * r for a, (_, r) in _MOVES.items()) * self.speed
        yaw = self._drag_deg[0] + sum(held.get(a, 0.0) * y for a, (y, _) in _TURNS.items()) * TURN_DEG_PER_S
        pitch = self._drag_deg[1] + sum(held.get(a, 0.0) * p for a, (_, p) in _TURNS.items()) * TURN_DEG_PER_S
        self._drag_deg = [0.0, 0.0]
        if forward or right:
            camera = moved(camera, forward, right)
        if yaw or pitch:
            camera = turned(camera, yaw, pitch)
        return camera
