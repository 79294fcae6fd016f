#!/usr/bin/env bash
# Builds Tessera's container image (deploy/Dockerfile) with Podman (or Buildah, or
# Docker), also on a machine that cannot reach a container registry:
#
#   1. base image: debian:bookworm and debian:bookworm-slim if they are already local or
#      can be pulled (each pull is given TESSERA_PULL_TIMEOUT seconds); otherwise one
#      made here with debootstrap from the Debian mirror apt already uses
#      (localhost/tessera-base:bookworm, a minbase root file system with the slim
#      image's dpkg filters, imported with `podman import`);
#   2. `podman build -f deploy/Dockerfile` on top of it, with BUILD_IMAGE and
#      RUNTIME_IMAGE set to that base. Every package the Dockerfile installs comes from
#      the same mirror, so the whole build needs no registry.
#
#   sudo bash deploy/build-image.sh                     # tessera:latest
#   sudo bash deploy/build-image.sh --tag tessera:1.0 --jobs 2
#   sudo bash deploy/build-image.sh --debootstrap       # never try a registry
#
# Safe to re-run: a base image that exists is reused (--rebuild-base makes it anew) and
# the build's layer cache makes an unchanged rebuild take seconds. Run it from anywhere;
# it builds from the repository this script is in. debootstrap needs root.
#
# Environment (all optional):
#   TESSERA_CONTAINER_TOOL   podman | buildah | docker (default: the first installed)
#   TESSERA_PODMAN_OPTS      global options for podman/buildah, e.g.
#                            "--storage-driver vfs --cgroup-manager cgroupfs"
#   TESSERA_DEBIAN_MIRROR    mirror for debootstrap and the image's apt sources
#                            (default: the host's first Debian URI, else deb.debian.org)
#   TESSERA_DEBIAN_SECURITY_MIRROR  (default: http://deb.debian.org/debian-security)
#   TESSERA_PULL_TIMEOUT     seconds per pull attempt (default 60)
#   TESSERA_BASE_IMAGE       base image name to make/use (default localhost/tessera-base:bookworm)
#   CONTAINERS_CONF          Podman/Buildah configuration; when unset and a trivial
#                            container fails, deploy/podman/containers.conf is tried
set -euo pipefail

usage() {
    sed -n '2,33p' "$0" | sed 's/^# \{0,1\}//'
    echo "Options: --tag NAME  --jobs N  --debootstrap  --rebuild-base  --no-movie  --no-cache"
}

tag=tessera:latest
jobs=1
force_debootstrap=0
rebuild_base=0
movie=1
no_cache=()
while [ "$#" -gt 0 ]; do
    case "$1" in
        --tag) tag=$2; shift 2 ;;
        --jobs) jobs=$2; shift 2 ;;
        --debootstrap) force_debootstrap=1; shift ;;
        --rebuild-base) rebuild_base=1; force_debootstrap=1; shift ;;
        --no-movie) movie=0; shift ;;
        --no-cache) no_cache=(--no-cache); shift ;;
        -h | --help) usage; exit 0 ;;
        *) echo "build-image: unknown argument $1" >&2; usage >&2; exit 2 ;;
    esac
done

repo=$(cd "$(dirname "$0")/.." && pwd)
suite=bookworm
base_image=${TESSERA_BASE_IMAGE:-localhost/tessera-base:$suite}
pull_timeout=${TESSERA_PULL_TIMEOUT:-60}
# Word-split on purpose: a list of global options.
read -r -a global_opts <<< "${TESSERA_PODMAN_OPTS:-}"

log() { printf 'build-image: %s\n' "$*" >&2; }
now() { date +%s; }

tool=${TESSERA_CONTAINER_TOOL:-}
if [ -z "$tool" ]; then
    for t in podman buildah docker; do
        if command -v "$t" > /dev/null; then tool=$t; break; fi
    done
fi
if [ -z "$tool" ]; then
    log "no podman, buildah or docker: apt-get install -y podman buildah debootstrap"
    exit 1
fi
if [ "$tool" = docker ]; then global_opts=(); fi
ctr() { "$tool" "${global_opts[@]}" "$@"; }

image_exists() {
    case "$tool" in
        podman) ctr image exists "$1" ;;
        buildah) ctr inspect --type image "$1" > /dev/null 2>&1 ;;
        docker) docker image inspect "$1" > /dev/null 2>&1 ;;
    esac
}

try_pull() {
    image_exists "$1" && return 0
    log "pulling $1 (at most ${pull_timeout}s)"
    if ! timeout "$pull_timeout" "$tool" "${global_opts[@]}" pull "$1" > /dev/null; then
        log "cannot pull $1"
        return 1
    fi
}

# The mirror apt uses on this host (deb822 or one-line sources), else deb.debian.org.
host_mirror() {
    local uri
    uri=$(grep -hsE '^(URIs:|deb )' /etc/apt/sources.list.d/*.sources /etc/apt/sources.list \
              /etc/apt/sources.list.d/*.list 2>/dev/null |
          grep -oE 'https?://[^ ]*/debian/?( |$)' | head -n 1 | tr -d ' ')
    echo "${uri:-http://deb.debian.org/debian}"
}

# A root file system folder -> the image $base_image (CMD bash, LANG=C.UTF-8).
import_rootfs() {
    local c mnt
    case "$tool" in
        buildah)
            c=$(ctr from scratch)
            mnt=$(ctr mount "$c")
            tar --numeric-owner --xattrs -C "$1" -c . | tar --numeric-owner --xattrs -C "$mnt" -x
            ctr umount "$c" > /dev/null
            ctr config --cmd bash --env LANG=C.UTF-8 "$c"
            ctr commit --rm "$c" "$base_image" > /dev/null ;;
        *)
            tar --numeric-owner --xattrs -C "$1" -c . |
                ctr import --change 'CMD ["bash"]' --change 'ENV LANG=C.UTF-8' - "$base_image" > /dev/null ;;
    esac
}

make_base() {
    local mirror security work root start
    mirror=${TESSERA_DEBIAN_MIRROR:-$(host_mirror)}
    security=${TESSERA_DEBIAN_SECURITY_MIRROR:-http://deb.debian.org/debian-security}
    if ! command -v debootstrap > /dev/null; then
        log "debootstrap is missing: apt-get install -y debootstrap"
        exit 1
    fi
    if [ "$(id -u)" -ne 0 ]; then
        log "debootstrap needs root: run this script with sudo"
        exit 1
    fi
    work=$(mktemp -d /var/tmp/tessera-base.XXXXXX)
    # shellcheck disable=SC2064  # expand now: the folder of this run
    trap "rm -rf '$work'" EXIT
    root=$work/rootfs
    start=$(now)
    log "debootstrap --variant=minbase $suite from $mirror"
    timeout 1800 debootstrap --variant=minbase "$suite" "$root" "$mirror" > "$work/debootstrap.log" 2>&1 || {
        tail -n 20 "$work/debootstrap.log" >&2
        log "debootstrap failed (log above)"
        exit 1
    }
    log "debootstrap took $(( $(now) - start ))s"

    # The slim image's dpkg filters (as in debian:bookworm-slim): no manuals, info pages,
    # translations or documentation beyond the copyright files.
    mkdir -p "$root/etc/dpkg/dpkg.cfg.d"
    cat > "$root/etc/dpkg/dpkg.cfg.d/docker" << 'EOF'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/groff/*
path-exclude /usr/share/info/*
path-exclude /usr/share/lintian/*
path-exclude /usr/share/linda/*
path-exclude /usr/share/locale/*
path-include /usr/share/locale/locale.alias
EOF
    cat > "$root/etc/apt/apt.conf.d/docker-clean" << 'EOF'
DPkg::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
APT::Update::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/archives/partial/*.deb /var/cache/apt/*.bin || true"; };
Dir::Cache::pkgcache "";
Dir::Cache::srcpkgcache "";
EOF
    cat > "$root/etc/apt/apt.conf.d/docker-no-recommends" << 'EOF'
APT::Install-Recommends "false";
EOF
    # The same suites as debian:bookworm: the release, its updates and security fixes.
    rm -f "$root/etc/apt/sources.list"
    cat > "$root/etc/apt/sources.list.d/debian.sources" << EOF
Types: deb
URIs: $mirror
Suites: $suite $suite-updates
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg

Types: deb
URIs: $security
Suites: $suite-security
Components: main
Signed-By: /usr/share/keyrings/debian-archive-keyring.gpg
EOF
    # Bring it up to the point release and security fixes, as the official image is.
    cp /etc/resolv.conf "$root/etc/resolv.conf"
    chroot "$root" sh -c 'export DEBIAN_FRONTEND=noninteractive &&
        apt-get update -qq && apt-get upgrade -y -qq && apt-get clean' > "$work/upgrade.log" 2>&1 || {
        tail -n 20 "$work/upgrade.log" >&2
        log "apt-get upgrade in the new root file system failed (log above)"
        exit 1
    }
    find "$root/usr/share/doc" -mindepth 1 -not -name copyright -not -type d -delete
    find "$root/usr/share/doc" -mindepth 1 -type d -empty -delete
    rm -rf "$root"/usr/share/man/* "$root"/usr/share/info/* "$root"/usr/share/locale/*/ \
        "$root"/var/lib/apt/lists/* "$root"/var/cache/apt/*.bin "$root"/var/log/*.log \
        "$root"/tmp/* "$root"/var/tmp/*
    # Podman writes these when a container starts.
    : > "$root/etc/resolv.conf"
    : > "$root/etc/hostname"
    rm -f "$root/etc/machine-id"; : > "$root/etc/machine-id"

    log "importing the root file system as $base_image"
    import_rootfs "$root"
    rm -rf "$work"
    trap - EXIT
    log "base image $base_image made in $(( $(now) - start ))s"
}

# 1. The base images.
build_base=debian:$suite
runtime_base=debian:$suite-slim
if [ "$force_debootstrap" = 0 ] && try_pull "docker.io/library/$build_base" &&
        try_pull "docker.io/library/$runtime_base"; then
    build_base=docker.io/library/$build_base
    runtime_base=docker.io/library/$runtime_base
    log "base images: $build_base, $runtime_base (registry)"
else
    if [ "$rebuild_base" = 1 ] || ! image_exists "$base_image"; then
        if [ "$tool" = docker ]; then
            log "no registry: make the base with podman or buildah, or docker import a debootstrap tarball"
        fi
        make_base
    else
        log "reusing $base_image (--rebuild-base makes it anew)"
    fi
    build_base=$base_image
    runtime_base=$base_image
    log "base image: $base_image (debootstrap)"
fi

# Podman's defaults fail on some hosts: crun refuses cgroup v1/v2 "hybrid" mounts, and
# Podman sets nofile/nproc limits above what a process without CAP_SYS_RESOURCE may
# set. deploy/podman/containers.conf (runc, lower limits) gets around both; it is used
# only when a trivial container fails without it.
if [ "$tool" = podman ] && [ -z "${CONTAINERS_CONF:-}" ]; then
    if ! probe=$(ctr run --rm --network none "$build_base" true 2>&1); then
        log "podman cannot start a container with its defaults: $probe"
        if ! command -v runc > /dev/null; then
            log "deploy/podman/containers.conf needs runc: apt-get install -y runc"
            exit 1
        fi
        export CONTAINERS_CONF=$repo/deploy/podman/containers.conf
        log "retrying with CONTAINERS_CONF=$CONTAINERS_CONF"
        if ! probe=$(ctr run --rm --network none "$build_base" true 2>&1); then
            log "containers cannot run on this host: $probe"
            exit 1
        fi
        log "that works: export CONTAINERS_CONF=$CONTAINERS_CONF for podman and podman-compose too"
    fi
fi

# 2. Tessera's image.
build_args=(
    -f deploy/Dockerfile
    --build-arg "BUILD_IMAGE=$build_base"
    --build-arg "RUNTIME_IMAGE=$runtime_base"
    --build-arg "BUILD_JOBS=$jobs"
    --build-arg "MOVIE_PREVIEWS=$movie"
    -t "$tag"
    "${no_cache[@]}"
)
case "$tool" in
    # Podman/Buildah do not read deploy/Dockerfile.dockerignore by themselves (BuildKit
    # does): name it, or the context would carry build/ and deploy/secrets/.
    podman | buildah)
        build_args=(--ignorefile deploy/Dockerfile.dockerignore --layers "${build_args[@]}") ;;
esac
start=$(now)
cd "$repo"
ctr build "${build_args[@]}" .
log "built $tag in $(( $(now) - start ))s"
case "$tool" in
    podman | docker) ctr image ls "$tag" ;;
    buildah) ctr images "$tag" ;;
esac
