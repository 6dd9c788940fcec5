#!/usr/bin/env bash
# Installs everything Specula needs to build, test and run on Debian 12 (bookworm).
# Run as root (or with sudo). Idempotent: re-running installs nothing new.
set -euo pipefail
if [ "$(id -u)" -ne 0 ]; then SUDO=sudo; else SUDO=; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends \
  build-essential cmake ninja-build pkg-config git \
  libvulkan-dev vulkan-validationlayers mesa-vulkan-drivers vulkan-tools \
  glslang-tools glslang-dev spirv-tools \
  libglm-dev libeigen3-dev libembree-dev libopenimageio-dev openimageio-tools \
  libtinygltf-dev nlohmann-json3-dev libcli11-dev libgtest-dev libgmock-dev libbenchmark-dev \
  libglfw3-dev xvfb xauth >/dev/null
echo "install-deps: done"
