#!/usr/bin/env bash
# Seed 000 eq. 18: reducer efficiency (ratio 11), both torque constants from step 3.
source "$(dirname "$0")/lib.sh"
kt=$(field "$(cat "$STATE_DIR/torque_constant.json")" 'd["Kt"]')
answer=$(post_json /efficiency "{\"run\": \"$(cat "$STATE_DIR/efficiency.id")\",
  \"ratio\": ${RATIO:-11}, \"k_in\": $kt, \"k_out\": $kt}")
echo "$answer" > "$STATE_DIR/efficiency.json"
field "$answer" '"efficiency = %.4f ± %.4f (%d load steps)" % (d["efficiency"], d["efficiency_std"], d.get("steps", 0))'
# The same analysis on an uploaded run file (multipart form, same field names):
answer=$(api POST /efficiency -F "run=@$STATE_DIR/efficiency_run.csv" -F "ratio=${RATIO:-11}" \
         -F "k_in=$kt" -F "k_out=$kt")
field "$answer" '"from the uploaded file: efficiency = %.4f" % d["efficiency"]'
