#!/usr/bin/env bash
# The whole test suite: installs dependencies, builds, runs every test on lavapipe
# (the CPU Vulkan driver) with the Khronos validation layer on. CI runs exactly this.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$root/tools/install-deps.sh"
"$root/tools/build.sh"
cd "$root/build"
ctest --output-on-failure --parallel "$(nproc)" --timeout 900
