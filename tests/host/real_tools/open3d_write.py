#!/usr/bin/python3
"""Writes a scan mesh as Open3D writes it: meshes (PLY binary and ASCII with normals and
colours, OBJ, STL) and point clouds of its vertices (PLY with double coordinates,
normals and colours; XYZ; PCD ASCII, binary and binary_compressed).
Usage: open3d_write.py SCAN.ply OUTDIR"""
import os
import sys

import numpy as np
import open3d as o3d

mesh = o3d.io.read_triangle_mesh(sys.argv[1])
out = sys.argv[2]
mesh.compute_vertex_normals()
mesh.compute_triangle_normals()
mesh.paint_uniform_color([0.6, 0.6, 0.65])
io = o3d.io


def must(ok, name):
    if not ok:
        sys.exit(f"open3d_write.py: Open3D could not write {name}")


for name, ascii_ in (("o3d_mesh_bin.ply", False), ("o3d_mesh_ascii.ply", True)):
    must(io.write_triangle_mesh(os.path.join(out, name), mesh, write_ascii=ascii_), name)
must(io.write_triangle_mesh(os.path.join(out, "o3d_mesh.obj"), mesh, write_vertex_colors=False), "obj")
must(io.write_triangle_mesh(os.path.join(out, "o3d_mesh.stl"), mesh), "stl")
cloud = o3d.geometry.PointCloud(mesh.vertices)
cloud.normals = mesh.vertex_normals
cloud.colors = mesh.vertex_colors
for name, ascii_, compressed in (("o3d_cloud_bin.ply", False, False), ("o3d_cloud_ascii.ply", True, False),
                                 ("o3d_cloud.xyz", True, False), ("o3d_cloud_ascii.pcd", True, False),
                                 ("o3d_cloud_bin.pcd", False, False), ("o3d_cloud_lzf.pcd", False, True)):
    must(io.write_point_cloud(os.path.join(out, name), cloud, write_ascii=ascii_, compressed=compressed), name)
print(f"open3d_write.py: {len(mesh.vertices)} vertices, {len(mesh.triangles)} triangles")
