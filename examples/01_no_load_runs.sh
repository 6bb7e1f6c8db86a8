#!/usr/bin/env bash
# Seed 000 §4.2: no-load identification runs on the stand (REPEATS, DURATION_S).
source "$(dirname "$0")/lib.sh"
answer=$(post_json /runs "{\"profile\": \"seed000_no_load\",
  \"overrides\": {\"repeats\": ${REPEATS:-5}, \"duration_s\": ${DURATION_S:-10}}}")
ids=$(field "$answer" '" ".join(d["runs"])')
echo "no-load runs queued: $ids"
wait_runs $ids
echo "$ids" > "$STATE_DIR/no_load.ids"
