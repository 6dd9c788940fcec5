#!/usr/bin/env bash
# Tests under AddressSanitizer + UndefinedBehaviorSanitizer (-DSPECULA_SANITIZE=ON,
# cmake/SpeculaSanitize.cmake) in build-asan/. CI runs the default, a subset that fits its
# time (.ci/run); `--all` builds everything and runs the whole suite.
#
# The subset: the code that reads what a user hands Specula and the code every ray goes
# through: core (JSON guards, image decoding, file writes, output folders), capture
# (capture.json, meshes and glTF), geometry (atlas, particles, RayScene's ray checks),
# visibility, the indirect light's transfer, and export (the bundle reader and writer); and the
# Vulkan layer with the conformance tests of its kernels: gpu (buffers, dispatch splitting,
# synchronization), material, metrics and the image-metrics, diffuse-solve, residual,
# factorization, indirect-gather and directed-lobe kernels against their C++ references. Left to `--all`: the solves' own tests, the renderer,
# the pipeline and the command-line tests. The whole suite passes under the sanitizers, but
# it takes about 16 minutes to build and 20 to 33 to run on 2 cores, which CI's 45 minutes
# cannot hold beside the plain suite (docs/pipeline.md section 17 has the figures).
#
# Fails on a failed test and on any sanitizer report, also one from a process whose exit
# status no test checks: the runtimes write their reports into build-asan/sanitizer-logs/
# (log_path), which must stay empty; the reports are printed at the end.
# Compiled at -O1 -g1 (line tables: reports still name file and line): capture.cpp takes 38 s
# of CPU there against 87 s at RelWithDebInfo's -O2 -g (21 s in Release without sanitizers).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${SPECULA_SANITIZE_BUILD_DIR:-$root/build-asan} # the folder: SPECULA_SANITIZE_BUILD_DIR overrides
tests=(core_tests capture_tests geometry_tests visibility_tests indirect_tests export_tests gpu_tests material_tests
  metrics_tests image_metrics_kernel_tests lambert_solve_kernel_tests residuals_kernel_tests factorization_kernel_tests
  indirect_gather_kernel_tests indirect_lobe_kernel_tests pixel_fit_tests)
targets=("${tests[@]}")
regex="^($(IFS='|'; echo "${tests[*]}"))\\."
if [ "${1:-}" = "--all" ]; then
  targets=(all)
  regex=
fi

cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" -DSPECULA_SANITIZE=ON >/dev/null
cmake --build "$build" --parallel "$(nproc)" --target "${targets[@]}"

logs=$build/sanitizer-logs
rm -rf "$logs"
mkdir -p "$logs"
export ASAN_OPTIONS="log_path=$logs/asan${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
export UBSAN_OPTIONS="log_path=$logs/ubsan${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"
status=0
ctest --test-dir "$build" --output-on-failure --parallel "$(nproc)" --timeout 900 ${regex:+-R "$regex"} || status=$?
if compgen -G "$logs/*" >/dev/null; then
  echo "run-sanitized-tests: sanitizer reports (each fails the run):" >&2
  for f in "$logs"/*; do
    echo "== $f" >&2
    cat "$f" >&2
  done
  status=1
fi
exit "$status"
