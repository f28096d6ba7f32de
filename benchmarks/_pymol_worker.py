"""PyMOL's side of `peers.py pymol`, run by the Python that has PyMOL (Debian's python3-pymol is
built for the system's Python, not raybench's venv): one JSON request a line on stdin, one JSON
answer a line on stdout. It imports nothing of raybench, so the two sides share no process.

    {"load": PATH, "atoms": {ELEMENT: [radius, [r, g, b]]}, "settings": {NAME: VALUE}, "view": [18 floats]}
        -> {"atoms": N, "pymol": VERSION}: the molecule shown as spheres, waters removed, each
           element's radius and colour set to the given ones
    {"ray": [W, H], "times": K} -> {"ms": [K timings]}: `ray W,H` K times, each timed alone
    {"png": PATH} -> {"saved": PATH}: the last ray's picture
    {"quit": true}
"""

import json
import sys
import time

import pymol

pymol.finish_launching(["pymol", "-qc"])
from pymol import cmd  # noqa: E402  (only once PyMOL has started)


def load(request):
    cmd.reinitialize()
    cmd.load(request["load"], "m")
    # raybench's molecule reader leaves waters out and keeps the first conformer
    cmd.remove("solvent")
    cmd.remove("not alt ''+A")
    cmd.hide("everything")
    cmd.show("spheres")
    for element, (radius, rgb) in request["atoms"].items():
        name = f"rb_{element}"
        cmd.set_color(name, rgb)
        cmd.color(name, f"m and elem {element}")
        cmd.alter(f"m and elem {element}", f"vdw={radius!r}")
    cmd.rebuild()
    for name, value in request["settings"].items():
        cmd.set(name, value)
    cmd.set_view(request["view"])
    return {"atoms": cmd.count_atoms("m"), "pymol": cmd.get_version()[0], "view": list(cmd.get_view())}


def ray(request):
    width, height = request["ray"]
    out = []
    for _ in range(request["times"]):
        start = time.perf_counter()
        cmd.ray(width, height)
        out.append((time.perf_counter() - start) * 1e3)
    return {"ms": out}


def main():
    for line in sys.stdin:
        request = json.loads(line)
        if "quit" in request:
            break
        if "load" in request:
            answer = load(request)
        elif "ray" in request:
            answer = ray(request)
        else:
            cmd.png(request["png"], ray=0)
            answer = {"saved": request["png"]}
        print(json.dumps(answer), flush=True)


if __name__ == "__main__":
    main()
