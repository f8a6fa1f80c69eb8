#!/usr/bin/env python3
"""Check that the workspace's declared `rust-version` is true for the locked dependency tree.

Reads `cargo metadata --locked` (the packages Cargo.lock resolves for this host, with the
workspace's features) and fails when any package declares a `rust-version` newer than the
workspace's. Also fails when a workspace member has no `rust-version` at all.

What this checks: every locked dependency's own declared minimum compiler. What it does not:
whether our code compiles on that compiler (no older toolchain can be installed here; clippy's
`incompatible_msrv` lint, on in CI through `clippy::all`, flags std APIs newer than our
`rust-version`), nor dependencies that under-declare their own minimum.

Usage: python3 .ci/check-msrv.py   (from anywhere inside the workspace; exit 0 = true, 1 = not)
"""
import json
import subprocess
import sys


def parse(version: str) -> tuple:
    """'1.85' or '1.85.0' -> (1, 85, 0)."""
    parts = [int(x) for x in version.split(".")]
    return tuple(parts + [0] * (3 - len(parts)))


def main() -> int:
    host = subprocess.run(
        ["rustc", "-vV"], check=True, capture_output=True, text=True
    ).stdout
    triple = next(line.split(":", 1)[1].strip() for line in host.splitlines() if line.startswith("host:"))
    out = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--locked", "--filter-platform", triple],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    meta = json.loads(out)
    packages = {p["id"]: p for p in meta["packages"]}
    members = [packages[i] for i in meta["workspace_members"]]
    missing = [p["name"] for p in members if not p.get("rust_version")]
    if missing:
        print(f"error: workspace members without rust-version: {', '.join(missing)}", file=sys.stderr)
        return 1
    ours = max(parse(p["rust_version"]) for p in members)
    ours_text = ".".join(map(str, ours))
    resolved = {node["id"] for node in meta["resolve"]["nodes"]}
    too_new = sorted(
        (parse(p["rust_version"]), p["name"], p["version"])
        for i, p in packages.items()
        if i in resolved and p.get("rust_version") and parse(p["rust_version"]) > ours
    )
    if too_new:
        print(
            f"error: Cargo.lock has packages that need a newer Rust than rust-version = {ours_text}:",
            file=sys.stderr,
        )
        for version, name, pkg_version in too_new:
            print(f"  {name} {pkg_version} needs {'.'.join(map(str, version))}", file=sys.stderr)
        print(
            "fix: raise [workspace.package] rust-version, or `cargo update -p NAME --precise OLDER`",
            file=sys.stderr,
        )
        return 1
    newest = max(
        (parse(packages[i]["rust_version"]), packages[i]["name"])
        for i in resolved
        if packages[i].get("rust_version")
    )
    print(
        f"rust-version {ours_text} holds for all {len(resolved)} locked packages on {triple} "
        f"(newest requirement: {newest[1]} {'.'.join(map(str, newest[0]))})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
