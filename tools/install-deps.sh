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
  libtinygltf-dev nlohmann-json3-dev libcli11-dev libgtest-dev libgmock-dev libmeshoptimizer-dev \
  libglfw3-dev xvfb xauth xdotool \
  clang-14 libclang-rt-14-dev >/dev/null
# (clang-14 and its compiler-rt: libFuzzer and the sanitizer runtimes for tools/fuzz.sh.)
# Node.js for the glTF validator: Debian's packages, unless a Node.js with npm is already
# there (e.g. NodeSource's nodejs, which bundles npm and conflicts with Debian's npm package).
if ! command -v npm >/dev/null 2>&1; then
  $SUDO apt-get install -y -qq --no-install-recommends nodejs npm >/dev/null
fi
# The Khronos glTF validator (a JS library compiled from the Dart validator), for
# tools/gltf-validate.js and the bundle test (export_tests.Bundle.KhronosValidatorReportsNoErrors).
# Pinned; installed globally, outside the source tree. Idempotent: skipped when present.
GLTF_VALIDATOR_VERSION=2.0.0-dev.3.10
# The version of a globally installed npm package (empty when absent).
npm_global_version() { node -p "require('$(npm root -g)/$1/package.json').version" 2>/dev/null || true; }
if [ "$(npm_global_version gltf-validator)" != "$GLTF_VALIDATOR_VERSION" ]; then
  $SUDO npm install -g --no-audit --no-fund "gltf-validator@${GLTF_VALIDATOR_VERSION}" >/dev/null ||
    echo "install-deps: warning: could not install gltf-validator from npm; the bundle validator test will be skipped" >&2
fi
# The browser check (tests/browser, tools/threejs-render.mjs): Debian's Chromium, and three.js and
# puppeteer-core from npm, pinned, installed globally like the validator. A missing one makes the
# browser test skip with the reason, not fail.
$SUDO apt-get install -y -qq --no-install-recommends chromium >/dev/null ||
  echo "install-deps: warning: could not install chromium; the browser test will be skipped" >&2
THREE_VERSION=0.187.0
PUPPETEER_CORE_VERSION=24.43.1
for pkg in "three@${THREE_VERSION}" "puppeteer-core@${PUPPETEER_CORE_VERSION}"; do
  if [ "$(npm_global_version "${pkg%@*}")" != "${pkg##*@}" ]; then
    $SUDO npm install -g --no-audit --no-fund "$pkg" >/dev/null ||
      echo "install-deps: warning: could not install $pkg from npm; the browser test will be skipped" >&2
  fi
done
# The Blender check (tests/browser/blender_check.sh, tools/blender-import.py): Debian's Blender and the
# numpy its glTF importer needs. Without them that test skips with the reason.
$SUDO apt-get install -y -qq --no-install-recommends blender python3-numpy >/dev/null ||
  echo "install-deps: warning: could not install blender; the Blender import test will be skipped" >&2
echo "install-deps: done"
