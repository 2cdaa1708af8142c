#!/usr/bin/env python3
"""The library's module graph: which file uses which, import cycles, and imports that go up
the layers of docs/ARCHITECTURE.md.

Usage: scripts/module-graph.py [--dot FILE]   (exit 1 on a cycle or an upward import)

A file's uses are the `crate::a::b` paths it names (in `use` lines and inline) and its
`super::` paths, resolved to the file that defines the module. Test code (`#[cfg(test)]`
modules at the end of a file) is left out: tests may reach anywhere.
"""
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SRC = ROOT / "src"

# Layers from the ground up: a module may use its own layer and those below, never one above.
# Keep in step with docs/ARCHITECTURE.md.
LAYERS = [
    ["error", "names", "cpu", "fmath"],
    ["raster", "tone"],
    ["io"],
    ["resize"],
    ["quality", "scielab", "printer_model", "color", "quantize", "press", "calibrate"],
    ["mask"],
    ["method", "rendering"],
    ["options", "preset"],
    ["pipeline", "batch", "api", "in_memory", "motion"],
    ["render", "serve"],
    ["lab"],
    ["lib"],
    ["cli", "main"],
]
LAYER_OF = {m: i for i, names in enumerate(LAYERS) for m in names}


def module_of(path: Path) -> list[str]:
    """The module path of a source file: src/io/pnm.rs -> ['io', 'pnm']. The binary's
    modules (src/main.rs, src/cli/) are named from `main` and `cli`."""
    rel = path.relative_to(SRC).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "mod":
        parts.pop()
    if parts == ["lib"]:
        return []
    return parts


def strip_tests(text: str) -> str:
    """The text before a trailing `#[cfg(test)] mod tests`."""
    m = re.search(r"^#\[cfg\(test\)\]\s*\n\s*mod tests", text, re.M)
    return text[: m.start()] if m else text


def strip_comments(text: str) -> str:
    text = re.sub(r"//[^\n]*", "", text)
    return re.sub(r"/\*.*?\*/", "", text, flags=re.S)


def main() -> int:
    files = sorted(SRC.rglob("*.rs"))
    mods = {tuple(module_of(p)): p for p in files}

    # The crate root's re-exports (`pub use io::{Compression, Format};`): `crate::Format`
    # is a use of `io`.
    reexports: dict[str, list[str]] = {}
    lib = strip_comments((SRC / "lib.rs").read_text())
    for u in re.finditer(r"pub use ((?:[A-Za-z_0-9]+::)*)(\{[^}]*\}|[A-Za-z_0-9]+)\s*;", lib):
        base = [p for p in u.group(1).split("::") if p]
        tail = u.group(2)
        names = tail.strip("{}").split(",") if tail.startswith("{") else [tail]
        for n in names:
            n = n.strip()
            if not n:
                continue
            item, _, alias = n.partition(" as ")
            item = item.strip().split("::")
            reexports[(alias.strip() or item[-1])] = base + item

    def resolve(path: list[str]):
        """The longest prefix of `path` that is a module with a file."""
        if path and path[0] in reexports and tuple(path[:1]) not in mods:
            path = reexports[path[0]] + path[1:]
        for n in range(len(path), 0, -1):
            if tuple(path[:n]) in mods:
                return tuple(path[:n])
        # An item of the crate root (`crate::halftone_image`).
        return () if () in mods else None

    edges: dict[tuple, set[tuple]] = {m: set() for m in mods}
    for m, p in mods.items():
        text = strip_comments(strip_tests(p.read_text()))
        # Expand `use crate::{a::b, c}` groups one level.
        for g in re.finditer(r"crate::\{([^}]*)\}", text):
            for item in g.group(1).split(","):
                item = item.strip().split(" as ")[0]
                if item:
                    text += f"\ncrate::{item}"
        if m and m[0] in ("cli", "main"):
            # The binary names the library `halftone::`, and its own modules `crate::`.
            for u in re.finditer(r"\bhalftone::((?:[A-Za-z_0-9]+::)*[A-Za-z_0-9]+)", text):
                target = resolve(u.group(1).split("::"))
                if target is not None:
                    edges[m].add(target)
            text = re.sub(r"\bcrate::", "crate::cli::", text) if m[0] == "main" else text
        for u in re.finditer(r"\bcrate::((?:[A-Za-z_0-9]+::)*[A-Za-z_0-9]+)", text):
            target = resolve(u.group(1).split("::"))
            if target is not None and target != m:
                edges[m].add(target)
        for u in re.finditer(r"\b((?:super::)+)((?:[A-Za-z_0-9]+::)*[A-Za-z_0-9]+)?", text):
            ups = u.group(1).count("super::")
            # A file `a/b.rs` is module a::b; `super` is a. A `mod.rs` is the module itself.
            base = list(m)[: len(m) - ups]
            rest = u.group(2).split("::") if u.group(2) else []
            target = resolve(base + rest) or (tuple(base) if tuple(base) in mods else None)
            if target is not None and target != m:
                edges[m].add(target)

    problems = 0
    # Cycles: strongly connected components (Tarjan) of more than one file.
    index, low, stack, on, comps = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            comps.append(comp)

    # A file may use what its parent module defines (a mod.rs holds the shared types of its
    # files, and declares them): those uses are the module's inside, not cycles.
    for m in edges:
        edges[m] = {t for t in edges[m] if not (0 < len(t) < len(m) and m[: len(t)] == t)}
    sys.setrecursionlimit(10000)
    for v in mods:
        if v not in index:
            visit(v)
    name = lambda m: "::".join(m) or "lib"
    for comp in comps:
        if len(comp) > 1:
            problems += 1
            print("cycle: " + ", ".join(sorted(name(c) for c in comp)))
    for m, targets in sorted(edges.items()):
        top = m[0] if m else "lib"
        for t in sorted(targets):
            ttop = t[0] if t else "lib"
            if top == ttop:
                continue
            lm, lt = LAYER_OF.get(top), LAYER_OF.get(ttop)
            if lm is None or lt is None:
                problems += 1
                print(f"unlayered: {name(m)} uses {name(t)} (add it to LAYERS)")
            elif lt > lm:
                problems += 1
                print(f"upward: {name(m)} (layer {lm}) uses {name(t)} (layer {lt})")
    if "--dot" in sys.argv:
        out = Path(sys.argv[sys.argv.index("--dot") + 1])
        lines = ["digraph modules {"]
        for m, targets in sorted(edges.items()):
            for t in sorted(targets):
                lines.append(f'  "{name(m)}" -> "{name(t)}";')
        lines.append("}")
        out.write_text("\n".join(lines) + "\n")
    n_edges = sum(len(t) for t in edges.values())
    print(f"{len(mods)} modules, {n_edges} uses, {problems} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
