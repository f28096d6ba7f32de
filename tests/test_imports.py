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


def reached(graph: dict[str, set[str]], start: str) -> set[str]:
    """Every module that the modules under start import, directly or through others."""
    seen, todo = set(), [m for m in graph if m == start or m.startswith(start + ".")]
    while todo:
        for child in graph[todo.pop()] - seen:
            seen.add(child)
            todo.append(child)
    return seen


def test_the_viewer_imports_no_benchmark_code():
    """The viewer is a sink beside the bench, not above it: what both need (the
    ramp of test 7) lives in the public model below them."""
    found = reached(imports(PACKAGE), "raybench.viewer")
    assert "raybench.scene" in found  # the graph was read
    assert sorted(m for m in found if m.split(".")[:2] in (["raybench", "bench"], ["raybench", "cli"])) == []
