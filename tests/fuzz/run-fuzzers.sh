#!/usr/bin/env bash
# Builds the libFuzzer harnesses (the `fuzz` CMake preset: clang, ASan + UBSan), makes their seed
# corpora and runs each harness for a while, one after the other on one core each.
#
#   tests/fuzz/run-fuzzers.sh [--seconds N] [HARNESS...]
#
# HARNESS: klv, ingest, mission (default: all three). N: seconds per harness (default 60; CI
# smoke runs use about 20). Seeds are made at every run into build/fuzz/corpus/<harness>/ from
# the shared data folder ($SAKER_TEST_DATA, else ../shared/data beside the source tree: KLV
# streams, MISB example packets, the real EO clip) and from the simulator; the corpus directories
# keep what earlier runs found. Findings (crash-*, timeout-*, oom-*, leak-*) go to
# build/fuzz/artifacts/<harness>/; reproduce one with `build/fuzz/tests/fuzz/fuzz_<harness> FILE`.
# Exit status: 0 when no harness found anything, 1 when one did, 2 on a usage or build error.
set -euo pipefail

usage() {
  sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
}

seconds=60
harnesses=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --seconds)
      [[ $# -ge 2 && "$2" =~ ^[0-9]+$ && "$2" -gt 0 ]] || { echo "--seconds needs a positive integer" >&2; exit 2; }
      seconds="$2"
      shift 2
      ;;
    -h | --help) usage ;;
    klv | ingest | mission)
      harnesses+=("$1")
      shift
      ;;
    *)
      echo "unknown argument '$1' (harnesses: klv ingest mission)" >&2
      exit 2
      ;;
  esac
done
[[ ${#harnesses[@]} -gt 0 ]] || harnesses=(klv ingest mission)

source_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build_dir="$source_dir/build/fuzz"
fuzz_bin="$build_dir/tests/fuzz"
cd "$source_dir"

# --- Build -------------------------------------------------------------------------------------
if [[ ! -f "$build_dir/CMakeCache.txt" ]]; then
  echo "== configuring the fuzz preset (clang, ASan + UBSan, libFuzzer)"
  cmake --preset fuzz >/dev/null || { echo "configure failed: cmake --preset fuzz" >&2; exit 2; }
fi
echo "== building the fuzzers (cmake --build --preset fuzz)"
cmake --build --preset fuzz -- -j2 >"$build_dir/fuzz-build.log" 2>&1 || {
  tail -30 "$build_dir/fuzz-build.log" >&2
  echo "build failed; full log: $build_dir/fuzz-build.log" >&2
  exit 2
}

# --- Seeds -------------------------------------------------------------------------------------
data_dir="${SAKER_TEST_DATA:-$source_dir/../shared/data}"
if [[ -d "$data_dir" ]]; then
  data_dir="$(cd "$data_dir" && pwd)"
  echo "== seeds from the data folder $data_dir and from the simulator"
else
  echo "== no data folder ($data_dir; set SAKER_TEST_DATA): seeds from the simulator only"
  data_dir=""
fi

corpus_root="$build_dir/corpus"
artifact_root="$build_dir/artifacts"
seed_tmp="$(mktemp -d)"
trap 'rm -rf "$seed_tmp"' EXIT

# A saker-cli for the simulator: this build's, else the release build's, else build it here.
saker_cli=""
for candidate in "$build_dir/app/saker-cli" "$source_dir/build/release/app/saker-cli"; do
  if [[ -x "$candidate" ]]; then saker_cli="$candidate"; break; fi
done
if [[ -z "$saker_cli" ]]; then
  echo "   (no saker-cli built yet: building it in $build_dir, a few minutes)"
  cmake --build "$build_dir" --target saker-cli -- -j2 >>"$build_dir/fuzz-build.log" 2>&1 || {
    echo "building saker-cli failed; see $build_dir/fuzz-build.log" >&2
    exit 2
  }
  saker_cli="$build_dir/app/saker-cli"
fi

# Small simulated clips: a few seconds of 320x240 H.264 with ST 0601 on every frame, a sparser
# one (KLV every third frame, 30 fps) and one over the antimeridian (footprints either side of
# 180 degrees), plus short missions processed from the first and the last.
simulate() {  # simulate OUT.ts [extra options]
  local out="$1"
  shift
  ASAN_OPTIONS=detect_leaks=0 "$saker_cli" simulate -q --force --scenario straight --width 320 \
    --height 240 -o "$out" --truth "$seed_tmp/$(basename "$out").truth.json" "$@" >/dev/null
}
simulated=()
if simulate "$seed_tmp/sim-10fps.ts" --fps 10 --duration 2 &&
  simulate "$seed_tmp/sim-sparse.ts" --fps 30 --duration 1 --klv-every 3 --seed 7 &&
  simulate "$seed_tmp/sim-antimeridian.ts" --fps 10 --duration 2 --lat 51.15 --lon 179.9999; then
  simulated=("$seed_tmp/sim-10fps.ts" "$seed_tmp/sim-sparse.ts" "$seed_tmp/sim-antimeridian.ts")
else
  echo "   warning: the simulator failed; no simulated seeds" >&2
fi

have_python=1
command -v python3 >/dev/null || { have_python=0; echo "   (no python3: KLV seeds only from raw packet files)"; }

make_seeds() {  # make_seeds HARNESS
  local corpus="$corpus_root/$1"
  mkdir -p "$corpus"
  case "$1" in
    klv)
      if [[ -n "$data_dir" ]]; then
        cp -f "$data_dir"/klvdata/*.bin "$data_dir"/jmisb/*.bin "$corpus/" 2>/dev/null || true
        if [[ $have_python == 1 ]]; then
          python3 tests/fuzz/make_seeds.py st0601-vectors "$corpus" \
            "$data_dir/st0601_vectors/st0601_tag_vectors.json" >/dev/null || true
          python3 tests/fuzz/make_seeds.py ts-klv "$corpus" "$data_dir"/kwiver/*.ts >/dev/null || true
        fi
      fi
      if [[ $have_python == 1 && ${#simulated[@]} -gt 0 ]]; then
        python3 tests/fuzz/make_seeds.py ts-klv "$corpus" "${simulated[@]}" >/dev/null || true
      fi
      ;;
    ingest)
      if [[ -n "$data_dir" ]]; then
        for ts in h264_klv h265_tricky_klv mpeg2_klv h264_no_klv aphill_short; do
          [[ -f "$data_dir/kwiver/$ts.ts" ]] && cp -f "$data_dir/kwiver/$ts.ts" "$corpus/"
        done
      fi
      [[ ${#simulated[@]} -gt 0 ]] && cp -f "${simulated[@]}" "$corpus/"
      ;;
    mission)
      "$fuzz_bin/make_mission_seed" "$corpus/fixture.saker" "$corpus/fixture-antimeridian.saker"
      # Edit scripts (inputs not starting with the SQLite header; see fuzz_mission.cc): set a
      # cell to an integer, a real, a text, a blob, a small integer; delete and duplicate a row.
      printf '\x01\x02\x03\x00\xff\xff\xff\xff\xff\xff\xff\x7f' >"$corpus/edit-integer"
      printf '\x02\x03\x04\x01\x00\x00\x00\x00\x00\x00\xf8\x7f' >"$corpus/edit-nan"
      printf '\x03\x01\x01\x00\x04abcd\x04\x05\x02\x01\x03\x01\x02' >"$corpus/edit-text-blob"
      printf '\x05\x04\x03\x00\xfb\x06\x05\x00\x01\x07\x06\x00\x02' >"$corpus/edit-rows"
      if [[ ${#simulated[@]} -gt 0 ]]; then
        for clip in sim-10fps sim-antimeridian; do
          ASAN_OPTIONS=detect_leaks=0 "$saker_cli" process "$seed_tmp/$clip.ts" \
            -o "$corpus/${clip/sim-10fps/simulated}.saker" --replace -q \
            >"$seed_tmp/process.log" 2>&1 || {
            echo "   warning: saker-cli process failed; no processed-mission seed from $clip:" >&2
            tail -3 "$seed_tmp/process.log" >&2
          }
        done
      fi
      rm -f "$corpus"/*.saker-wal "$corpus"/*.saker-shm
      ;;
  esac
  chmod -R u+w "$corpus"
  # Nothing may leave the corpus empty: libFuzzer would start from scratch.
  [[ -n "$(ls -A "$corpus")" ]] || printf 'seed' >"$corpus/empty-seed"
}

# Per harness: longest input, and the memory and per-input time limits.
max_len_of() {
  case "$1" in
    klv) echo 16384 ;;
    ingest) echo 262144 ;;  # longer seeds (the 1 MB EO clip) are cut: their first frames
    mission) echo 262144 ;;
  esac
}

# --- Run ---------------------------------------------------------------------------------------
failed=0
summary=()
for harness in "${harnesses[@]}"; do
  make_seeds "$harness"
  corpus="$corpus_root/$harness"
  artifacts="$artifact_root/$harness"
  mkdir -p "$artifacts"
  before=$(ls "$artifacts" | wc -l)
  dict=()
  [[ "$harness" != mission ]] && dict=(-dict="$source_dir/tests/fuzz/klv.dict")
  log="$build_dir/fuzz-$harness.log"
  echo "== fuzz_$harness for ${seconds} s (corpus $corpus, log $log)"
  start=$(date +%s)
  set +e
  ASAN_OPTIONS="detect_leaks=1:allocator_may_return_null=1" \
    UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
    "$fuzz_bin/fuzz_$harness" "$corpus" "${dict[@]}" -max_total_time="$seconds" \
    -max_len="$(max_len_of "$harness")" -rss_limit_mb=2048 -malloc_limit_mb=2048 -timeout=10 \
    -print_final_stats=1 -artifact_prefix="$artifacts/" >"$log" 2>&1
  status=$?
  set -e
  elapsed=$(($(date +%s) - start))
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  size=$(ls "$corpus" | wc -l)
  found=$(($(ls "$artifacts" | wc -l) - before))
  if [[ $status -ne 0 && $found -eq 0 ]]; then found=1; fi  # e.g. a crash in start-up
  line=$(printf '%-8s %6ss %12s execs %8s exec/s  corpus %5s  crashes %s' "$harness" "$elapsed" \
    "${runs:-?}" "${rate:-?}" "$size" "$found")
  summary+=("$line")
  if [[ $found -ne 0 ]]; then
    failed=1
    echo "!! fuzz_$harness found a problem (exit $status):" >&2
    grep -m1 -E "ERROR: |runtime error|broken promise|deadly signal|timeout" "$log" >&2 || true
    ls -t "$artifacts" | head -3 | sed "s|^|   $artifacts/|" >&2
  fi
done

echo
echo "harness     time    executions     rate  corpus       crashes"
printf '%s\n' "${summary[@]}"
exit $failed
