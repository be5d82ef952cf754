#!/bin/sh
# Run every libFuzzer harness in BUILD for SECONDS each, seeded from fuzz/corpus/<name>/.
# Fails if any harness finds a crash, leak or sanitizer error.
set -eu
BUILD=${1:-build-fuzz}
SECONDS_EACH=${2:-30}
HERE=$(cd "$(dirname "$0")" && pwd)
status=0
for bin in "$BUILD"/fuzz/fuzz_*; do
  [ -x "$bin" ] || continue
  name=$(basename "$bin")
  work="$BUILD/fuzz/work-$name"
  mkdir -p "$work/corpus"
  seeds="$HERE/corpus/${name#fuzz_}"
  [ -d "$seeds" ] && cp -r "$seeds"/. "$work/corpus/" 2>/dev/null || true
  echo "fuzz: $name for ${SECONDS_EACH}s"
  if ! ASAN_OPTIONS=detect_leaks=1 "$bin" -max_total_time="$SECONDS_EACH" -max_len=65536 -rss_limit_mb=2048 \
      -artifact_prefix="$work/" "$work/corpus" >"$work/log" 2>&1; then
    echo "fuzz: $name FAILED, see $work/log"; tail -30 "$work/log"; status=1
  else
    tail -1 "$work/log"
  fi
done
exit $status
