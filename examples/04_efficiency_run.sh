#!/usr/bin/env bash
# Seed 000 §3.6: the two-motor run, input at constant speed, output load steps.
source "$(dirname "$0")/lib.sh"
answer=$(post_json /runs '{"profile": "seed000_efficiency", "overrides": {}}')
id=$(field "$answer" 'd["id"]')
echo "efficiency run queued: $id"
wait_runs "$id"
echo "$id" > "$STATE_DIR/efficiency.id"
api GET "/runs/$id/samples" > "$STATE_DIR/efficiency_run.csv"
echo "samples saved to $STATE_DIR/efficiency_run.csv"
