#!/usr/bin/env bash
# Seed 000 §4.2: the same runs with the 1.007e-5 kg·m² disk mounted (added inertia).
source "$(dirname "$0")/lib.sh"
answer=$(post_json /runs "{\"profile\": \"seed000_no_load\",
  \"overrides\": {\"procedure\": \"added_inertia\", \"repeats\": ${REPEATS:-5},
                  \"duration_s\": ${DURATION_S:-10}}}")
ids=$(field "$answer" '" ".join(d["runs"])')
echo "added-inertia runs queued: $ids"
wait_runs $ids
echo "$ids" > "$STATE_DIR/loaded.ids"
