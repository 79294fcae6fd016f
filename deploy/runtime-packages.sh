#!/bin/sh
# Prints, one per line, the Debian packages that own the shared libraries the given
# binaries load (ldd's full, transitive list). The container image's runtime stage
# installs exactly these, so its package list follows the binaries and never has to be
# kept by hand; apt then brings in whatever those packages depend on themselves.
#
#   sh deploy/runtime-packages.sh build/coordinator/tessera-coordinator build/worker/tessera-worker
#
# Fails when a library cannot be found or belongs to no package (a library installed by
# hand, e.g. under /usr/local, would be missing from the runtime image).
# Libraries opened with dlopen() are invisible to ldd; none of Tessera's dependencies
# needs one that its own package does not already depend on (oneTBB's libtbbmalloc, the
# one candidate, is a dependency of libtbb12).
set -eu

if [ "$#" -eq 0 ]; then
    echo "usage: $0 BINARY..." >&2
    exit 2
fi

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# No pipelines around the loop: an exit inside one would only leave its subshell.
: > "$tmp/libs"
for bin in "$@"; do
    out=$(ldd "$bin") || { echo "runtime-packages: ldd failed on $bin" >&2; exit 1; }
    if printf '%s\n' "$out" | grep -q 'not found'; then
        printf '%s\n' "$out" | grep 'not found' >&2
        echo "runtime-packages: $bin has unresolved libraries" >&2
        exit 1
    fi
    # "libfoo.so.1 => /usr/lib/x86_64-linux-gnu/libfoo.so.1 (0x...)" and the loader line
    # "/lib64/ld-linux-x86-64.so.2 (0x...)".
    printf '%s\n' "$out" |
        awk '$2 == "=>" && $3 ~ /^\// { print $3 } $1 ~ /^\// { print $1 }' >> "$tmp/libs"
done
sort -u -o "$tmp/libs" "$tmp/libs"

# Debian 12 merged /lib into /usr/lib, but dpkg records each file under the path its
# package ships it at: look each library up as printed, with and without the /usr
# prefix, and by its symlink's target. "LIB<TAB>CANDIDATE" lines:
while read -r lib; do
    real=$(readlink -f "$lib")
    for p in "$lib" "$real"; do
        case "$p" in
            /usr/*) alt="${p#/usr}" ;;
            *) alt="/usr$p" ;;
        esac
        printf '%s\t%s\n%s\t%s\n' "$lib" "$p" "$lib" "$alt"
    done
done < "$tmp/libs" > "$tmp/candidates"

# One dpkg-query for all paths (each call scans the whole database). It exits 1 when
# some path has no owner, which is expected for the variants that do not exist.
cut -f 2 "$tmp/candidates" | sort -u > "$tmp/paths"
xargs dpkg-query -S < "$tmp/paths" > "$tmp/owners" 2>/dev/null || true

# "libc6:amd64: /lib/x86_64-linux-gnu/libc.so.6"; a shared file "a:amd64, b:amd64: path";
# "diversion by x from: path" lines are skipped.
awk -F '\t' '
    FNR == NR {
        if ($0 ~ /^diversion /) next
        i = index($0, ": ")
        if (i == 0) next
        pkg = substr($0, 1, i - 1); path = substr($0, i + 2)
        sub(/,.*/, "", pkg); sub(/:.*/, "", pkg)
        if (!(path in owner)) owner[path] = pkg
        next
    }
    {
        if (!($1 in found)) found[$1] = ""
        if (found[$1] == "" && ($2 in owner)) found[$1] = owner[$2]
    }
    END {
        bad = 0
        for (lib in found) {
            if (found[lib] == "") {
                print "runtime-packages: no package owns " lib > "/dev/stderr"
                bad = 1
            } else {
                print found[lib] > "'"$tmp/packages"'"
            }
        }
        exit bad
    }' "$tmp/owners" "$tmp/candidates"
sort -u "$tmp/packages"
