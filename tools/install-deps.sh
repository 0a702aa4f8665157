#!/usr/bin/env bash
# Installs every build, test and tool dependency from Debian packages.
# Idempotent and non-interactive: packages already present are not touched, and
# apt-get runs only when something is missing. Needs root (or sudo).
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev          # dense/sparse linear algebra (offline model compiler)
  libspectra-dev         # sparse eigen-solver (modal analysis)
  libsuitesparse-dev     # CHOLMOD sparse Cholesky (precompute)
  libopenblas0-pthread   # optimised BLAS behind CHOLMOD: tensor precompute 1.7x faster than reference BLAS
  libxxhash-dev          # xxHash64 integrity check of model images (and the recording's state hash)
  libzstd-dev zlib1g-dev # session recordings: zstd chunk compression, CRC-32 (rt/record)
  libusb-1.0-0-dev       # USB device backend
  libgpiod-dev           # GPIO lines backend (libgpiod v1 API on Debian 12)
  libsystemd-dev         # sd_notify: READY/WATCHDOG/STOPPING of the trainer service (rt/appliance)
  libtomlplusplus-dev    # TOML parser for scene/device files
  libcli11-dev           # command-line parser
  nlohmann-json3-dev     # JSON reports
  libgtest-dev libgmock-dev   # unit tests
  libbenchmark-dev       # benchmarks
  rt-tests               # cyclictest, the timing reference
  gnuplot-nox            # PNG plots of the tradeoff and jitter tools
  qemu-system-x86        # the bench VM (tools/benchvm): QEMU TCG boots the Debian RT kernel
  busybox-static         # the bench VM's initramfs: /init's shell, insmod, mount, cpio archive
  xz-utils               # the bench VM: vmlinux from the kernel package's xz-compressed bzImage
  can-utils              # candump/cansend/cangw in the bench VM's CAN tests (run from the host root)
  iproute2               # ip: vcan links in the bench VM's CAN tests
  clang-format clang-tidy
  clang libclang-rt-14-dev   # the fuzz preset: clang++ and its libFuzzer/ASan/UBSan runtimes
  libcivetweb-dev        # the viewer's HTTP + WebSocket server (tools/viewer)
  chromium               # headless browser of the viewer's page test (tools/viewer, puppeteer-core)
)
# The viewer's page is bundled at build time from npm (three.js, esbuild): Debian's nodejs and
# npm (18.x and 9.x on Debian 12), unless a node with npm is already installed (e.g.
# NodeSource's nodejs, which carries its own npm and conflicts with Debian's npm package).
if ! command -v npm >/dev/null 2>&1; then
  packages+=(nodejs npm)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
"${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"
