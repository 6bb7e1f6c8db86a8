#!/usr/bin/env bash
# Emergency: CiA 402 quick stop to every drive at once, the current run stops.
source "$(dirname "$0")/lib.sh"
api POST /stop
echo
