#!/usr/bin/env bash
# Run a command where this x86 machine can run linux/arm64 binaries: QEMU's user-mode emulator
# registered with the kernel's binfmt_misc with the F flag (interpreter opened at registration),
# so it also works inside containers and debootstrap's chroot, which hold no QEMU of their own.
# As root it mounts binfmt_misc, installs QEMU >= 10 from Debian when an older one (or none) is
# there, and registers the handler; otherwise, or when a step fails, the command runs anyway and
# the arm64 tests skip, naming the missing capability (tests/e2e/test_docker_arm64.py). Silent:
# that skip line is the one message. Re-runnable: a second run finds QEMU current and registered.
#
# Why 10: under bookworm's QEMU 7.2 the arm64 onnxruntime wheel segfaults while its extension
# loads and the faulted process then hangs instead of exiting, so the daemon never answers;
# QEMU 10.0 (trixie, and bookworm-backports for bookworm hosts) imports and runs it
# (bench/results/docker_arm64.md). From 9.1 on Debian ships the static emulator in `qemu-user`
# and registers it through binfmt.d files rather than update-binfmts.
set -uo pipefail
binfmt=/proc/sys/fs/binfmt_misc
min_major=10
qemu_major() {
    qemu-aarch64-static --version 2>/dev/null | sed -n 's/^qemu-aarch64 version \([0-9]*\)\..*/\1/p'
}
install_qemu() {
    local release
    release="$(. /etc/os-release 2>/dev/null && echo "${VERSION_CODENAME:-}")"
    local target=()
    if [ "$release" = bookworm ]; then
        grep -rqs bookworm-backports /etc/apt/sources.list /etc/apt/sources.list.d/ \
            || echo "deb http://deb.debian.org/debian bookworm-backports main" \
                >/etc/apt/sources.list.d/bookworm-backports.list
        target=(-t bookworm-backports)
    fi
    apt-get update -qq >/dev/null 2>&1
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${target[@]}" qemu-user-static \
        >/dev/null 2>&1
}
register() {
    # Replacing the package leaves the kernel holding the old emulator (F flag), or the old
    # package's removal unregisters it: register the installed one afresh.
    local conf=/usr/share/qemu/binfmt.d/qemu-aarch64.conf
    if [ -f "$conf" ]; then
        [ -e "$binfmt/qemu-aarch64" ] && echo -1 >"$binfmt/qemu-aarch64"
        grep -v '^#' "$conf" >"$binfmt/register"
    else
        update-binfmts --enable qemu-aarch64
    fi
}
if [ "$(id -u)" = 0 ] && [ "$(uname -m)" != aarch64 ]; then
    [ -e "$binfmt/register" ] || mount -t binfmt_misc binfmt_misc "$binfmt" >/dev/null 2>&1
    major="$(qemu_major)"
    if [ "${major:-0}" -lt "$min_major" ]; then
        install_qemu && register >/dev/null 2>&1
    elif ! grep -qx enabled "$binfmt/qemu-aarch64" 2>/dev/null; then
        register >/dev/null 2>&1
    fi
fi
exec "$@"
