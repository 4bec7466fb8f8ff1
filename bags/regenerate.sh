#!/usr/bin/env bash
# Regenerates the small scene bags committed here (32^3 voxels), both encodings.
#   bash bags/regenerate.sh
# The default-size scenes (machine-tool 128^3 x 64) are benchmarks: generate them with
#   cargo run --release -- scene machine-tool --out /tmp/machine-tool-128.mcap
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
bin=target/release/chronotope
for enc in bits percent; do
  $bin scene machine-tool --grid 32 --frames 16 --encoding $enc --out bags/machine-tool-32-$enc.mcap
  $bin scene four-spheres --grid 32 --frames 17 --encoding $enc --out bags/four-spheres-32-$enc.mcap
done
$bin scene carving-session --out bags/carving-session.mcap
# A six-axis arm recorded the ROS way (robot description, joint states, /tf_static) beside a
# machine-tool table's frames: replayed with launch_configs/robot_cell.yaml.
$bin scene robot-cell --grid 32 --out bags/robot-cell-32.mcap
$bin scene person-cell --grid 32 --frames 16 --out bags/person-cell-32.mcap
# The golden replay reports and output-bag digests follow the bags:
#   CHRONOTOPE_BLESS=1 cargo test --test golden
