#!/usr/bin/python3
"""Writes a synthetic scan (dentmark synth scan's PLY) as an organised ASCII PCD: one
point per sensor pixel, NaN where the sensor saw nothing, as a structured-light
scanner's PCL driver saves it. The simulator samples a regular grid in the image
coordinates u = x/z, v = y/z, so each vertex's pixel is its (u, v) over the grid step.
Usage: organise.py SCAN.ply OUT.pcd"""
import sys

import numpy as np
import open3d as o3d

mesh = o3d.io.read_triangle_mesh(sys.argv[1])
p = np.asarray(mesh.vertices, dtype=np.float64)
u, v = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
# Neighbours in file order are neighbouring pixels of a row: their spacing is the step.
du = np.abs(np.diff(u))
step = np.median(du[du > 0])
col = np.rint((u - u.min()) / step).astype(np.int64)
row = np.rint((v - v.min()) / step).astype(np.int64)
width, height = int(col.max()) + 1, int(row.max()) + 1
grid = np.full((height * width, 3), np.nan)
pixel = row * width + col
if len(np.unique(pixel)) != len(pixel):
    sys.exit("organise.py: two vertices fall on one pixel: not a scan on a regular image grid")
grid[pixel] = p
with open(sys.argv[2], "w") as f:
    f.write("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n"
            "TYPE F F F\nCOUNT 1 1 1\n")
    f.write(f"WIDTH {width}\nHEIGHT {height}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {width * height}\nDATA ascii\n")
    for x, y, z in grid:
        f.write("nan nan nan\n" if np.isnan(x) else f"{x:.7g} {y:.7g} {z:.7g}\n")
print(f"organise.py: {width} x {height} pixels, {len(p)} points")
