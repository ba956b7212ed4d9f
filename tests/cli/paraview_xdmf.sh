#!/usr/bin/env bash
# ParaView opens every kind of XDMF bsms writes, in each of its three XDMF readers (XDMFReader,
# Xdmf3ReaderS, Xdmf3ReaderT), without an error or warning line and without crashing, with the
# HDF5 source's point and cell counts, time steps, one point's coordinates and one node field's
# value (paraview_xdmf.py). Kinds: bsms datasets (2-D disks and 3-D bodies, exported to another
# folder), rollouts (a
# 3-step run rolled out, Lagrangian, and one on cylinder_flow, Eulerian), the MeshGraphNets
# fixtures exported (cylinder_flow and airfoil: Eulerian, fixed mesh; deforming_plate: 3-D
# tetrahedra; flag_simple: cloth, 2-D mesh in 3-D) and the solver's particle frames (bsms
# simulate, 2-D and 3-D Polyvertex).
#
#   paraview_xdmf.sh BSMS SRC WORK
#
# Needs ParaView's pvbatch (not installed by `make deps`; Debian: apt-get install paraview
# python3-paraview python3-h5py) and runs `pvbatch --force-offscreen-rendering paraview_xdmf.py`
# per file and reader. Without pvbatch or h5py it prints why and exits 77 (ctest: skipped).
set -u
bsms=$1 src=$2 work=$3
here=$(cd "$(dirname "$0")" && pwd)

if ! command -v pvbatch >/dev/null 2>&1; then
  echo "SKIP: pvbatch not found (ParaView is not installed; apt-get install paraview python3-paraview)"
  exit 77
fi
probe=$(mktemp)
printf 'import h5py, numpy\n' >"$probe"
if ! pvbatch --force-offscreen-rendering "$probe" >/dev/null 2>&1; then
  rm -f "$probe"
  echo "SKIP: pvbatch's Python cannot import h5py and numpy (apt-get install python3-h5py)"
  exit 77
fi
rm -f "$probe"

set -e
rm -rf "$work"
mkdir -p "$work"
cd "$work"
export OMP_WAIT_POLICY=PASSIVE
fixtures=$src/tests/fixtures/meshgraphnets
quiet() { "$@" >/dev/null 2>log.txt || { cat log.txt >&2; echo "FAIL: $*" >&2; exit 1; }; }

# A tiny bsms dataset, a run trained 3 steps on it and its rollout (as tests/cli/bad_input.sh).
quiet "$bsms" generate "$src/configs/families/disks2d.json" --out data --trajectories 3 \
  --split 1:1:1 --set frames=6 --set 'sample.count=[2,2]' --threads 1
quiet "$bsms" export data/train.h5 --xdmf --out bsms_view
# A 3-D dataset of the bodies family (tetrahedra of spheres and boxes), one small, soft
# trajectory (its bodies must meet, so it keeps the family's duration).
quiet "$bsms" generate "$src/configs/families/bodies3d.json" --out bodies --trajectories 1 \
  --split 0:0:1 --set sample.count=2 --set 'sample.nodes=[550, 800]' \
  --set sample.material.youngs_modulus=20000 --set scene.background.element_size=0.1 --threads 1
quiet "$bsms" export bodies/test.h5 --xdmf --out bodies_view
printf '{"data": "%s", "steps": 3, "valid_every": 2, "valid_samples": 2, "normalizer_steps": 2, "model": {"type": "bsms", "latent": 8, "levels": 2}, "optimizer": {"warmup_steps": 1}}\n' \
  "$work/data" >run.json
quiet "$bsms" train run.json --out run --threads 1
quiet "$bsms" rollout run --threads 1
# An Eulerian rollout: a BSMS run trained 3 steps on a copy of the cylinder_flow fixture (training
# caches graphs beside its data), rolled out on 5 steps of one test trajectory.
cp -r "$fixtures/cylinder_flow" cylinder_data
quiet "$bsms" train "$src/configs/train/cylinder-bsms.json" --set data="$work/cylinder_data" \
  --set steps=3 --set valid_every=2 --set valid_samples=1 --set normalizer_steps=2 \
  --set model.latent=8 --out run_cylinder --threads 1
quiet "$bsms" rollout run_cylinder --max-trajectories 1 --max-steps 5 --threads 1
for name in cylinder_flow airfoil deforming_plate flag_simple; do
  quiet "$bsms" export "$fixtures/$name" --xdmf --split train --trajectory 0 --out "mgn_$name"
done
quiet "$bsms" simulate "$src/configs/scenes/rotating_square.json" --out frames2d --threads 1 \
  --set background.element_size=0.05 --set solver.dt=1e-4 --set solver.end_time=0.003 \
  --set output.frames=4
quiet "$bsms" simulate "$src/configs/scenes/sphere_expansion.json" --out frames3d --threads 1 \
  --set solver.end_time=0.002 --set output.frames=3

# xdmf | kind | HDF5 source | field
cases=(
  "bsms_view/train_000000.xdmf dataset data/train.h5 velocity"
  "bodies_view/test_000000.xdmf dataset bodies/test.h5 velocity"
  "run/rollout/test_000000.xdmf dataset run/rollout/test.h5 target_world_pos"
  "run_cylinder/rollout/test_000000.xdmf dataset run_cylinder/rollout/test.h5 velocity"
  "mgn_cylinder_flow/train_000000.xdmf dataset mgn_cylinder_flow/train_000000.h5 velocity"
  "mgn_airfoil/train_000000.xdmf dataset mgn_airfoil/train_000000.h5 density"
  "mgn_deforming_plate/train_000000.xdmf dataset mgn_deforming_plate/train_000000.h5 stress"
  "mgn_flag_simple/train_000000.xdmf dataset mgn_flag_simple/train_000000.h5 node_type"
  "frames2d/frames.xdmf frames frames2d/frames.h5 velocity"
  "frames3d/frames.xdmf frames frames3d/frames.h5 velocity"
)
failed=0
for c in "${cases[@]}"; do
  read -r xdmf kind h5 field <<<"$c"
  for reader in XDMFReader Xdmf3ReaderS Xdmf3ReaderT; do
    status=0
    line=$(pvbatch --force-offscreen-rendering "$here/paraview_xdmf.py" "$reader" "$xdmf" "$kind" \
      "$h5" "$field" 2>stderr.txt) || status=$?
    # Any complaint of a reader or a crash fails the case (ParaView prints nothing else here).
    complaints=$(sed 's/\x1b\[[0-9;]*m//g' stderr.txt |
      grep -Ei 'err|warn|cannot|unable|segv|signal|abort|traceback|skipping' || true)
    if [[ $status -ne 0 || -n $complaints ]]; then
      echo "FAIL $xdmf in $reader (exit $status): ${line:-no result}"
      [[ -n $complaints ]] && printf '  %s\n' "$complaints" | head -5
      failed=1
    else
      echo "$line"
    fi
  done
done
exit $failed
