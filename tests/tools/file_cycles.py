#!/usr/bin/python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""The CTest case `file_cycles`: no two source files of librpiv call each other, directly or
through others. Reads the symbols of the object files given (nm): file A depends on file B
when A uses a symbol B defines. Prints every group of files that depend on each other in a
cycle (strongly connected components) and fails if there is one.
Usage: file_cycles.py OBJECT.o..."""
import subprocess
import sys


def symbols(obj):
    out = subprocess.run(["nm", obj], capture_output=True, text=True, check=True).stdout
    defined, used = set(), set()
    for line in out.splitlines():
        f = line.split()
        if len(f) == 3 and f[1] in "TDBRV":
            defined.add(f[2])
        elif len(f) == 2 and f[0] == "U":
            used.add(f[1])
    return defined, used


def name_of(obj):
    # .../rpiv_piv.dir/piv/deform.c.o -> piv/deform.c
    return obj.split(".dir/")[-1][:-2] if ".dir/" in obj else obj


def main(objs):
    defs, uses = {}, {}
    for o in objs:
        defs[name_of(o)], uses[name_of(o)] = symbols(o)
    owner = {s: f for f, d in defs.items() for s in d}
    graph = {f: sorted({owner[s] for s in u if s in owner and owner[s] != f}) for f, u in uses.items()}
    index, low, stack, on, groups, counter = {}, {}, [], set(), [], [0]

    def visit(v):  # Tarjan's strongly connected components, iteratively
        work = [(v, 0)]
        while work:
            node, i = work.pop()
            if i == 0:
                index[node] = low[node] = counter[0]
                counter[0] += 1
                stack.append(node)
                on.add(node)
            succ = graph[node]
            if i < len(succ):
                work.append((node, i + 1))
                w = succ[i]
                if w not in index:
                    work.append((w, 0))
                elif w in on:
                    low[node] = min(low[node], index[w])
                continue
            for w in succ:
                if w in on and index[w] > index[node]:
                    low[node] = min(low[node], low[w])
            if low[node] == index[node]:
                group = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    group.append(w)
                    if w == node:
                        break
                if len(group) > 1:
                    groups.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    for g in groups:
        print("file_cycles: these files call each other in a cycle: " + ", ".join(g))
    print(f"file_cycles: {len(defs)} files, {len(groups)} cycle(s)")
    return 1 if groups else 0


if __name__ == "__main__":
    # CTest passes each module's $<TARGET_OBJECTS:...> as one ;-separated argument
    sys.exit(main([o for a in sys.argv[1:] for o in a.split(";") if o]))
