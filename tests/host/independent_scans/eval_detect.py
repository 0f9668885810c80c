#!/usr/bin/python3
"""Recall and false alarms of `dentmark detect` per class and per distance band, on scans
from two generators: the project's (`dentmark synth scan`) and the independent one
(door_scan.py). A true defect is found when a reported defect of the same kind (dent or
bump) lies within max(5 mm, diameter / 2) of it along the surface (as `dentmark eval`).

Classes:
  features  defects beside the handle, the window, the panel's edge and a character line,
            their rims 3-50 mm from the feature's footprint (0.6 mm spacing, 20 um noise)
  lines     defects on and beside character lines of several directions (same scans)
  coarse    4-6 mm spacing, 0.3 mm noise, defects 9-25 mm wide and 2-11 mm high, with the
            paper's 9 mm x 11 mm bump and the handle
  flying    0.7 mm spacing, 20 um noise, 0.05-0.5 % flying pixels 1-10 mm along the ray

Prints one table per generator and class, and a summary; exits 1 when a target is missed
(recall >= 95 %, <= 0.1 false alarms per m²) and --check is given.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
CLASSES = ["features", "lines", "coarse", "flying"]
QUICK_PANEL = []  # --quick: smaller independent doors


def indep_args(cls, seed):
    rng = np.random.default_rng(10_000 + seed)
    if cls == "features":
        return ["--layout", "features", "--spacing", "0.0006", "--noise", "20e-6"]
    if cls == "lines":
        return ["--layout", "lines", "--spacing", "0.0006", "--noise", "20e-6"]
    if cls == "coarse":
        return ["--layout", "free", "--width", "1.1", "--height", "0.9", "--spacing", "%.4f" % rng.uniform(0.004, 0.006),
                "--noise", "3e-4", "--defects", "5", "--min-depth", "0.002", "--max-depth", "0.011",
                "--paper-bump", "--dropout-rate", "0.0"]
    return ["--layout", "free", "--spacing", "0.0007", "--noise", "20e-6", "--defects", "8",
            "--flying", "%.5f" % (0.0005 * 10 ** rng.uniform(0, 1)), "--shuffle"]


def own_args(cls, seed):
    rng = np.random.default_rng(20_000 + seed)
    if cls == "features":
        return ["--width", "0.9", "--height", "0.7", "--spacing", "0.0006", "--noise", "20e-6", "--defects", "0",
                "--near-features", "0.004,0.009,0.018,0.035", "--min-diameter", "0.009", "--max-diameter", "0.025",
                "--min-depth", "1e-4", "--max-depth", "1e-3"]
    if cls == "lines":
        ang = ["0", "0.26", "-0.26", "0.52", "1.47"][seed % 5]
        return ["--width", "0.9", "--height", "0.7", "--spacing", "0.0006", "--noise", "20e-6", "--defects", "0",
                "--no-crease", "--no-handle", "--no-window",
                "--character-line", "0.25,%s,%.4f,0.012" % (ang, 0.002 + 0.002 * rng.uniform()),
                "--character-line", "0.6,%s,%.4f,0.012" % (ang, -(0.002 + 0.002 * rng.uniform())),
                "--near-lines", "on,on,0.004,0.009,0.018,0.035", "--min-diameter", "0.009",
                "--max-diameter", "0.025", "--min-depth", "1e-4", "--max-depth", "1e-3"]
    if cls == "coarse":
        return ["--width", "1.1", "--height", "0.9", "--spacing", "%.4f" % rng.uniform(0.004, 0.006), "--noise", "3e-4",
                "--defects", "5", "--min-diameter", "0.009", "--max-diameter", "0.025", "--min-depth", "0.002",
                "--max-depth", "0.011", "--paper-bump"]
    return ["--spacing", "0.0007", "--noise", "20e-6", "--defects", "8", "--min-diameter", "0.009",
            "--max-diameter", "0.025", "--min-depth", "1e-4", "--max-depth", "1e-3",
            "--outliers", "%.5f" % (0.0005 * 10 ** rng.uniform(0, 1)), "--shuffle"]


def match(truth, found):
    """Greedy closest-first matching of same-kind defects; returns (found flags, false alarms)."""
    kind = lambda cls, h: 2 if cls == "hole" else (0 if h < 0 else 1)
    pairs = []
    for i, t in enumerate(truth):
        p, n = np.array(t["position"]), np.array(t["normal"]) / np.linalg.norm(t["normal"])
        for j, d in enumerate(found):
            off = np.array(d["position"]) - p
            dist = np.linalg.norm(off - off.dot(n) * n)
            if dist <= max(0.005, 0.5 * t["diameter"]):
                pairs.append((dist, i, j))
    pairs.sort()
    tu, du = [False] * len(truth), [False] * len(found)
    for dist, i, j in pairs:
        if tu[i] or du[j] or kind(truth[i]["class"], truth[i]["height"]) != kind(found[j]["class"], found[j]["height"]):
            continue
        tu[i] = du[j] = True
    return tu, [found[j] for j in range(len(found)) if not du[j]]


def run_one(dentmark, detector, gen, cls, seed, work, keep, config=None, reuse=False):
    base = os.path.join(work, "%s_%s_%d" % (gen, cls, seed))
    ply, truth, out = base + ".ply", base + "_truth.json", base + ".json"
    if gen == "indep":
        cmd = [os.path.join(HERE, "door_scan.py"), "--out", ply, "--truth", truth, "--seed", str(seed)]
        cmd += indep_args(cls, seed) + QUICK_PANEL
    else:
        cmd = [dentmark, "synth", "scan", "--out", ply, "--truth", truth, "--seed", str(seed)] + own_args(cls, seed)
    if not (reuse and os.path.exists(ply) and os.path.exists(truth)):
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    subprocess.run([detector, "detect", ply, "--out", base + ".dml", "--json", out] +
                   (["--config", config] if config else []), check=True, stdout=subprocess.DEVNULL)
    t = json.load(open(truth))
    d = json.load(open(out))
    found = [x for x in d["defects"] if x["class"] in ("dent", "bump", "hole")]
    flags, fa = match(t["defects"], found)
    bands = band_of(t)
    rows = []
    for k, (td, ok) in enumerate(zip(t["defects"], flags)):
        rows.append({"band": bands[k], "found": ok, "d": td["diameter"], "h": td["height"],
                     "feature": td.get("feature", "")})
    if not keep:
        for f in (ply, base + ".dml", truth, out):
            os.remove(f)
    return rows, fa, t["panel_area"], d["source"]["vertices"]


def band_of(truth):
    """Distance band of each true defect, from the feature it was placed beside and the gap
    from its rim to that feature's footprint (truth fields "feature" and "gap")."""
    out = []
    for td in truth["defects"]:
        b = td.get("band")
        if b in ("free", "paper"):
            out.append(b)
            continue
        if "feature" not in td:
            out.append("free")
            continue
        f = td["feature"]
        f = "line" if f.startswith("line") else f
        g = td["gap"]
        b = "on" if g < 0 else "3-6mm" if g < 0.006 else "6-12mm" if g < 0.012 else "12-25mm" if g < 0.025 \
            else "25-50mm"
        out.append(f + ":" + b)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dentmark", required=True)
    ap.add_argument("--detector", default=None, help="another dentmark to detect with (default: --dentmark)")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--classes", default=",".join(CLASSES))
    ap.add_argument("--generators", default="own,indep")
    ap.add_argument("--work", default=None, help="keep scans and results here")
    ap.add_argument("--reuse", action="store_true", help="detect again on the scans kept in --work")
    ap.add_argument("--config", default=None, help="detection settings (YAML) for detect --config")
    ap.add_argument("--check", action="store_true", help="exit 1 when a class misses a target")
    ap.add_argument("-v", action="store_true", help="print each missed defect and false alarm")
    ap.add_argument("--quick", action="store_true", help="independent doors of 0.6 x 0.5 m (for fast tests)")
    a = ap.parse_args()
    if a.quick:
        QUICK_PANEL[:] = ["--width", "0.6", "--height", "0.5"]
    work = a.work or tempfile.mkdtemp(prefix="eval-detect-")
    os.makedirs(work, exist_ok=True)
    ok = True
    summary = []
    for gen in a.generators.split(","):
        for cls in a.classes.split(","):
            rows, fas, area, verts = [], [], 0.0, []
            for seed in range(a.first_seed, a.first_seed + a.seeds):
                r, fa, ar, nv = run_one(a.dentmark, a.detector or a.dentmark, gen, cls, seed, work, a.work is not None, a.config,
                                         a.reuse)
                rows += r
                fas += fa
                area += ar
                verts.append(nv)
                if a.v:
                    for x in r:
                        if not x["found"]:
                            print("  miss %s %s seed %d: %s d %.1f mm h %.3f mm" % (gen, cls, seed, x["band"],
                                                                                  1e3 * x["d"], 1e3 * x["h"]))
                    for f in fa:
                        print("  false alarm %s %s seed %d: %s d %.1f mm h %.3f mm at %s" % (
                            gen, cls, seed, f["class"], 1e3 * f["diameter"], 1e3 * f["height"],
                            [round(1e3 * c, 1) for c in f["position"]]))
            n = len(rows)
            found = sum(x["found"] for x in rows)
            rec = found / n if n else 1.0
            fa_m2 = len(fas) / area if area else 0.0
            print("%s / %s: %d seeds, %d-%d vertices, %.2f m²: recall %.1f %% (%d of %d), false alarms %d "
                  "(%.3f per m²)" % (gen, cls, a.seeds, min(verts), max(verts), area, 100 * rec, found, n, len(fas),
                                     fa_m2))
            for band in sorted(set(x["band"] for x in rows)):
                sel = [x for x in rows if x["band"] == band]
                print("    %-20s %5.1f %% (%d of %d)" % (band, 100 * sum(x["found"] for x in sel) / len(sel),
                                                       sum(x["found"] for x in sel), len(sel)))
            sys.stdout.flush()
            met = rec >= 0.95 and fa_m2 <= 0.1
            ok &= met
            summary.append((gen, cls, rec, fa_m2, met))
    print("\nsummary (target: recall >= 95 %, <= 0.1 false alarms per m²)")
    for gen, cls, rec, fa, met in summary:
        print("  %-6s %-9s recall %5.1f %%  false alarms %.3f per m²  %s" % (gen, cls, 100 * rec, fa,
                                                                           "met" if met else "MISSED"))
    return 0 if ok or not a.check else 1


if __name__ == "__main__":
    sys.exit(main())
