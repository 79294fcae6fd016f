#!/usr/bin/env bash
# Makes the farm's secrets in deploy/secrets/ (git-ignored): a CA, the coordinator's
# TLS certificate, the token file and one worker and one client token. Idempotent: a
# file that exists is kept (never a new key over an old one), so re-running it only
# fills in what is missing.
#
#   bash deploy/make-secrets.sh                          # then: docker compose ... up -d
#   bash deploy/make-secrets.sh --host farm.example.org  # more names for the server cert
#   TESSERA_SECRETS=/etc/tessera/tls bash deploy/make-secrets.sh
#
# What it writes (the names docker-compose.yml, the Kubernetes recipe and the systemd
# units expect):
#   ca.pem ca.key            the farm's CA (ca.key signs certificates: keep it offline)
#   server.pem server.key    the coordinator's certificate, valid for localhost,
#                            127.0.0.1, ::1, "coordinator" (the Compose service),
#                            "tessera-coordinator" (the Kubernetes Service) and --host
#   tokens                   the coordinator's --tokens file
#   worker.token             the workers' token (--token-file)
#   client.token             a client token for `tessera submit` and friends
# Delete worker.token or client.token to get a new one; the old token stays valid until
# its line is removed from tokens (and the coordinator restarted).
#
# It runs `tessera` from TESSERA_CLI, PATH or build/cli/, else from the image
# (TESSERA_IMAGE, default tessera:latest) with Docker.
#
# The containers run as uid 10001 and Compose bind-mounts secret files with their host
# owner and mode. Run as root, the script hands the files to TESSERA_SECRETS_OWNER
# (default 10001:10001) with mode 0600; run as another user, it keeps them yours and
# makes them readable (0644) inside a folder only you may enter (0700).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
dir="${TESSERA_SECRETS:-$here/secrets}"
owner="${TESSERA_SECRETS_OWNER:-10001:10001}"
hosts=(coordinator tessera-coordinator)
while [[ $# -gt 0 ]]; do
    case "$1" in
        --host) [[ $# -ge 2 ]] || { echo "make-secrets: --host needs a name" >&2; exit 2; }
                hosts+=("$2"); shift 2 ;;
        --dir) [[ $# -ge 2 ]] || { echo "make-secrets: --dir needs a folder" >&2; exit 2; }
               dir="$2"; shift 2 ;;
        -h | --help) sed -n '2,29p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "make-secrets: unknown argument $1 (--host NAME, --dir DIR)" >&2; exit 2 ;;
    esac
done

umask 077
mkdir -p "$dir"
chmod 0700 "$dir"
dir="$(cd "$dir" && pwd)"

# `tessera ARGS...` with paths under $dir: the host's binary, else the image's.
if [[ -n "${TESSERA_CLI:-}" ]]; then
    cli=("$TESSERA_CLI")
elif command -v tessera > /dev/null; then
    cli=(tessera)
elif [[ -x "$here/../build/cli/tessera" ]]; then
    cli=("$here/../build/cli/tessera")
elif command -v docker > /dev/null; then
    cli=(docker run --rm --user "$(id -u):$(id -g)" -v "$dir:$dir" -w "$dir"
         "${TESSERA_IMAGE:-tessera:latest}" tessera)
else
    echo "make-secrets: no tessera binary (TESSERA_CLI, PATH, build/cli) and no docker" >&2
    exit 1
fi
tessera() { "${cli[@]}" "$@"; }

made=()
if [[ ! -e "$dir/ca.pem" && ! -e "$dir/ca.key" ]]; then
    tessera cert ca --dir "$dir"
    made+=(ca.pem ca.key)
fi
if [[ ! -e "$dir/server.pem" && ! -e "$dir/server.key" ]]; then
    host_args=()
    for h in "${hosts[@]}"; do host_args+=(--host "$h"); done
    tessera cert server --dir "$dir" "${host_args[@]}"
    made+=(server.pem server.key)
fi
# `tessera token` appends a line to the token file and writes the token to --out.
if [[ ! -e "$dir/worker.token" ]]; then
    tessera token --role worker --name workers --tokens "$dir/tokens" --out "$dir/worker.token"
    made+=(worker.token)
fi
if [[ ! -e "$dir/client.token" ]]; then
    tessera token --role client --name admin --tokens "$dir/tokens" --out "$dir/client.token"
    made+=(client.token)
fi

# Make the files the containers read readable by their user (see above). ca.key is
# never mounted anywhere and stays 0600 and yours.
shared=(ca.pem server.pem server.key tokens worker.token client.token)
if [[ "$(id -u)" -eq 0 ]]; then
    for f in "${shared[@]}"; do
        chown "$owner" "$dir/$f"
        chmod 0600 "$dir/$f"
    done
    chmod 0644 "$dir/ca.pem" "$dir/server.pem"
else
    for f in "${shared[@]}"; do chmod 0644 "$dir/$f"; done
fi
# (ca.key may have been moved offline: only needed to make new certificates.)
if [[ -e "$dir/ca.key" ]]; then chmod 0600 "$dir/ca.key"; fi

if [[ ${#made[@]} -eq 0 ]]; then
    echo "make-secrets: $dir already holds every secret; nothing changed"
else
    echo "make-secrets: made ${made[*]} in $dir"
fi
