"""raybench's own import graph has no cycle: data moves one way, from the
scene and the kernels up to the backends, render(), the cluster, the bench
and the CLI, and a lower layer never reaches back up.

An edge is any import of a raybench module, at the top of a file or inside
a function: an import deferred to save start-up time is a dependency all the
same. A package's __init__ counts only where it is imported by name
(`from raybench import bvh`), not as the parent of every module below it.
"""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "src" / "raybench"


def modules(root: Path) -> dict[str, Path]:
    """{dotted name: file} of every module of the package at root."""
    out = {}
    for path in root.rglob("*.py"):
        parts = list(path.relative_to(root.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def imports(root: Path) -> dict[str, set[str]]:
    """{module: the package's modules it imports}."""
    found = modules(root)
    graph = {name: set() for name in found}
    for name, path in found.items():
        package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                graph[name] |= {alias.name for alias in node.names if alias.name in found}
            elif isinstance(node, ast.ImportFrom):
                base = package[: len(package) - node.level + 1] if node.level else []
                target = ".".join(base + (node.module.split(".") if node.module else []))
                for alias in node.names:
                    # `from a import b`: the module a.b where there is one, else a's names
                    inner = f"{target}.{alias.name}"
                    if inner in found:
                        graph[name].add(inner)
                    elif target in found:
                        graph[name].add(target)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's
    algorithm, iterative), and the modules that import themselves."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1 or node in graph[node]:
                    out.append(sorted(component))
    return out


def test_raybench_imports_no_cycle():
    graph = imports(PACKAGE)
    assert len(graph) > 50 and "raybench.bvh" in graph["raybench.backends.cpu.tracer"]  # the graph was read
    assert cycles(graph) == []


def test_the_cycle_check_finds_a_cycle(tmp_path):
    """The check fails where two modules import each other, directly or
    through a function's import, or through a package's __init__."""
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from .a import f\n")
    (pkg / "a.py").write_text("from . import b\n\ndef f():\n    return b\n")
    (pkg / "b.py").write_text("def g():\n    from .sub import c\n    return c\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "c.py").write_text("import pkg.d\n")
    (pkg / "d.py").write_text("x = 1\n")
    assert cycles(imports(pkg)) == []
    (pkg / "d.py").write_text("def h():\n    from .a import f\n    return f\n")  # d -> a -> b -> c -> d
    assert cycles(imports(pkg)) == [["pkg.a", "pkg.b", "pkg.d", "pkg.sub.c"]]
    (pkg / "d.py").write_text("from . import f\n")  # d -> pkg (its __init__) -> a -> b -> c -> d
    assert cycles(imports(pkg)) == [["pkg", "pkg.a", "pkg.b", "pkg.d", "pkg.sub.c"]]


# The public model: what a scene is (spheres, camera, camera paths, lights,
# materials, motion) and the layouts its arrays share with the kernels. It
# imports no layer above it: no kernel, builder, backend, render(), bench,
# CLI, cluster or viewer.
MODEL = (
    "raybench.scene",
    "raybench.camera",
    "raybench.camera_path",
    "raybench.lighting",
    "raybench.layout",
    "raybench.animate",
)
ABOVE_MODEL = (
    "raybench.kernels",
    "raybench.bvh",
    "raybench.backends",
    "raybench.render",
    "raybench.bench",
    "raybench.cli",
    "raybench.cluster",
    "raybench.viewer",
)


def within(name: str, packages) -> bool:
    return any(name == p or name.startswith(p + ".") for p in packages)


def reaches(graph: dict[str, set[str]], starts, packages) -> list[str]:
    """Each module of `packages` that any of `starts` imports, directly or
    through other modules, as its chain of imports ("a -> b -> c"), sorted."""
    parent = {start: None for start in starts}
    queue = list(starts)
    while queue:
        node = queue.pop(0)
        for child in sorted(graph[node]):
            if child not in parent:
                parent[child] = node
                queue.append(child)
    out = []
    for name in parent:
        if name not in starts and within(name, packages):
            chain = [name]
            while parent[chain[-1]] is not None:
                chain.append(parent[chain[-1]])
            out.append(" -> ".join(reversed(chain)))
    return sorted(out)


def test_the_public_model_imports_no_higher_layer():
    graph = imports(PACKAGE)
    assert all(name in graph for name in MODEL + ABOVE_MODEL)
    assert "raybench.layout" in graph["raybench.lighting"]  # the graph was read
    assert reaches(graph, MODEL, ABOVE_MODEL) == []


def test_the_viewer_imports_no_benchmark_code():
    graph = imports(PACKAGE)
    viewer = sorted(name for name in graph if within(name, ["raybench.viewer"]))
    assert len(viewer) > 5  # the graph was read
    assert reaches(graph, viewer, ["raybench.bench", "raybench.cli"]) == []


def test_the_layer_check_finds_an_import_up(tmp_path):
    """The check fails where a low module imports a high one, directly or
    through another module's import in a function."""
    pkg = tmp_path / "pkg"
    (pkg / "high").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "high" / "__init__.py").write_text("")
    (pkg / "high" / "h.py").write_text("from ..low import x\n")
    (pkg / "low.py").write_text("from . import util\n\nx = 1\n")
    (pkg / "util.py").write_text("y = 2\n")
    graph = imports(pkg)
    assert reaches(graph, ["pkg.low"], ["pkg.high"]) == []
    assert reaches(graph, ["pkg.high.h"], ["pkg.high"]) == []  # a module is not its own reach
    (pkg / "util.py").write_text("def f():\n    from .high import h\n    return h\n")
    assert reaches(imports(pkg), ["pkg.low"], ["pkg.high"]) == ["pkg.low -> pkg.util -> pkg.high.h"]
