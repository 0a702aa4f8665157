#!/usr/bin/env bash
# The Debian package end to end: cpack builds it from the build tree, then in a throwaway root
# (an overlayfs over the host's / in a private mount namespace: the host is never written) it is
# installed, checked (files, user, conffiles, model image, the unit verifies, the installed
# scene loads), upgraded to a bumped version, removed (conffiles, user and state stay) and
# purged (nothing of it stays). Skips (77) when not root or when overlayfs cannot be mounted.
# usage: package_install_test.sh BUILD_DIR
set -euo pipefail
build=$1
[ "$(id -u)" -eq 0 ] || { echo "needs root (unshare, mount, chroot)"; exit 77; }
for tool in cpack dpkg-deb unshare; do
  command -v "$tool" >/dev/null || { echo "$tool not installed"; exit 77; }
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
started=$(date +%s.%N)

# 1. The package.
(cd "$build" && cpack -G DEB -B "$work/cpack" >"$work/cpack.log" 2>&1) ||
  { cat "$work/cpack.log"; exit 1; }
deb=$(ls "$work"/cpack/trainer_*.deb)
packed=$(date +%s.%N)
depends=$(dpkg-deb -f "$deb" Depends)
echo "$(basename "$deb"): Depends: $depends"
[[ "$depends" == *adduser*systemd* ]] || { echo "Depends lacks adduser/systemd"; exit 1; }
[[ "$depends" == *libc6* && "$depends" == *libusb-1.0-0* ]] ||
  { echo "Depends lacks the shlibdeps (libc6, libusb-1.0-0)"; exit 1; }
[ "$(dpkg-deb --ctrl-tarfile "$deb" | tar -t | grep -c -E '^\./(conffiles|postinst|prerm|postrm)$')" -eq 4 ] ||
  { echo "control archive lacks conffiles or a maintainer script"; exit 1; }
# The upgrade: the same contents with the Debian revision bumped.
mkdir "$work/repack"
dpkg-deb -R "$deb" "$work/repack"
sed -i -E 's/^(Version: .*-)([0-9]+)$/\1\2+upgrade1/' "$work/repack/DEBIAN/control"
dpkg-deb -Znone -b "$work/repack" "$work/trainer_upgrade.deb" >/dev/null
version2=$(dpkg-deb -f "$work/trainer_upgrade.deb" Version)

# 2. The throwaway root, and the checks run inside it.
cat >"$work/in_root.sh" <<'INNER'
#!/bin/bash
set -euo pipefail
fail() { echo "FAIL: $*"; exit 1; }
dpkg -i /tmp/pkg/trainer.deb
for path in /usr/bin/trainer /usr/bin/modelc /lib/systemd/system/trainer.service \
            /lib/udev/rules.d/60-trainer.rules /etc/trainer/scene.toml /etc/trainer/device.toml \
            /etc/default/trainer /usr/share/trainer/models/duct.toml; do
  [ -e "$path" ] || fail "$path not installed"
done
getent passwd trainer >/dev/null || fail "user trainer not created"
getent group trainer >/dev/null || fail "group trainer not created"
[ "$(stat -c %U /var/lib/trainer/reports)" = trainer ] || fail "reports not owned by trainer"
[ -s /var/lib/trainer/models/duct.img ] || { cat /var/lib/trainer/models/build.log; fail "no duct image"; }
grep -qx /etc/trainer/scene.toml /var/lib/dpkg/info/trainer.conffiles || fail "scene not a conffile"
systemd-analyze verify --man=no /lib/systemd/system/trainer.service 2>/tmp/verify.txt ||
  { cat /tmp/verify.txt; fail "systemd-analyze verify on the installed unit"; }
[ ! -s /tmp/verify.txt ] || { cat /tmp/verify.txt; fail "systemd-analyze verify printed messages"; }
! systemctl --root=/ is-enabled trainer.service >/dev/null 2>&1 || fail "enabled before commissioning"
# The installed scene, device file and image load: a short simulated run as the service user.
runuser -u trainer -- trainer --scene /etc/trainer/scene.toml --hal sim --time simulated \
  --cycles 200 --report-dir /var/lib/trainer/reports >/tmp/run.txt 2>&1 || { cat /tmp/run.txt; fail "run"; }
[ -L /var/lib/trainer/reports/latest.json ] || fail "no report"
echo "installed: files, user, conffiles, image, unit verifies, a 200-cycle run wrote $(readlink /var/lib/trainer/reports/latest.json)"
# What the unit grants, without systemd: user trainer with no capabilities, no new privileges,
# RLIMIT_RTPRIO 95 and RLIMIT_MEMLOCK unlimited (LimitRTPRIO=, LimitMEMLOCK=) — enough for
# SCHED_FIFO 80 and mlockall, and the self-check reads those limits, not a capability. Raising a
# hard limit needs CAP_SYS_RESOURCE; where this root lacks it (a container), the same run checks
# the other side: the limits it has are reported as failures and the run falls back.
if prlimit --rtprio=95 --memlock=unlimited true 2>/dev/null; then limits=raised; else limits=as-is; fi
as_service() {
  if [ "$limits" = raised ]; then set -- prlimit --rtprio=95 --memlock=unlimited -- "$@"; fi
  "$@"
}
service_user() {
  as_service setpriv --reuid=trainer --regid=trainer --init-groups --no-new-privs \
    --inh-caps=-all --bounding-set=-all -- "$@"
}
service_user trainer --check-rt --json --scene /etc/trainer/scene.toml >/tmp/check.json \
  2>/tmp/check.err || true
[ -s /tmp/check.json ] || { cat /tmp/check.err; fail "self-check as the service user"; }
service_user trainer --scene /usr/share/trainer/examples/scenes/wall.toml --seconds 0.5 --cpu 0 \
  --report /var/lib/trainer/reports/rt.json >/tmp/rt.txt 2>&1 || { cat /tmp/rt.txt; fail "RT run as the service user"; }
python3 - /tmp/check.json /var/lib/trainer/reports/rt.json "$limits" <<'PY' || fail "RT limits as the service user"
import json, sys
checks = {c["check"]: c for c in json.load(open(sys.argv[1]))["checks"]}
rt = json.load(open(sys.argv[2]))["rt"]
if sys.argv[3] == "raised":
    assert checks["memlock"]["outcome"] == "pass" and "unlimited" in checks["memlock"]["detail"], checks["memlock"]
    assert checks["rtprio"]["outcome"] == "pass" and "RLIMIT_RTPRIO 95" in checks["rtprio"]["detail"], checks["rtprio"]
    assert rt["policy"] == "SCHED_FIFO" and rt["priority"] == 80 and rt["memory_locked"] is True, rt
    print(f"as user trainer with the unit's limits: {rt['policy']} {rt['priority']}, memory locked")
else:
    assert checks["rtprio"]["outcome"] == "fail" and "LimitRTPRIO=" in checks["rtprio"]["fix"], checks["rtprio"]
    assert checks["memlock"]["outcome"] == "fail" and "KiB" in checks["memlock"]["detail"], checks["memlock"]
    assert rt["policy"] == "SCHED_OTHER" and rt["warnings"], rt
    print("limits cannot be raised here (no CAP_SYS_RESOURCE): as user trainer the self-check "
          f"fails rtprio/memlock ({checks['rtprio']['detail']}) and the run falls back to {rt['policy']}")
PY

echo "# local edit" >>/etc/trainer/scene.toml
dpkg -i /tmp/pkg/trainer_upgrade.deb
[ "$(dpkg-query -W -f='${Version}' trainer)" = "$VERSION2" ] || fail "not upgraded"
tail -n1 /etc/trainer/scene.toml | grep -q "# local edit" || fail "upgrade lost the conffile edit"
[ -L /var/lib/trainer/reports/latest.json ] || fail "upgrade lost the reports"
echo "upgraded to $VERSION2, conffile edit and reports kept"

dpkg -r trainer
[ ! -e /usr/bin/trainer ] || fail "remove left /usr/bin/trainer"
[ ! -e /lib/systemd/system/trainer.service ] || fail "remove left the unit"
[ -e /etc/trainer/scene.toml ] || fail "remove deleted a conffile"
getent passwd trainer >/dev/null || fail "remove deleted the user"
echo "removed: programs and unit gone; conffiles, user and /var/lib/trainer kept"

dpkg -P trainer
for path in /etc/trainer /etc/default/trainer /var/lib/trainer /usr/share/trainer \
            /lib/udev/rules.d/60-trainer.rules /var/lib/dpkg/info/trainer.list; do
  [ ! -e "$path" ] || fail "purge left $path"
done
! getent passwd trainer >/dev/null || fail "purge left user trainer"
! getent group trainer >/dev/null || fail "purge left group trainer"
[ -z "$(dpkg-query -W -f='${Status}' trainer 2>/dev/null | grep -v 'not-installed')" ] ||
  fail "dpkg still knows the package: $(dpkg-query -W -f='${Status}' trainer)"
echo "purged: nothing left"
INNER
chmod +x "$work/in_root.sh"
mkdir -p "$work/pkg"
cp "$deb" "$work/pkg/trainer.deb"
cp "$work/trainer_upgrade.deb" "$work/pkg/"

status=0
unshare -m --propagation private bash -euo pipefail -c '
  work=$1
  mkdir -p "$work/layer" "$work/merged"
  mount -t tmpfs tmpfs "$work/layer"
  mkdir "$work/layer/upper" "$work/layer/work"
  mount -t overlay overlay -o "lowerdir=/,upperdir=$work/layer/upper,workdir=$work/layer/work" \
    "$work/merged" || exit 77
  mount -t proc proc "$work/merged/proc"
  mount --rbind /dev "$work/merged/dev"
  mount -t tmpfs tmpfs "$work/merged/tmp"
  mount -t tmpfs tmpfs "$work/merged/run"
  mkdir "$work/merged/tmp/pkg"
  cp "$work"/pkg/*.deb "$work/merged/tmp/pkg/"
  cp "$work/in_root.sh" "$work/merged/tmp/"
  VERSION2=$2 chroot "$work/merged" /tmp/in_root.sh
  # What the whole sequence left in the root: the upper layer, minus dpkg'"'"'s own records.
  (cd "$work/layer/upper" && find . -mindepth 1 ! -type d | grep -v -E "^\./(var/lib/dpkg|var/log|var/cache|tmp|run|etc/(passwd|group|shadow|gshadow|subuid|subgid)-?$)" || true) \
    >"$work/left.txt"
' _ "$work" "$version2" || status=$?
[ "$status" -eq 77 ] && { echo "overlayfs over / not possible here"; exit 77; }
[ "$status" -eq 0 ] || exit "$status"
if grep -i trainer "$work/left.txt"; then echo "FAIL: the purge left the files above"; exit 1; fi
echo "left in the root after the purge (not the package's): $(tr '\n' ' ' <"$work/left.txt")"
finished=$(date +%s.%N)
python3 -c "import sys; a,b,c=map(float,sys.argv[1:]); print(f'cpack {b-a:.1f} s, install/upgrade/remove/purge {c-b:.1f} s')" \
  "$started" "$packed" "$finished"
