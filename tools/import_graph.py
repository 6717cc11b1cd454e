#!/usr/bin/env python3
"""The crate's module-level import graph (one node per file) and its cycles.

Edges come from every `use crate::…`, `use super::…`, `use self::…` (brace trees expanded)
and from inline `crate::a::b` / `super::a` paths, each resolved to the longest prefix that is
a module file; `super::` inside an inline `mod x { … }` resolves from that block. A parent's
edges to its own children (`mod x; pub use x::…` in mod.rs) are structure, not design, and
are dropped; a child's edges to its parent are kept.

Usage: tools/import_graph.py [--no-tests] [--edges | --dot] [--root DIR]
  --no-tests  leave out test modules and test helpers
  --edges     print every module's imports before the cycles
  --dot       print the graph for Graphviz instead
  --root DIR  the checkout to read (default: the one holding this script)
Prints the strongly connected sets (cycles); exits 1 if there is one.
"""

import os
import re
import sys

ROOT = sys.argv[sys.argv.index("--root") + 1] if "--root" in sys.argv else os.path.join(os.path.dirname(__file__), "..")
SRC = os.path.join(ROOT, "src")
no_tests = "--no-tests" in sys.argv


def file_module(path):
    rel = os.path.relpath(path, SRC)[:-3].split(os.sep)
    if rel[-1] in ("mod", "lib"):
        rel = rel[:-1]
    return tuple(rel)


files = {}
for root, _, names in os.walk(SRC):
    for n in names:
        if n.endswith(".rs") and not root.startswith(os.path.join(SRC, "bin")):
            p = os.path.join(root, n)
            files[file_module(p)] = p
# `#[path = "x.rs"] mod m;`: file x.rs is module m of the file that declares it
for mod, path in list(files.items()):
    for m in re.finditer(r'#\[path\s*=\s*"([^"]+)"\]\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+(\w+)\s*;', open(path).read()):
        target = file_module(os.path.join(os.path.dirname(path), m.group(1)))
        if target in files:
            files[mod + (m.group(2),)] = files.pop(target)
mods = set(files)


def strip(text):
    text = re.sub(r"//[^\n]*", "", text)
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r'b?"(\\.|[^"\\])*"', '""', text)
    text = re.sub(r"'(\\.|[^'\\])'", "' '", text)
    return text


def expand(tree):
    """`a::{b, c::{d, e}}` → [a::b, a::c::d, a::c::e]."""
    tree = tree.replace(" ", "").replace("\n", "")
    out = []

    def rec(prefix, s):
        i = s.find("{")
        if i < 0:
            out.append(prefix + s)
            return
        head, body = s[:i], s[i + 1 : s.rfind("}")]
        depth, start = 0, 0
        for j, ch in enumerate(body + ","):
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth -= 1
            elif ch == "," and depth == 0:
                part = body[start:j]
                if part:
                    rec(prefix + head, part)
                start = j + 1

    rec("", tree)
    return out


def resolve(base, path):
    segs = [s for s in path.split("::") if s]
    if not segs:
        return None
    cur = list(base)
    if segs[0] == "crate":
        cur, segs = [], segs[1:]
    elif segs[0] in ("super", "self"):
        while segs and segs[0] in ("super", "self"):
            if segs[0] == "super":
                cur = cur[:-1]
            segs = segs[1:]
    else:
        return None
    best = tuple(cur)
    for s in segs:
        cur.append(s.split(" as ")[0])
        if tuple(cur) in mods:
            best = tuple(cur)
    return best


edges = {}
for mod, path in files.items():
    text = strip(open(path).read())
    is_test_file = bool(mod) and mod[-1] in ("tests", "silhouette_tests", "testutil")
    if no_tests and is_test_file:
        continue
    # inline module stack by brace depth
    stack = []  # (name, depth at open, is_test)
    depth = 0
    pending_test = False
    i = 0
    tokens = re.finditer(
        r"#\[cfg\(test\)\]|\bmod\s+(\w+)\s*\{|\buse\s+([^;]+);|\b((?:crate|super)(?:::\w+)+)|[{}]",
        text,
    )
    for m in tokens:
        tok = m.group(0)
        if tok == "#[cfg(test)]":
            pending_test = True
            continue
        if m.group(1):
            depth += 1
            stack.append((m.group(1), depth, pending_test))
            pending_test = False
            continue
        if tok == "{":
            depth += 1
            continue
        if tok == "}":
            if stack and stack[-1][1] == depth:
                stack.pop()
            depth -= 1
            continue
        in_test = any(t for _, _, t in stack)
        if no_tests and in_test:
            continue
        base = mod + tuple(n for n, _, _ in stack)
        paths = expand(m.group(2)) if m.group(2) else [m.group(3)]
        for p in paths:
            tgt = resolve(base, p)
            if tgt is None:
                continue
            # inline test modules belong to their file
            while tgt not in mods and tgt:
                tgt = tgt[:-1]
            if tgt and tgt != mod and tgt in mods:
                edges.setdefault(mod, set()).add(tgt)
        pending_test = False

name = lambda m: "::".join(m) or "crate"


def sccs(nodes, adj):
    index, low, on, st, out, n = {}, {}, set(), [], [], [0]

    def strong(v):
        index[v] = low[v] = n[0]
        n[0] += 1
        st.append(v)
        on.add(v)
        for w in adj.get(v, ()):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = st.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(nodes):
        if v not in index:
            strong(v)
    return out


def is_ancestor(a, b):
    return len(a) < len(b) and b[: len(a)] == a


# A parent mod.rs necessarily names its children (`mod x; pub use x::…`) and children often
# reach siblings through the parent's re-exports; those parent→child edges are structure, not
# design cycles. The graph below drops edges from a module to its own descendants.
adj = {a: {b for b in bs if not is_ancestor(a, b)} for a, bs in edges.items()}

if "--dot" in sys.argv:
    print("digraph imports {")
    for a in sorted(adj):
        for b in sorted(adj[a]):
            print(f'  "{name(a)}" -> "{name(b)}";')
    print("}")
    sys.exit()

if "--edges" in sys.argv:
    for a in sorted(adj):
        print(f"{name(a)} -> {', '.join(sorted(name(b) for b in adj[a]))}")

comps = sccs(mods, adj)
print(f"{len(mods)} modules, {sum(len(v) for v in adj.values())} edges, {len(comps)} cycles (strongly connected sets):")
for c in comps:
    cs = set(c)
    print("  {" + ", ".join(name(m) for m in c) + "}")
    for a in c:
        inner = sorted(name(b) for b in adj.get(a, ()) if b in cs)
        print(f"    {name(a)} -> {', '.join(inner)}")
sys.exit(1 if comps else 0)
