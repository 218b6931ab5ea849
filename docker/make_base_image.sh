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
case "${platform:-linux/$(dpkg --print-architecture)}" in
    linux/amd64) arch=amd64 ;;
    linux/arm64) arch=arm64 ;;
    *) echo "make_base_image: platform $platform is not linux/amd64 or linux/arm64" >&2; exit 2 ;;
esac
root="$(mktemp -d)"
trap 'rm -rf "$root"' EXIT
debootstrap --arch="$arch" --variant=minbase --include=python3,python3-pip,python3-venv,ca-certificates \
    bookworm "$root" http://deb.debian.org/debian >/dev/null
cp /etc/ssl/certs/ca-certificates.crt "$root/etc/ssl/certs/ca-certificates.crt"
printf '[global]\ncert = /etc/ssl/certs/ca-certificates.crt\nbreak-system-packages = true\n' \
    >"$root/etc/pip.conf"
ln -sf /usr/bin/python3 "$root/usr/local/bin/python"
ln -sf /usr/bin/pip3 "$root/usr/local/bin/pip"
rm -rf "$root/var/cache/apt/archives/"*.deb "$root/var/lib/apt/lists/"*
# `docker load` of a one-layer image rather than `docker import`: import records the engine's
# own architecture (its --platform is experimental), and an arm64 base labelled amd64 makes
# `docker build --platform linux/arm64` look for another one in a registry.
image="$(mktemp -d)"
trap 'rm -rf "$root" "$image"' EXIT
tar -C "$root" -cf "$image/layer.tar" .
layer="sha256:$(sha256sum "$image/layer.tar" | cut -d' ' -f1)"
printf '{"architecture":"%s","os":"linux","config":{"Env":["PATH=%s","LANG=C.UTF-8"],"Cmd":["python3"]},"rootfs":{"type":"layers","diff_ids":["%s"]}}' \
    "$arch" /usr/local/bin:/usr/local/sbin:/usr/sbin:/usr/bin:/sbin:/bin "$layer" >"$image/config.json"
printf '[{"Config":"config.json","RepoTags":["%s"],"Layers":["layer.tar"]}]' "$tag" \
    >"$image/manifest.json"
tar -C "$image" -c manifest.json config.json layer.tar | docker load >/dev/null
echo "base image $tag: built from Debian bookworm for linux/$arch"
