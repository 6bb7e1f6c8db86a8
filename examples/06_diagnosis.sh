#!/usr/bin/env bash
# CONTRACT §3: the sim-to-real gap of the nominal model, trained on the first no-load run
# and scored on the second. Prints the verdict, or why the method refused the data.
source "$(dirname "$0")/lib.sh"
set -- $(cat "$STATE_DIR/no_load.ids")
if [ $# -lt 2 ]; then echo "need two no-load runs (REPEATS >= 2)" >&2; exit 1; fi
if answer=$(post_json /diagnose "{\"train\": \"$1\", \"holdout\": \"$2\"}" 2>"$STATE_DIR/diagnose.err"); then
    echo "$answer" > "$STATE_DIR/diagnosis.json"
    field "$answer" '"gap %.2f %%, where %s, verdict: %s" % (d["gap_percent"], d["where"]["regime"], d["verdict"])'
elif grep -q "HTTP 422" "$STATE_DIR/diagnose.err"; then
    echo "diagnosis refused these runs: $(cat "$STATE_DIR/diagnose.err")"
else
    cat "$STATE_DIR/diagnose.err" >&2
    exit 1
fi
