"""The viewer's keys: one table, read by the event handler, by `raybench view
--help` and by the H key, so the three can never disagree.

Key names are rendercanvas's (the browser's KeyboardEvent.key names): letters
arrive upper case while Shift is held, so they are compared in lower case.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Binding:
    keys: tuple[str, ...]
    action: str
    help: str
    held: bool = False  # acts for as long as the key is down (motion), not once per press


BINDINGS = (
    Binding(("w",), "forward", "move forward", held=True),
    Binding(("s",), "back", "move back", held=True),
    Binding(("a",), "left", "move left", held=True),
    Binding(("d",), "right", "move right", held=True),
    Binding(("ArrowLeft",), "turn_left", "turn left", held=True),
    Binding(("ArrowRight",), "turn_right", "turn right", held=True),
    Binding(("ArrowUp",), "look_up", "look up", held=True),
    Binding(("ArrowDown",), "look_down", "look down", held=True),
    Binding(("Tab",), "next_device", "switch device live: cpu, cuda, wgpu (where the window's adapter can)"),
    Binding(("1",), "device_cpu", "trace on the CPU"),
    Binding(("2",), "device_cuda", "trace on the GPU (cuda)"),
    Binding(("3",), "device_wgpu", "trace on the GPU through wgpu, into the window's texture (no copy)"),
    # "=" is the + key without Shift on many layouts; glfw reports the key, not the character.
    Binding(("+", "="), "more_spheres", "add 10 spheres"),
    Binding(("-", "_"), "fewer_spheres", "remove 10 spheres"),
    Binding(
        ("t",), "ramp", "ramp (the thesis's test 7): from 10 spheres, 10 more every frame, up to 1000; again to stop"
    ),
    Binding(
        ("g",), "toggle_shading", "toggle the shading: thesis, whitted (the scene's lights, shadows, mirrors, glass)"
    ),
    Binding(("j",), "light_left", "move the (first) light left, in the camera's frame"),
    Binding(("l",), "light_right", "move the light right"),
    Binding(("i",), "light_up", "move the light up"),
    Binding(("k",), "light_down", "move the light down"),
    Binding(("u",), "light_away", "move the light away from the camera"),
    Binding(("o",), "light_near", "move the light towards the camera"),
    Binding(("r",), "reset", "reset the view and the light"),
    Binding(("p",), "screenshot", "save what is on screen as a PNG in the current folder"),
    Binding(("h",), "help", "show the keys in the title bar (and print them); again to hide"),
    Binding(("Escape",), "quit", "quit"),
)

MOUSE_HELP = ("drag", "look around (hold the left mouse button)")

_BY_KEY = {key.lower(): b for b in BINDINGS for key in b.keys}


def binding_for(key: str) -> Binding | None:
    """The binding of a rendercanvas key name, or None for a key that does nothing."""
    if not isinstance(key, str):
        return None
    return _BY_KEY.get(key.lower())


def _key_label(keys: tuple[str, ...]) -> str:
    names = {"ArrowLeft": "Left", "ArrowRight": "Right", "ArrowUp": "Up", "ArrowDown": "Down", "Escape": "Esc"}
    return " or ".join(names.get(k, k.upper() if len(k) == 1 else k) for k in keys)


def help_lines() -> list[str]:
    """The keys, one per line, for --help and the terminal."""
    rows = [(_key_label(b.keys), b.help) for b in BINDINGS]
    rows.insert(8, MOUSE_HELP)
    width = max(len(k) for k, _ in rows)
    return [f"{k.ljust(width)}  {h}" for k, h in rows]


def help_summary() -> str:
    """The keys in one short line, for the title bar."""
    return (
        "WASD move, drag/arrows turn, Tab device, +/- spheres, T ramp, G shading, IJKL/UO light, R reset, "
        "P screenshot, H help, Esc quit"
    )
