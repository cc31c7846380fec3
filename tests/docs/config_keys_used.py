#!/usr/bin/env python3
"""Fails when a configuration key is read by the loader but used nowhere else (a dead key), or when
docs/CONFIG.md and the loader disagree on which keys exist.

A key counts as used when the member it is read into is referenced (as `.member` or `->member`) in a
source file other than the loader itself. Usage: config_keys_used.py SOURCE_DIR
"""
import pathlib
import re
import sys

root = pathlib.Path(sys.argv[1])
loader = root / "service/src/config.cc"
pairs = re.findall(r'\.(?:optional_)?field\("(\w+)",\s*([\w.]+)\)', loader.read_text())
if len(pairs) < 50:
    sys.exit(f"{loader}: found only {len(pairs)} keys; the loader's shape changed, update this test")

sources = {}
for top in ("service", "mapping", "geometry", "clients"):
    for path in (root / top).rglob("*"):
        if path.suffix in (".cc", ".h") and path.name not in ("config.cc", "config.h"):
            sources[path] = path.read_text(errors="replace")

dead = []
for key, expr in pairs:
    member = expr.split(".")[-1]
    pattern = re.compile(r"(\.|->)" + re.escape(member) + r"\b")
    if not any(pattern.search(text) for text in sources.values()):
        dead.append(f"{key} (read into {expr})")

# Every key of the documented block is read by the loader (nested sections included).
documented = set()
doc = (root / "docs/CONFIG.md").read_text()
block = re.search(r"```yaml\n(.*?)```", doc, re.S)
if not block:
    sys.exit("docs/CONFIG.md: no ```yaml block with the keys")
for line in block.group(1).splitlines():
    match = re.match(r"\s*(?:# )?([a-z_]\w*):", line)  # an optional key is documented commented out
    if match:
        documented.add(match.group(1))
loader_keys = {key for key, _ in pairs} | set(re.findall(r'section(?:s)?\("(\w+)"', loader.read_text()))
loader_keys |= set(re.findall(r'read_\w+\(\w+, "(\w+)"', loader.read_text()))
undocumented = sorted({key for key, _ in pairs} - documented)
unknown = sorted(documented - loader_keys)

problems = []
if dead:
    problems.append("keys read but never used: " + ", ".join(dead))
if undocumented:
    problems.append("keys read but missing from docs/CONFIG.md: " + ", ".join(undocumented))
if unknown:
    problems.append("keys in docs/CONFIG.md the loader does not read: " + ", ".join(unknown))
if problems:
    sys.exit("\n".join(problems))
print(f"{len(pairs)} configuration keys, each documented and used")
