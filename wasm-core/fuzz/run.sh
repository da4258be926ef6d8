#!/usr/bin/env bash
# Fuzzing the importers (BVH parser, .mmdb loader, builder) and the character update; see
# docs/robustness.md.
#
#   fuzz/run.sh ci                  the CI form (< 2 min, nothing to install): replays the
#                                   committed corpus, the malformed BVH cases and ~9,800
#                                   deterministic .mmdb mutations, 4,000 random call sequences
#                                   on a character (the integration tests hostile_*:: and roundtrip::)
#   fuzz/run.sh long [SECONDS] [TARGET...]
#                                   coverage-guided AFL++ runs (cargo-afl, stable Rust), SECONDS
#                                   per target (default 600), targets bvh mmdb builder character roundtrip
#                                   (default all); PARALLEL=1 runs them at once (one core each).
#                                   Installs cargo-afl when missing (~2 min). Findings land in
#                                   fuzz/out/TARGET/default/crashes|hangs; a summary is printed.
#
# A crash found: reproduce with `fuzz/target/release/TARGET < FILE`, fix, then copy FILE to
# fuzz/regressions/TARGET/ so `cargo test` replays it for ever.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
mode="${1:-ci}"

if [[ "$mode" == ci ]]; then
  cd "$here/.."
  exec cargo test --profile test-opt --test integration -- hostile_bvh:: hostile_mmdb:: hostile_character:: roundtrip::
fi
if [[ "$mode" != long ]]; then
  echo "usage: fuzz/run.sh ci | long [SECONDS] [bvh|mmdb|builder|character|roundtrip ...]" >&2
  exit 2
fi
seconds="${2:-600}"
shift $(( $# >= 2 ? 2 : $# ))
targets=("$@")
(( ${#targets[@]} )) || targets=(bvh mmdb builder character roundtrip)

if ! cargo afl --version >/dev/null 2>&1; then
  echo "installing cargo-afl (cargo install cargo-afl)…"
  cargo install cargo-afl
fi
cd "$here"
cargo afl build --release
# Without root-level tuning AFL refuses to start; these accept the machine as it is.
export AFL_SKIP_CPUFREQ=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1 AFL_NO_UI=1 AFL_NO_AFFINITY=1
corpus_of() { case "$1" in builder) echo build ;; *) echo "$1" ;; esac; }

run() {
  local t="$1" out="$here/out/$1" limit=2000
  # A round-trip case builds, writes, loads and plays 120 updates: up to a few seconds in the
  # instrumented build with overflow checks.
  [[ "$t" == roundtrip ]] && limit=10000
  mkdir -p "$out"
  # -V: stop after SECONDS; -t: a per-input time limit (ms), above which AFL reports a hang.
  # A previous run's queue is resumed (AFL_AUTORESUME) so long runs add up.
  AFL_AUTORESUME=1 cargo afl fuzz -V "$seconds" -t "$limit" -i "$here/corpus/$(corpus_of "$t")" -o "$out" \
    "$here/target/release/$t" > "$out/afl.log" 2>&1 || true
}

if [[ "${PARALLEL:-0}" == 1 ]]; then
  for t in "${targets[@]}"; do run "$t" & done
  wait
else
  for t in "${targets[@]}"; do run "$t"; done
fi

status=0
for t in "${targets[@]}"; do
  stats="$here/out/$t/default/fuzzer_stats"
  if [[ ! -f "$stats" ]]; then
    echo "$t: no fuzzer_stats (see $here/out/$t/afl.log)"; status=1; continue
  fi
  get() { awk -F' *: *' -v k="$1" '$1==k {print $2}' "$stats"; }
  crashes=$(find "$here/out/$t/default/crashes" -type f ! -name README.txt 2>/dev/null | wc -l)
  hangs=$(find "$here/out/$t/default/hangs" -type f 2>/dev/null | wc -l)
  echo "$t: $(get run_time) s, $(get execs_done) execs ($(get execs_per_sec)/s), corpus $(get corpus_count), edges $(get edges_found)/$(get total_edges), crashes $crashes, hangs $hangs"
  (( crashes == 0 && hangs == 0 )) || status=1
done
exit $status
