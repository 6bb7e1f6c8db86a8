#!/usr/bin/env bash
# A whole lab session against a running service:
#   BASE_URL=http://127.0.0.1:8000 API_KEY=... bash examples/session.sh
# Shorter runs for a quick check: REPEATS=2 DURATION_S=3 bash examples/session.sh
source "$(dirname "$0")/lib.sh"
here=$(dirname "$0")
api GET /health > /dev/null
for step in 01_no_load_runs 02_loaded_runs 03_torque_constant 04_efficiency_run 05_efficiency \
            06_diagnosis; do
    echo "== $step"
    bash "$here/$step.sh"
done
echo "== bus"
field "$(api GET /bus)" '"; ".join("node %s %s heartbeat %.3f s ago" % (n["node_id"], n["nmt_state"], n["heartbeat_age_s"] or -1) for n in d["nodes"])'
echo "session state in $STATE_DIR"
