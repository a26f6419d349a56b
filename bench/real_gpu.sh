#!/usr/bin/env bash
# The real-GPU figures of the README, in one run: `hooke bench --backend gpu` over the grids and
# the irregular mesh on Vulkan, with and without self-collision, then the NVIDIA Warp peer
# (bench/warp_peer.py, CUDA) on the same workload, after checking that hooke's GPU and Warp step
# the same grid to the same state.
#
#   bench/real_gpu.sh HOOKE_BINARY OUT_DIR [SIZES [WARP_PEER_OPTIONS...]]
#
# Needs a Vulkan driver for the GPU (WGPU_BACKEND=vulkan is set here) and `import warp` to work.
# Every table also goes to OUT_DIR. GPU_METHODS picks hooke's methods (default: those Warp has a
# peer for; the paper's blend paths take over a minute at 2048^2 on an H200).
set -euo pipefail
hooke=$1
out=$2
sizes=${3:-128,256,512,1024,2048}
shift $(($# < 3 ? $# : 3))
mkdir -p "$out"
export WGPU_BACKEND=vulkan
here=$(cd "$(dirname "$0")" && pwd)
scenes=$here/../scenes
work=$(mktemp -d)

nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.sm,clocks.max.sm,clocks.mem \
  --format=csv | tee "$out/nvidia-smi.csv" || true

echo "== hooke bench --backend gpu"
"$hooke" bench --backend gpu --gpu-methods "${GPU_METHODS:-gather,atomic-f32,incidence}" \
  --sizes "$sizes" --irregular 65536 --shuffled 0 --steps 200 --rounds 3 --warmup 20 2>&1 |
  tee "$out/hooke-gpu.txt"

echo "== hooke bench --backend gpu --self-collision 4"
"$hooke" bench --backend gpu --gpu-methods gather --sizes "$sizes" --irregular 65536 \
  --shuffled 0 --self-collision 4 --steps 100 --rounds 3 --warmup 20 2>&1 |
  tee "$out/hooke-gpu-self-collision.txt"

if ! python3 -c "import warp" 2>/dev/null; then
  echo "== no warp peer: python3 cannot import warp (see docs/performance-log.md)" >&2
  exit 1
fi

echo "== the same grid on hooke's GPU and in Warp"
"$hooke" run "$scenes/bench-grid-128.toml" --backend gpu --method gather --steps 100 \
  --no-frames --output "$work/grid-128" >/dev/null
# The bench's irregular mesh as hooke builds it, for the peer to read.
"$hooke" run "$scenes/bench-irregular.toml" --steps 0 --allow-unstable --no-frames \
  --output "$work/irregular-65536" >/dev/null

echo "== warp peer"
python3 "$here/warp_peer.py" --sizes "$sizes" --mesh "$work/irregular-65536/final-state.ply" \
  --compare "$work/grid-128/final-state.ply" --steps 300 --repeats 5 "$@" 2>&1 | tee "$out/warp.txt"
rm -rf "$work"
