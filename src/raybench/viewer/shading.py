"""The shading of the next frame: the G key's toggle between the thesis's
shading and Whitted's, and the keys that move the scene's (first) light.

A Whitted frame needs a lighting.Shading, the arrays its kernel reads, made
by Shading.of from a scene: here the scene on screen with its first light
where the keys put it. Scene and Shading are made once for each scene and
light position and kept, so frames reuse their tracer until the light moves
(a new Shading makes a new tracer, as a new scene does). Under the thesis's
shading the light plays no part: frames get the scene as it is, and no Shading.

A scene without lights toggled to Whitted shading is traced too; with
nothing lit it is, by design, the thesis's picture (the ambient light and
any mirrors and glass aside).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..camera import Camera
from ..errors import RaybenchError
from ..lighting import Shading, check_depth, check_shading, check_shadow_samples
from ..scene import Scene
from .controls import axes

# How far one press of a light key moves the light: what WASD moves the
# camera in this many seconds (so a step suits the scene's scale).
LIGHT_STEP_S = 0.25
# The light keys' directions in the camera's frame: (forward, right, up).
LIGHT_MOVES = {
    "light_left": (0, -1, 0),
    "light_right": (0, 1, 0),
    "light_up": (0, 0, 1),
    "light_down": (0, 0, -1),
    "light_away": (1, 0, 0),
    "light_near": (-1, 0, 0),
}


@dataclasses.dataclass(frozen=True)
class FirstShading:
    """The first frame's shading, as render() takes it: "thesis" or
    "whitted", and Whitted's depth and shadow samples (None: lighting's
    defaults). The G key toggles it from there."""

    shading: str = "thesis"
    depth: int | None = None
    shadow_samples: int | None = None


def with_first_light_at(scene: Scene, position) -> Scene:
    """The scene with its first light moved to position; the spheres (the
    same float32 bits), materials and the other lights as they were."""
    first = dataclasses.replace(scene.lights[0], position=tuple(float(v) for v in position))
    return scene.with_lights((first,) + scene.lights[1:])


class ShadingControl:
    def __init__(self, first: FirstShading | None = None, step: float = 1.0):
        """first: the first frame's shading (None: the thesis's); step: scene
        units a light key moves the light."""
        first = first or FirstShading()
        self.shading = check_shading(first.shading)
        self.depth = None if first.depth is None else check_depth(first.depth)
        self.shadow_samples = None if first.shadow_samples is None else check_shadow_samples(first.shadow_samples)
        self.step = step
        self.offset = np.zeros(3)  # where the keys moved the first light from its place in the scene
        self._made = None  # (scene, offset, lit scene, Shading): the last ones made, kept for the next frames

    @property
    def whitted(self) -> bool:
        return self.shading == "whitted"

    def toggle(self) -> str:
        """Thesis to Whitted or back; the message to show."""
        self.shading = "thesis" if self.whitted else "whitted"
        return f"shading: {self.shading}"

    def move_light(self, action: str, scene: Scene, camera: Camera) -> str:
        """One step of the first light along the camera's right, up or
        forward (LIGHT_MOVES[action]); the message to show."""
        if not scene.lights:
            return "the scene has no lights to move"
        forward, right, up = axes(camera)
        f, r, u = LIGHT_MOVES[action]
        offset = self.offset + self.step * (f * forward + r * right + u * up)
        position = np.add(scene.lights[0].position, offset)
        try:
            dataclasses.replace(scene.lights[0], position=tuple(position.tolist()))  # checks it
        except RaybenchError as exc:
            return f"the light stays: {exc}"
        self.offset = offset
        where = ", ".join(f"{v:.2f}" for v in position)
        return f"light at ({where})" + ("" if self.whitted else "; it shows under whitted shading (G)")

    def reset_light(self) -> None:
        self.offset = np.zeros(3)

    def for_scene(self, scene: Scene) -> tuple[Scene, Shading | None]:
        """What the next frame traces: the scene (with its first light moved,
        under Whitted shading) and its Shading; under the thesis's shading
        the scene itself and None."""
        if not self.whitted:
            return scene, None
        offset = tuple(self.offset.tolist())
        made = self._made
        if made is None or made[0] is not scene or made[1] != offset:
            lit = scene if not scene.lights or not any(offset) else self._lit(scene)
            made = (scene, offset, lit, Shading.of(lit, self.depth, self.shadow_samples))
            self._made = made
        return made[2], made[3]

    def _lit(self, scene: Scene) -> Scene:
        return with_first_light_at(scene, np.add(scene.lights[0].position, self.offset))
