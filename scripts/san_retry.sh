#!/bin/sh
# Runs one test of the sanitizer build (tests/CMakeLists.txt wraps every test in it when
# SPX_SANITIZE is on). It reruns the test once, saying so, only when the failure is LeakSanitizer's
# own stop-the-world tracer crashing at process exit ("Tracer caught signal" + "LeakSanitizer has
# encountered a fatal error"): a known flake of the sanitizer runtime in processes with many
# threads (here PoCL's workers), which reports no leak and says nothing about the test. A leak
# report, an ASan/UBSan error or a failed check fails at once, as without this wrapper.
log=$(mktemp "${TMPDIR:-/tmp}/spx-san.XXXXXX") || exit 1
"$@" >"$log" 2>&1
rc=$?
cat "$log"
if [ "$rc" -ne 0 ] && grep -q "Tracer caught signal" "$log" &&
   grep -q "LeakSanitizer has encountered a fatal error" "$log"; then
  echo "san_retry: LeakSanitizer's tracer crashed at exit (no leak was reported); running the test once more"
  "$@"
  rc=$?
fi
rm -f "$log"
exit "$rc"
