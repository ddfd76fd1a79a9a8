#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""`occswitch info` over every model file of assimp-testmodels, checked against
tests/testmodels.txt: the counts of each file that imports, the exit status 2 and one `error:`
line naming the file for each that does not, and no file of the package left out of the table."""
import json
import os
import subprocess
import sys

exe, table = sys.argv[1], sys.argv[2]
root = "/usr/share/assimp/models"
exts = (".glb", ".gltf", ".obj", ".ply", ".off", ".stl")
keys = {"triangles": lambda j: j["triangles"], "kept": lambda j: j["triangles_kept"],
        "objects": lambda j: j["objects"], "meshes": lambda j: j["meshes"],
        "points": lambda j: j["skipped"]["points"], "lines": lambda j: j["skipped"]["lines"],
        "degenerate": lambda j: j["skipped"]["degenerate_faces"],
        "repeated": lambda j: j["skipped"]["repeated_corner_triangles"]}

expected = {}
for line in open(table, encoding="utf-8"):
    if not line.strip() or line.startswith("#"):
        continue
    path, want = line.rstrip("\n").split("\t")[:2]
    expected[path] = want

on_disk = sorted(os.path.relpath(os.path.join(d, f), root)
                 for d, _, fs in os.walk(root) for f in fs if f.lower().endswith(exts))
failures = [f"{p}: in the package but not in {table}" for p in on_disk if p not in expected]
failures += [f"{p}: in {table} but not in the package" for p in expected if p not in on_disk]

for path, want in sorted(expected.items()):
    full = os.path.join(root, path)
    if not os.path.exists(full):
        continue
    try:
        r = subprocess.run([exe, "info", full], capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        failures.append(f"{path}: info did not finish in 120 s")
        continue
    kind, _, rest = want.partition(" ")
    if kind == "ok":
        if r.returncode != 0:
            failures.append(f"{path}: exit {r.returncode}, expected success: {r.stderr.strip()}")
            continue
        got = json.loads(r.stdout)
        for item in rest.split():
            key, value = item.split("=")
            if keys[key](got) != int(value):
                failures.append(f"{path}: {key} {keys[key](got)}, expected {value}")
    else:
        lines = r.stderr.strip().splitlines()
        if r.returncode != 2:
            failures.append(f"{path}: exit {r.returncode}, expected 2")
        elif len(lines) != 1 or not lines[0].startswith(f"error: {full}: ") or rest not in lines[0]:
            failures.append(f"{path}: expected one 'error: {full}: ...{rest}...' line, got: {r.stderr.strip()}")

checked = len([p for p in expected if p in on_disk])
for f in failures:
    print("FAIL:", f)
print(f"{checked} model files checked, {len(failures)} failures")
sys.exit(1 if failures or checked == 0 else 0)
