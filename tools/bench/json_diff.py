#!/usr/bin/env python3
"""Compares two JSON reports value by value: prints every differing path with both values and
the relative difference of numbers, then the largest relative difference and whether any
non-numeric value (a name, a verdict, a list's length) differs.

Usage: python3 tools/bench/json_diff.py A.json B.json [--ignore KEY ...] [--quiet]
Exit status 0 when every non-numeric value is equal, 1 otherwise."""
import json
import sys


def walk(a, b, path, out, ignore):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k in ignore:
                continue
            if k not in a or k not in b:
                out.append((f"{path}.{k}", a.get(k, "<absent>"), b.get(k, "<absent>"), None))
            else:
                walk(a[k], b[k], f"{path}.{k}", out, ignore)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append((f"{path}[len]", len(a), len(b), None))
            return
        for i, (x, y) in enumerate(zip(a, b)):
            walk(x, y, f"{path}[{i}]", out, ignore)
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        if a != b:
            rel = abs(a - b) / max(abs(a), abs(b))
            out.append((path, a, b, rel))
    elif a != b:
        out.append((path, a, b, None))


def main():
    args = sys.argv[1:]
    quiet = "--quiet" in args
    args = [x for x in args if x != "--quiet"]
    ignore = set()
    if "--ignore" in args:
        i = args.index("--ignore")
        ignore = set(args[i + 1:])
        args = args[:i]
    with open(args[0]) as f:
        a = json.load(f)
    with open(args[1]) as f:
        b = json.load(f)
    out = []
    walk(a, b, "", out, ignore)
    numeric = [d for d in out if d[3] is not None]
    other = [d for d in out if d[3] is None]
    if not quiet:
        for p, x, y, rel in out:
            print(f"{p}: {x} | {y}" + (f"  (rel {rel:.2e})" if rel is not None else ""))
    worst = max(numeric, key=lambda d: d[3]) if numeric else None
    print(f"{len(numeric)} numbers differ; largest relative difference "
          + (f"{worst[3]:.3e} at {worst[0]}" if worst else "0")
          + f"; {len(other)} non-numeric differences")
    sys.exit(1 if other else 0)


if __name__ == "__main__":
    main()
