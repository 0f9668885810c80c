#!/bin/bash
# Scans written by real tools give the same defects as the scan they were made from.
# A synthetic door (dentmark synth scan) is written by PCL (pcl_converter: PLY, OBJ, STL,
# PCD in each encoding; pcl_convert_pcd_ascii_binary: an organised PCD with NaN holes in
# each encoding; pcl_mesh_sampling: a cloud sampled off the mesh), by Open3D (meshes
# and clouds in every format it writes), by CloudCompare (meshes as PLY, OBJ, STL; its
# vertices as an ASC and a PLY cloud; headless on Qt's offscreen platform) and by MeshLab
# (meshlabserver: PLY, OBJ, STL with normals, under xvfb-run: it needs an OpenGL
# context); each file is read by 'dentmark detect' and its defects compared with the
# original's (same_defects.py).
# A tool that is missing fails the test: scripts/setup-deps installs pcl-tools,
# python3-open3d, cloudcompare, meshlab and xvfb.
# Usage: run.sh DENTMARK OUTDIR
set -euo pipefail
dentmark=$1
out=$2
here=$(cd "$(dirname "$0")" && pwd)
py=/usr/bin/python3
for tool in pcl_converter pcl_convert_pcd_ascii_binary pcl_mesh_sampling CloudCompare meshlabserver xvfb-run; do
  command -v $tool >/dev/null ||
    { echo "FAIL: $tool not found (scripts/setup-deps installs pcl-tools, cloudcompare, meshlab, xvfb)"; exit 1; }
done
$py -c 'import open3d' 2>/dev/null || { echo "FAIL: no Open3D for $py (scripts/setup-deps installs python3-open3d)"; exit 1; }

rm -rf "$out" && mkdir -p "$out" && cd "$out"
"$dentmark" synth scan --out door.ply --truth truth.json --width 0.3 --height 0.25 --spacing 0.001 --defects 3 \
  --min-diameter 0.012 --max-diameter 0.025 --min-depth 0.0002 --max-depth 0.0005 \
  --seed 5 >/dev/null
"$dentmark" detect door.ply --out door.dml --json door.json >/dev/null
n=$($py -c 'import json; print(len(json.load(open("door.json"))["defects"]))')
[[ $n -ge 3 ]] || { echo "FAIL: the original scan gives $n defects (3 planted)"; exit 1; }

# PCL. (Its tools print progress to stdout; kept in logs.)
for f in pcd:binary pcd:ascii pcd:binary_compressed ply:binary ply:ascii obj:ascii stl:binary stl:ascii; do
  ext=${f%%:*} enc=${f#*:}
  pcl_converter -f "$enc" door.ply "pcl_${enc}.$ext" >>pcl.log 2>&1
done
$py "$here/organise.py" door.ply organised_ascii.pcd >>pcl.log
pcl_convert_pcd_ascii_binary organised_ascii.pcd organised_bin.pcd 1 >>pcl.log 2>&1
pcl_convert_pcd_ascii_binary organised_ascii.pcd organised_lzf.pcd 2 >>pcl.log 2>&1
# Dense enough to keep the 1 mm spacing: a 0.5 mm voxel grid over 1.5 M samples.
pcl_mesh_sampling door.ply sampled.pcd -n_samples 1500000 -leaf_size 0.0005 -write_normals -no_vis_result \
  >>pcl.log 2>&1
# Open3D.
$py "$here/open3d_write.py" door.ply . >>open3d.log
# CloudCompare.
for fmt in PLY OBJ STL; do
  QT_QPA_PLATFORM=offscreen CloudCompare -SILENT -NO_TIMESTAMP -O door.ply -M_EXPORT_FMT $fmt \
    -SAVE_MESHES FILE "cc_mesh.${fmt,,}" >>cloudcompare.log 2>&1
done
for fmt in ASC PLY; do
  QT_QPA_PLATFORM=offscreen CloudCompare -SILENT -NO_TIMESTAMP -O door.ply -EXTRACT_VERTICES -C_EXPORT_FMT $fmt \
    -SAVE_CLOUDS FILE "cc_cloud.${fmt,,}" >>cloudcompare.log 2>&1
done
# MeshLab.
for ext in ply obj stl; do
  xvfb-run -a meshlabserver -i door.ply -o "ml_mesh.$ext" -m vn >>meshlab.log 2>&1
done

grep -q '^HEIGHT 1$' organised_lzf.pcd && { echo "FAIL: organised_lzf.pcd is not organised"; exit 1; }
grep -q '^DATA binary_compressed' organised_lzf.pcd || { echo "FAIL: organised_lzf.pcd not compressed"; exit 1; }
failed=0
for f in pcl_*.{pcd,ply,obj,stl} organised_*.pcd sampled.pcd o3d_*.{ply,obj,stl,xyz,pcd} cc_*.{ply,obj,stl,asc} \
  ml_*.{ply,obj,stl}; do
  [[ -f $f ]] || { echo "FAIL: $f was not written"; failed=1; continue; }
  if ! "$dentmark" detect "$f" --out "$f.dml" --json "$f.json" >"$f.log" 2>&1; then
    echo "FAIL: $f: $(tail -1 "$f.log")"
    failed=1
    continue
  fi
  $py "$here/same_defects.py" door.json "$f.json" || failed=1
done
exit $failed
