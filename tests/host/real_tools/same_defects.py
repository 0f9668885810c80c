#!/usr/bin/python3
"""Whether two defect lists (dentmark detect --json) name the same defects: as many, each
of one matched by class to one of the other within TOL metres. Prints the pairs' largest
distance. Usage: same_defects.py ORIGINAL.json OTHER.json [TOL]"""
import json
import math
import sys

a = json.load(open(sys.argv[1]))["defects"]
b = json.load(open(sys.argv[2]))["defects"]
tol = float(sys.argv[3]) if len(sys.argv) > 3 else 0.002
if len(a) != len(b):
    sys.exit(f"{sys.argv[2]}: {len(b)} defects, the original {len(a)}")
left = list(b)
worst = 0.0
for d in a:
    best = min(left, key=lambda e: math.dist(e["position"], d["position"]), default=None)
    dist = math.dist(best["position"], d["position"]) if best else math.inf
    if dist > tol or best["class"] != d["class"]:
        sys.exit(f"{sys.argv[2]}: no {d['class']} within {tol * 1e3:.1f} mm of the original's #{d['id']}")
    worst = max(worst, dist)
    left.remove(best)
print(f"{sys.argv[2]}: the same {len(a)} defects, at most {worst * 1e3:.2f} mm apart")
