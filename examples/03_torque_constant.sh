#!/usr/bin/env bash
# Seed 000 eqs. 11-17: the torque constant from the stored no-load and loaded runs.
source "$(dirname "$0")/lib.sh"
as_list() { python3 -c 'import json,sys; print(json.dumps(sys.argv[1:]))' $(cat "$1"); }
answer=$(post_json /torque-constant "{\"no_load\": $(as_list "$STATE_DIR/no_load.ids"),
  \"loaded\": $(as_list "$STATE_DIR/loaded.ids"), \"added_inertia\": 1.007e-5}")
echo "$answer" > "$STATE_DIR/torque_constant.json"
field "$answer" '"Kt = %.5f ± %.5f N·m/A, J = %.4g kg·m², no-load current %.3f A" % (d["Kt"], d["Kt_std"], d["J"], d["no_load_current_A"])'
