#!/usr/bin/env bash
# Outputs that never lie (issue 21 item 4), end to end on `specula reconstruct`:
#   output_safety.sh kill       SPECULA WORK   kill -9 at several moments of a run into an
#       existing OUT: OUT is afterwards byte-identical to before (every file's SHA-256), or
#       complete and new (the file list of a complete run with the new settings and a report
#       of them); the next run removes what the killed ones left beside OUT.
#   output_safety.sh concurrent SPECULA WORK   a second run on the OUT a first one is writing
#       is refused at once, naming OUT and the first run's pid; the first completes.
#   output_safety.sh readonly   SPECULA WORK   an OUT on a read-only mount (a tmpfs mounted
#       read-only in a private mount namespace: unshare -m, as root) is refused before any
#       stage starts. Exits 77 (skipped) where no such mount can be made.
# Each case writes its small synthetic capture into WORK (replaced).
set -euo pipefail
mode=$1
specula=$2
work=$3
rm -rf "$work"
mkdir -p "$work"
cap=$work/cap
out=$work/out

fail() {
  echo "FAIL: $*" >&2
  exit 1
}
# "SHA-256  ./path" of every file below $1, sorted by path.
hashes() { (cd "$1" && find . -type f -print0 | sort -z | xargs -0 -r sha256sum); }
files() { (cd "$1" && find . -type f | sort); }
now() { date +%s.%N; }
calc() { awk "BEGIN { print ($1) }"; }
# Everything beside OUT other than the capture, OUT and the reference: what killed runs left.
leftovers() { (cd "$work" && find . -mindepth 1 -maxdepth 1 ! -name cap ! -name out ! -name ref ! -name pristine | sort); }

"$specula" -q synth --preset can --size 64 --views 4 --lights 3 --out "$cap"

case $mode in
kill)
  # The previous result: default settings. The new runs: --specular off (another bundle: no
  # lobe), so a new result is told from the old one by its report, not only by timings.
  "$specula" -q reconstruct "$cap" -o "$out"
  cp -a "$out" "$work/pristine"
  start=$(now)
  "$specula" -q reconstruct "$cap" -o "$work/ref" --specular off
  run_s=$(calc "$(now) - $start")
  echo "a complete run with the new settings takes $run_s s"
  ref_files=$(files "$work/ref")
  old_hashes=$(hashes "$work/pristine")
  # 0.5, 1.5 and 3 s in, and around the end of a run (the commit is the last thing it does).
  delays="0.5 1.5 3"
  for back in 0.6 0.3 0.15 0.05 0.0; do
    d=$(calc "$run_s - $back")
    if [ "$(calc "$d > 0.2")" = 1 ]; then delays="$delays $d"; fi
  done
  kept=0
  replaced=0
  for d in $delays; do
    rm -rf "$out"
    cp -a "$work/pristine" "$out"
    "$specula" -q reconstruct "$cap" -o "$out" --specular off &
    pid=$!
    sleep "$d"
    kill -9 "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
    [ -d "$out" ] || fail "kill after $d s: OUT is missing"
    if [ "$(hashes "$out")" = "$old_hashes" ]; then
      echo "kill after $d s: OUT byte-identical to before"
      kept=$((kept + 1))
    else
      [ "$(files "$out")" = "$ref_files" ] || fail "kill after $d s: OUT changed but is not a complete result: $(files "$out" | tr '\n' ' ')"
      grep -q '"specula_version"' "$out/report.json" || fail "kill after $d s: report.json is not a report"
      grep -q '"has_lobe": false' "$out/report.json" ||
        fail "kill after $d s: OUT is complete but its report is not the new run's (--specular off: no lobe)"
      echo "kill after $d s: OUT complete and new"
      replaced=$((replaced + 1))
    fi
  done
  echo "leftovers of the killed runs: $(leftovers | tr '\n' ' ')"
  # The next run (not killed) completes and removes them.
  "$specula" -q reconstruct "$cap" -o "$out" --specular off
  [ -z "$(leftovers)" ] || fail "the run after the kills left: $(leftovers | tr '\n' ' ')"
  [ "$(files "$out")" = "$ref_files" ] || fail "the run after the kills is not complete"
  echo "kills: $kept left OUT as it was, $replaced found it complete and new; the next run cleaned up"
  [ "$kept" -ge 1 ] || fail "no kill landed before the end of a run (the delays are too long for this machine?)"
  ;;
concurrent)
  "$specula" -q reconstruct "$cap" -o "$out" &
  first=$!
  for _ in $(seq 1 200); do
    [ -e "$work/.out.lock" ] && break
    sleep 0.05
  done
  [ -e "$work/.out.lock" ] || fail "the first run took no lock"
  set +e
  second=$("$specula" reconstruct "$cap" -o "$out" 2>&1)
  rc=$?
  set -e
  echo "$second"
  [ "$rc" -eq 1 ] || fail "the second run exited $rc, not 1"
  echo "$second" | grep -q "$out: --out: another specula run (pid $first) is writing this output folder" ||
    fail "the second run's message does not name OUT and the first run"
  if echo "$second" | grep -q '\[load\]'; then fail "the second run started work"; fi
  wait "$first" || fail "the first run failed"
  grep -q '"specula_version"' "$out/report.json" || fail "the first run's result is incomplete"
  [ -z "$(leftovers)" ] || fail "left beside OUT: $(leftovers | tr '\n' ' ')"
  echo "second run refused; the first completed"
  ;;
readonly)
  mkdir -p "$work/ro"
  set +e
  msg=$(unshare -m sh -c 'mount -t tmpfs -o ro tmpfs "$1" || exit 77; exec "$2" reconstruct "$3" -o "$1/out"' sh \
    "$work/ro" "$specula" "$cap" 2>&1)
  rc=$?
  set -e
  echo "$msg"
  if [ "$rc" -eq 77 ] || echo "$msg" | grep -q "unshare: "; then
    echo "no read-only mount can be made here: skipped"
    exit 77
  fi
  [ "$rc" -eq 1 ] || fail "exit status $rc, not 1"
  echo "$msg" | grep -q "ro/out: --out: cannot create the output folder here (.*Read-only file system)" ||
    fail "the message does not say the mount is read-only"
  if echo "$msg" | grep -q '\[load\]'; then fail "the run started work"; fi
  ;;
*)
  fail "unknown mode $mode"
  ;;
esac
