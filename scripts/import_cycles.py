#!/usr/bin/env python3
"""Import cycles between the modules of src/ (issue 23: "no import cycles").

A module is a file (`foo.rs` or `foo/mod.rs` is `crate::foo`). Module A
depends on B when A's text names a path into B (`use crate::...`,
`super::...`, `crate::...` anywhere, braces expanded one level); a path
into A's own ancestors or descendants does not count. Prints every
strongly connected component of more than one module and exits 1 if there
is one. `--no-tests` leaves out `#[cfg(test)]` modules (unit tests may use
the registry that lists the module under test).

    python3 scripts/import_cycles.py [src] [--no-tests]
"""
import os
import re
import sys

root = next((a for a in sys.argv[1:] if not a.startswith('--')), 'src')
no_tests = '--no-tests' in sys.argv

mods = {}
for dp, _, fs in os.walk(root):
    for f in fs:
        if not f.endswith('.rs'):
            continue
        p = os.path.join(dp, f)
        rel = os.path.relpath(p, root)[:-3].split(os.sep)
        if rel[-1] == 'mod':
            rel = rel[:-1]
        if rel in (['lib'], ['main']):
            rel = []
        mods['::'.join(['crate'] + rel)] = p


def resolve(cur, path):
    """The module a path from module `cur` lands in (longest known prefix)."""
    parts = path.split('::')
    if parts[0] == 'crate':
        base, parts = ['crate'], parts[1:]
    elif parts[0] in ('super', 'self'):
        base = cur.split('::')
        if parts[0] == 'self':
            parts = parts[1:]
        while parts and parts[0] == 'super':
            base, parts = (base[:-1] if base != ['crate'] else base), parts[1:]
    else:
        return None
    best = None
    for i in range(len(parts) + 1):
        m = '::'.join(base + parts[:i])
        if m in mods:
            best = m
    return best


def strip_test_modules(src):
    while True:
        mt = re.search(r'#\[cfg\(test\)\]\s*(?:pub\s+)?mod\s+\w+\s*\{', src)
        if not mt:
            return src
        depth, i = 1, mt.end()
        while depth and i < len(src):
            depth += {'{': 1, '}': -1}.get(src[i], 0)
            i += 1
        src = src[:mt.start()] + src[i:]


edges = {m: set() for m in mods}
for m, p in mods.items():
    with open(p, encoding='utf-8') as fh:
        src = re.sub(r'//.*', '', fh.read())
    if no_tests:
        src = strip_test_modules(src)
    targets = []
    for mm in re.finditer(r'((?:crate|super)(?:::\w+)*)::\{([^{}]*)\}', src):
        for item in mm.group(2).split(','):
            item = item.strip().split(' as ')[0]
            if item and item != 'self':
                targets.append(mm.group(1) + '::' + item)
    targets += [mm.group(1) for mm in re.finditer(r'\b((?:crate|super|self)(?:::\w+)+)', src)]
    for path in targets:
        t = resolve(m, path)
        if t and t != m and not m.startswith(t + '::') and not t.startswith(m + '::'):
            edges[m].add(t)

# Strongly connected components (Tarjan).
sys.setrecursionlimit(10000)
index, low, stack, on_stack, cycles = {}, {}, [], set(), []


def visit(v):
    index[v] = low[v] = len(index)
    stack.append(v)
    on_stack.add(v)
    for w in edges[v]:
        if w not in index:
            visit(w)
            low[v] = min(low[v], low[w])
        elif w in on_stack:
            low[v] = min(low[v], index[w])
    if low[v] == index[v]:
        c = []
        while True:
            w = stack.pop()
            on_stack.discard(w)
            c.append(w)
            if w == v:
                break
        if len(c) > 1:
            cycles.append(sorted(c))


for v in mods:
    if v not in index:
        visit(v)
print(f'{len(mods)} modules, {sum(map(len, edges.values()))} dependencies between them')
for c in cycles:
    print('cycle:', ' <-> '.join(c))
if not cycles:
    print('no import cycles')
sys.exit(1 if cycles else 0)
