"""Which spheres are on screen: the +/- keys and the ramp.

Every frame traces the first `count` spheres of one scene, as the benchmark's
test 7 does (a tracer holds the scene once and traces a prefix of it, so the
ramp costs no upload per frame):

- random spheres (--spheres N): the scene starts as random_spheres(N, seed),
  the very picture `raybench render --spheres N --seed S` draws. `-` hides the
  last 10; `+` shows them again, and past the end of the scene it becomes
  random_spheres(count + 10, seed), again what `raybench render` would draw;
- a scene file: `-` and `+` move within the file's spheres (a mesh's:
  its triangles, in the file's order);
- the ramp (T): test 7's scene, random_spheres(1000, seed), from 10 spheres,
  10 more every frame up to 1000 (a file ramps over its own spheres).

Random spheres made with --materials stay so: the scenes made for + and the
ramp are random_spheres(..., materials=True) too, what `raybench render
--materials` draws.
"""

from __future__ import annotations

from ..scene import RAMP, Scene, random_spheres

STEP = RAMP[2]


class SphereSupply:
    def __init__(self, scene: Scene, seed: int | None):
        """seed: that of random_spheres for a generated scene; None for a scene file."""
        self.scene = scene
        self.seed = seed
        # A generated scene with materials came from random_spheres(..., materials=True): so do the next.
        self.materials = scene.materials is not None
        self.traced = scene.traced()  # what is counted: the spheres, or a mesh scene's triangles
        self.noun = self.traced.noun
        self.count = len(self.traced)
        self.ramping = False

    @property
    def generated(self) -> bool:
        return self.seed is not None

    def more(self) -> str | None:
        """Ten more spheres; a message when there are none to add."""
        target = self.count + STEP
        if target > len(self.traced):
            if not self.generated:
                self.count = len(self.traced)
                return f"the scene file has {len(self.traced):,} {self.noun}, all shown"
            self.scene = random_spheres(target, self.seed, materials=self.materials)
            self.traced = self.scene.traced()
        self.count = target
        return None

    def fewer(self) -> None:
        self.count = max(0, self.count - STEP)

    def toggle_ramp(self) -> str:
        """Start the ramp, or stop it where it is; the message to show."""
        if self.ramping:
            self.ramping = False
            return f"ramp stopped at {self.count:,} {self.noun}"
        first, last, _ = RAMP
        if self.generated and len(self.scene) != last:
            self.scene = random_spheres(last, self.seed, materials=self.materials)
            self.traced = self.scene.traced()
        self.count = min(first, len(self.traced))
        self.ramping = True
        return f"ramp: {self.count:,} to {len(self.traced):,} {self.noun}, {STEP} more every frame"

    def frame_count(self) -> tuple[Scene, int, str | None]:
        """The scene and sphere count of the next frame to trace; during the ramp
        every call is one frame, and the count grows for the next. The message
        is set when the ramp ends."""
        scene, count = self.scene, self.count
        message = None
        if self.ramping:
            if count >= len(self.traced):
                self.ramping = False
                message = f"ramp done: {count:,} {self.noun}"
            else:
                self.count = min(count + STEP, len(self.traced))
        return scene, count, message
