#!/usr/bin/env bash
# CONTRACT §3: the sim-to-real gap of the nominal model. Two runs of the reversing
# diagnosis profile (the speed command crosses zero, so Coulomb friction and a current
# offset can be told apart): the model is trained on the first and scored on the second.
# Prints the gap, where it lies and the verdict, and any note on what the runs cannot tell.
source "$(dirname "$0")/lib.sh"
answer=$(post_json /runs "{\"profile\": \"diagnosis_reversing\",
  \"overrides\": {\"duration_s\": ${DURATION_S:-10}}}")
set -- $(field "$answer" '" ".join(d["runs"])')
echo "diagnosis runs queued: $*"
wait_runs "$@"
echo "$*" > "$STATE_DIR/diagnosis.ids"
answer=$(post_json /diagnose "{\"train\": \"$1\", \"holdout\": \"$2\"}")
echo "$answer" > "$STATE_DIR/diagnosis.json"
field "$answer" '"gap %.2f %%, where %s, verdict: %s" % (d["gap_percent"], d["where"]["regime"], d["verdict"])'
field "$answer" '"\n".join("note: " + n for n in d.get("notes", []))'
