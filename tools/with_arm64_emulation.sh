#!/usr/bin/env bash
# Run a command where this x86 machine can run linux/arm64 binaries: QEMU's user-mode emulator
# registered with the kernel's binfmt_misc (Debian's qemu-user-static registers it with the F
# flag, so the interpreter also works inside containers and debootstrap's chroot). As root it
# mounts binfmt_misc, installs qemu-user-static from Debian when missing and enables the handler;
# otherwise, or when a step fails, the command runs anyway and the arm64 tests skip, naming the
# missing capability (tests/e2e/test_docker_arm64.py). Silent: that skip line is the one message.
set -uo pipefail
binfmt=/proc/sys/fs/binfmt_misc
if [ "$(id -u)" = 0 ] && ! grep -qx enabled "$binfmt/qemu-aarch64" 2>/dev/null; then
    [ -e "$binfmt/register" ] || mount -t binfmt_misc binfmt_misc "$binfmt" >/dev/null 2>&1
    if ! command -v update-binfmts >/dev/null 2>&1 || [ ! -e /usr/share/binfmts/qemu-aarch64 ]; then
        apt-get update -qq >/dev/null 2>&1
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq qemu-user-static binfmt-support \
            >/dev/null 2>&1
    fi
    update-binfmts --enable qemu-aarch64 >/dev/null 2>&1
fi
exec "$@"
