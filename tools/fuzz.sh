#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ with clang into build-fuzz/, writes their seed corpus,
# and runs each target for a bounded time with a 2 GB memory limit and a 10 s limit per input.
#   tools/fuzz.sh [SECONDS_PER_TARGET]     (default 60)
#   tools/fuzz.sh --seeds                  each target over its seed corpus once, no mutation
#                                          (deterministic: CI's check that the targets build and run)
# The growing corpus is kept in build-fuzz/corpus/<target>/ between runs; an input that crashes,
# leaks, times out or runs out of memory is written to build-fuzz/findings/<target>/ and the
# script exits with status 1. Needs clang and libFuzzer (Debian: clang-14 libclang-rt-14-dev,
# installed by tools/install-deps.sh); SPECULA_FUZZ_CXX picks another clang++.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=${1:-60}
limit=(-max_total_time="$seconds")
if [ "$seconds" = "--seeds" ]; then limit=(-runs=0); fi
cxx=${SPECULA_FUZZ_CXX:-$(command -v clang++-14 || command -v clang++ || true)}
if [ -z "$cxx" ]; then
  echo "fuzz.sh: clang++ not found (apt install clang-14 libclang-rt-14-dev)" >&2
  exit 2
fi
build="$root/build-fuzz"
launcher=()
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
cmake -S "$root/fuzz" -B "$build" -G Ninja -DCMAKE_CXX_COMPILER="$cxx" "${launcher[@]}" >/dev/null
cmake --build "$build" --parallel "$(nproc)"
rm -rf "$build/seeds"
"$build/make_seeds" "$build/seeds"

status=0
for target in capture_json gltf_mesh bundle image_decode; do
  mkdir -p "$build/corpus/$target" "$build/findings/$target"
  extra=()
  if [ "$target" = capture_json ]; then extra=(-dict="$root/fuzz/capture.dict"); fi
  echo "fuzz.sh: fuzz_$target ${limit[*]}"
  # close_fd_mask=3: the libraries' own chatter (libpng errors) is dropped; libFuzzer and the
  # sanitizers still report on a duplicate of stderr.
  if ! "$build/fuzz_$target" "$build/corpus/$target" "$build/seeds/$target" "${extra[@]}" \
      "${limit[@]}" -rss_limit_mb=2048 -timeout=10 -close_fd_mask=3 -print_final_stats=1 \
      -artifact_prefix="$build/findings/$target/" 2>"$build/fuzz_$target.log"; then
    echo "fuzz.sh: fuzz_$target found a failure; the input is in $build/findings/$target/, the log in $build/fuzz_$target.log" >&2
    tail -40 "$build/fuzz_$target.log" >&2
    status=1
  else
    grep -E "stat::number_of_executed_units|stat::average_exec_per_sec|stat::peak_rss_mb" "$build/fuzz_$target.log" | sed "s/^/  /"
  fi
done
exit $status
