#!/usr/bin/env bash
# Live progress and samples of a run (Server-Sent Events), e.g. for a dashboard:
#   bash examples/watch.sh RUN_ID
source "$(dirname "$0")/lib.sh"
curl -sS -N "${AUTH[@]}" "$BASE_URL/runs/${1:?usage: watch.sh RUN_ID}/events" \
    | grep --line-buffered -E '^(event|data: \{"id")'
