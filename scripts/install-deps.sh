#!/usr/bin/env bash
# Installs every build and test dependency of mcslam: Debian 12 packages, and the npm packages of
# the bench report's page (web/report, versions pinned by its package-lock.json).
# Idempotent: what is already present is left alone. Nothing else is downloaded.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev
  libopencv-dev libopencv-contrib-dev
  libceres-dev
  libcli11-dev
  libspdlog-dev libfmt-dev
  nlohmann-json3-dev
  liboctomap-dev  # the dense occupancy map (src/mapping: OctoMap's log-odds octree, ray casting)
  libsqlite3-dev liblz4-dev libzstd-dev  # ROS 2 recordings: sqlite3 storage, MCAP chunks, rosbag2 zstd
  libboost-dev  # Boost.Beast (header-only): the live viewer's HTTP and WebSocket server
  libgtest-dev libgmock-dev
  libbenchmark-dev
  clang-format
  clang libclang-rt-14-dev  # libFuzzer and the sanitizers of the fuzz preset (scripts/fuzz.sh)
  python3
  # the Python bindings (python/: pybind11, numpy), their tests and the plotting example
  pybind11-dev python3-dev python3-numpy python3-pytest python3-matplotlib
  chromium  # headless browser test of report.html
  # ROS 1 (the optional ros module: bags, `mcslam ros`; roscore for its test)
  libroscpp-dev librosbag-storage-dev libmessage-filters-dev libtf2-ros-dev libtf2-msgs-dev
  libsensor-msgs-dev libgeometry-msgs-dev libnav-msgs-dev libstd-msgs-dev libvisualization-msgs-dev
  pluginlib-dev librcpputils-dev libament-index-cpp-dev  # included by rosbag/bag.h
  python3-roslaunch python3-rosmaster rosout
  # Slurm 22.05 (slurmctld, slurmd, sbatch, squeue, sacct) and munge: the one-node cluster the
  # test of `mcslam bench --executor slurm` starts on 127.0.0.1 (mcslam links nothing of them)
  slurm-wlm munge
)
# Node.js and npm bundle the report's scripts: Debian's, unless a Node.js with npm is already
# installed (a newer one from elsewhere would conflict with Debian's npm package).
if ! command -v npm > /dev/null 2>&1; then PACKAGES+=(nodejs npm); fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} Debian packages present"
else
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  echo "install-deps: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# The report's npm packages, exactly as package-lock.json pins them; reinstalled when it changes.
web=web/report
stamp=$web/node_modules/.mcslam-installed-lock
if [ -f "$stamp" ] && cmp -s "$web/package-lock.json" "$stamp"; then
  echo "install-deps: report npm packages present"
else
  echo "install-deps: installing the report's npm packages (npm ci in $web)"
  (cd "$web" && npm ci --no-audit --no-fund --loglevel=error)
  cp "$web/package-lock.json" "$stamp"
fi
