#!/usr/bin/env bash
# Build the Dockerfile's base image (python:3.11-slim) locally from Debian packages, for machines
# that reach Debian's and PyPI's package servers but no container registry (CI here).
# Debian bookworm's python3 is 3.11. The machine's CA bundle goes in, so pip and apt inside the
# build trust the same TLS as the host does.
#   docker/make_base_image.sh [TAG [PLATFORM]]   (root, debootstrap and a running Docker engine)
# PLATFORM linux/arm64 on an x86 machine builds the arm64 base (tag it arm64v8/python:3.11-slim,
# the name Docker Hub gives the arm64 variant): debootstrap's second stage then runs arm64
# binaries, which needs QEMU registered with binfmt_misc (tools/with_arm64_emulation.sh).
set -euo pipefail
tag="${1:-python:3.11-slim}"
platform="${2:-}"
if docker image inspect "$tag" >/dev/null 2>&1; then
    echo "base image $tag: present"
    exit 0
fi
arch=()
import_platform=()
if [ -n "$platform" ]; then
    case "$platform" in
        linux/amd64) arch=(--arch=amd64) ;;
        linux/arm64) arch=(--arch=arm64) ;;
        *) echo "make_base_image: platform $platform is not one of linux/amd64, linux/arm64" >&2; exit 2 ;;
    esac
    import_platform=(--platform "$platform")
fi
root="$(mktemp -d)"
trap 'rm -rf "$root"' EXIT
debootstrap "${arch[@]}" --variant=minbase --include=python3,python3-pip,python3-venv,ca-certificates \
    bookworm "$root" http://deb.debian.org/debian >/dev/null
cp /etc/ssl/certs/ca-certificates.crt "$root/etc/ssl/certs/ca-certificates.crt"
printf '[global]\ncert = /etc/ssl/certs/ca-certificates.crt\nbreak-system-packages = true\n' \
    >"$root/etc/pip.conf"
ln -sf /usr/bin/python3 "$root/usr/local/bin/python"
ln -sf /usr/bin/pip3 "$root/usr/local/bin/pip"
rm -rf "$root/var/cache/apt/archives/"*.deb "$root/var/lib/apt/lists/"*
tar -C "$root" -c . | docker import "${import_platform[@]}" \
    --change 'ENV PATH=/usr/local/bin:/usr/local/sbin:/usr/sbin:/usr/bin:/sbin:/bin' \
    --change 'ENV LANG=C.UTF-8' \
    --change 'CMD ["python3"]' - "$tag" >/dev/null
echo "base image $tag: built from Debian bookworm${platform:+ for $platform}"
