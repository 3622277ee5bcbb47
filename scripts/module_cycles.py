#!/usr/bin/env python3
"""Module circles inside each crate (run by scripts/check-layers.sh).

Usage: module_cycles.py --workspace   (every lib and bin target of the
       cargo workspace, from `cargo metadata`)
   or: module_cycles.py CRATE_NAME SRC_DIR [CRATE_NAME SRC_DIR ...]

For every crate root (a target's root file; with SRC_DIR: lib.rs, main.rs,
bin/*.rs in it) the module tree
is found by following `mod name;` declarations; a module is a file module
(`a/b.rs` or `a/b/mod.rs` is `a::b`; inline `mod x { … }` blocks such as
`mod tests` belong to the file they are written in). Edges come from every
path in the code (comments and strings stripped) that starts with `crate::`,
`super::` or `self::`, from `use` trees (braces expanded), and from paths
that start with a name a `use` imported as a module.

Rules:
- A path is resolved to the file module that defines the item it names.
  An item a module only re-exports (`use x::Item;` / `pub use x::Item;`,
  e.g. the crate root's `pub use chain::Chain`) resolves to where it comes
  from, so `crate::Chain` is an edge to `chain`, not to the crate root.
  Glob imports are not followed (such an item stays with the importing module).
- Importing a module itself (`use super::pose_format;`) is no edge; the paths
  that go through the import (`pose_format::encode`) are.
- A parent declaring its child (`mod child;`) is no edge, and neither is a
  module using its own descendants (`child::f`, `self::child::X`): a parent
  owns its subtree and may assemble and re-export it.
- A child using its parent's (or any ancestor's) own items (`super::State`)
  IS an edge to the parent. Since a parent's use of its own children is no
  edge, a parent and its child alone never form a circle; a circle through a
  parent needs the parent to use a module outside its subtree.
- Edges in `#[cfg(test)]` blocks count like any other (tests are code too).
- Edges to other crates are ignored (check-layers.sh checks those).

Prints each circle as `crate: a -> b -> a` (one shortest circle per strongly
connected group of modules, starting from its first module by name) with the
file, line and path of each edge, and exits 1 if there is any.
"""

import json
import os
import re
import subprocess
import sys
from collections import defaultdict, deque

IDENT = re.compile(r"(?:r#)?[A-Za-z_][A-Za-z0-9_]*")


def strip(src):
    """Source with comments, strings and char literals blanked (newlines kept)."""
    out = []
    i, n = 0, len(src)

    def blank(text):
        out.append(re.sub(r"[^\n]", " ", text))

    while i < n:
        c = src[i]
        if src.startswith("//", i):
            j = src.find("\n", i)
            j = n if j < 0 else j
            blank(src[i:j])
            i = j
        elif src.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if src.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif src.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            blank(src[i:j])
            i = j
        elif (m := re.compile(r'b?r(#*)"').match(src, i)) and (
            i == 0 or not (src[i - 1].isalnum() or src[i - 1] == "_")
        ):
            end = '"' + m.group(1)
            j = src.find(end, m.end())
            j = n if j < 0 else j + len(end)
            blank(src[i:j])
            i = j
        elif c == '"' or (c == "b" and src.startswith('b"', i)):
            j = i + (2 if c == "b" else 1)
            while j < n and src[j] != '"':
                j += 2 if src[j] == "\\" else 1
            blank(src[i : j + 1])
            i = j + 1
        elif c == "'":
            m = re.compile(r"'(?:\\(?:x[0-9a-fA-F]{2}|u\{[0-9a-fA-F]+\}|.)|[^\\'])'").match(src, i)
            if m:
                blank(m.group(0))
                i = m.end()
            else:  # a lifetime
                out.append(c)
                i += 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def tokens(code):
    """(token, line) pairs: identifiers, `::` and single punctuation."""
    line = 1
    i, n = 0, len(code)
    while i < n:
        c = code[i]
        if c == "\n":
            line += 1
            i += 1
        elif c.isspace():
            i += 1
        elif m := IDENT.match(code, i):
            yield m.group(0).removeprefix("r#"), line
            i = m.end()
        elif code.startswith("::", i):
            yield "::", line
            i += 2
        else:
            yield c, line
            i += 1


def parse_use_tree(toks, k):
    """Expands the use tree starting at toks[k]; returns (leaves, k after `;`).
    A leaf is (segments, alias) with alias None for `*`."""
    leaves = []

    def tree(prefix, k):
        segs = list(prefix)
        while k < len(toks):
            t = toks[k][0]
            if t == "{":
                k += 1
                while toks[k][0] != "}":
                    k = tree(segs, k)
                    if toks[k][0] == ",":
                        k += 1
                return k + 1
            if t == "*":
                leaves.append((segs, None))
                return k + 1
            if t == "::":
                k += 1
                continue
            if IDENT.fullmatch(t):
                segs.append(t)
                k += 1
                if k < len(toks) and toks[k][0] == "as":
                    leaves.append((segs, toks[k + 1][0]))
                    return k + 2
                if k < len(toks) and toks[k][0] == "::":
                    continue
                alias = segs[-2] if segs[-1] == "self" and len(segs) > 1 else segs[-1]
                leaves.append((segs, alias))
                return k
            return k
        return k

    k = tree([], k)
    while k < len(toks) and toks[k][0] != ";":
        k += 1
    return leaves, k + 1


class FileModule:
    """One file module: its path, its `mod x;` children, its imports and paths."""

    def __init__(self, path, file):
        self.path = path  # tuple of names, () for the crate root
        self.file = file
        self.children = []  # names declared with `mod name;`
        self.imports = []  # (scope, alias, segments, line)
        self.paths = []  # (scope, segments, line, kind: use, glob or path)

    def parse(self):
        with open(self.file, encoding="utf-8") as f:
            toks = list(tokens(strip(f.read())))
        stack = []  # (inline module name or None, brace depth)
        depth = 0
        k = 0
        while k < len(toks):
            t, line = toks[k]
            prev = toks[k - 1][0] if k else ""
            scope = self.path + tuple(name for name, _ in stack if name)
            if t == "{":
                depth += 1
                stack.append((None, depth))
            elif t == "}":
                depth -= 1
                if stack:
                    stack.pop()
            elif t == "mod" and k + 2 < len(toks) and IDENT.fullmatch(toks[k + 1][0]):
                name, after = toks[k + 1][0], toks[k + 2][0]
                if after == ";" and len(scope) == len(self.path):
                    self.children.append(name)
                elif after == "{":
                    depth += 1
                    stack.append((name, depth))
                    k += 3
                    continue
            elif t == "mod" and k + 3 < len(toks) and toks[k + 1][0] == "$" \
                    and toks[k + 3][0] == "{":
                # `mod $name { … }` in a macro: an inline module all the same.
                depth += 1
                stack.append(("$" + toks[k + 2][0], depth))
                k += 4
                continue
            elif t == "use" and prev != "::":
                leaves, k2 = parse_use_tree(toks, k + 1)
                for segs, alias in leaves:
                    if segs[-1] == "self":
                        segs = segs[:-1]
                    if not segs:
                        continue
                    if alias:
                        self.imports.append((scope, alias, segs, line))
                    self.paths.append((scope, segs, line, "use" if alias else "glob"))
                k = k2
                continue
            elif IDENT.fullmatch(t) and prev not in ("::", "$", ".") and k + 1 < len(toks) \
                    and toks[k + 1][0] == "::":
                segs = [t]
                j = k + 1
                while j + 1 < len(toks) and toks[j][0] == "::" and IDENT.fullmatch(toks[j + 1][0]):
                    segs.append(toks[j + 1][0])
                    j += 2
                self.paths.append((scope, segs, line, "path"))
                k = j
                continue
            k += 1


class Crate:
    """The file modules of one crate root and the edges between them."""

    def __init__(self, name, root_file):
        self.name = name
        self.modules = {}
        self._load((), root_file, os.path.dirname(root_file))

    def _load(self, path, file, child_dir):
        m = FileModule(path, file)
        m.parse()
        self.modules[path] = m
        # Children of `lib.rs`, `main.rs` and `a/mod.rs` are beside them; those of `a.rs` in `a/`.
        for c in m.children:
            for cand in (os.path.join(child_dir, c + ".rs"), os.path.join(child_dir, c, "mod.rs")):
                if os.path.isfile(cand):
                    self._load(path + (c,), cand, os.path.join(child_dir, c))
                    break

    def file_module_of(self, path):
        """The longest prefix of `path` that is a file module, and the rest."""
        for i in range(len(path), -1, -1):
            if tuple(path[:i]) in self.modules:
                return tuple(path[:i]), list(path[i:])
        return (), list(path)

    def absolute(self, scope, segs):
        """`segs` as seen from module `scope` (file path + inline names), as an
        absolute path, or None for another crate."""
        first = segs[0]
        if first == "crate":
            return list(segs[1:])
        if first in ("self", "super"):
            cur = list(scope)
            i = 0
            while i < len(segs) and segs[i] in ("self", "super"):
                if segs[i] == "super":
                    if not cur:
                        return None
                    cur.pop()
                i += 1
            return cur + list(segs[i:])
        file_mod, _ = self.file_module_of(scope)
        for imp_scope, alias, isegs, _ in self.modules[file_mod].imports:
            if imp_scope == tuple(scope) and alias == first and isegs[0] != first:
                base = self.absolute(imp_scope, isegs)
                return None if base is None else base + list(segs[1:])
        if tuple(scope) + (first,) in self.modules:
            return list(scope) + list(segs)
        return None

    def resolve(self, abs_path, depth=0):
        """(file module, names after it) of an absolute path, following re-exports."""
        mod, rest = self.file_module_of(abs_path)
        if rest and depth < 16:
            for imp_scope, alias, isegs, _ in self.modules[mod].imports:
                if imp_scope == mod and alias == rest[0]:
                    target = self.absolute(imp_scope, isegs)
                    if target is None:
                        return None, []
                    if target != list(abs_path[: len(mod) + 1]):
                        return self.resolve(target + rest[1:], depth + 1)
        return mod, rest

    def edges(self):
        """{(from, to): (file, line, path text)} between file modules."""
        found = {}
        for path, m in self.modules.items():
            for scope, segs, line, kind in m.paths:
                absp = self.absolute(scope, segs)
                if absp is None:
                    continue
                target, rest = self.resolve(absp)
                if target is None or (kind == "use" and not rest):
                    continue  # another crate, or a module imported as a name
                if target[: len(path)] == path:
                    continue  # itself or one of its descendants
                found.setdefault((path, target), (m.file, line, "::".join(segs)))
        return found


def shortest_cycle(start, graph, members):
    prev = {start: None}
    queue = deque([start])
    while queue:
        u = queue.popleft()
        for v in sorted(graph[u]):
            if v not in members:
                continue
            if v == start:
                cycle = [u]
                while prev[cycle[-1]] is not None:
                    cycle.append(prev[cycle[-1]])
                return list(reversed(cycle)) + [start]
            if v not in prev:
                prev[v] = u
                queue.append(v)
    return None


def components(graph, nodes):
    """Strongly connected components (Tarjan), each as a set."""
    index, low, on, stack, out = {}, {}, set(), [], []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            out.append(comp)

    sys.setrecursionlimit(10000)
    for v in sorted(nodes):
        if v not in index:
            visit(v)
    return out


def show(path):
    return "::".join(path) or "crate"


def check(label, crate):
    edges = crate.edges()
    graph = defaultdict(set)
    for a, b in edges:
        graph[a].add(b)
    circles = 0
    for comp in components(graph, crate.modules):
        if len(comp) < 2:
            continue
        start = min(comp)
        cycle = shortest_cycle(start, graph, comp)
        circles += 1
        print(f"module circle: {label}: " + " -> ".join(show(p) for p in cycle))
        for a, b in zip(cycle, cycle[1:]):
            file, line, text = edges[(a, b)]
            print(f"    {show(a)} -> {show(b)}: {os.path.relpath(file)}:{line} uses {text}")
        shown = set(zip(cycle, cycle[1:]))
        for a, b in sorted(e for e in edges if e[0] in comp and e[1] in comp and e not in shown):
            file, line, text = edges[(a, b)]
            print(f"    also in this knot: {show(a)} -> {show(b)}: "
                  f"{os.path.relpath(file)}:{line} uses {text}")
    return circles


def workspace_roots():
    """(label, root file) of every lib and bin target of the workspace members."""
    meta = json.loads(subprocess.run(
        ["cargo", "metadata", "--no-deps", "--format-version", "1", "--locked"],
        check=True, capture_output=True, text=True).stdout)
    members = set(meta["workspace_members"])
    roots = []
    for pkg in sorted(meta["packages"], key=lambda p: p["name"]):
        if pkg["id"] not in members:
            continue
        for t in pkg["targets"]:
            if set(t["kind"]) & {"lib", "rlib", "proc-macro"}:
                roots.append((pkg["name"], pkg["name"], t["src_path"]))
            elif "bin" in t["kind"]:
                roots.append((pkg["name"], f"{pkg['name']} (bin {t['name']})", t["src_path"]))
    return roots


def dir_roots(name, src):
    """(crate, label, root file) of the crate roots in a source directory."""
    files = [os.path.join(src, f) for f in ("lib.rs", "main.rs")]
    bindir = os.path.join(src, "bin")
    if os.path.isdir(bindir):
        files += sorted(os.path.join(bindir, f) for f in os.listdir(bindir) if f.endswith(".rs"))
    return [(name, name if f.endswith("lib.rs") else f"{name} ({os.path.relpath(f, src)})", f)
            for f in files if os.path.isfile(f)]


SELF_TEST = {
    # A circle through a re-export at the root, found whatever the spelling.
    "lib.rs": "mod a; mod b; mod c; mod p; pub use c::Thing;\n",
    "a.rs": "use crate::b::{self, Other};\nfn f() { b::g(); }\n",
    "b.rs": "pub fn g() { crate::Thing::new(); } // crate::a::nothing\n",
    "c.rs": "use super::a::F; pub struct Thing; const S: &str = \"crate::b::x\";\n"
            "#[cfg(test)] mod tests { use super::*; use crate::p::q::Q; }\n",
    # Parent and child using each other: no circle; `mod tests { super }` is the file itself.
    "p.rs": "mod q; pub struct State; fn h() { q::run(); }\n",
    "p/q.rs": "use super::State; pub fn run() {} mod tests { use super::*; }\n",
}


def self_test():
    """Checks the rules on a small crate with a known circle; 0 when they hold."""
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        for name, text in SELF_TEST.items():
            os.makedirs(os.path.dirname(os.path.join(d, name)), exist_ok=True)
            with open(os.path.join(d, name), "w", encoding="utf-8") as f:
                f.write(text)
        crate = Crate("t", os.path.join(d, "lib.rs"))
        got = sorted((show(a), show(b)) for a, b in crate.edges())
    want = [("a", "b"), ("b", "c"), ("c", "a"), ("c", "p::q"), ("p::q", "p")]
    if got != want:
        print(f"module_cycles self-test: edges {got}, expected {want}", file=sys.stderr)
        return 1
    return 0


def main(argv):
    if self_test():
        return 2
    if argv == ["--workspace"]:
        roots = workspace_roots()
    elif argv and len(argv) % 2 == 0:
        roots = [r for name, src in zip(argv[0::2], argv[1::2]) for r in dir_roots(name, src)]
    else:
        print(__doc__.split("\n\n")[1], file=sys.stderr)
        return 2
    found = defaultdict(int)
    for name, label, root in roots:
        found[name] += check(label, Crate(label, root))
    for name in sorted(found):
        if found[name] == 0:
            print(f"check-layers: {name} modules ok (no circles)")
    return 1 if any(found.values()) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
