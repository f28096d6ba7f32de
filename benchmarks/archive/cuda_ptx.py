"""The PTX of cuda's kernels that walk a tree, for one version of raybench (its src first on
PYTHONPATH, with compile caches of its own), or two such dumps compared: to show that a change of
shared source left a kind's GPU code as it was, where this machine has no libnvrtc to compile PTX.

    PYTHONPATH=<src> python benchmarks/archive/cuda_ptx.py dump DIR [triangle]
    python benchmarks/archive/cuda_ptx.py compare DIR_A DIR_B

dump renders small frames of spheres (and of a mesh, with `triangle`): the thesis's ray and packet
walks, Whitted's pixel program and wavefront; each kernel's `inspect_asm()` is written to DIR, its
comments and `.loc`/`.file` lines (the source's line numbers) dropped. compare prints, a kernel a
line, whether the instructions are the same and whether numba's environment globals, which the PTX
declares in no fixed order, are the same set. The figures: benchmarks/results/h100/triangles/README.md.
"""

import difflib
import os
import sys

ENV = ".common .global .align 8 .u64 _ZN08NumbaEnv"


def normalised(ptx: str) -> str:
    lines = (line.split("//")[0].strip() for line in ptx.splitlines())
    return "\n".join(s for s in lines if s and not s.startswith((".loc", ".file")))


def dump(folder: str, kinds: list[str]) -> None:
    import raybench
    from raybench import RaybenchError
    from raybench.bench import meshes

    os.makedirs(folder, exist_ok=True)
    scenes = {"sphere": (raybench.random_spheres(3000), raybench.Camera())}
    if "triangle" in kinds:
        mesh = meshes.mesh_scene("icosphere", 20480)
        scenes["triangle"] = (mesh, mesh.camera)
    for kind, (scene, camera) in scenes.items():
        for shading in ("thesis", "whitted"):
            for walk in ("ray", "packet"):
                for schedule in ("wavefront", "pixel") if shading == "whitted" else (None,):
                    options = {"walk": walk} | ({"schedule": schedule} if schedule else {})
                    try:
                        with raybench.Renderer(scene, 64, 48, "cuda", shading, **options) as renderer:
                            renderer.render(camera)
                            for name, kernel in renderer.tracer.kernels().items():
                                for ptx in kernel.inspect_asm().values():
                                    path = os.path.join(folder, f"{kind}_{shading}_{walk}_{schedule}_{name}.ptx")
                                    with open(path, "w") as out:
                                        out.write(normalised(ptx))
                    except RaybenchError as error:  # a combination the tracer refuses (a packet walk of Whitted's)
                        print(kind, shading, walk, schedule, "not traced:", type(error).__name__, error)


def compare(a: str, b: str) -> None:
    for name in sorted(os.listdir(a)):
        one = open(os.path.join(a, name)).read().splitlines()
        other = open(os.path.join(b, name)).read().splitlines()
        ia, ib = [s for s in one if not s.startswith(ENV)], [s for s in other if not s.startswith(ENV)]
        ea, eb = sorted(s for s in one if s.startswith(ENV)), sorted(s for s in other if s.startswith(ENV))
        print("instructions", "SAME" if ia == ib else "DIFFER", "declarations",
              "SAME SET" if ea == eb else "DIFFER", name, len(ia), len(ib))  # fmt: skip
        if ia != ib:
            print("\n".join(list(difflib.unified_diff(ia, ib, lineterm="", n=0))[:20]))


if __name__ == "__main__":
    if sys.argv[1] == "dump":
        dump(sys.argv[2], sys.argv[3:])
    else:
        compare(sys.argv[2], sys.argv[3])
