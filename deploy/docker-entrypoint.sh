#!/bin/sh
# Entry point of the Tessera image: the first argument picks the program.
#   coordinator ARGS...   tessera-coordinator ARGS...
#   worker ARGS...        tessera-worker ARGS...
#   tessera ARGS...       the CLI (submit, status, watch, cancel, fetch, render)
#   anything else         run as a command (e.g. bash)
set -eu

case "${1:-}" in
    coordinator | tessera-coordinator)
        shift
        exec /usr/local/bin/tessera-coordinator "$@" ;;
    worker | tessera-worker)
        shift
        exec /usr/local/bin/tessera-worker "$@" ;;
    tessera | cli)
        shift
        exec /usr/local/bin/tessera "$@" ;;
    "" | help | -h | --help)
        sed -n '2,6p' "$0" | sed 's/^# \{0,1\}//'
        exit 0 ;;
    -*)
        echo "tessera-entrypoint: name the program first: coordinator, worker or tessera" >&2
        exit 2 ;;
    *)
        exec "$@" ;;
esac
