# Helpers of the example lab session (sourced by the scripts here).
# Environment: BASE_URL (default http://127.0.0.1:8000), API_KEY (optional),
# STATE_DIR (where run ids and results are kept between scripts; default ./lab-session).
set -euo pipefail
BASE_URL=${BASE_URL:-http://127.0.0.1:8000}
STATE_DIR=${STATE_DIR:-./lab-session}
mkdir -p "$STATE_DIR"
AUTH=()
if [ -n "${API_KEY:-}" ]; then AUTH=(-H "Authorization: Bearer $API_KEY"); fi

# api METHOD PATH [curl args...]: JSON answer on stdout; fails (with the answer) on HTTP errors.
api() {
    local method=$1 path=$2; shift 2
    local out status
    out=$(mktemp)
    status=$(curl -sS -o "$out" -w '%{http_code}' -X "$method" "${AUTH[@]}" "$@" "$BASE_URL$path")
    if [ "$status" -ge 400 ]; then
        echo "$method $path: HTTP $status: $(cat "$out")" >&2
        rm -f "$out"
        return 1
    fi
    cat "$out"
    rm -f "$out"
}

# post_json PATH JSON
post_json() { api POST "$1" -H 'Content-Type: application/json' -d "$2"; }

# field JSON PYTHON-EXPRESSION-ON-d: one value out of a JSON answer (python3, no jq needed).
field() { python3 -c "import json,sys; d=json.loads(sys.argv[1]); print($2)" "$1"; }

# wait_runs ID...: until every run is over; fails unless each is done.
wait_runs() {
    local id state
    for id in "$@"; do
        while true; do
            state=$(field "$(api GET "/runs/$id")" 'd["state"]')
            case $state in
                queued|running) sleep 0.5 ;;
                done) break ;;
                *) echo "run $id ended $state" >&2; return 1 ;;
            esac
        done
    done
}
