#!/bin/sh
# One timed libFuzzer run (make fuzz): BIN over RUN_DIR/corpus (started from SEED_DIR's files),
# for SECONDS, inputs up to MAX_LEN bytes, 2 GB RSS and 10 s per input at most. Prints the
# run's statistics and writes a one-line RUN_DIR/summary. Exit status: libFuzzer's (non-zero
# on a crash, leak, timeout or out-of-memory; the input is in RUN_DIR/artifacts).
#   usage: run-fuzz.sh BIN SEED_DIR RUN_DIR SECONDS MAX_LEN
set -u
bin=${1:?usage: run-fuzz.sh BIN SEED_DIR RUN_DIR SECONDS MAX_LEN}
seeds=${2:?} run=${3:?} secs=${4:?} len=${5:?}
name=$(basename "$bin")
mkdir -p "$run/corpus" "$run/artifacts" || exit 1
cp "$seeds"/* "$run/corpus/" || exit 1
before=$(ls "$run/artifacts" | wc -l)
echo "fuzzing $name for $secs s (corpus $run/corpus, max_len $len)"
"$bin" -max_total_time="$secs" -max_len="$len" -rss_limit_mb=2048 -timeout=10 \
	-print_final_stats=1 -artifact_prefix="$run/artifacts/" "$run/corpus" >"$run/log" 2>&1
rc=$?
grep -E '^(stat::number_of_executed_units|stat::average_exec_per_sec|stat::peak_rss_mb|Done|SUMMARY)' "$run/log"
execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$run/log")
rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$run/log")
arts=$(( $(ls "$run/artifacts" | wc -l) - before ))
printf '%-18s %10s executions in %s s (%s/s), exit %s, %s new crash artifact(s)\n' \
	"$name" "${execs:-?}" "$secs" "${rate:-?}" "$rc" "$arts" | tee "$run/summary"
[ "$rc" -eq 0 ] || tail -n 40 "$run/log" >&2
exit $rc
