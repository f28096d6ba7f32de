"""A WGSL piece's top-level names given a prefix, so that two pieces that
answer to the same names can sit in one shader.

WGSL has no include and no namespaces: sphere.wgsl and triangle.wgsl both
define hit, surface, read_leaf... because every walk calls a primitive by
those names. The mixed kind's shader (mixed.wgsl) needs both pieces at once,
each kind's answers under a name of its own (sphere_hit, triangle_hit), and
answers to the walks' names itself by dispatching on a primitive's tag, as
kernels/primitives/mixed.py calls sphere.py's and triangle.py's functions.
So the host renames a piece's declarations as it assembles the shader: the
pieces' text, and with it the sphere's and the triangle's shaders, stay as
they are, and their arithmetic is not copied.

A declaration is kept and renamed (prefix + name, every use of it in the
piece's code too), or by the caller's choice:
- kept: left as it is (a type the whole shader shares);
- dropped: removed, its uses left as they are (the shader declares that
  name once for both kinds: the scene's row, the leaf buffer's binding);
- replaced: removed, its uses renamed (the caller declares prefix + name:
  a reader of a buffer whose layout is the mixed kind's).
A struct's members, and members read (s.name), keep their names. Comments
are left as they are; the comment lines right above a removed declaration
go with it.
"""

from __future__ import annotations

import re

# A top-level declaration's first line: its attributes, its keyword, its name.
DECLARATION = re.compile(r"^(?:@\S+\s+)*(fn|struct|const|alias|override|var(?:<[^>]*>)?)\s+(\w+)")


def declarations(text: str) -> list[tuple[str | None, str | None, list[str]]]:
    """The piece as (name, keyword, lines) in order: a declaration with the
    comment lines right above it, or (None, None, lines) for the lines
    between (blank lines and comments above a blank one). A line of code
    outside a declaration is an error: the piece is not one this module can
    rename."""
    parts: list[tuple[str | None, str | None, list[str]]] = []
    loose: list[str] = []  # blank and comment lines not yet given to a declaration
    name, keyword, lines, depth, opened = None, None, [], 0, False
    for line in text.splitlines(keepends=True):
        code = line.split("//", 1)[0]
        if name is None:
            found = DECLARATION.match(code)
            if found is None:
                if code.strip():
                    raise ValueError(f"not a top-level declaration: {line.strip()!r}")
                loose.append(line)
                continue
            # the comment lines right above it (no blank line between) are its own
            mine = len(loose)
            while mine > 0 and loose[mine - 1].strip().startswith("//"):
                mine -= 1
            if mine:
                parts.append((None, None, loose[:mine]))
            keyword, name, lines, depth, opened = found.group(1), found.group(2), loose[mine:], 0, False
            loose = []
        lines.append(line)
        depth += code.count("{") - code.count("}")
        opened = opened or "{" in code
        if depth == 0 and (opened or code.rstrip().endswith(";")):
            parts.append((name, keyword, lines))
            name = None
    if name is not None:
        raise ValueError(f"{name}: its declaration does not end")
    if loose:
        parts.append((None, None, loose))
    return parts


def namespaced(text: str, prefix: str, kept=(), dropped=(), replaced=()) -> str:
    """The piece with its declarations renamed prefix + name, except those
    kept (as they are), dropped and replaced (removed; uses of a replaced one
    renamed, of a dropped one not): the module's docstring says why each."""
    parts = declarations(text)
    names = {name for name, _, _ in parts if name is not None}
    unknown = (set(kept) | set(dropped) | set(replaced)) - names
    if unknown:
        raise ValueError(f"not declared in the piece: {', '.join(sorted(unknown))}")
    renamed = (names - set(kept) - set(dropped)) | set(replaced)
    # a name used, not a member (.name) or part of a longer name; in a
    # struct's body, not a member's declaration (name: type) either
    names = "(" + "|".join(sorted(renamed, key=len, reverse=True)) + ")"
    use = re.compile(r"(?<![\w.])" + names + r"(?!\w)")
    in_struct = re.compile(r"(?<![\w.])" + names + r"(?!\w|\s*:)")

    def rename(line: str, pattern) -> str:
        code, sep, comment = line.partition("//")
        return pattern.sub(lambda m: prefix + m.group(1), code) + sep + comment

    out = []
    for name, keyword, lines in parts:
        if name in dropped or name in replaced:
            continue
        pattern = in_struct if keyword == "struct" else use
        out += [rename(line, pattern) for line in lines] if renamed else lines
    return "".join(out)


def members(text: str, struct: str) -> str:
    """The member lines of a piece's struct, as written between its braces:
    for a struct that is another's members and more (mixed.wgsl's Tagged,
    a triangle's Facet and the tag)."""
    for name, keyword, lines in declarations(text):
        if keyword == "struct" and name == struct:
            first = next(i for i, line in enumerate(lines) if DECLARATION.match(line.split("//", 1)[0]))
            body = "".join(lines[first:])
            return body[body.index("{") + 1 : body.rindex("}")].strip()
    raise ValueError(f"struct {struct}: not declared in the piece")
