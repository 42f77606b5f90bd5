#!/usr/bin/env bash
# Runs each cargo-fuzz target (fuzz/fuzz_targets) for SECONDS, one after another, niced, and
# writes the executions and crashes of each to benchmarks/results/fuzz.md.
#   scripts/fuzz.sh SECONDS [TARGET...]      (default: every target)
# Needs the nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`). Exit 1 if any target
# crashed; the crashing inputs are kept in fuzz/artifacts/TARGET/.
set -euo pipefail
secs=${1:?usage: scripts/fuzz.sh SECONDS [TARGET...]}
shift
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root/fuzz"
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    mapfile -t targets < <(cargo +nightly fuzz list)
fi
out="$root/benchmarks/results/fuzz.md"
logs="$root/fuzz/logs"
mkdir -p "$logs" "$(dirname "$out")"
commit=$(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo "?")
nice -n 5 cargo +nightly fuzz build --release
rows=()
failed=0
for t in "${targets[@]}"; do
    log="$logs/$t.log"
    mkdir -p "corpus/$t" "artifacts/$t"
    before=$(find "artifacts/$t" -type f | wc -l)
    start=$(date +%s)
    set +e
    nice -n 5 cargo +nightly fuzz run --release "$t" "corpus/$t" -- \
        -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
        >"$log" 2>&1
    rc=$?
    set -e
    took=$(( $(date +%s) - start ))
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | tail -1 | grep -o '[0-9]*$' || true)
    after=$(find "artifacts/$t" -type f | wc -l)
    crashes=$(( after - before ))
    if [ "$rc" -ne 0 ] && [ "$crashes" -eq 0 ]; then crashes="exit $rc"; fi
    if [ "$rc" -ne 0 ] || [ "$after" -ne "$before" ]; then failed=1; fi
    corpus=$(find "corpus/$t" -type f | wc -l)
    echo "$t: ${execs:-?} executions in ${took}s, crashes: $crashes, corpus $corpus (log $log)"
    load=$(cut -d' ' -f1 /proc/loadavg)
    rows+=("| \`$t\` | $(date -u '+%Y-%m-%d %H:%M') | $commit | ${took} | ${execs:-?} | $crashes | $corpus | $load |")
done
# Rows of targets not run this time are kept from the previous file.
kept=()
if [ -f "$out" ]; then
    while IFS= read -r line; do
        name=$(sed -n 's/^| `\([^`]*\)`.*/\1/p' <<<"$line")
        [ -n "$name" ] || continue
        [[ " ${targets[*]} " == *" $name "* ]] || kept+=("$line")
    done <"$out"
fi
{
    echo "# Fuzzing"
    echo
    echo "Written by \`scripts/fuzz.sh SECONDS [TARGET...]\` ($(nproc) cores; $(cargo +nightly --version))."
    echo "Each target ran alone, niced, for the seconds given, from the corpus in \`fuzz/corpus/\`"
    echo "(empty on a fresh clone); the commit is the one fuzzed (with any uncommitted changes); load"
    echo "is the 1-minute load average at the end. What each target checks: \`fuzz/README.md\`."
    echo
    echo "| target | finished (UTC) | commit | seconds | executions | crashes | corpus files | load |"
    echo "|---|---|---|---:|---:|---:|---:|---:|"
    printf '%s\n' "${kept[@]}" "${rows[@]}" | sort
} >"$out"
echo "wrote $out"
exit $failed
