#!/usr/bin/env bash
# Runs every test stage CI runs, in order, and stops at the first that fails:
#   release  configure + build + ctest, the whole suite (RelWithDebInfo)
#   asan     configure + build + ctest, the whole suite under AddressSanitizer + UBSan (Debug)
#   tsan     configure + build + ctest, the tests labelled `threads` under ThreadSanitizer
#   fuzz     tests/fuzz/run-fuzzers.sh --seconds 20, when that script exists
#   tidy     clang-tidy with the repository's .clang-tidy over every source file (on request only:
#            about 8 minutes on 2 cores, which CI's time budget does not cover)
# Prints one timing line per stage and a summary; the exit status is the failing stage's (or 0).
# Installs nothing: packaging/install-deps.sh does that. ccache is used when installed.
#
# Usage: tests/run-all.sh [STAGE...]   (default: release asan tsan fuzz, in that order)
# Environment: SAKER_JOBS (build jobs, default: the number of cores).
set -uo pipefail

cd "$(dirname "$0")/.." || exit 1

all_stages=(release asan tsan fuzz)
if (($# > 0)); then
  stages=("$@")
  for s in "${stages[@]}"; do
    case "$s" in
      release | asan | tsan | fuzz | tidy) ;;
      *)
        echo "run-all: unknown stage '$s' (stages: ${all_stages[*]} tidy)" >&2
        exit 2
        ;;
    esac
  done
else
  stages=("${all_stages[@]}")
fi

jobs="${SAKER_JOBS:-$(nproc)}"
configure_args=()
if command -v ccache >/dev/null 2>&1; then
  # CMake reads these when the build tree is first configured; C matters for the fuzz preset.
  configure_args+=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi

summary=()
started_all=$(date +%s)

now() { date +%s; }

# step NAME COMMAND...: runs one step of a stage, adds its seconds to `timing`, returns its status.
timing=""
step() {
  local name=$1
  shift
  local t0 status
  t0=$(now)
  echo "run-all: ---- $stage: $name: $*"
  "$@"
  status=$?
  timing+="${timing:+, }$name $(($(now) - t0)) s"
  return "$status"
}

run_cmake_stage() {
  local preset=$1
  step configure cmake --preset "$preset" "${configure_args[@]}" &&
    step build cmake --build --preset "$preset" -j "$jobs" &&
    step test ctest --preset "$preset"
}

finish() {
  local total=$(($(now) - started_all))
  echo
  echo "run-all: summary"
  for line in "${summary[@]}"; do echo "run-all:   $line"; done
  echo "run-all:   total $total s ($((total / 60)) min $((total % 60)) s)"
}

for stage in "${stages[@]}"; do
  timing=""
  t0=$(now)
  status=0
  case "$stage" in
    release | asan | tsan)
      run_cmake_stage "$stage"
      status=$?
      ;;
    tidy)
      # Over the release tree's compile_commands.json, built first (the GUI's sources include
      # generated headers); only the project's own sources, not those generated in the build tree.
      step configure cmake --preset release "${configure_args[@]}" &&
        step build cmake --build --preset release -j "$jobs" &&
        step tidy run-clang-tidy -p build/release -j "$jobs" -quiet \
          "^$PWD/(core|ui|app|tests|benchmarks)/"
      status=$?
      ;;
    fuzz)
      if [[ -x tests/fuzz/run-fuzzers.sh ]]; then
        step fuzzers tests/fuzz/run-fuzzers.sh --seconds 20
        status=$?
      else
        summary+=("$(printf '%-8s skipped (no tests/fuzz/run-fuzzers.sh)' "$stage")")
        echo "run-all: stage fuzz skipped: tests/fuzz/run-fuzzers.sh not found"
        continue
      fi
      ;;
  esac
  seconds=$(($(now) - t0))
  if ((status == 0)); then
    line=$(printf '%-8s ok      %5d s (%s)' "$stage" "$seconds" "$timing")
  else
    line=$(printf '%-8s FAILED  %5d s (%s) exit %d' "$stage" "$seconds" "$timing" "$status")
  fi
  echo "run-all: stage $line"
  summary+=("$line")
  if ((status != 0)); then
    finish
    echo "run-all: stopped at stage $stage" >&2
    exit "$status"
  fi
done
finish
exit 0
